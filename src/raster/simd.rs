//! The rasterizer's part of the SIMD facade: 8-lane coverage masks,
//! depth and stencil compares and stencil operations on the
//! [`crate::simd`] lane types (which keep every SIMD level to the same
//! bits).

use super::state::{CompareFunc, StencilOp};
use crate::simd::{f32x8, i32x8};

/// Lanes per fragment batch (one row of an 8×8 block).
pub const LANES: usize = 8;

const LANE_BITS: i32x8 = i32x8::new([1, 2, 4, 8, 16, 32, 64, 128]);

/// `[0, 1, ..., 7]`, the lane offsets along x.
pub const LANE_OFFSETS: f32x8 = f32x8::new([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);

/// Expands a coverage bit mask (bit k = lane k) into all-ones lanes.
#[inline]
pub fn lanes_from_bits(bits: u8) -> i32x8 {
    (i32x8::splat(bits as i32) & LANE_BITS).cmp_eq(LANE_BITS)
}

/// Collapses all-ones lanes into a bit mask.
#[inline]
pub fn bits_from_lanes(lanes: i32x8) -> u8 {
    lanes.move_mask() as u8
}

/// Bit mask of lanes where `incoming func stored` holds.
#[inline]
pub fn compare_f32(func: CompareFunc, incoming: f32x8, stored: f32x8) -> u8 {
    match func {
        CompareFunc::Never => 0,
        CompareFunc::Always => 0xff,
        _ => bits_from_lanes(compare_f32_lanes(func, incoming, stored)),
    }
}

/// All-ones lanes where `incoming func stored` holds, zero lanes elsewhere.
#[inline]
pub fn compare_f32_lanes(func: CompareFunc, incoming: f32x8, stored: f32x8) -> i32x8 {
    let m = match func {
        CompareFunc::Never => return i32x8::splat(0),
        CompareFunc::Always => return i32x8::splat(-1),
        CompareFunc::Less => incoming.cmp_lt(stored),
        CompareFunc::LessEqual => incoming.cmp_le(stored),
        CompareFunc::Equal => incoming.cmp_eq(stored),
        CompareFunc::GreaterEqual => incoming.cmp_ge(stored),
        CompareFunc::Greater => incoming.cmp_gt(stored),
        CompareFunc::NotEqual => incoming.cmp_ne(stored),
    };
    m.cast_i32()
}

/// Bit mask of lanes where `reference func stored` holds.
#[inline]
pub fn compare_i32(func: CompareFunc, reference: i32, stored: i32x8) -> u8 {
    let r = i32x8::splat(reference);
    let m = match func {
        CompareFunc::Never => return 0,
        CompareFunc::Always => return 0xff,
        CompareFunc::Less => r.cmp_lt(stored),
        CompareFunc::LessEqual => !r.cmp_gt(stored),
        CompareFunc::Equal => r.cmp_eq(stored),
        CompareFunc::GreaterEqual => !r.cmp_lt(stored),
        CompareFunc::Greater => r.cmp_gt(stored),
        CompareFunc::NotEqual => !r.cmp_eq(stored),
    };
    bits_from_lanes(m)
}

/// The result of a stencil operation on every lane.
#[inline]
pub fn stencil_op(op: StencilOp, stored: i32x8, reference: i32) -> i32x8 {
    match op {
        StencilOp::Keep => stored,
        StencilOp::Zero => i32x8::splat(0),
        StencilOp::Replace => i32x8::splat(reference),
        StencilOp::Increment => stored + i32x8::splat(1),
        StencilOp::Decrement => stored - i32x8::splat(1),
        StencilOp::Invert => !stored,
    }
}

/// `new` where `bits` is set, `old` elsewhere.
#[inline]
pub fn select_i32(bits: u8, new: i32x8, old: i32x8) -> i32x8 {
    lanes_from_bits(bits).blend(new, old)
}

/// `new` where `bits` is set, `old` elsewhere.
#[inline]
pub fn select_f32(bits: u8, new: f32x8, old: f32x8) -> f32x8 {
    lanes_from_bits(bits).cast_f32().blend(new, old)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SIMD compares and stencil ops agree with the scalar tables for
    /// every function, operation and ordering (including equal values).
    #[test]
    fn simd_tables_agree_with_scalar_tables() {
        let funcs = [
            CompareFunc::Never,
            CompareFunc::Less,
            CompareFunc::LessEqual,
            CompareFunc::Equal,
            CompareFunc::GreaterEqual,
            CompareFunc::Greater,
            CompareFunc::NotEqual,
            CompareFunc::Always,
        ];
        let stored = [-3, -1, 0, 1, 2, 2, 5, i32::MAX];
        let stored_f = stored.map(|v| v as f32);
        for f in funcs {
            for r in [-1, 0, 2] {
                let bits = compare_i32(f, r, i32x8::new(stored));
                let fb = compare_f32(f, f32x8::splat(r as f32), f32x8::new(stored_f));
                for k in 0..8 {
                    assert_eq!(
                        bits >> k & 1 == 1,
                        f.test(r, stored[k]),
                        "{f:?} {r} {}",
                        stored[k]
                    );
                    assert_eq!(fb >> k & 1 == 1, f.test(r as f32, stored_f[k]), "{f:?}");
                }
            }
        }
        let ops = [
            StencilOp::Keep,
            StencilOp::Zero,
            StencilOp::Replace,
            StencilOp::Increment,
            StencilOp::Decrement,
            StencilOp::Invert,
        ];
        for op in ops {
            let got = stencil_op(op, i32x8::new(stored), 7).to_array();
            for k in 0..8 {
                assert_eq!(got[k], op.apply(stored[k], 7), "{op:?}");
            }
        }
    }

    #[test]
    fn masks_round_trip() {
        for bits in 0..=255u8 {
            assert_eq!(bits_from_lanes(lanes_from_bits(bits)), bits);
            let s = select_f32(bits, f32x8::splat(1.0), f32x8::splat(0.0)).to_array();
            for (k, v) in s.iter().enumerate() {
                assert_eq!(*v == 1.0, bits >> k & 1 == 1);
            }
        }
    }
}
