//! Tile traversal: hierarchical descent from a 64×64 tile to 8×8 blocks
//! (trivial accept / reject on exact corner values), then 8-lane rows with
//! SIMD coverage, depth and stencil.

use super::fragment::{FragmentBatch, FragmentStage};
use super::framebuffer::{DepthStencilTile, TILE_SIZE};
use super::setup::SetupTriangle;
use super::simd::{
    compare_f32, compare_i32, load_f32, load_i32, select_f32, select_i32, stencil_op, LANE_OFFSETS,
};
use super::state::RasterState;
use wide::{f32x8, f64x4};

const BLOCK: i32 = 8;
const OFFSETS_LO: f64x4 = f64x4::new([0.0, 1.0, 2.0, 3.0]);
const OFFSETS_HI: f64x4 = f64x4::new([4.0, 5.0, 6.0, 7.0]);

/// One partial edge's values along a block row, stepped down the rows.
#[derive(Clone, Copy, Default)]
struct EdgeRows {
    value: f64x4,
    lanes_lo: f64x4,
    lanes_hi: f64x4,
    step_y: f64x4,
}

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
    pub triangles: &'a [SetupTriangle<N>],
    pub bin: &'a [u32],
    pub state: &'a RasterState,
    pub stage: &'a S,
}

impl<const N: usize, S: FragmentStage<N>> TileJob<'_, N, S> {
    /// Rasterizes every binned triangle into this tile, in bin order.
    pub fn run(&self, ds: &mut DepthStencilTile, target: &mut S::Target) -> TileStats {
        let mut stats = TileStats::default();
        let (tx, ty) = self.origin;
        let last = TILE_SIZE as i32 - 1;
        for &ti in self.bin {
            let t = &self.triangles[ti as usize];
            let x0 = t.bbox[0].max(tx);
            let y0 = t.bbox[1].max(ty);
            let x1 = t.bbox[2].min(tx + last);
            let y1 = t.bbox[3].min(ty + last);
            if x0 > x1 || y0 > y1 {
                continue;
            }
            let mut by = y0 & !(BLOCK - 1);
            while by <= y1 {
                let mut bx = x0 & !(BLOCK - 1);
                while bx <= x1 {
                    self.block(t, bx, by, [x0, y0, x1, y1], ds, target, &mut stats);
                    bx += BLOCK;
                }
                by += BLOCK;
            }
        }
        stats
    }

    /// One 8×8 block: classify each edge on the block's corner samples.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn block(
        &self,
        t: &SetupTriangle<N>,
        bx: i32,
        by: i32,
        clip: [i32; 4],
        ds: &mut DepthStencilTile,
        target: &mut S::Target,
        stats: &mut TileStats,
    ) {
        let mut partial = [false; 3];
        for (e, p) in t.edges.iter().zip(partial.iter_mut()) {
            let corner = e.at_pixel(bx as i64, by as i64);
            let sx = e.step_x() * (BLOCK as i64 - 1);
            let sy = e.step_y() * (BLOCK as i64 - 1);
            if corner + sx.max(0) + sy.max(0) < 0 {
                return; // the whole block is outside this edge
            }
            *p = corner + sx.min(0) + sy.min(0) < 0;
        }
        // Lanes inside the scissored bounding box.
        let lo = (clip[0] - bx).max(0);
        let hi = (clip[2] - bx).min(BLOCK - 1);
        let box_bits = ((0xffu32 << lo) & (0xffu32 >> (BLOCK - 1 - hi))) as u8;
        let first_row = by.max(clip[1]);
        let last_row = (by + BLOCK - 1).min(clip[3]);
        // Partial edges, stepped row by row in f64: every value is an
        // integer below 2^53, so the additions are exact.
        let mut rows = [EdgeRows::default(); 3];
        let mut n = 0;
        for (e, _) in t.edges.iter().zip(partial).filter(|(_, p)| *p) {
            let step = f64x4::splat(e.step_x() as f64);
            rows[n] = EdgeRows {
                value: f64x4::splat(e.at_pixel(bx as i64, first_row as i64) as f64),
                lanes_lo: OFFSETS_LO * step,
                lanes_hi: OFFSETS_HI * step,
                step_y: f64x4::splat(e.step_y() as f64),
            };
            n += 1;
        }
        for y in first_row..=last_row {
            let mut mask = box_bits;
            if n > 0 {
                // A lane is outside when any partial edge is negative
                // there: OR the values and read the sign bits. (Values are
                // never -0.0: they are sums of integers starting from a
                // converted i64.)
                let (mut lo, mut hi) = (f64x4::splat(0.0), f64x4::splat(0.0));
                for r in &mut rows[..n] {
                    lo = lo | (r.value + r.lanes_lo);
                    hi = hi | (r.value + r.lanes_hi);
                    r.value += r.step_y;
                }
                let outside = lo.move_mask() | (hi.move_mask() << 4);
                mask &= !(outside as u8);
            }
            if mask != 0 {
                self.row(t, bx, y, mask, ds, target, stats);
            }
        }
    }

    /// Tests, updates and shades one row of 8 fragments.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn row(
        &self,
        t: &SetupTriangle<N>,
        x: i32,
        y: i32,
        mut mask: u8,
        ds: &mut DepthStencilTile,
        target: &mut S::Target,
        stats: &mut TileStats,
    ) {
        let local = ((y - self.origin.1) as usize) * TILE_SIZE + (x - self.origin.0) as usize;
        let depth = (f32x8::splat(t.depth.row_start(x, y))
            + LANE_OFFSETS * f32x8::splat(t.depth.dx))
        .max(f32x8::splat(0.0))
        .min(f32x8::splat(1.0));
        let stored_depth = load_f32(&ds.depth[local..]);
        let mut batch = FragmentBatch {
            x,
            y,
            tile: self.tile,
            local,
            mask,
            depth,
            stored_depth,
            varyings: [f32x8::splat(0.0); N],
            front_facing: t.front_facing,
            primitive: t.primitive,
        };
        let mut varyings_ready = false;
        if S::DISCARDS {
            interpolate(t, x, y, &mut batch.varyings);
            varyings_ready = true;
            mask &= self.stage.discard(&batch);
            if mask == 0 {
                return;
            }
        }
        stats.fragments += mask.count_ones() as u64;

        let state = self.state;
        let passed = match (&state.stencil, ds.stencil.as_mut()) {
            (Some(st), Some(stencil)) => {
                let face = if t.front_facing { st.front } else { st.back };
                let stored = load_i32(&stencil[local..]);
                let s_pass = compare_i32(face.func, st.reference, stored) & mask;
                let s_fail = mask & !s_pass;
                let d_pass = compare_f32(state.depth_func, depth, stored_depth) & s_pass;
                let d_fail = s_pass & !d_pass;
                let r = st.reference;
                let mut new = select_i32(s_fail, stencil_op(face.stencil_fail, stored, r), stored);
                new = select_i32(d_fail, stencil_op(face.depth_fail, stored, r), new);
                new = select_i32(d_pass, stencil_op(face.pass, stored, r), new);
                stencil[local..local + 8].copy_from_slice(&new.to_array());
                d_pass
            }
            _ => compare_f32(state.depth_func, depth, stored_depth) & mask,
        };
        if passed == 0 {
            return;
        }
        stats.passed += passed.count_ones() as u64;
        if state.depth_write {
            let new = select_f32(passed, depth, stored_depth);
            ds.depth[local..local + 8].copy_from_slice(&new.to_array());
        }
        if !varyings_ready {
            interpolate(t, x, y, &mut batch.varyings);
        }
        batch.mask = passed;
        self.stage.shade(&batch, target);
    }
}

/// Perspective-correct varyings: `(v / w) / (1 / w)`, both interpolated
/// linearly in screen space.
#[inline]
fn interpolate<const N: usize>(t: &SetupTriangle<N>, x: i32, y: i32, out: &mut [f32x8; N]) {
    if N == 0 {
        return;
    }
    let row = |p: &super::setup::Plane| {
        f32x8::splat(p.row_start(x, y)) + LANE_OFFSETS * f32x8::splat(p.dx)
    };
    let inv_w = row(&t.inv_w);
    for (o, p) in out.iter_mut().zip(t.varyings.iter()) {
        *o = row(p) / inv_w;
    }
}
