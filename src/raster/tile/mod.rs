//! Tile traversal. Small triangles (bounding box within 8×8 pixels, most
//! triangles of a detailed mesh) go straight to 8-lane rows over their box
//! with `i32` edge values; larger ones descend from the 64×64 tile to 8×8
//! blocks (trivial accept / reject on exact corner values), then rows with
//! exact `f64` lanes on the edges that cross the block. Depth, stencil and
//! fragment batches are 8-lane SIMD either way. Counting passes take the
//! span walk of [`counting`]; passes that read depth without
//! writing it skip rectangles by [`depth_bounds`].
//!
//! The files depend one way: `job.rs` (shared types, a leaf) ←
//! `depth_bounds.rs` ← `blocks.rs`, `counting.rs`; this file only picks
//! the walk.

#[forbid(unsafe_code)]
mod blocks;
#[forbid(unsafe_code)]
mod counting;
#[forbid(unsafe_code)]
mod depth_bounds;
#[forbid(unsafe_code)]
mod job;

pub(crate) use job::{
    CountingPass, DepthShifts, SetupList, SetupPart, TileJob, TileStats, CHUNK_LOCAL_BITS,
    MAX_DEPTH_SHIFTS,
};

use super::fragment::FragmentStage;
use super::framebuffer::DepthStencilTile;

impl<const N: usize, S: FragmentStage<N>> TileJob<'_, N, S> {
    /// Rasterizes every binned triangle into this tile, in bin order.
    pub fn run(&self, ds: &mut DepthStencilTile, target: &mut S::Target) -> TileStats {
        match self.counting {
            Some(c) => self.run_counting(c, ds, target),
            None => self.run_blocks(ds, target),
        }
    }
}
