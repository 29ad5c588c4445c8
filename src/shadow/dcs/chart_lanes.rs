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

/// [`chart_rows`] with AVX2, four cells per step.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
fn chart_rows_avx2(
    key: u64,
    a: u32,
    (i0, j0, w): (u32, u32, usize),
    (inv_a, inv_b): (f64, f64),
    xs: &mut [f32],
    ys: &mut [f32],
) {
    use crate::sampling::{GOLDEN, MIX_1, MIX_2};
    use core::arch::x86_64::*;
    // `z · c` (mod 2⁶⁴) for 64-bit lanes `z` and a constant `c`: the low
    // halves' full product plus the cross products shifted up (the high
    // halves' product falls off the top).
    let mul = |z: __m256i, c: u64| {
        let (c_lo, c_hi) = (
            _mm256_set1_epi64x((c & 0xffff_ffff) as i64),
            _mm256_set1_epi64x((c >> 32) as i64),
        );
        let low = _mm256_mul_epu32(z, c_lo);
        let cross = _mm256_add_epi64(
            _mm256_mul_epu32(_mm256_srli_epi64::<32>(z), c_lo),
            _mm256_mul_epu32(z, c_hi),
        );
        _mm256_add_epi64(low, _mm256_slli_epi64::<32>(cross))
    };
    let mix = |z: __m256i| {
        let z = mul(_mm256_xor_si256(z, _mm256_srli_epi64::<30>(z)), MIX_1);
        let z = mul(_mm256_xor_si256(z, _mm256_srli_epi64::<27>(z)), MIX_2);
        _mm256_xor_si256(z, _mm256_srli_epi64::<31>(z))
    };
    // `(h >> 32)` as f64, then × 2⁻³²: below 2³², so OR-ing it into the
    // mantissa of 2⁵² and subtracting 2⁵² is exact.
    let bias = _mm256_set1_epi64x(0x4330_0000_0000_0000);
    let two52 = _mm256_set1_pd(4_503_599_627_370_496.0);
    let scale = _mm256_set1_pd(1.0 / 4_294_967_296.0);
    let to_unit = |h: __m256i| {
        let v = _mm256_or_si256(_mm256_srli_epi64::<32>(h), bias);
        _mm256_mul_pd(_mm256_sub_pd(_mm256_castsi256_pd(v), two52), scale)
    };
    let g2 = GOLDEN.wrapping_mul(2);
    let (g, g8) = (
        _mm256_set1_epi64x(GOLDEN as i64),
        _mm256_set1_epi64x(GOLDEN.wrapping_mul(8) as i64),
    );
    let (two, one, four) = (
        _mm256_set1_pd(2.0),
        _mm256_set1_pd(1.0),
        _mm256_set1_pd(4.0),
    );
    let (inv_a, inv_b) = (_mm256_set1_pd(inv_a), _mm256_set1_pd(inv_b));
    let first_col = _mm256_setr_pd(
        f64::from(i0),
        f64::from(i0 + 1),
        f64::from(i0 + 2),
        f64::from(i0 + 3),
    );
    let rows = xs.chunks_exact_mut(w).zip(ys.chunks_exact_mut(w));
    for (j, (xs, ys)) in (j0..).zip(rows) {
        // Lane `l` of cell `k = k0 + l` hashes `key + (2k + 1) G` and
        // `key + (2k + 2) G`: from the row's first cell's, steps of `2G`
        // per lane and `8G` per four cells (wrapping, as the scalar
        // products).
        let k0 = u64::from(j * a + i0);
        let first = key.wrapping_add((2 * k0 + 1).wrapping_mul(GOLDEN));
        let mut h1 = _mm256_setr_epi64x(
            first as i64,
            first.wrapping_add(g2) as i64,
            first.wrapping_add(g2.wrapping_mul(2)) as i64,
            first.wrapping_add(g2.wrapping_mul(3)) as i64,
        );
        let row = _mm256_set1_pd(f64::from(j));
        let mut col = first_col;
        for (xs, ys) in xs.chunks_exact_mut(4).zip(ys.chunks_exact_mut(4)) {
            let xi = to_unit(mix(h1));
            let xi2 = to_unit(mix(_mm256_add_epi64(h1, g)));
            let s = _mm256_mul_pd(_mm256_add_pd(col, xi), inv_a);
            let t = _mm256_mul_pd(_mm256_add_pd(row, xi2), inv_b);
            let x = _mm256_cvtpd_ps(_mm256_sub_pd(_mm256_mul_pd(two, s), one));
            let y = _mm256_cvtpd_ps(_mm256_sub_pd(one, _mm256_mul_pd(two, t)));
            // SAFETY: `xs` and `ys` are chunks of exactly four `f32` (16
            // bytes), what an unaligned 128-bit store writes.
            unsafe {
                _mm_storeu_ps(xs.as_mut_ptr(), x);
                _mm_storeu_ps(ys.as_mut_ptr(), y);
            }
            h1 = _mm256_add_epi64(h1, g8);
            col = _mm256_add_pd(col, four);
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
