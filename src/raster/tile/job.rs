//! What one tile's work shares with every stage of it: the job (triangles,
//! bin, state, stage), the counting form of a pass, the per-tile counters
//! and the block size. A leaf: it imports no other file of `tile/`, so
//! the block descent, the counting walk and the depth bounds can all
//! import it.

use crate::raster::fragment::FragmentStage;
use crate::raster::setup::{QuadExtra, SetupTriangle};
use crate::raster::state::{CompareFunc, RasterState, StencilFace, StencilOp};
use crate::simd::i32x8;

/// Bits of a [`SetupList`] number that count within a chunk: a setup
/// chunk makes at most 7 triangles per input triangle (a clipped polygon
/// has at most 9 corners), so at most `7 × 2048 < 2^14`.
pub(crate) const CHUNK_LOCAL_BITS: u32 = 14;

/// One setup work item's output: its set-up triangles and their merged
/// quads' extras (a triangle's `quad` indexes its own chunk's).
pub(crate) type SetupPart<const N: usize> = (Vec<SetupTriangle<N>>, Vec<QuadExtra>);

/// A draw's set-up triangles, left in the chunks setup made them in rather
/// than copied into one list: at 1024² a shadow volume's list is ~40 MB,
/// which the allocator maps afresh for every draw (above its 32 MiB
/// threshold), so each draw page-faulted all of it in. A triangle is
/// numbered `chunk << CHUNK_LOCAL_BITS | index in chunk`, which orders
/// triangles as the input does.
#[derive(Clone, Copy)]
pub(crate) struct SetupList<'a, const N: usize> {
    pub chunks: &'a [SetupPart<N>],
}

impl<'a, const N: usize> SetupList<'a, N> {
    /// Triangle `number`, and the quad extras of its chunk.
    #[inline(always)]
    pub fn get(&self, number: u32) -> (&'a SetupTriangle<N>, &'a [QuadExtra]) {
        let (tris, quads) = &self.chunks[(number >> CHUNK_LOCAL_BITS) as usize];
        (
            &tris[(number & ((1 << CHUNK_LOCAL_BITS) - 1)) as usize],
            quads,
        )
    }
}

/// Side of a block, and lanes per row of it.
pub(crate) const BLOCK: i32 = 8;

/// A triangle's pixel bounding box `[x0, y0, x1, y1]` (inclusive) clipped
/// to the tile at `(tx, ty)`; `None` when they do not meet.
#[inline(always)]
pub(crate) fn clip_to_tile(bbox: [i32; 4], tx: i32, ty: i32) -> Option<[i32; 4]> {
    let last = crate::raster::TILE_SIZE as i32 - 1;
    let clip = [
        bbox[0].max(tx),
        bbox[1].max(ty),
        bbox[2].min(tx + last),
        bbox[3].min(ty + last),
    ];
    (clip[0] <= clip[2] && clip[1] <= clip[3]).then_some(clip)
}
pub(crate) const OFFSETS_I32: i32x8 = i32x8::new([0, 1, 2, 3, 4, 5, 6, 7]);

/// Per-tile counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TileStats {
    /// Covered samples that reached the tests.
    pub fragments: u64,
    /// Samples that passed stencil and depth tests.
    pub passed: u64,
}

/// Everything constant over one tile's work.
pub(crate) struct TileJob<'a, const N: usize, S: FragmentStage<N>> {
    pub tile: usize,
    pub origin: (i32, i32),
    /// The draw's set-up triangles, in the chunks setup made them in.
    pub setup: SetupList<'a, N>,
    /// The tile's triangles, as [`SetupList`] numbers, in draw order.
    pub bin: &'a [u32],
    pub state: &'a RasterState,
    pub stage: &'a S,
    /// Set for pure counting passes (see [`CountingPass`]).
    pub counting: Option<CountingPass>,
}

/// A stencil pass that only counts: no fragment stage, no depth writes, an
/// always-passing stencil test, and per facing a single operation that
/// adds ±1 either where the depth test fails (z-fail) or where it passes
/// (z-pass). Shadow volumes are exactly this; rows then reduce to one
/// compare and one masked add.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CountingPass {
    /// Added per front-facing fragment.
    pub(crate) front: i32,
    /// Added per back-facing fragment.
    pub(crate) back: i32,
    /// Count where the depth test fails (z-fail) rather than passes.
    pub(crate) on_depth_fail: bool,
    /// Also record, per scale, the change of the count when each stored
    /// depth is scaled by it ([`crate::raster::draw_depth_shift_counts`]), into
    /// the tiles' [`crate::raster::DepthStencilTile::shifted`] images.
    pub(crate) shifts: DepthShifts,
}

/// Most depth scales one counting walk records
/// ([`CountingPass::shifts`]).
pub(crate) const MAX_DEPTH_SHIFTS: usize = 4;

/// The depth scales of a counting walk (at most [`MAX_DEPTH_SHIFTS`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct DepthShifts {
    pub(super) scales: [f32; MAX_DEPTH_SHIFTS],
    pub(super) len: usize,
}

impl DepthShifts {
    /// The scales `scales`, or `None` when there are too many.
    pub(crate) fn new(scales: &[f32]) -> Option<DepthShifts> {
        let mut out = DepthShifts::default();
        out.scales.get_mut(..scales.len())?.copy_from_slice(scales);
        out.len = scales.len();
        Some(out)
    }

    /// The scales, in order.
    pub(crate) fn as_slice(&self) -> &[f32] {
        &self.scales[..self.len]
    }
}

impl CountingPass {
    /// The counting form of `state`, if it has one.
    pub(crate) fn of<const N: usize, S: FragmentStage<N>>(state: &RasterState) -> Option<Self> {
        if S::SHADES || S::DISCARDS || state.depth_write {
            return None;
        }
        let st = state.stencil?;
        let delta = |op: StencilOp| match op {
            StencilOp::Keep => Some(0),
            StencilOp::Increment => Some(1),
            StencilOp::Decrement => Some(-1),
            _ => None,
        };
        let face = |f: StencilFace| -> Option<(i32, i32)> {
            if f.func != CompareFunc::Always || f.stencil_fail != StencilOp::Keep {
                return None;
            }
            Some((delta(f.depth_fail)?, delta(f.pass)?))
        };
        let (front_fail, front_pass) = face(st.front)?;
        let (back_fail, back_pass) = face(st.back)?;
        if front_pass == 0 && back_pass == 0 {
            Some(CountingPass {
                front: front_fail,
                back: back_fail,
                on_depth_fail: true,
                shifts: DepthShifts::default(),
            })
        } else if front_fail == 0 && back_fail == 0 {
            Some(CountingPass {
                front: front_pass,
                back: back_pass,
                on_depth_fail: false,
                shifts: DepthShifts::default(),
            })
        } else {
            None
        }
    }
}

/// A small deterministic generator for the traversal tests.
#[cfg(test)]
pub(crate) struct Lcg(pub u64);

#[cfg(test)]
impl Lcg {
    /// Uniform in `0..n`.
    pub fn below(&mut self, n: i64) -> i64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 33) as i64).rem_euclid(n)
    }
}
