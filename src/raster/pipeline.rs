//! The draw call: vertex outputs → clip → setup → bin → tiles in parallel.

use super::bin::TileBins;
use super::clip::{classify, clip_triangle, ClipClass};
use super::fragment::FragmentStage;
use super::framebuffer::Framebuffer;
use super::setup::{setup_polygon, SetupTriangle, Viewport};
use super::state::{CullMode, RasterState};
use super::tile::{CountingPass, TileJob, TileStats};
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

/// Triangles per setup work item: large enough to amortise scheduling,
/// small enough to balance two to many cores.
const SETUP_CHUNK: usize = 2048;

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
    let grid = framebuffer.grid();
    if targets.len() != grid.tile_count() {
        return Err(Error::param(
            "targets",
            format!(
                "{} tile targets for {} tiles",
                targets.len(),
                grid.tile_count()
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
    if state.stencil.is_some() && framebuffer.tile(0).stencil.is_none() {
        framebuffer.clear_stencil(0);
    }
    let viewport = Viewport {
        width: grid.width,
        height: grid.height,
    };
    let (gx, gy) = viewport.guard_ndc();
    let cull_front = state.cull == CullMode::Front;
    let cull_back = state.cull == CullMode::Back;

    let setup: Vec<SetupTriangle<N>> = triangles
        .par_chunks(SETUP_CHUNK)
        .enumerate()
        .map(|(chunk, tris)| {
            let mut out = Vec::with_capacity(tris.len());
            for (k, tri) in tris.iter().enumerate() {
                let prim = first_primitive + (chunk * SETUP_CHUNK + k) as u32;
                let v = tri.map(|i| vertices[i as usize]);
                match classify(&v, gx, gy) {
                    ClipClass::Inside => {
                        setup_polygon(&v, viewport, cull_front, cull_back, prim, &mut out)
                    }
                    ClipClass::Outside => {}
                    ClipClass::Crossing => {
                        let c = clip_triangle(v, gx, gy);
                        let poly = &c.vertices[..c.len];
                        setup_polygon(poly, viewport, cull_front, cull_back, prim, &mut out)
                    }
                }
            }
            out
        })
        .collect::<Vec<_>>()
        .into_iter()
        .fold(Vec::new(), |mut all, chunk| {
            // Whole chunks are moved with one copy each, in chunk order.
            if all.is_empty() {
                chunk
            } else {
                all.extend(chunk);
                all
            }
        });

    let bins = TileBins::build(&grid, &setup);
    let counting = CountingPass::of::<N, S>(state);

    let stats = framebuffer
        .tiles_mut()
        .par_iter_mut()
        .zip(targets.par_iter_mut())
        .enumerate()
        .map(|(tile, (ds, target))| {
            let job = TileJob {
                tile,
                origin: grid.tile_origin(tile),
                triangles: &setup,
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
        setup_triangles: setup.len(),
        binned: bins.len(),
        fragments: stats.fragments,
        passed: stats.passed,
    })
}
