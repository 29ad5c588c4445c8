//! The programmable vertex stage and its output.

use glam::Vec4;
use rayon::prelude::*;

/// A vertex after the vertex stage: a clip-space position and `N` varyings.
///
/// Clip space follows the reversed-Z, infinite-far convention of
/// [`crate::raster::RasterState`]: inside the view volume
/// `0 <= z <= w`, `-w <= x, y <= w`. A vertex with `w = 0` (and `z = 0`)
/// is a point at infinity, e.g. a shadow-volume vertex extruded away from
/// the light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClipVertex<const N: usize> {
    /// Homogeneous clip-space position.
    pub position: Vec4,
    /// Varyings, interpolated perspective-correctly across the triangle.
    pub varyings: [f32; N],
}

/// Runs a vertex stage over all inputs in parallel; output order is input
/// order, so the result does not depend on the thread count.
pub fn run_vertex_stage<I, F, const N: usize>(inputs: &[I], stage: F) -> Vec<ClipVertex<N>>
where
    I: Sync,
    F: Fn(&I) -> ClipVertex<N> + Sync,
{
    let mut out = Vec::new();
    run_vertex_stage_into(inputs, stage, &mut out);
    out
}

/// [`run_vertex_stage`] into a reused vector (cleared first), so a frame
/// loop allocates nothing.
pub fn run_vertex_stage_into<I, F, const N: usize>(
    inputs: &[I],
    stage: F,
    out: &mut Vec<ClipVertex<N>>,
) where
    I: Sync,
    F: Fn(&I) -> ClipVertex<N> + Sync,
{
    out.clear();
    out.par_extend(inputs.par_iter().with_min_len(4096).map(&stage));
}
