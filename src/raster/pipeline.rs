//! The draw call: vertex outputs → clip → setup → bin → tiles in parallel.

use super::bin::{tile_pairs, TileBins};
use super::clip::{clip_triangle, vertex_code, CLIP_PLANES, MAX_CLIPPED_VERTICES};
use super::fragment::FragmentStage;
use super::fragment::NoFragmentStage;
use super::framebuffer::{Framebuffer, TileGrid};
use super::setup::{setup_polygon, setup_quad, Viewport};
use super::state::{CullMode, RasterState};
use super::tile::{
    CountingPass, DepthShifts, SetupList, SetupPart, TileJob, TileStats, CHUNK_LOCAL_BITS,
    MAX_DEPTH_SHIFTS,
};
use super::vertex::ClipVertex;
use crate::error::{Error, Result};
use rayon::prelude::*;

/// Counters of one draw call.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DrawStats {
    /// Triangles submitted.
    pub triangles: usize,
    /// Triangles after clipping, culling and setup (fan pieces count).
    pub setup_triangles: usize,
    /// (triangle, tile) pairs binned.
    pub binned: usize,
    /// Covered samples that reached the depth/stencil tests.
    pub fragments: u64,
    /// Samples that passed them.
    pub passed: u64,
}

impl std::ops::AddAssign for DrawStats {
    fn add_assign(&mut self, o: DrawStats) {
        self.triangles += o.triangles;
        self.setup_triangles += o.setup_triangles;
        self.binned += o.binned;
        self.fragments += o.fragments;
        self.passed += o.passed;
    }
}

/// One setup work item's output: its set-up triangles and their merged
/// quads' extras, and their `(tile, SetupList number)` pairs.
type SetupChunk<const N: usize> = (SetupPart<N>, Vec<(u32, u32)>);

/// Triangles per setup work item: large enough to amortise scheduling,
/// small enough to balance two to many cores.
const SETUP_CHUNK: usize = 2048;

// A chunk's set-up triangles are numbered in `CHUNK_LOCAL_BITS`: a
// clipped polygon fans into at most `MAX_CLIPPED_VERTICES − 2` of them.
const _: () = assert!((MAX_CLIPPED_VERTICES - 2) * SETUP_CHUNK < 1 << CHUNK_LOCAL_BITS);

/// Rasterizes indexed triangles into `framebuffer` and the stage's targets.
///
/// `targets` holds one `S::Target` per tile of the framebuffer's grid.
/// Results are independent of the thread count: setup output keeps input
/// order, bins keep setup order, and each tile is processed by one thread.
pub fn draw<const N: usize, S: FragmentStage<N>>(
    framebuffer: &mut Framebuffer,
    targets: &mut [S::Target],
    state: &RasterState,
    vertices: &[ClipVertex<N>],
    triangles: &[[u32; 3]],
    stage: &S,
) -> Result<DrawStats> {
    draw_numbered(framebuffer, targets, state, vertices, triangles, 0, stage)
}

/// [`draw`] for a slice of a larger triangle list: fragments report
/// primitive ids `first_primitive + index in triangles`.
pub fn draw_numbered<const N: usize, S: FragmentStage<N>>(
    framebuffer: &mut Framebuffer,
    targets: &mut [S::Target],
    state: &RasterState,
    vertices: &[ClipVertex<N>],
    triangles: &[[u32; 3]],
    first_primitive: u32,
    stage: &S,
) -> Result<DrawStats> {
    draw_inner(
        framebuffer,
        targets,
        state,
        vertices,
        triangles,
        first_primitive,
        stage,
        DepthShifts::default(),
    )
}

/// A counting stencil pass (`state` must have a counting form: an
/// always-passing stencil adding ±1 on depth fail or on depth pass, no
/// depth write; otherwise a parameter error) giving one image per entry
/// of `scales`: `None` the plain counts, `Some(scale)` each pixel's
/// *change* of count when its stored depth `d` is replaced by `d × scale`
/// (the f32 product): the fragments whose depth test flips, signed, i.e.
/// the count a depth-scaled copy would get minus the framebuffer's own,
/// exactly. One walk over one setup and binning of the triangles makes
/// them all (at most `MAX_DEPTH_SHIFTS` distinct scales): each fragment's
/// depth is computed once and tested against each depth, and for a
/// change, rectangles where no fragment's test can flip (the volume in
/// front of or behind both depths throughout) are skipped by the depth
/// bounds. The stencil is left holding the plain counts.
pub fn draw_depth_shift_counts(
    framebuffer: &mut Framebuffer,
    state: &RasterState,
    vertices: &[ClipVertex<0>],
    triangles: &[[u32; 3]],
    scales: &[Option<f32>],
) -> Result<Vec<Vec<i32>>> {
    let grid = framebuffer.grid();
    let mut none = vec![(); grid.tile_count()];
    let mut distinct: Vec<f32> = Vec::new();
    for &s in scales.iter().flatten() {
        if !distinct.iter().any(|d| d.to_bits() == s.to_bits()) {
            distinct.push(s);
        }
    }
    let shifts = DepthShifts::new(&distinct);
    let (Some(shifts), Some(_)) = (shifts, CountingPass::of::<0, NoFragmentStage>(state)) else {
        return Err(Error::param(
            "state",
            format!(
                "a depth-shift count needs a counting stencil pass and at most \
                 {MAX_DEPTH_SHIFTS} distinct scales"
            ),
        ));
    };
    if distinct.iter().any(|s| !s.is_finite()) {
        return Err(Error::param("scales", "depth-shift scales must be finite"));
    }
    framebuffer.clear_stencil(0);
    framebuffer.clear_shifted(distinct.len());
    draw_inner(
        framebuffer,
        &mut none,
        state,
        vertices,
        triangles,
        0,
        &NoFragmentStage,
        shifts,
    )?;
    let images = scales
        .iter()
        .map(|scale| match scale {
            None => framebuffer.stencil_image(),
            Some(s) => {
                let k = distinct.iter().position(|d| d.to_bits() == s.to_bits());
                framebuffer.shifted_image(k.unwrap_or(0))
            }
        })
        .collect();
    // The change images are not part of the framebuffer's state.
    framebuffer.clear_shifted(0);
    Ok(images)
}

#[allow(clippy::too_many_arguments)]
fn draw_inner<const N: usize, S: FragmentStage<N>>(
    framebuffer: &mut Framebuffer,
    targets: &mut [S::Target],
    state: &RasterState,
    vertices: &[ClipVertex<N>],
    triangles: &[[u32; 3]],
    first_primitive: u32,
    stage: &S,
    shifts: DepthShifts,
) -> Result<DrawStats> {
    let grid = framebuffer.grid();
    check_draw_input(&grid, targets.len(), vertices, triangles)?;
    if state.stencil.is_some() && framebuffer.tile(0).stencil.is_none() {
        framebuffer.clear_stencil(0);
    }
    let viewport = Viewport {
        width: grid.width,
        height: grid.height,
    };
    let guard = viewport.guard_ndc();
    // Outcodes once per vertex, not once per use.
    let codes: Vec<u16> = vertices
        .par_iter()
        .with_min_len(4096)
        .map(|v| vertex_code(v.position, guard.0, guard.1))
        .collect();

    // A pass that only counts draws pairs of triangles sharing a diagonal
    // ([a, b, c], [a, c, d], as shadow-volume sides come) as one quad when
    // that gives the same coverage and depths (see QuadExtra).
    let counting = CountingPass::of::<N, S>(state);
    let setup_stage = SetupStage {
        vertices,
        codes: &codes,
        viewport,
        guard,
        cull_front: state.cull == CullMode::Front,
        cull_back: state.cull == CullMode::Back,
        merge: counting.is_some(),
        first_primitive,
        grid,
    };
    // Setup, then the chunk's (tile, triangle) pairs: binning's edge tests
    // run in parallel too.
    let (parts, runs): (Vec<SetupPart<N>>, Vec<Vec<(u32, u32)>>) = triangles
        .par_chunks(SETUP_CHUNK)
        .enumerate()
        .map(|(chunk, tris)| setup_stage.chunk(chunk, tris))
        .unzip();
    let bins = TileBins::from_pairs(&grid, &runs);
    let setup = SetupList { chunks: &parts };

    let counting = counting.map(|c| CountingPass { shifts, ..c });
    let stats = framebuffer
        .tiles_mut()
        .par_iter_mut()
        .zip(targets.par_iter_mut())
        .enumerate()
        .map(|(tile, (ds, target))| {
            let job = TileJob {
                tile,
                origin: grid.tile_origin(tile),
                setup,
                bin: bins.tile(tile),
                state,
                stage,
                counting,
            };
            job.run(ds, target)
        })
        .reduce(TileStats::default, |a, b| TileStats {
            fragments: a.fragments + b.fragments,
            passed: a.passed + b.passed,
        });

    Ok(DrawStats {
        triangles: triangles.len(),
        setup_triangles: parts.iter().map(|(tris, _)| tris.len()).sum(),
        binned: bins.len(),
        fragments: stats.fragments,
        passed: stats.passed,
    })
}

/// One target per tile, and every vertex index in range.
fn check_draw_input<const N: usize>(
    grid: &TileGrid,
    target_count: usize,
    vertices: &[ClipVertex<N>],
    triangles: &[[u32; 3]],
) -> Result<()> {
    if target_count != grid.tile_count() {
        return Err(Error::param(
            "targets",
            format!(
                "{} tile targets for {} tiles",
                target_count,
                grid.tile_count()
            ),
        ));
    }
    // `SetupList` numbers hold the chunk in their high bits.
    let most = SETUP_CHUNK << (32 - CHUNK_LOCAL_BITS);
    if triangles.len() > most {
        return Err(Error::param(
            "triangles",
            format!(
                "{} triangles in one draw; at most {most} can be drawn at once",
                triangles.len()
            ),
        ));
    }
    if let Some(bad) = triangles
        .iter()
        .flatten()
        .find(|&&i| i as usize >= vertices.len())
    {
        return Err(Error::param(
            "triangles",
            format!(
                "vertex index {bad} out of range ({} vertices)",
                vertices.len()
            ),
        ));
    }
    Ok(())
}

/// What setting up any chunk of one draw's triangles reads.
struct SetupStage<'a, const N: usize> {
    vertices: &'a [ClipVertex<N>],
    /// Outcodes per vertex.
    codes: &'a [u16],
    viewport: Viewport,
    /// Guard band extents in NDC units ([`Viewport::guard_ndc`]).
    guard: (f32, f32),
    cull_front: bool,
    cull_back: bool,
    /// Merge quads (counting passes).
    merge: bool,
    first_primitive: u32,
    grid: TileGrid,
}

impl<const N: usize> SetupStage<'_, N> {
    /// Setup of chunk number `chunk` (triangles `tris`), then its
    /// `(tile, chunk-local triangle)` pairs.
    fn chunk(&self, chunk: usize, tris: &[[u32; 3]]) -> SetupChunk<N> {
        let (vertices, codes, viewport) = (self.vertices, self.codes, self.viewport);
        let (cull_front, cull_back) = (self.cull_front, self.cull_back);
        let mut out = Vec::with_capacity(tris.len());
        let mut quads = Vec::new();
        let mut k = 0;
        while k < tris.len() {
            let prim = self.first_primitive + (chunk * SETUP_CHUNK + k) as u32;
            let tri = tris[k];
            let c = tri.map(|i| codes[i as usize]);
            k += 1;
            if self.merge && k < tris.len() {
                let next = tris[k];
                let d = codes[next[2] as usize];
                if next[0] == tri[0]
                    && next[1] == tri[2]
                    && (c[0] | c[1] | c[2] | d) & CLIP_PLANES == 0
                    && c[0] & c[1] & c[2] == 0
                    && c[0] & c[2] & d == 0
                {
                    let v = [tri[0], tri[1], tri[2], next[2]].map(|i| vertices[i as usize]);
                    let prims = [prim, prim + 1];
                    setup_quad(
                        &v, viewport, cull_front, cull_back, prims, &mut out, &mut quads,
                    );
                    k += 1;
                    continue;
                }
            }
            if c[0] & c[1] & c[2] != 0 {
                continue; // outside one clip plane, or beyond one screen side
            }
            let v = tri.map(|i| vertices[i as usize]);
            if (c[0] | c[1] | c[2]) & CLIP_PLANES == 0 {
                setup_polygon(&v, viewport, cull_front, cull_back, prim, &mut out)
            } else {
                let c = clip_triangle(v, self.guard.0, self.guard.1);
                let poly = &c.vertices[..c.len];
                setup_polygon(poly, viewport, cull_front, cull_back, prim, &mut out)
            }
        }
        let mut pairs = Vec::with_capacity(out.len() * 2);
        tile_pairs(&self.grid, &out, &quads, &mut pairs);
        // `SetupList` numbers (`check_draw_input` bounds the chunk count,
        // and the fan bound above the count within a chunk).
        debug_assert!(out.len() < 1 << CHUNK_LOCAL_BITS);
        let base = (chunk as u32) << CHUNK_LOCAL_BITS;
        for p in &mut pairs {
            p.1 |= base;
        }
        ((out, quads), pairs)
    }
}
