//! The stratified pattern's samples in a rect light's chart, four cells
//! of a row at a time.
//!
//! Sample `k = j a + i` of the jittered `a × b` grid is
//! `s = (i + ξ) / a`, `t = (j + ξ') / b` with `(ξ, ξ')` =
//! [`uniform_pair`]`(key, k)` (`Strata::point`), and its chart point is
//! `(2 s − 1, 1 − 2 t)` rounded to f32. Per receiver that is hundreds of
//! SplitMix64 hashes and f64 → f32 conversions, one after another in
//! scalar code. [`chart_rows`] makes a rectangle of cells, rows `4 m`
//! cells wide: with AVX2, four at a time (the hash's 64-bit products from 32-bit
//! ones, the 32-bit integers to f64 exactly by the 2⁵² bias, then the
//! scalar code's f64 operations in its order), otherwise one at a time.
//! Integer arithmetic is exact and each float operation is the same IEEE
//! operation, so both give the scalar walk's bits; a test holds them to
//! `Strata::point`.
//!
//! Only grids whose sides are powers of two take this path (the walk
//! multiplies by the exact inverse there, and divides otherwise).

use crate::sampling::{uniform_pair, Strata};
#[cfg(target_arch = "x86_64")]
use crate::simd::level::runs_v3;

/// Whether a receiver's `n` samples on `strata` can be made by
/// [`chart_rows`]: every cell one sample, both sides powers of two, rows
/// of whole steps of four.
pub(super) fn chart_rows_apply(strata: Strata, n: u32) -> bool {
    strata.count() == n
        && strata.a.is_power_of_two()
        && strata.b.is_power_of_two()
        && strata.a.is_multiple_of(4)
}

/// Chart points of the cells `i0 .. i0 + w` of rows `j0, j0 + 1, …` of a
/// jittered grid `a` cells wide (`a` and the rows `b` powers of two,
/// `inv` = `(1 / a, 1 / b)`, `w` a multiple of 4) under the pixel's
/// sample `key`, row after row into `xs`, `ys` (as many rows as they
/// hold).
#[inline(always)]
pub(super) fn chart_rows(
    key: u64,
    a: u32,
    (i0, j0, w): (u32, u32, usize),
    inv: (f64, f64),
    xs: &mut [f32],
    ys: &mut [f32],
) {
    debug_assert!(xs.len() == ys.len() && w.is_multiple_of(4) && xs.len().is_multiple_of(w));
    #[cfg(target_arch = "x86_64")]
    if runs_v3() {
        // SAFETY: `runs_v3` checked that the CPU has x86-64-v3's
        // features, AVX and AVX2 among them: the kernel's one requirement.
        return unsafe { chart_rows_avx2(key, a, (i0, j0, w), inv, xs, ys) };
    }
    chart_rows_scalar(key, a, (i0, j0, w), inv, xs, ys);
}

/// [`chart_rows`] one cell at a time: the scalar twin, and the baseline.
#[inline(always)]
fn chart_rows_scalar(
    key: u64,
    a: u32,
    (i0, j0, w): (u32, u32, usize),
    (inv_a, inv_b): (f64, f64),
    xs: &mut [f32],
    ys: &mut [f32],
) {
    let rows = xs.chunks_exact_mut(w).zip(ys.chunks_exact_mut(w));
    for (j, (xs, ys)) in (j0..).zip(rows) {
        for (i, (x, y)) in (i0..).zip(xs.iter_mut().zip(ys.iter_mut())) {
            let (xi, xi2) = uniform_pair(key, j * a + i);
            let (s, t) = ((f64::from(i) + xi) * inv_a, (f64::from(j) + xi2) * inv_b);
            *x = (2.0 * s - 1.0) as f32;
            *y = (1.0 - 2.0 * t) as f32;
        }
    }
}

/// [`chart_rows`] with AVX2, four cells per step, on the SIMD facade's
/// AVX lane types.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
fn chart_rows_avx2(
    key: u64,
    a: u32,
    (i0, j0, w): (u32, u32, usize),
    inv: (f64, f64),
    xs: &mut [f32],
    ys: &mut [f32],
) {
    use crate::simd::avx::F64x4;
    let (two, one) = (F64x4::splat(2.0), F64x4::splat(1.0));
    let rows = xs.len() / w.max(1);
    jittered_rows_avx2(key, a, (i0, j0, w), inv, rows, |at, s, t| {
        if let (Some(xs), Some(ys)) = (xs.get_mut(at..at + 4), ys.get_mut(at..at + 4)) {
            xs.copy_from_slice(&two.mul(s).sub(one).to_f32_array());
            ys.copy_from_slice(&one.sub(two.mul(t)).to_f32_array());
        }
    });
}

/// The jittered grid's `(s, t)` four cells at a time, with AVX2: cells
/// `i0 .. i0 + w` of `rows` rows from `j0` of a grid `a` cells wide (`w`
/// a multiple of 4; `inv` = `(1 / a, 1 / b)`, both sides powers of two)
/// under the pixel's sample `key`, each step handed to `f` with its
/// first cell's place in row-after-row order. `s = (i + ξ) · inv_a`, `t =
/// (j + ξ') · inv_b` with `(ξ, ξ')` = [`uniform_pair`]`(key, j a + i)`:
/// SplitMix64 on 64-bit lanes (its 64-bit products from 32-bit ones), the
/// 32-bit integers to f64 exactly by the 2⁵² bias, then the scalar code's
/// f64 operations in its order, so the scalar walk's bits. Shared by
/// [`chart_rows`] and `sample_lanes`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
#[inline]
pub(super) fn jittered_rows_avx2(
    key: u64,
    a: u32,
    (i0, j0, w): (u32, u32, usize),
    (inv_a, inv_b): (f64, f64),
    rows: usize,
    mut f: impl FnMut(usize, crate::simd::avx::F64x4, crate::simd::avx::F64x4),
) {
    use crate::sampling::{GOLDEN, MIX_1, MIX_2};
    use crate::simd::avx::{F64x4, U64x4};
    // SplitMix64's output function, four lanes at once (`mix64`).
    let mix = |z: U64x4| {
        let z = z.xor(z.shr::<30>()).wrapping_mul(MIX_1);
        let z = z.xor(z.shr::<27>()).wrapping_mul(MIX_2);
        z.xor(z.shr::<31>())
    };
    // `(h >> 32) as f64 × 2⁻³²`, as `uniform_pair`.
    let scale = F64x4::splat(1.0 / 4_294_967_296.0);
    let to_unit = |h: U64x4| h.high_half_to_f64().mul(scale);
    let golden_2 = GOLDEN.wrapping_mul(2);
    let (golden, golden_8) = (U64x4::splat(GOLDEN), U64x4::splat(GOLDEN.wrapping_mul(8)));
    let four = F64x4::splat(4.0);
    let (inv_a, inv_b) = (F64x4::splat(inv_a), F64x4::splat(inv_b));
    let first_col = F64x4::new([
        f64::from(i0),
        f64::from(i0 + 1),
        f64::from(i0 + 2),
        f64::from(i0 + 3),
    ]);
    for (r, j) in (0..rows).zip(j0..) {
        // Lane `l` of cell `k = k0 + l` hashes `key + (2k + 1) G` and
        // `key + (2k + 2) G`: from the row's first cell's, steps of `2G`
        // per lane and `8G` per four cells (wrapping, as the scalar
        // products).
        let k0 = u64::from(j * a + i0);
        let first = key.wrapping_add((2 * k0 + 1).wrapping_mul(GOLDEN));
        let mut hash = U64x4::new([
            first,
            first.wrapping_add(golden_2),
            first.wrapping_add(golden_2.wrapping_mul(2)),
            first.wrapping_add(golden_2.wrapping_mul(3)),
        ]);
        let row = F64x4::splat(f64::from(j));
        let mut col = first_col;
        for step in (0..w).step_by(4) {
            let xi = to_unit(mix(hash));
            let xi2 = to_unit(mix(hash.wrapping_add(golden)));
            f(
                r * w + step,
                col.add(xi).mul(inv_a),
                row.add(xi2).mul(inv_b),
            );
            hash = hash.wrapping_add(golden_8);
            col = col.add(four);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both kernels give `Strata::point`'s chart points bit for bit, on
    /// rectangles of whole rows and of rows' parts (as the 4 × 4 blocks
    /// make them), from the first, a middle and the last row down.
    #[test]
    fn rows_are_the_strata_points() {
        let mut key = 0x1234_5678_9abc_def0u64;
        for a in [4u32, 8, 16, 32] {
            let strata = Strata { a, b: a };
            let inv = (1.0 / f64::from(a), 1.0 / f64::from(a));
            for round in 0..40 {
                key = crate::sampling::mix64(key.wrapping_add(round));
                let parts = [(0, a), (a - 4, 4), (a / 2, a / 2)];
                for (i0, w) in parts.into_iter().filter(|p| p.1 % 4 == 0) {
                    for j0 in [0, a / 2, a - 1] {
                        let want: Vec<(u32, u32)> = (j0..a)
                            .flat_map(|j| (i0..i0 + w).map(move |i| (i, j)))
                            .map(|(i, j)| {
                                let (s, t) = strata.point(key, j * a + i);
                                let x = (2.0 * s - 1.0) as f32;
                                let y = (1.0 - 2.0 * t) as f32;
                                (x.to_bits(), y.to_bits())
                            })
                            .collect();
                        let n = want.len();
                        let cells = (i0, j0, w as usize);
                        let bits = |xs: &[f32], ys: &[f32]| -> Vec<(u32, u32)> {
                            xs.iter()
                                .zip(ys)
                                .map(|(x, y)| (x.to_bits(), y.to_bits()))
                                .collect()
                        };
                        let (mut xs, mut ys) = (vec![0f32; n], vec![0f32; n]);
                        chart_rows(key, a, cells, inv, &mut xs, &mut ys);
                        assert_eq!(bits(&xs, &ys), want, "a {a}, {cells:?}");
                        let (mut xs, mut ys) = (vec![0f32; n], vec![0f32; n]);
                        chart_rows_scalar(key, a, cells, inv, &mut xs, &mut ys);
                        assert_eq!(bits(&xs, &ys), want, "scalar: a {a}, {cells:?}");
                    }
                }
            }
        }
    }
}
