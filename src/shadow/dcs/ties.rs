//! Receivers whose shadow-volume start count is a depth tie, and their
//! exact start counts by one ray to the light's centre.
//!
//! The stencil decides `D(O)` at the rasterized receiver `p` with a depth
//! test. When a volume face passes through `p` — the receiver's own face
//! on an open (Bergeron) caster, whose caps are the faces themselves, or
//! coplanar duplicate faces whose depths differ by rounding — that test is
//! a tie, and it may disagree with the shadow-ray origin `p'` the counters
//! follow. `p'` is on the viewer's side of the receiver's surface, so the
//! count it needs is the one of a receiver slightly *nearer* the eye.
//! Such receivers are found by counting once more with the scene depth
//! moved towards the eye by [`DEPTH_BAND`] (relative): where that count
//! differs from the stencil's, a volume face lies within the band behind
//! the depth-test tie. (A receiver on its own open face, rasterized from
//! the same triangle as the G-buffer, ties exactly, and the z-fail test
//! counts a face at equal depth as behind: already the nearer count, so it
//! is not flagged.) For those few pixels the start counts of every caster
//! group are recounted exactly at `p'`, by one ray to the centre through
//! the groups' faces, with the stencil's weights (closed caster: its
//! light-facing faces; open caster: every face).

use super::faces::FaceTree;
use crate::error::Result;
use crate::geom::{EdgeAdjacency, SceneGeometry};
use crate::raster::Framebuffer;
use crate::shadow::kit::volumes::{stencil_count_shifts, ShadowVolume};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::sync::OnceLock;

/// Relative depth band of the tie test: 64 f32 ulps, far above the
/// rounding difference of two coplanar triangles' depths.
pub const DEPTH_BAND: f32 = 4e-6;

/// A receiver's start count as the tie test finds it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Tie {
    /// No volume face near the receiver: the stencil's count holds at
    /// `p'`, and the quad correction applies.
    None,
    /// Only the receiver's own face passes through it, already counted
    /// on the eye's side (the side of `p'`) by the depth test: the
    /// stencil's count is the count at `p'`, exactly.
    OwnFace,
    /// Another face lies in the band: recount by a ray.
    Tied,
}

/// Per pixel: does the count of `volume` change when the receiver moves
/// [`DEPTH_BAND`] nearer the eye than in `counts` (the stencil's counts
/// at the scene depth), or, with `both_sides`, when it moves that much
/// farther by more than `own_face(i)` — the change the receiver's own
/// face alone makes ([`own_face_change`]; `None` when it cannot be told,
/// then any change is a tie)? `scene_depth` is the scene's depth (its
/// stencil is unused). Reversed Z: nearer is larger.
///
/// One side catches the ties the stencil resolved the wrong way for `p'`;
/// both sides also catch receivers where a face passes between the
/// view-ray point and `p'` (off the view ray, along the normal). Moving
/// farther always crosses the receiver's own face when that face is a cap
/// of the volume (an open caster's every face, a closed caster's
/// light-facing ones): told apart as [`Tie::OwnFace`], it no longer sends
/// every receiver on the ground of most scenes to a ray that would
/// recount the stencil's own value.
pub fn tied_pixels(
    scene_depth: &Framebuffer,
    volume: &ShadowVolume,
    counts: &[i32],
    both_sides: bool,
    own_face: impl Fn(usize) -> Option<i32> + Sync,
) -> Result<Vec<Tie>> {
    // The depth-shifted counts minus the stencil's (`counts`), from one
    // setup of the volume's faces, tested only between the two depths.
    let mut fb = scene_depth.clone();
    let scales: Vec<Option<f32>> = depth_shifts(both_sides).iter().map(|&s| Some(s)).collect();
    let changes = stencil_count_shifts(&mut fb, volume, false, &scales)?;
    tied_from_changes(&changes, counts, own_face)
}

/// The depth scales of the tie test: nearer, then (`both_sides`)
/// farther.
pub fn depth_shifts(both_sides: bool) -> &'static [f32] {
    const BOTH: [f32; 2] = [1.0 + DEPTH_BAND, 1.0 - DEPTH_BAND];
    if both_sides {
        &BOTH
    } else {
        &BOTH[..1]
    }
}

/// [`tied_pixels`] from the changes of the counts under
/// [`depth_shifts`] (one image per scale, as
/// [`stencil_count_shifts`] gives them), e.g. made with the stencil pass
/// itself ([`crate::shadow::kit::membership::light_start_shifted`]).
pub fn tied_from_changes(
    changes: &[Vec<i32>],
    counts: &[i32],
    own_face: impl Fn(usize) -> Option<i32> + Sync,
) -> Result<Vec<Tie>> {
    let Some(nearer) = changes.first() else {
        return Ok(vec![Tie::None; counts.len()]);
    };
    let mut tied: Vec<Tie> = nearer
        .par_iter()
        .with_min_len(4096)
        .map(|&change| if change != 0 { Tie::Tied } else { Tie::None })
        .collect();
    if let Some(farther) = changes.get(1) {
        // Own-face changes need the G-buffer: in parallel.
        tied.par_iter_mut()
            .zip(farther.par_iter())
            .enumerate()
            .with_min_len(4096)
            .for_each(|(i, (t, &change))| {
                if *t == Tie::None && change != 0 {
                    *t = match own_face(i) {
                        Some(own) if own != 0 && change == own => Tie::OwnFace,
                        _ => Tie::Tied,
                    };
                }
            });
    }
    debug_assert_eq!(counts.len(), tied.len());
    Ok(tied)
}

/// The change of a volume's count that crossing a receiver's own face
/// makes when the receiver moves from the eye's side of it to the other:
/// the face adds `weight` (its stencil weight: 1 for an open caster's
/// face, 1 for a closed caster's light-facing face, else 0) to points on
/// its side away from the light's `centre`, so `+weight` when the eye and
/// the centre are on the same side, `−weight` otherwise. `normal` is the
/// face's geometric normal towards the eye, `p` the receiver; `None` when
/// the centre is too near the face's plane to tell the side.
pub fn own_face_change(weight: i32, normal: Vec3, p: Vec3, centre: Vec3) -> Option<i32> {
    if weight == 0 {
        return Some(0);
    }
    let (n, to_c) = (normal.as_dvec3(), (centre - p).as_dvec3());
    let along = n.dot(to_c);
    // The f32 normal of a triangle and p on it: a relative margin far
    // above their rounding.
    (along.abs() > 1e-4 * n.length() * to_c.length()).then_some(if along > 0.0 {
        weight
    } else {
        -weight
    })
}

/// The segment [`ExactStart::cap_near`] tests for receiver `p` with
/// shadow-ray origin `origin` seen from `eye`, as `(start, direction)`
/// (`t ∈ [0, 1]`): from `p_n`, `p` moved towards the eye as far as the tie
/// test's nearer count moved it, to `origin`, extended by a quarter of its
/// length at both ends.
pub fn cap_segment(p: Vec3, origin: Vec3, eye: Vec3) -> (Vec3, Vec3) {
    let (p, origin, eye) = (p.as_dvec3(), origin.as_dvec3(), eye.as_dvec3());
    let band = f64::from(DEPTH_BAND);
    let p_n = p + (eye - p) * (band / (1.0 + band));
    let d = origin - p_n;
    ((p_n - d * 0.25).as_vec3(), (d * 1.5).as_vec3())
}

/// No group.
const NONE: u32 = u32::MAX;

/// Exact start counts of every caster group at given points. The tree
/// over the groups' faces ([`FaceTree`]: it reports exactly the
/// brute-force hits of the BVH's watertight test, at a small part of the
/// scene BVH's build cost) is built on first use (most renders need
/// none); it is the same whichever thread builds it.
pub struct ExactStart<'a> {
    geometry: &'a SceneGeometry,
    tree: OnceLock<FaceTree>,
    /// Per scene triangle: `group << 2 | closed << 1 | weight` (weight 1
    /// when the face counts from the centre), or [`NONE`].
    table: Vec<u32>,
}

impl<'a> ExactStart<'a> {
    /// For `groups` (each: adjacency and its faces' light-facing flags
    /// from the centre).
    pub fn new(geometry: &'a SceneGeometry, groups: &[(&EdgeAdjacency, &[bool])]) -> Self {
        let mut table = vec![NONE; geometry.triangles.len()];
        for (g, (adj, lit)) in groups.iter().enumerate() {
            for (slot, &f) in adj.faces.iter().enumerate() {
                let closed = adj.face_closed[slot];
                let weight = if closed { u32::from(lit[slot]) } else { 1 };
                table[f as usize] = (g as u32) << 2 | u32::from(closed) << 1 | weight;
            }
        }
        ExactStart {
            geometry,
            tree: OnceLock::new(),
            table,
        }
    }

    /// Builds the tree now, from the calling thread (whose parallel
    /// build then has every worker): for callers about to query it from a
    /// parallel loop, where the first query's build would hold the other
    /// workers waiting.
    pub fn prepare(&self) {
        self.tree();
    }

    /// Bytes held: the per-triangle group table, and the face tree when a
    /// recount built it.
    pub fn bytes(&self) -> u64 {
        self.table.capacity() as u64 * 4 + self.tree.get().map_or(0, FaceTree::bytes)
    }

    /// Whether a recount built the face tree.
    pub fn built(&self) -> bool {
        self.tree.get().is_some()
    }

    /// The tree over the groups' faces, built on first use.
    fn tree(&self) -> &FaceTree {
        self.tree
            .get_or_init(|| FaceTree::build(self.geometry, |t| self.table[t as usize] != NONE))
    }

    /// Does a cap face (a face of weight 1 in its group) other than
    /// triangle `own` cross a receiver's segment `(start, dir)`
    /// ([`cap_segment`]: from `p_n`, the receiver `p` moved towards the
    /// eye as far as the tie test's nearer count moved it, to the
    /// shadow-ray origin `p'`, extended by a quarter of its length at both
    /// ends; the extensions only ever add a `true`)?
    ///
    /// Why this makes an own-face tie exact ([`Tie::OwnFace`]): the
    /// nearer count is the count at `p_n` (the tie test found it equal to
    /// the stencil's), and the count at `p'` differs from it by the signed
    /// crossings of volume faces along the segment `p_n → p'`. Both ends
    /// lie on the eye's side of the own face's plane, so the segment does
    /// not cross the own face; when this is `false` it crosses no other
    /// cap either. Side quads are the counter pass's concern (the quad
    /// correction, or a ray where it meets an own-face tie).
    pub fn cap_near(&self, own: u32, (start, dir): (Vec3, Vec3)) -> bool {
        // A boolean OR over the hits: only the faces that can set it are
        // tested, and the first that does ends the walk.
        let mut near = false;
        self.tree().for_each_hit_of(
            start,
            dir,
            1.0,
            |t| self.is_cap(t, own),
            |_| {
                near = true;
                false
            },
        );
        near
    }

    /// The cap faces other than `own` that may cross the segment
    /// ([`cap_segment`]) of a receiver on triangle `own` lying in the box
    /// `[lo, hi]` ([`FaceTree::faces_near`]), into `near` (cleared first);
    /// `false` when there are more than `limit` (or the box is not
    /// finite), and then per-receiver walks are the cheaper test.
    pub fn caps_near(
        &self,
        own: u32,
        lo: Vec3,
        hi: Vec3,
        limit: usize,
        near: &mut Vec<u32>,
    ) -> bool {
        near.clear();
        let stopped = self.tree().faces_near(
            lo,
            hi,
            |t| self.is_cap(t, own),
            |c| {
                near.push(c);
                near.len() <= limit
            },
        );
        !stopped
    }

    /// [`cap_near`](Self::cap_near) of the receiver whose segment
    /// ([`cap_segment`]) is `(start, dir)`, with the faces the walk could
    /// report given by [`caps_near`](Self::caps_near) on a box holding
    /// that segment: the same answer, with no walk.
    pub fn cap_near_among(&self, near: &[u32], (start, dir): (Vec3, Vec3)) -> bool {
        !near.is_empty() && self.tree().hits_any(near, start, dir, 1.0)
    }

    /// A cap face (weight 1 in its group) other than `own`.
    fn is_cap(&self, t: u32, own: u32) -> bool {
        let e = self.table[t as usize];
        t != own && e != NONE && e & 1 == 1
    }

    /// The start count of each group at `origin` for the light centre
    /// `centre`, into `out` (one entry per group).
    pub fn counts(&self, origin: Vec3, centre: Vec3, out: &mut [i32]) {
        out.fill(0);
        let dir = centre - origin;
        // Stop just short of the centre, as the reference's rays do.
        let t_max = (1.0 - crate::shadow::kit::rays::END_SHORTEN) as f32;
        // Integer sums over the hits: any order gives the same counts, and
        // faces of weight 0 add nothing (not tested).
        let weighted = |t: u32| {
            let e = self.table[t as usize];
            e != NONE && e & 1 == 1
        };
        self.tree()
            .for_each_hit_of(origin, dir, t_max, weighted, |t| {
                if let Some(c) = out.get_mut((self.table[t as usize] >> 2) as usize) {
                    *c += 1;
                }
                true
            });
    }

    /// The count of each group on the segment from `origin` to the light
    /// point `target`, into `out`, by the rule the counters follow: a
    /// closed caster's face counts where `target` is in front of it (it
    /// faces that light point), an open caster's every face. At the
    /// centre this is [`counts`](Self::counts).
    pub fn counts_towards(&self, origin: Vec3, target: DVec3, out: &mut [i32]) {
        out.fill(0);
        let dir = target.as_vec3() - origin;
        let t_max = (1.0 - crate::shadow::kit::rays::END_SHORTEN) as f32;
        let geometry = self.geometry;
        self.tree().for_each_hit_of(
            origin,
            dir,
            t_max,
            |t| self.table[t as usize] != NONE,
            |t| {
                let e = self.table[t as usize];
                let counts = if e & 2 == 0 {
                    true
                } else {
                    let [a, b, c] = geometry.triangles[t as usize]
                        .map(|i| geometry.positions[i as usize].as_dvec3());
                    (b - a).cross(c - a).dot(target - a) > 0.0
                };
                if let (true, Some(c)) = (counts, out.get_mut((e >> 2) as usize)) {
                    *c += 1;
                }
                true
            },
        );
    }
}
