//! The block descent: small triangles (bounding box within 8×8 pixels)
//! go straight to 8-lane rows over their box with `i32` edge values;
//! larger ones descend from the 64×64 tile to 8×8 blocks (trivial accept /
//! reject on exact corner values), then rows with exact `f64` lanes on the
//! edges that cross the block. The 8-lane row (depth, stencil, fragment
//! batch) is shared with the counting walk.

use super::depth_bounds::{DepthBounds, Verdict};
use super::job::{clip_to_tile, TileJob, TileStats, BLOCK, OFFSETS_I32};
use crate::raster::fragment::{FragmentBatch, FragmentStage};
use crate::raster::framebuffer::{DepthStencilTile, TILE_SIZE};
use crate::raster::setup::SetupTriangle;
use crate::raster::simd::{compare_f32, compare_i32, select_f32, select_i32, stencil_op, LANES};
use crate::raster::state::{CompareFunc, StencilOp};
use crate::simd::{f32x8, f64x4, i32x8};

const OFFSETS_LO: f64x4 = f64x4::new([0.0, 1.0, 2.0, 3.0]);
const OFFSETS_HI: f64x4 = f64x4::new([4.0, 5.0, 6.0, 7.0]);

/// Set bits of every byte; `count_ones` is a library loop on baseline
/// x86-64 (no POPCNT), a table is one load.
const POPCOUNT: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = (i as u8).count_ones() as u8;
        i += 1;
    }
    t
};

/// Side of the first level of blocks inside a tile.
const SUPER: i32 = 16;

/// Classifies the `size × size` block at `(x, y)` against each edge on its
/// corner samples: `None` when it lies wholly outside an edge, else which
/// edges cross it.
#[inline]
fn classify<const N: usize>(t: &SetupTriangle<N>, x: i32, y: i32, size: i32) -> Option<[bool; 3]> {
    let mut partial = [false; 3];
    for (e, p) in t.edges.iter().zip(partial.iter_mut()) {
        let corner = e.at_pixel(x as i64, y as i64);
        let sx = e.step_x() * (size as i64 - 1);
        let sy = e.step_y() * (size as i64 - 1);
        if corner + sx.max(0) + sy.max(0) < 0 {
            return None;
        }
        *p = corner + sx.min(0) + sy.min(0) < 0;
    }
    Some(partial)
}

/// One partial edge's values along a block row, stepped down the rows.
#[derive(Clone, Copy, Default)]
struct EdgeRows {
    value: f64x4,
    lanes_lo: f64x4,
    lanes_hi: f64x4,
    step_y: f64x4,
}

impl<const N: usize, S: FragmentStage<N>> TileJob<'_, N, S> {
    /// [`TileJob::run`] for every pass but a counting one: the block
    /// descent, or straight rows for small triangles.
    pub(super) fn run_blocks(
        &self,
        ds: &mut DepthStencilTile,
        target: &mut S::Target,
    ) -> TileStats {
        let mut stats = TileStats::default();
        let (tx, ty) = self.origin;
        // Depth bounds skip rectangles where no fragment can pass, for
        // passes whose only effect is on passing fragments (no depth
        // write, no stencil): a wedge pass counting faces in front of
        // (Greater) or behind (LessEqual, the exact complement) receivers.
        let use_bounds = !self.state.depth_write
            && self.state.stencil.is_none()
            && matches!(
                self.state.depth_func,
                CompareFunc::Greater | CompareFunc::LessEqual
            );
        let on_fail = self.state.depth_func == CompareFunc::LessEqual;
        let mut bounds: Option<DepthBounds> = None;
        let mut skip = |t: &SetupTriangle<N>, rect: [i32; 4], depth: &[f32]| -> bool {
            use_bounds && {
                let local = [rect[0] - tx, rect[1] - ty, rect[2] - tx, rect[3] - ty];
                let b = bounds.get_or_insert_with(|| DepthBounds::of(depth));
                b.verdict(&t.depth, None, self.origin, local, on_fail) == Verdict::Skip
            }
        };
        for &ti in self.bin {
            let (t, _) = self.setup.get(ti);
            let Some(clip) = clip_to_tile(t.bbox, tx, ty) else {
                continue;
            };
            if skip(t, clip, &ds.depth) {
                continue;
            }
            if t.small {
                self.small(t, clip, ds, target, &mut stats);
                continue;
            }
            // Two levels: 16×16 sub-blocks, then 8×8 blocks, each
            // classified on exact corner values; thin triangles (shadow
            // volume sides) skip most of their bounding box at the first
            // level.
            let mut sy = clip[1] & !(SUPER - 1);
            while sy <= clip[3] {
                let mut sx = clip[0] & !(SUPER - 1);
                while sx <= clip[2] {
                    let sub = [
                        sx.max(clip[0]),
                        sy.max(clip[1]),
                        (sx + SUPER - 1).min(clip[2]),
                        (sy + SUPER - 1).min(clip[3]),
                    ];
                    let covered = classify(t, sx, sy, SUPER);
                    if let Some(partial) = covered.filter(|_| !skip(t, sub, &ds.depth)) {
                        let inside = !partial.iter().any(|&p| p);
                        let mut by = sy.max(clip[1] & !(BLOCK - 1));
                        while by < sy + SUPER && by <= clip[3] {
                            let mut bx = sx.max(clip[0] & !(BLOCK - 1));
                            while bx < sx + SUPER && bx <= clip[2] {
                                let block_partial = if inside {
                                    Some([false; 3])
                                } else {
                                    classify(t, bx, by, BLOCK)
                                };
                                if let Some(p) = block_partial {
                                    self.block(t, bx, by, clip, p, ds, target, &mut stats);
                                }
                                bx += BLOCK;
                            }
                            by += BLOCK;
                        }
                    }
                    sx += SUPER;
                }
                sy += SUPER;
            }
        }
        stats
    }

    /// A triangle spanning less than 8×8 pixels: one batch per box row,
    /// lanes starting at the box's left column. Its edge coefficients are
    /// below 8 · 256 and the box's samples lie within 9 pixels of every
    /// vertex, so edge values stay below 2 · 8 · 256 · 9 · 256 < 2^31 in
    /// magnitude: `i32` lanes hold them exactly.
    #[inline]
    pub(super) fn small(
        &self,
        t: &SetupTriangle<N>,
        clip: [i32; 4],
        ds: &mut DepthStencilTile,
        target: &mut S::Target,
        stats: &mut TileStats,
    ) {
        let x = clip[0];
        let lanes = (0xffu32 >> (BLOCK - 1 - (clip[2] - x))) as u8;
        let mut value = [i32x8::splat(0); 3];
        let mut step_y = [0i32; 3];
        for k in 0..3 {
            let e = &t.edges[k];
            let base = e.at_pixel(x as i64, clip[1] as i64) as i32;
            value[k] = i32x8::splat(base) + OFFSETS_I32 * i32x8::splat(e.step_x() as i32);
            step_y[k] = e.step_y() as i32;
        }
        for y in clip[1]..=clip[3] {
            let outside = (value[0] | value[1] | value[2]).move_mask() as u8;
            let mask = lanes & !outside;
            if mask != 0 {
                self.row(t, x, y, mask, ds, target, stats);
            }
            for k in 0..3 {
                value[k] += i32x8::splat(step_y[k]);
            }
        }
    }

    /// One 8×8 block whose edges crossing it are `partial`.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn block(
        &self,
        t: &SetupTriangle<N>,
        bx: i32,
        by: i32,
        clip: [i32; 4],
        partial: [bool; 3],
        ds: &mut DepthStencilTile,
        target: &mut S::Target,
        stats: &mut TileStats,
    ) {
        // Lanes inside the scissored bounding box.
        let lo = (clip[0] - bx).max(0);
        let hi = (clip[2] - bx).min(BLOCK - 1);
        let box_bits = ((0xffu32 << lo) & (0xffu32 >> (BLOCK - 1 - hi))) as u8;
        let first_row = by.max(clip[1]);
        let last_row = (by + BLOCK - 1).min(clip[3]);
        let any_partial = partial.iter().any(|&p| p);
        if any_partial && t.block_i32 {
            // Partial edges of a triangle whose edges are short enough:
            // inside a block they cross, values stay below 2^31, so 8
            // exact i32 lanes do one row at once.
            let mut value = [i32x8::splat(0); 3];
            let mut step_y = [0i32; 3];
            let mut n = 0;
            for (e, _) in t.edges.iter().zip(partial).filter(|(_, p)| *p) {
                let base = e.at_pixel(bx as i64, first_row as i64) as i32;
                value[n] = i32x8::splat(base) + OFFSETS_I32 * i32x8::splat(e.step_x() as i32);
                step_y[n] = e.step_y() as i32;
                n += 1;
            }
            for y in first_row..=last_row {
                let mut or = value[0];
                for v in &value[1..n] {
                    or |= *v;
                }
                let mask = box_bits & !(or.move_mask() as u8);
                if mask != 0 {
                    self.row(t, bx, y, mask, ds, target, stats);
                }
                for k in 0..n {
                    value[k] += i32x8::splat(step_y[k]);
                }
            }
            return;
        }
        // Partial edges, stepped row by row in f64: every value is an
        // integer below 2^53, so the additions are exact.
        let zero = f64x4::splat(0.0);
        let mut rows = [EdgeRows {
            value: zero,
            lanes_lo: zero,
            lanes_hi: zero,
            step_y: zero,
        }; 3];
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
                    lo |= r.value + r.lanes_lo;
                    hi |= r.value + r.lanes_hi;
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

    /// Tests, updates and shades 8 fragments `(x + k, y)` of one row.
    /// Live lanes lie inside the tile; the depth and stencil tiles carry 8
    /// elements of padding so that a batch starting near a row's end may
    /// read and write back (unchanged) lanes past it.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
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
        // Clamped into [0, 1] (planes are finite; the facade's `max` /
        // `min` are one instruction each on x86).
        let depth = t
            .depth
            .lanes(x, y)
            .max(f32x8::splat(0.0))
            .min(f32x8::splat(1.0));
        let stored_depth = f32x8::load(&ds.depth[local..]);
        if let (Some(c), Some(stencil)) = (self.counting, ds.stencil.as_mut()) {
            let pass = compare_f32(self.state.depth_func, depth, stored_depth);
            let lanes = mask & if c.on_depth_fail { !pass } else { pass };
            let delta = if t.front_facing { c.front } else { c.back };
            stats.fragments += POPCOUNT[mask as usize] as u64;
            if delta == 0 {
                return;
            }
            let (d, zero) = (i32x8::splat(delta), i32x8::splat(0));
            if lanes != 0 {
                let stored = i32x8::load(&stencil[local..]);
                let next = stored + select_i32(lanes, d, zero);
                stencil[local..local + LANES].copy_from_slice(&next.to_array());
            }
            // Per depth scale, the change of the count: + where the
            // scaled depth counts, − where the stored one did.
            for (image, &scale) in ds.shifted.iter_mut().zip(c.shifts.as_slice()) {
                let pass = compare_f32(
                    self.state.depth_func,
                    depth,
                    stored_depth * f32x8::splat(scale),
                );
                let shifted = mask & if c.on_depth_fail { !pass } else { pass };
                if shifted != lanes {
                    let stored = i32x8::load(&image[local..]);
                    let next = stored + select_i32(shifted, d, zero) - select_i32(lanes, d, zero);
                    image[local..local + LANES].copy_from_slice(&next.to_array());
                }
            }
            return;
        }
        // The batch is built only for stages that look at it: a depth or
        // stencil pass never pays for it.
        let batch = |mask: u8| {
            let mut varyings = [f32x8::splat(0.0); N];
            interpolate(t, x, y, &mut varyings);
            FragmentBatch {
                x,
                y,
                tile: self.tile,
                local,
                mask,
                depth,
                stored_depth,
                varyings,
                front_facing: t.front_facing,
                primitive: t.primitive,
            }
        };
        if S::DISCARDS {
            mask &= self.stage.discard(&batch(mask));
            if mask == 0 {
                return;
            }
        }
        stats.fragments += POPCOUNT[mask as usize] as u64;

        let state = self.state;
        let passed = match (&state.stencil, ds.stencil.as_mut()) {
            (Some(st), Some(stencil)) => {
                let face = if t.front_facing { st.front } else { st.back };
                let stored = i32x8::load(&stencil[local..]);
                let s_pass = match face.func {
                    CompareFunc::Always => mask,
                    func => compare_i32(func, st.reference, stored) & mask,
                };
                let d_pass = compare_f32(state.depth_func, depth, stored_depth) & s_pass;
                // Only operations that change something are evaluated: a
                // z-fail pass, say, has a single non-Keep operation.
                let r = st.reference;
                let mut new = stored;
                let mut changed = false;
                for (op, lanes) in [
                    (face.stencil_fail, mask & !s_pass),
                    (face.depth_fail, s_pass & !d_pass),
                    (face.pass, d_pass),
                ] {
                    if lanes != 0 && !matches!(op, StencilOp::Keep) {
                        new = select_i32(lanes, stencil_op(op, stored, r), new);
                        changed = true;
                    }
                }
                if changed {
                    stencil[local..local + LANES].copy_from_slice(&new.to_array());
                }
                d_pass
            }
            _ => compare_f32(state.depth_func, depth, stored_depth) & mask,
        };
        if passed == 0 {
            return;
        }
        stats.passed += POPCOUNT[passed as usize] as u64;
        if state.depth_write {
            let new = select_f32(passed, depth, stored_depth);
            ds.depth[local..local + LANES].copy_from_slice(&new.to_array());
        }
        if S::SHADES {
            self.stage.shade(&batch(passed), target);
        }
    }
}

/// Perspective-correct varyings: `(v / w) / (1 / w)`, both interpolated
/// linearly in screen space.
#[inline]
fn interpolate<const N: usize>(t: &SetupTriangle<N>, x: i32, y: i32, out: &mut [f32x8; N]) {
    if N == 0 {
        return;
    }
    let inv_w = t.inv_w.lanes(x, y);
    for (o, p) in out.iter_mut().zip(t.varyings.iter()) {
        *o = p.lanes(x, y) / inv_w;
    }
}
