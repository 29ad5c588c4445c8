//! The programmable fragment stage.

use super::simd::LANES;
use crate::simd::f32x8;

/// Eight horizontally adjacent fragments of one triangle (one row of an
/// 8×8 block): lane `k` is pixel `(x + k, y)`.
#[derive(Debug, Clone, Copy)]
pub struct FragmentBatch<const N: usize> {
    /// Pixel x of lane 0.
    pub x: i32,
    /// Pixel row.
    pub y: i32,
    /// Tile index.
    pub tile: usize,
    /// Index of lane 0 inside the tile's row-major 64×64 buffers; lane `k`
    /// is at `local + k`.
    pub local: usize,
    /// Live lanes (bit k = lane k): covered and, in [`FragmentStage::shade`],
    /// past the stencil and depth tests.
    pub mask: u8,
    /// Interpolated depth (reversed Z).
    pub depth: f32x8,
    /// The depth buffer's values before this batch's write.
    pub stored_depth: f32x8,
    /// Perspective-correct varyings.
    pub varyings: [f32x8; N],
    /// Whether the triangle faces the camera (counter-clockwise on screen).
    pub front_facing: bool,
    /// Index of the input triangle.
    pub primitive: u32,
}

impl<const N: usize> FragmentBatch<N> {
    /// Iterates the live lanes.
    pub fn lanes(&self) -> impl Iterator<Item = usize> + '_ {
        (0..LANES).filter(move |k| self.mask >> k & 1 == 1)
    }
}

/// A programmable per-fragment stage.
///
/// `Target` is whatever one tile of the stage's outputs is (a tile of a
/// [`super::TiledTarget`], several of them, per-sample counters, ...): the
/// pipeline hands each tile's target to exactly one thread at a time.
pub trait FragmentStage<const N: usize>: Sync {
    /// One tile of this stage's render targets.
    type Target: Send;

    /// Whether [`FragmentStage::discard`] may kill fragments (e.g. an alpha
    /// test); when false the pipeline skips the call.
    const DISCARDS: bool = false;

    /// Whether [`FragmentStage::shade`] does anything; when false the
    /// pipeline never builds fragment batches for it.
    const SHADES: bool = true;

    /// Called before the stencil and depth tests; returns the lanes that
    /// survive (a subset of `batch.mask`).
    fn discard(&self, batch: &FragmentBatch<N>) -> u8 {
        batch.mask
    }

    /// Called for the lanes that passed every test.
    fn shade(&self, batch: &FragmentBatch<N>, target: &mut Self::Target);
}

/// A stage with no outputs besides depth and stencil.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoFragmentStage;

impl<const N: usize> FragmentStage<N> for NoFragmentStage {
    type Target = ();
    const SHADES: bool = false;
    fn shade(&self, _batch: &FragmentBatch<N>, _target: &mut ()) {}
}
