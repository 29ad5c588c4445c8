//! The passes of one light, in the order
//! [`DepthComplexitySampling::light`](super::DepthComplexitySampling)
//! runs them after the kit's per-light start (the opaque casters' shadow
//! volume and stencil counts `D(O)`):
//!
//! 1. [`group_starts`]: one shadow volume and start count per semi-opaque
//!    caster group.
//! 2. [`recount_ties`]: start counts decided by a depth tie, recounted
//!    exactly at the shadow-ray origin.
//! 3. [`candidate_edges`] and [`build_wedges`]: every group's candidate
//!    edges and their wedges (or, for an edge without a bounded wedge, its
//!    screen rectangle and world region).
//! 4. [`wedge_membership`]: the (pixel, edge) pairs inside a half-wedge.
//! 5. [`s_triangle_membership`]: the (pixel, S-triangle) pairs inside a
//!    soft textured shadow volume.
//! 6. [`count_tiles`]: tile by tile, every receiver's counters and their
//!    Vcoef or direct light ([`receiver`](super::receiver)).
//! 7. [`assemble`] and, for interleaved sampling, [`gather`]: the images.

use super::bitfield::{CoverageTables, TableResolution};
use super::block_extras::{BlockExtras, BLOCK};
use super::chart::ReceiverChart;
use super::counters::ChartSamples;
use super::edges::{CandidateEdge, CandidateEdges, LightShapeForSilhouettes};
use super::options::{CoverageTest, SilhouetteMode};
use super::receiver::{Extras, GroupPass, LightPass, PixelResult, Scratch};
use super::region::{ReceiverBlock, ReceiverBoxes, RegionBound};
use super::settings::{DcsLightReport, DepthComplexitySampling};
use super::ties::{cap_segment, own_face_change, tied_from_changes, tied_pixels, ExactStart, Tie};
use crate::error::{Error, Result};
use crate::geom::silhouette::faces_point;
use crate::geom::EdgeAdjacency;
use crate::raster::{Framebuffer, TileGrid, TILE_PIXELS, TILE_SIZE};
use crate::sampling::{LightSampler, PatternSampler, SamplePattern};
use crate::scene::{Light, LightShape};
use crate::shade::gather::{gather_filter, GatherParams};
use crate::shadow::kit::groups::Attenuation;
use crate::shadow::kit::membership::{draw_wedges, HalfSink, LightStart, MembershipTile};
use crate::shadow::kit::rays::scene_diagonal;
use crate::shadow::kit::stsv::{
    membership as stsv_membership, STriangles, ShadowOrigin, StsvMembership,
};
use crate::shadow::kit::tiles::TilePixels;
use crate::shadow::kit::timing::{timed, PassTimer};
use crate::shadow::kit::volumes::{build_volume, stencil_counts, ShadowVolume};
use crate::shadow::kit::wedge_geometry::{HalfWedge, LightBound, SilhouetteQuad, Wedges};
use crate::shadow::{PassTiming, ShadowContext};
use crate::simd::level::runs_v3;
use crate::view::View;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// One caster group's shadow-volume start for a light.
pub(super) struct GroupStart<'a> {
    /// What one layer of the group attenuates.
    pub attenuation: Attenuation,
    /// The group's casters.
    pub adj: &'a EdgeAdjacency,
    /// Stencil count `D(O)` (a layer count for semi-opaque groups) per
    /// pixel.
    pub counts: Vec<i32>,
    /// The hard shadow volume the counts came from.
    pub volume: ShadowVolume,
    /// The counts' changes under the tie test's depth shifts
    /// ([`ties::depth_shifts`](super::ties::depth_shifts)), when the
    /// stencil pass made them; empty otherwise.
    pub shift_changes: Vec<Vec<i32>>,
}

/// Every caster group's start for light `k`: the opaque group's from the
/// kit's `start`, then one per semi-opaque opacity in `partial`, each
/// with its own shadow volume and stencil counts (the stencil pass reuses
/// the scene depth of the start's framebuffer, returned for the wedges).
pub(super) fn group_starts<'a>(
    ctx: &ShadowContext,
    k: usize,
    (start, shift_changes): (LightStart<'a>, Vec<Vec<i32>>),
    partial: &'a [(Attenuation, EdgeAdjacency)],
    passes: &mut Vec<PassTiming>,
) -> Result<(Vec<GroupStart<'a>>, Framebuffer)> {
    let LightStart {
        adj,
        point,
        counts,
        mut framebuffer,
        volume,
        ..
    } = start;
    let t = PassTimer::start(format!("semi-opaque shadow volumes light {k}"));
    let mut groups = vec![GroupStart {
        attenuation: Attenuation::Opaque,
        adj,
        counts,
        volume,
        shift_changes,
    }];
    for (attenuation, adj) in partial {
        let volume = build_volume(adj, ctx.view, point);
        let counts = stencil_counts(&mut framebuffer, &volume, false)?;
        groups.push(GroupStart {
            attenuation: *attenuation,
            adj,
            counts,
            volume,
            shift_changes: Vec::new(),
        });
    }
    if groups.len() > 1 {
        t.finish(passes);
    }
    Ok((groups, framebuffer))
}

/// Side of the square pixel blocks whose own-face receivers share one
/// test for other caps near their segments (`recount_ties`): one query
/// per face per block, so larger blocks query a face seen across block
/// borders once (tie pass on bunny.toml at 1024²: ~42.9 ms with 8² blocks,
/// ~39.9 with 16², ~38.9 with 32²; medians of 5).
const CAP_BLOCK: usize = 32;

/// Most faces near one face's receivers of a block tested directly;
/// beyond, each receiver walks the tree.
const CAP_LIST: usize = 16;

/// Depth ties of the start counts ([`ties`](super::ties)), recounted in
/// `groups` exactly at the shadow-ray origin by one ray to the centre
/// `point`; per pixel, its [`Tie`] (after the recount, [`Tie::Tied`]
/// means recounted), and the exact counter the counter pass uses for
/// own-face ties at a quad (see `receiver.rs`). Only in the exact mode
/// (whole-light silhouettes), where per-sample counts are meant to equal
/// ray casting; the fast centre mode keeps the thesis's approximations
/// and the stencil's constant.
pub(super) fn recount_ties<'a>(
    ctx: &ShadowContext<'a>,
    k: usize,
    point: Vec3,
    groups: &mut [GroupStart],
    mode: SilhouetteMode,
    passes: &mut Vec<PassTiming>,
) -> Result<(Vec<Tie>, ExactStart<'a>)> {
    let timer = PassTimer::start(format!("start-count ties light {k}"));
    let mut tied = vec![Tie::None; ctx.gbuffer.len()];
    let lits: Vec<Vec<bool>> = groups.iter().map(|g| faces_point(g.adj, point)).collect();
    if mode == SilhouetteMode::WholeLight {
        own_face_ties(ctx, point, groups, &lits, &mut tied)?;
    }
    let sets: Vec<(&EdgeAdjacency, &[bool])> = groups
        .iter()
        .zip(&lits)
        .map(|(group, lit)| (group.adj, lit.as_slice()))
        .collect();
    let exact = ExactStart::new(ctx.geometry, &sets);
    let origin = ShadowOrigin::new(ctx.scene, ctx.geometry);
    if tied.par_iter().any(|&t| t == Tie::OwnFace) {
        exact.prepare();
    }
    let demoted = near_other_caps(ctx, &tied, &exact, &origin);
    for &i in &demoted {
        tied[i] = Tie::Tied;
    }
    let recounted = recount_tied(ctx, point, groups, &tied, &exact, &origin);
    let own = tied.iter().filter(|&&t| t == Tie::OwnFace).count();
    timer.finish_with(
        passes,
        format!(
            "{} receivers recounted ({} near another cap), {own} on their own face",
            recounted,
            demoted.len()
        ),
    );
    Ok((tied, exact))
}

/// Into `tied`, every group's depth ties of its start counts, with the
/// own-face verdict where the receiver lies on one of the group's caps
/// (`lits`: per group, which faces see the centre `point`).
fn own_face_ties(
    ctx: &ShadowContext,
    point: Vec3,
    groups: &[GroupStart],
    lits: &[Vec<bool>],
    tied: &mut [Tie],
) -> Result<()> {
    // Per scene triangle: the group it is a cap of, and its stencil
    // weight there (closed casters: light-facing; open: every face).
    let mut cap = vec![(usize::MAX, 0); ctx.geometry.triangles.len()];
    for (k, (group, lit)) in groups.iter().zip(lits).enumerate() {
        for (slot, &face) in group.adj.faces.iter().enumerate() {
            let weight = if group.adj.face_closed[slot] {
                i32::from(lit[slot])
            } else {
                1
            };
            cap[face as usize] = (k, weight);
        }
    }
    for (k, group) in groups.iter().enumerate() {
        let own_face = |i: usize| {
            let Some((position, geo_normal, triangle)) = ctx.gbuffer.surface_geometry(i) else {
                return Some(0);
            };
            match cap.get(triangle as usize) {
                Some(&(c, weight)) if c == k => {
                    own_face_change(weight, geo_normal, position, point)
                }
                _ => Some(0),
            }
        };
        let group_tied = if group.shift_changes.is_empty() {
            tied_pixels(ctx.depth, &group.volume, &group.counts, true, own_face)?
        } else {
            tied_from_changes(&group.shift_changes, &group.counts, own_face)?
        };
        tied.par_iter_mut()
            .zip(group_tied)
            .with_min_len(4096)
            .for_each(|(a, b)| *a = (*a).max(b));
    }
    Ok(())
}

/// The own-face receivers of `tied` whose verdict does not hold: an
/// own-face verdict holds only where no other cap face comes between the
/// stencil's point and `p'` ([`ExactStart::cap_near`]): a face folded
/// over the receiver's own (bunny.toml at 1024², pixel (644, 446)) lies
/// across the normal offset but off the view ray, where the
/// depth-shifted counts cannot see it.
fn near_other_caps(
    ctx: &ShadowContext,
    tied: &[Tie],
    exact: &ExactStart,
    origin: &ShadowOrigin,
) -> Vec<usize> {
    let width = ctx.gbuffer.width as usize;
    let height = ctx.gbuffer.len() / width.max(1);
    let blocks_x = width.div_ceil(CAP_BLOCK);
    (0..blocks_x * height.div_ceil(CAP_BLOCK))
        .into_par_iter()
        .flat_map_iter(|b| {
            let corner = (b % blocks_x * CAP_BLOCK, b / blocks_x * CAP_BLOCK);
            let mut block = own_face_segments(ctx, tied, origin, corner, (width, height));
            // One query for the receivers of the block on one face: the
            // cap faces other than their own that come near any of their
            // segments (none on most of a ground, a handful of neighbours
            // on a mesh), then each segment against those alone. (Pushed in
            // pixel order: a stable sort by face keeps it within a face,
            // and finds a 32² block's long runs of one face in one pass.)
            block.sort_by_key(|r| r.1);
            let mut near = Vec::new();
            let mut caps = Vec::new();
            for on_face in block.chunk_by(|a, b| a.1 == b.1) {
                let own = on_face[0].1;
                let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
                for &(_, _, start, dir) in on_face {
                    lo = lo.min(start).min(start + dir);
                    hi = hi.max(start).max(start + dir);
                }
                let listed = exact.caps_near(own, lo, hi, CAP_LIST, &mut caps);
                if listed && caps.is_empty() {
                    continue;
                }
                for &(i, own, start, dir) in on_face {
                    let hit = if listed {
                        exact.cap_near_among(&caps, (start, dir))
                    } else {
                        exact.cap_near(own, (start, dir))
                    };
                    if hit {
                        near.push(i);
                    }
                }
            }
            near
        })
        .collect()
}

/// The own-face receivers of `tied` in the [`CAP_BLOCK`]² block at
/// `(x, y)` of a `(width, height)` screen, in pixel order: pixel, face,
/// and the segment from the stencil's point to `p'` ([`cap_segment`]).
fn own_face_segments(
    ctx: &ShadowContext,
    tied: &[Tie],
    origin: &ShadowOrigin,
    (block_x, block_y): (usize, usize),
    (width, height): (usize, usize),
) -> Vec<(usize, u32, Vec3, Vec3)> {
    let eye = ctx.view.eye.as_vec3();
    let mut block = Vec::new();
    for y in block_y..(block_y + CAP_BLOCK).min(height) {
        for x in block_x..(block_x + CAP_BLOCK).min(width) {
            let i = y * width + x;
            if tied[i] != Tie::OwnFace {
                continue;
            }
            if let Some((position, geo_normal, triangle)) = ctx.gbuffer.surface_geometry(i) {
                let p_ray = origin.of(position, geo_normal);
                let (start, dir) = cap_segment(position, p_ray, eye);
                block.push((i, triangle, start, dir));
            }
        }
    }
    block
}

/// Every group's start count at the tied surface receivers of `tied`,
/// by one ray from `p'` to the centre `point`; how many were recounted.
fn recount_tied(
    ctx: &ShadowContext,
    point: Vec3,
    groups: &mut [GroupStart],
    tied: &[Tie],
    exact: &ExactStart,
    origin: &ShadowOrigin,
) -> usize {
    let tied_surface: Vec<usize> = (0..tied.len())
        .into_par_iter()
        .with_min_len(4096)
        .filter(|&i| tied[i] == Tie::Tied && ctx.gbuffer.is_surface(i))
        .collect();
    if !tied_surface.is_empty() {
        let n_groups = groups.len();
        let fixes: Vec<(usize, Vec<i32>)> = tied_surface
            .par_iter()
            .map(|&i| {
                let sample = ctx.gbuffer.sample(i);
                let mut counts = vec![0; n_groups];
                exact.counts(
                    origin.of(sample.position, sample.geo_normal),
                    point,
                    &mut counts,
                );
                (i, counts)
            })
            .collect();
        for (i, counts) in fixes {
            for (group, count) in groups.iter_mut().zip(counts) {
                group.counts[i] = count;
            }
        }
    }
    tied_surface.len()
}

/// Every group's candidate edges from `light` (centre `point`) in
/// `dcs`'s [`SilhouetteMode`], with its start counts: the groups of the
/// counter pass, their edges numbered globally, contiguous per group.
pub(super) fn candidate_edges(
    light: &Light,
    point: Vec3,
    dcs: &DepthComplexitySampling,
    groups: Vec<GroupStart>,
) -> Vec<GroupPass> {
    let corners: Vec<Vec3>;
    let shape = match light.shape {
        LightShape::Rect { center, u, v, .. } => {
            corners = vec![
                center - u - v,
                center + u - v,
                center + u + v,
                center - u + v,
            ];
            LightShapeForSilhouettes::Polygon(&corners)
        }
        LightShape::Sphere { center, radius } => LightShapeForSilhouettes::Sphere {
            center: center.as_dvec3(),
            radius: f64::from(radius),
        },
    };
    let mut next_edge = 0u32;
    groups
        .into_iter()
        .map(|group| {
            let lit = faces_point(group.adj, point);
            let candidates = CandidateEdges::build(group.adj, &lit, dcs.silhouettes, shape);
            let first_edge = next_edge;
            next_edge += candidates.edges.len() as u32;
            GroupPass {
                per_layer: dcs.transmittance.per_layer(group.attenuation),
                candidates,
                start: group.counts,
                first_edge,
            }
        })
        .collect()
}

/// An edge with no bounded wedge: its global id, the screen rectangle
/// `[x0, y0, x1, y1)` and the world-space half-spaces holding every
/// receiver it can affect.
pub(super) struct UnboundedEdge {
    id: u32,
    rect: [usize; 4],
    region: RegionBound,
}

/// Candidate edges whose regions [`build_wedges`] builds at once (in
/// parallel) before moving them into its lists: 8 MB or so of regions in
/// flight, whatever the edge count.
const REGION_CHUNK: usize = 1 << 14;

/// Unbounded edges per [`EdgeCluster`] (consecutive in id order, which
/// follows the meshes' own order and so is spatially coherent).
const CLUSTER: usize = 32;

/// A run of [`CLUSTER`] consecutive unbounded edges culled together (the
/// edge hierarchy of Laine et al. 2005, one level): the union of their
/// screen rectangles and a world-space bound holding all their regions
/// ([`RegionBound::around_box`]), so that a tile rejects the whole run by
/// one test. Conservative: every edge it lets through is still tested
/// alone, so the edges reaching a receiver are the same.
pub(super) struct EdgeCluster {
    edges: std::ops::Range<usize>,
    rect: [usize; 4],
    region: RegionBound,
}

/// One light's wedges over every group's candidate edges.
pub(super) struct LightWedges {
    /// Both wedge sets.
    pub wedges: Wedges,
    /// Global candidate edge of each z-fail half.
    pub zfail_edge: Vec<u32>,
    /// Global candidate edge of each z-pass half.
    pub zpass_edge: Vec<u32>,
    /// Edges without a bounded wedge, tested per receiver instead.
    pub unbounded: Vec<UnboundedEdge>,
    /// The unbounded edges' clusters, in order.
    pub clusters: Vec<EdgeCluster>,
}

impl LightWedges {
    /// Bytes of the unbounded edges' and clusters' regions and of the
    /// halves' edge ids (the wedges' own triangles are counted with the
    /// membership pairs they make).
    pub fn region_bytes(&self) -> u64 {
        // Each item's own size, its region's inline part included, and its
        // region's plane groups.
        fn held<'r, T: 'r>(regions: impl Iterator<Item = &'r RegionBound>) -> usize {
            regions
                .map(|r| std::mem::size_of::<T>() - std::mem::size_of::<RegionBound>() + r.bytes())
                .sum()
        }
        let unbounded = held::<UnboundedEdge>(self.unbounded.iter().map(|u| &u.region));
        let clusters = held::<EdgeCluster>(self.clusters.iter().map(|c| &c.region));
        (unbounded + clusters + 4 * (self.zfail_edge.len() + self.zpass_edge.len())) as u64
    }
}

/// The wedge of every candidate edge of `groups` from the light `bound`
/// (centre `point`), or, for an edge without a bounded wedge, its
/// [`UnboundedEdge`].
pub(super) fn build_wedges(
    ctx: &ShadowContext,
    bound: &LightBound,
    point: Vec3,
    groups: &[GroupPass],
    silhouettes: SilhouetteMode,
) -> LightWedges {
    let mut wedges = Wedges::default();
    let (mut zfail_edge, mut zpass_edge) = (Vec::new(), Vec::new());
    let mut unbounded = Vec::new();
    let mut ends: Vec<(DVec3, DVec3)> = Vec::new();
    let corners = light_corners(bound);
    // Receivers' positions round at f32 and move by the shadow-ray
    // offset (≤ 1e-5 relative): a generous slack keeps the test
    // conservative.
    let slack = 1e-4 * scene_diagonal(ctx.scene, ctx.geometry);
    let region_of = |e: &CandidateEdge, dihedral: Option<[(DVec3, f64); 2]>| {
        let region = RegionBound::new(e.v0, e.v1, &corners, slack);
        let region = match dihedral {
            Some(faces) => region.with_dihedral(faces, slack),
            None => region,
        };
        (fallback_rect(ctx.view, e, bound), region)
    };
    for group in groups {
        let candidates = &group.candidates;
        // In whole-light mode an edge matters only where it is a
        // silhouette from the receiver: the dihedral region of its two
        // faces, inside its wedge. A world-space test of that region
        // finds those receivers far more cheaply than rasterizing a full
        // wedge per edge (most of a centre silhouette's wedge lies
        // outside it: 58 % of the wedge pairs on `bunny.toml`), so every
        // manifold edge takes it. The centre mode counts a centre
        // silhouette at every receiver of its wedge (the thesis's rule),
        // so there only the other edges do. Those regions are built in
        // parallel (each edge's alone), the wedges in order.
        // Room for every edge: growing a list of region bounds by doubling
        // copied megabytes.
        unbounded.reserve(candidates.edges.len());
        ends.reserve(candidates.edges.len());
        // Chunk by chunk: the regions of a whole group at once, beside
        // the list they move into, doubled the build's peak (1.0M edges
        // of ~0.5 kB at 4.1M triangles).
        for (c, chunk) in candidates.edges.chunks(REGION_CHUNK).enumerate() {
            let first = group.first_edge + (c * REGION_CHUNK) as u32;
            let by_region: Vec<_> = chunk
                .par_iter()
                .map(|e| {
                    let wanted = silhouettes == SilhouetteMode::WholeLight || e.quad_sign == 0;
                    let dihedral = wanted.then(|| candidates.dihedral(e)).flatten();
                    dihedral.map(|faces| region_of(e, Some(faces)))
                })
                .collect();
            if by_region.iter().all(Option::is_some) {
                // Every edge has its region (closed meshes in whole-light
                // mode): moved into the lists in parallel, in order (the
                // serial moves and first touches of ~0.4 kB regions were
                // ~5 ms of bunny.toml's build). Only an indexed iterator
                // extends in place: a filtered parallel extend for every
                // group (rayon's chunk lists, then a serial append) made
                // bunny.toml's build ~32.9 ms against ~29.3 with this path.
                ends.par_extend(chunk.par_iter().map(|e| (e.v0, e.v1)));
                unbounded.par_extend(by_region.into_par_iter().enumerate().map(|(k, regional)| {
                    let (rect, region) = regional.expect("every edge has its region");
                    UnboundedEdge {
                        id: first + k as u32,
                        rect,
                        region,
                    }
                }));
                continue;
            }
            for ((id, e), regional) in (first..).zip(chunk).zip(by_region) {
                // The quad as the stencil pass drew it, or (no quad) any
                // order.
                let (q0, q1) = if e.quad_sign < 0 {
                    (e.v1, e.v0)
                } else {
                    (e.v0, e.v1)
                };
                let quad = SilhouetteQuad {
                    q0: q0.as_vec3(),
                    q1: q1.as_vec3(),
                    weight: e.quad_weight,
                };
                let regional = match regional {
                    Some(r) => Some(r),
                    None if !wedges.add(ctx.view, bound, point, quad, None) => {
                        Some(region_of(e, None))
                    }
                    None => None,
                };
                if let Some((rect, region)) = regional {
                    unbounded.push(UnboundedEdge { id, rect, region });
                    ends.push((e.v0, e.v1));
                    continue;
                }
                zfail_edge.resize(wedges.zfail.halves.len(), id);
                zpass_edge.resize(wedges.zpass.halves.len(), id);
            }
        }
    }
    let clusters = (0..unbounded.len().div_ceil(CLUSTER))
        .into_par_iter()
        .map(|k| {
            let first = k * CLUSTER;
            let edges = first..(first + CLUSTER).min(unbounded.len());
            let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
            let mut rect = [usize::MAX, usize::MAX, 0, 0];
            for (u, &(v0, v1)) in unbounded[edges.clone()].iter().zip(&ends[edges.clone()]) {
                (lo, hi) = (lo.min(v0).min(v1), hi.max(v0).max(v1));
                rect = [
                    rect[0].min(u.rect[0]),
                    rect[1].min(u.rect[1]),
                    rect[2].max(u.rect[2]),
                    rect[3].max(u.rect[3]),
                ];
            }
            EdgeCluster {
                edges,
                rect,
                region: RegionBound::around_box(lo, hi, &corners, slack),
            }
        })
        .collect();
    LightWedges {
        wedges,
        zfail_edge,
        zpass_edge,
        unbounded,
        clusters,
    }
}

/// The screen rectangle `[x0, y0, x1, y1)` (pixels) holding every
/// receiver from which edge `e` can be seen overlapping the light: such a
/// receiver lies on a ray from a light point `x` through the edge, beyond
/// it, i.e. in `conv({v0, v1}) + cone{v_i − x_j}` over the light's
/// bounding corners `x_j` — a convex set whose image is the hull of its
/// projected vertices (finite ones and vanishing points), when all are in
/// front of the eye; otherwise the whole screen. Used for the few edges
/// whose line pierces the light, where no bounded wedge exists.
fn fallback_rect(view: &View, e: &CandidateEdge, light: &LightBound) -> [usize; 4] {
    let whole = [0, 0, view.width as usize, view.height as usize];
    let corners = light_corners(light);
    let mut clip = vec![
        view.clip_point(e.v0.as_vec3()),
        view.clip_point(e.v1.as_vec3()),
    ];
    for q in [e.v0, e.v1] {
        for x in &corners {
            clip.push(view.clip_direction((q - *x).as_vec3()));
        }
    }
    let (w, h) = (f64::from(view.width), f64::from(view.height));
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for c in clip {
        if !(c.w > 1e-6 * c.truncate().length()) {
            return whole;
        }
        let iw = 1.0 / f64::from(c.w);
        let sx = (f64::from(c.x) * iw * 0.5 + 0.5) * w;
        let sy = (0.5 - f64::from(c.y) * iw * 0.5) * h;
        b = [b[0].min(sx), b[1].min(sy), b[2].max(sx), b[3].max(sy)];
    }
    // One pixel of slack covers the f32 clip coordinates' rounding.
    let lo = |v: f64, max: f64| (v - 1.0).floor().clamp(0.0, max) as usize;
    let hi = |v: f64, max: f64| (v + 2.0).floor().clamp(0.0, max) as usize;
    [lo(b[0], w), lo(b[1], h), hi(b[2], w), hi(b[3], h)]
}

/// Corners of a convex polytope holding the light: the rect's own, or a
/// sphere's bounding cube.
fn light_corners(light: &LightBound) -> Vec<DVec3> {
    match light {
        LightBound::Rect(frame) => frame.corners().to_vec(),
        LightBound::Sphere { center, radius } => (0..8)
            .map(|k| {
                let s = |b: usize| if k >> b & 1 == 1 { *radius } else { -*radius };
                *center + DVec3::new(s(0), s(1), s(2))
            })
            .collect(),
    }
}

/// One tile of the membership pass: its (pixel, edge) pairs
/// `local << 33 | edge << 1 | outer`, so that sorting groups them by
/// pixel.
pub(super) type PairTile = MembershipTile<Vec<u64>>;

/// What the membership pass does with a finished half-wedge: records its
/// (pixel, edge) pairs.
struct PairSink<'a> {
    halves: &'a [HalfWedge],
    /// Candidate edge of each half.
    half_edge: &'a [u32],
}

impl HalfSink for PairSink<'_> {
    type Tile = Vec<u64>;
    /// The half's tag `edge << 1 | outer`.
    type Half = u64;

    fn half(&self, h: u32) -> u64 {
        u64::from(self.half_edge[h as usize]) << 1 | u64::from(self.halves[h as usize].outer)
    }

    fn inside(&self, &tag: &u64, entries: &mut Vec<u64>, local: usize) {
        entries.push((local as u64) << 33 | tag);
    }
}

/// Which pixels each half-wedge of `w` holds, per tile of `framebuffer`
/// (the scene depth).
pub(super) fn wedge_membership(
    framebuffer: &mut Framebuffer,
    w: &LightWedges,
) -> Result<Vec<PairTile>> {
    let grid = framebuffer.grid();
    let mut tiles: Vec<PairTile> = (0..grid.tile_count())
        .map(|_| MembershipTile::new(Vec::new()))
        .collect();
    draw_wedges(framebuffer, &mut tiles, &w.wedges, |set, zpass| PairSink {
        halves: &set.halves,
        half_edge: if zpass { &w.zpass_edge } else { &w.zfail_edge },
    })?;
    Ok(tiles)
}

/// Soft textured shadow volumes: which receivers lie in which of
/// `s_triangles`' volumes from light `k`; `None` (and no pass) when the
/// scene has no S-triangle.
pub(super) fn s_triangle_membership(
    ctx: &ShadowContext,
    k: usize,
    s_triangles: &STriangles,
    passes: &mut Vec<PassTiming>,
) -> Result<Option<StsvMembership>> {
    if s_triangles.is_empty() {
        return Ok(None);
    }
    let name = format!("soft textured shadow volumes light {k}");
    timed(passes, name, || stsv_membership(ctx, k, s_triangles)).map(Some)
}

/// The bit-field tables of light `k` (none with the exact test): one per
/// sample set, built from the chart of a pixel that uses it.
pub(super) fn coverage_tables(
    dcs: &DepthComplexitySampling,
    ctx: &ShadowContext,
    k: usize,
    bound: &LightBound,
) -> Result<Vec<CoverageTables>> {
    if dcs.coverage == CoverageTest::Exact {
        return Ok(Vec::new());
    }
    let light = &ctx.scene.lights[k];
    let bad = |e: String| Error::param("--coverage", e);
    let sets = CoverageTables::applicable(dcs.pattern, &light.shape).map_err(bad)?;
    let sampler = LightSampler::new(light);
    let pattern = PatternSampler::new(dcs.pattern, dcs.samples, dcs.seed, k);
    let n = match dcs.pattern {
        SamplePattern::Interleaved { n } => n.max(1),
        _ => 1,
    };
    let mut samples = Vec::new();
    let mut chart = ChartSamples::default();
    (0..sets)
        .map(|set| {
            let pixel = (set % n, set / n);
            // Rect lights: the chart does not depend on the receiver.
            let p = DVec3::ZERO;
            sampler.samples_with(&pattern, p.as_vec3(), pixel, &mut samples);
            let frame = ReceiverChart::new(bound, p).ok_or_else(|| bad("no chart".into()))?;
            chart.set(samples.iter().map(|s| frame.point(s.x.as_dvec3())));
            CoverageTables::from_chart(&chart, TableResolution::default()).map_err(bad)
        })
        .collect()
}

/// One tile's results of the counter pass.
pub(super) struct TileResult {
    /// Per local pixel.
    pixels: Vec<PixelResult>,
    /// (pixel, edge) pairs the membership pass recorded.
    pairs: usize,
    /// Receivers that needed per-sample counters.
    sampled: usize,
    /// (pixel, unbounded edge) pairs.
    unbounded: usize,
    /// Receivers whose start count was recounted across a quad.
    recounted: usize,
}

impl TileResult {
    /// A tile not computed (the render was cancelled).
    fn blank() -> Self {
        TileResult {
            pixels: vec![PixelResult::default(); TILE_PIXELS],
            pairs: 0,
            sampled: 0,
            unbounded: 0,
            recounted: 0,
        }
    }
}

/// Side of the blocks whose receivers' bounding box narrows a tile's
/// unbounded edges first.
const OUTER: usize = 16;
/// Side of the blocks whose edge lists the pixels test.
const INNER: usize = 4;

/// Side of the blocks between [`OUTER`] and [`INNER`].
const MIDDLE: usize = 8;
/// Inner blocks per tile row.
const PER_ROW: usize = TILE_SIZE / INNER;
/// [`OUTER`] blocks per tile row…
const OUTERS_PER_ROW: usize = TILE_SIZE / OUTER;
/// …and per tile.
const OUTERS: usize = OUTERS_PER_ROW * OUTERS_PER_ROW;
// `unbounded_near` keeps a cluster's 16² blocks as the bits of a `u16`.
const _: () = assert!(OUTERS <= 16);
/// [`MIDDLE`] blocks per [`OUTER`] block's row, and per block.
const MIDDLES_PER_ROW: usize = OUTER / MIDDLE;
const MIDDLES: usize = MIDDLES_PER_ROW * MIDDLES_PER_ROW;
/// [`INNER`] blocks per [`MIDDLE`] block's row, and per block.
const INNERS_PER_ROW: usize = MIDDLE / INNER;
const INNERS: usize = INNERS_PER_ROW * INNERS_PER_ROW;

/// Every receiver's results, tile by tile in parallel: its (pixel, edge)
/// pairs from `tiles` (taken), the `unbounded` edges that may apply and
/// its (pixel, S-triangle) pairs from `stsv`, counted by `pass`.
pub(super) fn count_tiles(
    pass: &LightPass,
    grid: TileGrid,
    tiles: &mut [PairTile],
    unbounded: &[UnboundedEdge],
    clusters: &[EdgeCluster],
    stsv: Option<&StsvMembership>,
) -> Vec<TileResult> {
    tiles
        .par_iter_mut()
        .enumerate()
        .map_init(Scratch::default, |scratch, (tile, t)| {
            let entries = std::mem::take(&mut t.data);
            if pass.ctx.observer.cancelled() {
                // The render discards a cancelled pass: a blank tile of
                // the right size keeps the assembly's indices valid.
                return TileResult::blank();
            }
            let stsv_entries: &[u64] = stsv.map_or(&[], |m| &m.tiles[tile]);
            let unbounded = (unbounded, clusters);
            tile_counters(pass, grid, tile, entries, unbounded, stsv_entries, scratch)
        })
        .collect()
}

/// The unbounded edges that may apply to receivers of `tile`, and per
/// inner block (row-major, [`PER_ROW`] per row) the indices into them of
/// those that may apply to its receivers, each with the mask of those
/// receivers: the receivers' boxes (one, or two across a depth gap:
/// [`ReceiverBoxes`]) of the tile, then of 16², 8² and 4² blocks, against
/// each edge's screen rectangle and world-space region,
/// then the sixteen receivers of a 4² block against the region at once
/// ([`RegionBound::admits`]).
#[inline(always)]
fn unbounded_near<'u>(
    ctx: &ShadowContext,
    grid: TileGrid,
    tile: usize,
    (unbounded, clusters): (&'u [UnboundedEdge], &[EdgeCluster]),
) -> (Vec<&'u UnboundedEdge>, Vec<BlockEdges>) {
    let (width, height) = (grid.width as usize, grid.height as usize);
    let (ox, oy) = grid.tile_origin(tile);
    let (ox, oy) = (ox as usize, oy as usize);
    let in_tile = |r: [usize; 4]| rect_meets(r, ox, oy, TILE_SIZE);
    let mut near: Vec<&UnboundedEdge> = Vec::new();
    let on_screen: Vec<&EdgeCluster> = clusters.iter().filter(|c| in_tile(c.rect)).collect();
    // The receivers of a `size`² block as one or two boxes.
    let bbox = |x0: usize, y0: usize, size: usize| {
        let points = (y0..(y0 + size).min(height)).flat_map(move |y| {
            (x0..(x0 + size).min(width))
                .filter_map(move |x| ctx.gbuffer.surface_position(y * width + x))
                .map(|q| q.as_dvec3())
        });
        ReceiverBoxes::of(points)
    };
    // The region's box and per-receiver tests in AVX registers where the
    // CPU has them (the same verdicts, `RegionBound::excludes_box_avx`
    // and `RegionBound::admits_avx`): the facade's lanes are two SSE2
    // halves in a baseline build, even inside the AVX2 copy of this pass.
    let avx = crate::simd::avx::available();
    let excludes_one = |region: &RegionBound, (lo, hi): (DVec3, DVec3)| {
        #[cfg(target_arch = "x86_64")]
        if avx {
            // SAFETY: `avx` is set only where the CPU has AVX, the one
            // requirement of `excludes_box_avx`.
            return unsafe { region.excludes_box_avx(lo, hi) };
        }
        region.excludes_box(lo, hi)
    };
    let excludes = |region: &RegionBound, boxes: &ReceiverBoxes| {
        boxes.as_slice().iter().all(|&b| excludes_one(region, b))
    };
    let mut block_edges: Vec<BlockEdges> = vec![Vec::new(); PER_ROW * PER_ROW];
    let admits = |u: &UnboundedEdge, receivers: &ReceiverBlock| {
        #[cfg(target_arch = "x86_64")]
        if avx {
            // SAFETY: `avx` is set only where the CPU has AVX, the one
            // requirement of `admits_avx`.
            return unsafe { u.region.admits_avx(receivers) };
        }
        u.region.admits(receivers)
    };
    // The clusters the tile keeps, each with its run of `near`.
    let mut kept: Vec<(&EdgeCluster, std::ops::Range<u32>)> = Vec::new();
    if !on_screen.is_empty() {
        if let Some(b) = bbox(ox, oy, TILE_SIZE) {
            for c in on_screen {
                if excludes(&c.region, &b) {
                    continue;
                }
                let first = near.len() as u32;
                let edges = unbounded[c.edges.clone()].iter();
                let region_of = |u: &'u UnboundedEdge| in_tile(u.rect).then_some(&u.region);
                keep_regions(avx, edges, region_of, &b, &mut near);
                kept.push((c, first..near.len() as u32));
            }
        }
    }
    if near.is_empty() {
        return (near, block_edges);
    }
    // Edge by edge rather than block by block: each region is read once
    // for the tile's 16² blocks and once per 16² block it reaches for
    // that block's 8² and 4² blocks, while the blocks' boxes (a few kB)
    // stay in cache. Block by block, every 16², 8² and 4² block swept
    // its list of regions (~0.7 kB each, megabytes per tile at 1M
    // triangles) out of cache again. The tests, and the order of each
    // list (ascending in `near`), are the same.
    let outer_xy = |o: usize| sub_block((ox, oy), o, OUTERS_PER_ROW, OUTER);
    // Whether an edge's (or a cluster's) screen rectangle meets the
    // `size`² block at `(x, y)` and its region admits the block's boxes.
    let meets = |rect: [usize; 4], region: &RegionBound, (x, y), size, boxes: &Option<_>| {
        boxes
            .as_ref()
            .is_some_and(|b| rect_meets(rect, x, y, size) && !excludes(region, b))
    };
    let outer_boxes: [Option<ReceiverBoxes>; OUTERS] = std::array::from_fn(|o| {
        let (x0, y0) = outer_xy(o);
        bbox(x0, y0, OUTER)
    });
    // Per 16² block, the near edges that may apply to it (their
    // cluster's region and their own admit the block's receivers), in
    // ascending order as `near`.
    let mut outer_edges: [Vec<u32>; OUTERS] = std::array::from_fn(|_| Vec::new());
    for (c, run) in &kept {
        if run.is_empty() {
            continue;
        }
        let cluster_reach = (0..OUTERS).fold(0u16, |m, o| {
            let admits = meets(c.rect, &c.region, outer_xy(o), OUTER, &outer_boxes[o]);
            m | u16::from(admits) << o
        });
        for k in run.clone() {
            let u = near[k as usize];
            let mut blocks = cluster_reach;
            while blocks != 0 {
                let o = blocks.trailing_zeros() as usize;
                blocks &= blocks - 1;
                if meets(u.rect, &u.region, outer_xy(o), OUTER, &outer_boxes[o]) {
                    outer_edges[o].push(k);
                }
            }
        }
    }
    for (o, edges) in outer_edges.iter().enumerate() {
        if edges.is_empty() {
            continue;
        }
        let (x0, y0) = outer_xy(o);
        // Its 8² blocks (row-major), then their 4² blocks: halving the
        // side twice instead of once tests ~40 % fewer boxes (on
        // `spheres.toml` half of a 16² block's edges reach its 4² blocks,
        // a fifth of those pass).
        let middle_xy = |m: usize| sub_block((x0, y0), m, MIDDLES_PER_ROW, MIDDLE);
        let middle_boxes: [Option<ReceiverBoxes>; MIDDLES] = std::array::from_fn(|m| {
            let (xm, ym) = middle_xy(m);
            bbox(xm, ym, MIDDLE)
        });
        // One read of a 4² block's receivers gives both their boxes and
        // their lanes; `inner_xy(m, s)` is 4² block `s` of 8² block `m`.
        // Read when an edge first reaches the block's 8² block.
        let inner_xy = |m: usize, s: usize| sub_block(middle_xy(m), s, INNERS_PER_ROW, INNER);
        let mut inner_blocks: [[Option<InnerBlock>; INNERS]; MIDDLES] = [[None; INNERS]; MIDDLES];
        for &k in edges {
            let u = near[k as usize];
            for (m, middle_box) in middle_boxes.iter().enumerate() {
                if !meets(u.rect, &u.region, middle_xy(m), MIDDLE, middle_box) {
                    continue;
                }
                for (s, inner) in inner_blocks[m].iter_mut().enumerate() {
                    let (x1, y1) = inner_xy(m, s);
                    let (receivers, boxes) =
                        inner.get_or_insert_with(|| receiver_block(ctx, x1, y1));
                    if !meets(u.rect, &u.region, (x1, y1), INNER, boxes) {
                        continue;
                    }
                    let mask = rect_mask(u.rect, x1, y1) & admits(u, receivers);
                    if mask != 0 {
                        let cell = (y1 - oy) / INNER * PER_ROW + (x1 - ox) / INNER;
                        block_edges[cell].push((k, mask));
                    }
                }
            }
        }
    }
    (near, block_edges)
}

/// The corner of sub-block `k` (row-major, `per_row` to a row) of side
/// `size` in the block whose corner is `(x0, y0)`.
#[inline(always)]
fn sub_block((x0, y0): (usize, usize), k: usize, per_row: usize, size: usize) -> (usize, usize) {
    (x0 + k % per_row * size, y0 + k / per_row * size)
}

/// Whether the screen rectangle `r` (`[x0, y0, x1, y1)`) meets the
/// `size`² block at `(x0, y0)`.
#[inline(always)]
fn rect_meets(r: [usize; 4], x0: usize, y0: usize, size: usize) -> bool {
    r[0] < x0 + size && r[2] > x0 && r[1] < y0 + size && r[3] > y0
}

/// [`RegionBound::keep_avx`] where the CPU has AVX (`avx`), else
/// [`RegionBound::keep_lanes`]: the same items.
#[inline(always)]
fn keep_regions<'r, T: Copy>(
    avx: bool,
    items: impl Iterator<Item = T>,
    region_of: impl Fn(T) -> Option<&'r RegionBound>,
    boxes: &ReceiverBoxes,
    out: &mut Vec<T>,
) {
    #[cfg(target_arch = "x86_64")]
    if avx {
        // SAFETY: `avx` is set only where the CPU has AVX, the one
        // requirement of `keep_avx`.
        return unsafe { RegionBound::keep_avx(items, region_of, boxes, out) };
    }
    let _ = avx;
    RegionBound::keep_lanes(items, region_of, boxes, out)
}

/// A 4² block's receivers as lanes, and their boxes (`None`: no receiver).
type InnerBlock = (ReceiverBlock, Option<ReceiverBoxes>);

/// One 4² block's unbounded edges that may apply: indices into the tile's
/// near edges, each with the mask of the block's receivers it may affect.
type BlockEdges = Vec<(u32, u16)>;

/// The receivers of the [`INNER`]² block at pixel `(x0, y0)`, and their
/// boxes.
fn receiver_block(
    ctx: &ShadowContext,
    x0: usize,
    y0: usize,
) -> (ReceiverBlock, Option<ReceiverBoxes>) {
    let (width, height) = (ctx.gbuffer.width as usize, ctx.gbuffer.height as usize);
    let points: [Option<DVec3>; INNER * INNER] = std::array::from_fn(|k| {
        let (x, y) = (x0 + k % INNER, y0 + k / INNER);
        let i = y * width + x;
        if x < width && y < height {
            ctx.gbuffer.surface_position(i).map(|p| p.as_dvec3())
        } else {
            None
        }
    });
    let boxes = ReceiverBoxes::of(points.iter().flatten().copied());
    (ReceiverBlock::new(&points), boxes)
}

/// Of the [`INNER`]² block at pixel `(x0, y0)`, the pixels inside the
/// screen rectangle `rect` (bit `k` for pixel `k`, row by row).
fn rect_mask(rect: [usize; 4], x0: usize, y0: usize) -> u16 {
    let inside = |v: usize, lo: usize, hi: usize| v >= lo && v < hi;
    let columns = (0..INNER).fold(0u16, |m, c| {
        m | (u16::from(inside(x0 + c, rect[0], rect[2])) << c)
    });
    (0..INNER).fold(0u16, |m, r| {
        m | if inside(y0 + r, rect[1], rect[3]) {
            columns << (INNER * r)
        } else {
            0
        }
    })
}

/// One tile's receivers: each surface pixel's sorted (pixel, edge) pairs
/// of `entries`, the unbounded edges whose region holds it and its
/// S-triangles of `stsv_entries` (sorted by local pixel), counted by
/// `pass`.
fn tile_counters(
    pass: &LightPass,
    grid: TileGrid,
    tile: usize,
    entries: Vec<u64>,
    unbounded: (&[UnboundedEdge], &[EdgeCluster]),
    stsv_entries: &[u64],
    scratch: &mut Scratch,
) -> TileResult {
    #[cfg(target_arch = "x86_64")]
    if runs_v3() {
        // SAFETY: the CPU has every feature the v3 copy enables
        // (`runs_v3` checks them), its one requirement.
        return unsafe {
            tile_counters_v3(pass, grid, tile, entries, unbounded, stsv_entries, scratch)
        };
    }
    tile_counters_body(pass, grid, tile, entries, unbounded, stsv_entries, scratch)
}

/// [`tile_counters`] compiled for `Level::V3` (`simd::level`): the same
/// code and bits, with the x86-64-v3 instructions that change no
/// arithmetic (no FMA).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,bmi1,bmi2,lzcnt,popcnt")]
fn tile_counters_v3(
    pass: &LightPass,
    grid: TileGrid,
    tile: usize,
    entries: Vec<u64>,
    unbounded: (&[UnboundedEdge], &[EdgeCluster]),
    stsv_entries: &[u64],
    scratch: &mut Scratch,
) -> TileResult {
    tile_counters_body(pass, grid, tile, entries, unbounded, stsv_entries, scratch)
}

/// [`tile_counters`] itself, inlined into each level's copy (with the
/// per-receiver and per-edge routines it calls).
#[inline(always)]
fn tile_counters_body(
    pass: &LightPass,
    grid: TileGrid,
    tile: usize,
    mut entries: Vec<u64>,
    unbounded: (&[UnboundedEdge], &[EdgeCluster]),
    stsv_entries: &[u64],
    scratch: &mut Scratch,
) -> TileResult {
    let gbuffer = pass.ctx.gbuffer;
    let (width, height) = (grid.width as usize, grid.height as usize);
    let pairs = entries.len();
    entries.sort_unstable();
    entries.dedup();
    let mut out = vec![PixelResult::default(); TILE_PIXELS];
    let mut sampled = 0;
    let mut unbounded_pairs = 0;
    let mut recounted = 0;
    let (near, block_edges) = unbounded_near(pass.ctx, grid, tile, unbounded);
    // The ids alone, contiguous: reading them through the edges (each
    // behind its region bound) missed the cache once per pair.
    let near_ids: Vec<u32> = near.iter().map(|u| u.id).collect();
    // Each local pixel's run of `entries` and of `stsv_entries`.
    let runs = |sorted: &[u64], shift: u32| -> Vec<usize> {
        let mut starts = vec![0; TILE_PIXELS + 1];
        for &v in sorted {
            starts[(v >> shift) as usize + 1] += 1;
        }
        for k in 0..TILE_PIXELS {
            starts[k + 1] += starts[k];
        }
        starts
    };
    let (tag_runs, stsv_runs) = (runs(&entries, 33), runs(stsv_entries, 32));
    let in_lanes = pass.blocks_in_lanes();
    // The lane kernel in AVX registers where the CPU has them (and
    // `PENUMBRA_SIMD` does not force the baseline).
    let avx = crate::simd::avx::available();
    let mut made = BlockExtras::default();
    let mut extra = Vec::new();
    let mut here = Vec::new();
    // Block by block (4², as `block_edges`), each block's receivers row by
    // row, so that a block's unbounded edges can be made for all of its
    // receivers at once.
    for (cell, cell_edges) in block_edges.iter().enumerate() {
        let (cx, cy) = (cell % PER_ROW * INNER, cell / PER_ROW * INNER);
        let pixels: [Option<usize>; BLOCK] = std::array::from_fn(|k| {
            let local = (cy + k / INNER) * TILE_SIZE + cx + k % INNER;
            let (x, y) = grid.tile_pixel_xy(tile, local);
            let i = y * width + x;
            (x < width && y < height && gbuffer.is_surface(i)).then_some(i)
        });
        let lanes = in_lanes && !cell_edges.is_empty();
        if lanes {
            let edges = cell_edges.iter().map(|&(k, m)| (near_ids[k as usize], m));
            pass.block_extras(&pixels, edges, &mut made, avx);
        }
        for (bit, pixel) in pixels.iter().enumerate() {
            let local = (cy + bit / INNER) * TILE_SIZE + cx + bit % INNER;
            let Some(i) = *pixel else {
                continue;
            };
            here.clear();
            here.extend(
                stsv_entries[stsv_runs[local]..stsv_runs[local + 1]]
                    .iter()
                    .map(|&v| v as u32),
            );
            let tags = &mut entries[tag_runs[local]..tag_runs[local + 1]];
            for tag in tags.iter_mut() {
                *tag &= (1 << 33) - 1;
            }
            let extras = if lanes {
                Extras::Made(made.of(bit))
            } else {
                extra.clear();
                extra.extend(
                    cell_edges
                        .iter()
                        .filter(|&&(_, mask)| mask >> bit & 1 == 1)
                        .map(|&(k, _)| near_ids[k as usize]),
                );
                Extras::Ids(&extra)
            };
            let admitted = match extras {
                Extras::Ids(ids) => ids.len(),
                Extras::Made(m) => m.admitted,
            };
            sampled += usize::from(!tags.is_empty() || admitted > 0 || !here.is_empty());
            unbounded_pairs += admitted;
            let r = pass.pixel(i, tags, extras, &here, scratch);
            recounted += usize::from(r.recounted);
            out[local] = r;
        }
    }
    TileResult {
        pixels: out,
        pairs,
        sampled,
        unbounded: unbounded_pairs,
        recounted,
    }
}

/// One light's images from its tiles' `results`: Vcoef, the radiance
/// (empty unless `with_radiance`) and the AOVs (max and mean depth
/// complexity, edges per pixel); the tiles' pair and receiver counts go
/// into `report`.
pub(super) fn assemble(
    grid: TileGrid,
    results: Vec<TileResult>,
    with_radiance: bool,
    report: &mut DcsLightReport,
) -> (Vec<f32>, Vec<Vec3>, [Vec<f32>; 3]) {
    let n = grid.width as usize * grid.height as usize;
    let mut vcoef = vec![0.0f32; n];
    let mut radiance = vec![Vec3::ZERO; if with_radiance { n } else { 0 }];
    let mut aovs = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
    for (tile, result) in results.into_iter().enumerate() {
        report.unbounded_pairs += result.unbounded;
        report.pairs += result.pairs;
        report.sampled_pixels += result.sampled;
        report.quad_recounts += result.recounted;
        grid.for_each_tile_pixel(tile, |local, i| {
            let r = &result.pixels[local];
            vcoef[i] = r.vcoef;
            if let Some(d) = radiance.get_mut(i) {
                *d = r.radiance;
            }
            aovs[0][i] = r.max_dc;
            aovs[1][i] = r.mean_dc;
            aovs[2][i] = r.edges;
        });
    }
    (vcoef, radiance, aovs)
}

/// Interleaved sampling (`n` × `n` sample sets): neighbours used
/// different sample sets; gathers them back, not across depth or normal
/// discontinuities.
pub(super) fn gather(
    ctx: &ShadowContext,
    grid: TileGrid,
    n: u32,
    vcoef: Vec<f32>,
    radiance: Vec<Vec3>,
) -> (Vec<f32>, Vec<Vec3>) {
    let guide = |i: usize| {
        let g = ctx.gbuffer.sample(i);
        g.is_surface().then_some((g.depth, g.normal))
    };
    let params = GatherParams::default();
    let (w, h) = (grid.width, grid.height);
    let vcoef = gather_filter(&vcoef, w, h, n, &guide, params);
    let radiance = if radiance.is_empty() {
        radiance
    } else {
        gather_filter(&radiance, w, h, n, &guide, params)
    };
    (vcoef, radiance)
}
