//! A rect light's stratified samples, four cells of a row at a time.
//!
//! [`LightSampler::samples_with`](crate::sampling::LightSampler::samples_with) maps sample `k = j a + i` of the
//! jittered `a × b` grid, `s = (i + ξ) / a`, `t = (j + ξ') / b` with
//! `(ξ, ξ')` = [`uniform_pair`](crate::sampling::uniform_pair)`(key, k)`, to the point `center + u
//! (2 s − 1) + v (1 − 2 t)` in f64, rounded to f32, and `(s, t)` rounded
//! to f32. The traced path ([`super::rays`]) draws these for every
//! receiver the light's hull does not settle (about 65 instructions a sample one at a time,
//! callgrind, the 278k bunny at 512², 64 samples). With AVX2 this makes
//! four at a time: SplitMix64 on 64-bit lanes, the 32-bit integers to f64
//! exactly, then the scalar code's f64 operations in its order, each the
//! same IEEE operation, so the same bits (`tests` holds the two equal).
//! Only grids whose sides are powers of two, rows a multiple of four
//! wide, take this path (the scalar walk multiplies by the exact inverse
//! there).

use crate::sampling::Strata;
use crate::shade::LightSample;
use glam::{DVec3, Vec2, Vec3};

/// The `n` samples of the jittered grid `strata` under the pixel's `key`
/// on the rect `center ± u ± v` of inverse pdf `area`, in sample order
/// into `out` (cleared first), when this kernel can make them: the grid
/// is one the chart points' walk takes
/// ([`super::chart_lanes::chart_rows_apply`]) and the CPU has AVX2 (and
/// `PENUMBRA_SIMD` does not force the baseline). `false`, with `out`
/// untouched, otherwise: the caller's scalar sampler makes them then.
pub(super) fn rect_rows(
    strata: Strata,
    key: u64,
    n: u32,
    (center, u, v, area): (DVec3, DVec3, DVec3, f32),
    out: &mut Vec<LightSample>,
) -> bool {
    if !super::chart_lanes::chart_rows_apply(strata, n) {
        return false;
    }
    #[cfg(target_arch = "x86_64")]
    if crate::simd::level::runs_v3() {
        out.clear();
        out.resize(n as usize, LightSample::default());
        // SAFETY: `runs_v3` checked that the CPU has x86-64-v3's
        // features, AVX and AVX2 among them: the kernel's one requirement.
        unsafe { rect_rows_avx2(strata, key, (center, u, v, area), out) };
        return true;
    }
    let _ = (key, center, u, v, area, out);
    false
}

/// [`rect_rows`] with AVX2, four cells per step (`(s, t)` by
/// [`super::chart_lanes::jittered_rows_avx2`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
fn rect_rows_avx2(
    strata: Strata,
    key: u64,
    (center, u, v, area): (DVec3, DVec3, DVec3, f32),
    out: &mut [LightSample],
) {
    use crate::simd::avx::F64x4;
    let (two, one) = (F64x4::splat(2.0), F64x4::splat(1.0));
    let splat3 = |p: DVec3| [F64x4::splat(p.x), F64x4::splat(p.y), F64x4::splat(p.z)];
    let (c, u, v) = (splat3(center), splat3(u), splat3(v));
    let (a, b) = (strata.a, strata.b);
    let inv = (1.0 / f64::from(a), 1.0 / f64::from(b));
    let cells = (0, 0, a as usize);
    super::chart_lanes::jittered_rows_avx2(key, a, cells, inv, b as usize, |at, s, t| {
        let (ks, kt) = (two.mul(s).sub(one), one.sub(two.mul(t)));
        // `center + u · ks + v · kt` per axis, in that order.
        let axis = |k: usize| c[k].add(u[k].mul(ks)).add(v[k].mul(kt)).to_f32_array();
        let (x, y, z) = (axis(0), axis(1), axis(2));
        let (s, t) = (s.to_f32_array(), t.to_f32_array());
        if let Some(cells) = out.get_mut(at..at + 4) {
            for (l, cell) in cells.iter_mut().enumerate() {
                *cell = LightSample {
                    x: Vec3::new(x[l], y[l], z[l]),
                    st: Vec2::new(s[l], t[l]),
                    inv_pdf_area: area,
                };
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{LightSampler, PatternSampler, SamplePattern};
    use crate::scene::{Light, LightShape};

    /// The kernel gives `LightSampler::samples_with`'s samples bit for bit
    /// (points, chart coordinates, inverse pdf), for the grids it takes
    /// (4 × 4, 4 × 8, 8 × 8, 16 × 16), the stratified and correlated
    /// patterns, many pixels and a tilted light far from the origin.
    #[test]
    fn rows_are_the_sampler_samples() {
        let light = Light {
            shape: LightShape::Rect {
                center: glam::Vec3::new(130.5, 4.25, -77.0),
                u: glam::Vec3::new(0.61, 0.02, 0.13),
                v: glam::Vec3::new(-0.05, 0.1, 0.47),
                two_sided: false,
            },
            radiance: glam::Vec3::ONE,
            texture: None,
        };
        let sampler = LightSampler::new(&light);
        let LightSampler::Rect { center, u, v, area } = sampler else {
            panic!("a rect light");
        };
        let mut checked = 0;
        for pattern in [SamplePattern::Stratified, SamplePattern::Correlated] {
            for n in [16u32, 32, 64, 256] {
                let patterns = PatternSampler::new(pattern, n, 7, 0);
                for pixel in [(0, 0), (3, 5), (511, 2), (1000, 777)] {
                    let Some((strata, key)) = patterns.jittered(pixel) else {
                        panic!("a jittered pattern");
                    };
                    assert!(
                        super::super::chart_lanes::chart_rows_apply(strata, n),
                        "{n}"
                    );
                    let mut want = Vec::new();
                    sampler.samples_with(&patterns, glam::Vec3::ZERO, pixel, &mut want);
                    let mut got = Vec::new();
                    if !rect_rows(strata, key, n, (center, u, v, area), &mut got) {
                        eprintln!("no AVX2 on this CPU: nothing to check");
                        return;
                    }
                    let bits = |s: &[LightSample]| -> Vec<[u32; 6]> {
                        s.iter()
                            .map(|s| {
                                let [x, y, z] = s.x.to_array().map(f32::to_bits);
                                let [a, b] = s.st.to_array().map(f32::to_bits);
                                [x, y, z, a, b, s.inv_pdf_area.to_bits()]
                            })
                            .collect()
                    };
                    assert_eq!(bits(&got), bits(&want), "{pattern:?} {n} {pixel:?}");
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 32);
    }
}
