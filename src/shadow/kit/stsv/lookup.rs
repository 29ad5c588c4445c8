//! Per-light-sample texture access (thesis §5.1.4, eqs. 5.7–5.10): the
//! light samples are projected from the receiver onto the S-triangle with
//! one matrix per (receiver, S-triangle), `J = W·M'`, into homogeneous
//! barycentrics.
//!
//! With `o` the shadow-ray origin, `n` the triangle's (unnormalised)
//! normal, `v0` its first corner, `dual1`, `dual2` its barycentric duals
//! ([`crate::geom::TriangleFrame`]), `e = n·(v0 − o)`, `σ = sign(e)` and
//! `βi = (o − v0)·dual_i` (the barycentrics of `o`'s foot on the plane),
//! a sample `s` with `d = s − o` maps to
//!
//! ```text
//! X = σ (e dual1 + β1 n) · d      (= b1 Z)
//! Y = σ (e dual2 + β2 n) · d      (= b2 Z)
//! Z = σ n · d                     (= |e| / λ, λ the crossing's segment parameter)
//! ```
//!
//! so the segment `o → s` crosses the triangle at barycentrics
//! `(X/Z, Y/Z)` exactly when `X ≥ 0, Y ≥ 0, Z − X − Y ≥ 0` (edges
//! included, as the reference's watertight test) and `Z > |e| / t_max`
//! (the crossing lies before the reference's shortened segment end
//! `t_max = 1 − END_SHORTEN`; the thesis leaves this test out because its
//! light is on one side of the triangle). This is the thesis's
//! `s*_h = J s` up to a positive factor `|e|` that keeps every entry
//! finite however close `o` is to the plane (the thesis divides by the
//! distance `e`). `J` is built in f64 per receiver, scaled to unit
//! largest entry and rounded to f32; per sample it costs 3 subtractions,
//! 9 multiplications, 8 additions/subtractions, 4 compares, and 2
//! divisions for the samples that hit, eight samples at a time with
//! `wide` (exact IEEE operations, no fused multiply-add: every SIMD level
//! gives the same bits, and [`SampleProjector::for_each_hit_scalar`]
//! gives them one sample at a time).

use super::STriangle;
use crate::scene::{Texture, TextureData};
use crate::shade::LightSample;
use crate::shadow::kit::rays::END_SHORTEN;
use crate::simd::f32x8;
use glam::{Vec2, Vec3};

/// Samples per SIMD step.
const LANES: usize = 8;

/// Light sample positions as structure of arrays, padded to a multiple
/// of eight: laid out once per receiver, tested against each of its
/// S-triangles.
#[derive(Debug, Clone, Default)]
pub struct SamplePositions {
    xs: Vec<f32>,
    ys: Vec<f32>,
    zs: Vec<f32>,
    n: usize,
}

impl SamplePositions {
    /// Replaces the positions with those of `samples`.
    pub fn set(&mut self, samples: &[LightSample]) {
        self.n = samples.len();
        let padded = self.n.div_ceil(LANES) * LANES;
        for v in [&mut self.xs, &mut self.ys, &mut self.zs] {
            v.clear();
            v.resize(padded, 0.0);
        }
        for (k, s) in samples.iter().enumerate() {
            (self.xs[k], self.ys[k], self.zs[k]) = (s.x.x, s.x.y, s.x.z);
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }
}

/// `J` for one receiver and one S-triangle, in f32.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleProjector {
    origin: Vec3,
    /// Rows giving `X`, `Y`, `Z` from `s − o`.
    rows: [[f32; 3]; 3],
    /// `|e| / t_max`, scaled with the rows.
    threshold: f32,
}

impl SampleProjector {
    /// `J` for shadow-ray origin `origin` and `tri`; `None` when the origin
    /// lies in the triangle's plane (no segment from it crosses the
    /// triangle at a positive parameter, as for the reference's rays), the
    /// triangle has no area, or anything is not finite.
    pub fn new(tri: &STriangle, origin: Vec3) -> Option<SampleProjector> {
        let f = &tri.frame;
        let o = origin.as_dvec3();
        let e = f.normal.dot(f.a - o);
        if !(e != 0.0 && e.is_finite()) || f.normal.length_squared() == 0.0 {
            return None;
        }
        let sigma = e.signum();
        let (b1, b2) = ((o - f.a).dot(f.dual1), (o - f.a).dot(f.dual2));
        let r1 = (f.dual1 * e + f.normal * b1) * sigma;
        let r2 = (f.dual2 * e + f.normal * b2) * sigma;
        let rz = f.normal * sigma;
        let t_max = f64::from((1.0 - END_SHORTEN) as f32);
        let threshold = e.abs() / t_max;
        // Homogeneous: any positive factor leaves every test and ratio
        // unchanged; unit largest entry keeps f32 away from overflow.
        let scale = [r1, r2, rz]
            .iter()
            .map(|r| r.abs().max_element())
            .fold(threshold, f64::max);
        if !(scale > 0.0 && scale.is_finite()) {
            return None;
        }
        let row = |r: glam::DVec3| (r / scale).as_vec3().to_array();
        let p = SampleProjector {
            origin,
            rows: [row(r1), row(r2), row(rz)],
            threshold: (threshold / scale) as f32,
        };
        let finite = p.rows.iter().flatten().all(|x| x.is_finite()) && p.threshold.is_finite();
        finite.then_some(p)
    }

    /// Calls `hit(k, b1, b2)`, in sample order, for every sample `k` whose
    /// segment from the origin crosses the triangle, with the crossing's
    /// barycentrics (weights of the second and third corner). Eight
    /// samples at a time; for many S-triangles seen from one receiver,
    /// [`SampleProjector::for_each_hit_in`] with the positions laid out
    /// once is faster.
    pub fn for_each_hit(&self, samples: &[LightSample], hit: impl FnMut(usize, f32, f32)) {
        let mut positions = SamplePositions::default();
        positions.set(samples);
        self.for_each_hit_in(&positions, hit);
    }

    /// [`SampleProjector::for_each_hit`] on sample positions laid out by
    /// [`SamplePositions::set`].
    pub fn for_each_hit_in(
        &self,
        positions: &SamplePositions,
        mut hit: impl FnMut(usize, f32, f32),
    ) {
        let [r1, r2, rz] = self.rows.map(|r| r.map(f32x8::splat));
        let o = self.origin;
        let (ox, oy, oz) = (f32x8::splat(o.x), f32x8::splat(o.y), f32x8::splat(o.z));
        let threshold = f32x8::splat(self.threshold);
        let zero = f32x8::ZERO;
        let p = positions;
        let chunks =
            p.xs.chunks_exact(LANES)
                .zip(p.ys.chunks_exact(LANES))
                .zip(p.zs.chunks_exact(LANES));
        for (chunk, ((xs, ys), zs)) in chunks.enumerate() {
            let load = |v: &[f32]| f32x8::from(<[f32; LANES]>::try_from(v).unwrap_or([0.0; LANES]));
            let dx = load(xs) - ox;
            let dy = load(ys) - oy;
            let dz = load(zs) - oz;
            let x = r1[0] * dx + r1[1] * dy + r1[2] * dz;
            let y = r2[0] * dx + r2[1] * dy + r2[2] * dz;
            let z = rz[0] * dx + rz[1] * dy + rz[2] * dz;
            let w = z - x - y;
            let inside = x.cmp_ge(zero) & y.cmp_ge(zero) & w.cmp_ge(zero) & z.cmp_gt(threshold);
            // Padding lanes past the last sample never count.
            let valid = p.n.saturating_sub(chunk * LANES).min(LANES);
            let mut mask = inside.move_mask() & ((1u32 << valid) - 1);
            if mask == 0 {
                continue;
            }
            // Z > threshold ≥ 0 on every hit lane; elsewhere divide by 1.
            let z = inside.blend(z, f32x8::ONE);
            let (b1, b2) = ((x / z).to_array(), (y / z).to_array());
            while mask != 0 {
                let k = mask.trailing_zeros() as usize;
                hit(chunk * LANES + k, b1[k], b2[k]);
                mask &= mask - 1;
            }
        }
    }

    /// [`SampleProjector::for_each_hit`] one sample at a time, with the
    /// same operations in the same order (the same bits).
    pub fn for_each_hit_scalar(
        &self,
        samples: &[LightSample],
        mut hit: impl FnMut(usize, f32, f32),
    ) {
        let [r1, r2, rz] = self.rows;
        let o = self.origin;
        for (k, s) in samples.iter().enumerate() {
            let (dx, dy, dz) = (s.x.x - o.x, s.x.y - o.y, s.x.z - o.z);
            let x = r1[0] * dx + r1[1] * dy + r1[2] * dz;
            let y = r2[0] * dx + r2[1] * dy + r2[2] * dz;
            let z = rz[0] * dx + rz[1] * dy + rz[2] * dz;
            let w = z - x - y;
            if x >= 0.0 && y >= 0.0 && w >= 0.0 && z > self.threshold {
                hit(k, x / z, y / z);
            }
        }
    }
}

/// Rec. 709 luminance, as [`Texture::lookup_scalar`] reads RGB textures.
const LUMA: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// Scalar texel `(col, row)` (row 0 at the top); 0 if out of range.
fn texel(t: &Texture, col: usize, row: usize) -> f32 {
    let i = row * t.width as usize + col;
    match &t.data {
        TextureData::Scalar(d) => d.get(i).copied().unwrap_or(0.0),
        TextureData::Rgb(d) => d.get(i).map_or(0.0, |c| Vec3::from_array(LUMA).dot(*c)),
    }
}

/// Bilinear scalar look-up with the contract's convention: texel
/// `(col, row)` covers `u ∈ [col/W, (col+1)/W)` and `1 − v ∈ [row/H,
/// (row+1)/H)`, so texel centres are at `u W − ½`, `(1 − v) H − ½`
/// (where this equals [`Texture::lookup_scalar`]); the four nearest
/// centres are weighted by distance, repeating outside `[0, 1]`. Computed
/// in f64; NaN or infinite uv give texel 0 (as the nearest look-up). An
/// RGB texture gives its luminance.
pub fn bilinear_scalar(t: &Texture, uv: Vec2) -> f32 {
    if t.width == 0 || t.height == 0 {
        return 0.0;
    }
    let (w, h) = (f64::from(t.width), f64::from(t.height));
    let x = f64::from(uv.x) * w - 0.5;
    let y = (1.0 - f64::from(uv.y)) * h - 0.5;
    if !(x.is_finite() && y.is_finite()) {
        return texel(t, 0, 0);
    }
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let wrap = |i: f64, n: f64| (i.rem_euclid(n) as usize).min(n as usize - 1);
    let (c0, c1) = (wrap(x0, w), wrap(x0 + 1.0, w));
    let (r0, r1) = (wrap(y0, h), wrap(y0 + 1.0, h));
    let v = |c: usize, r: usize| f64::from(texel(t, c, r));
    let top = v(c0, r0) * (1.0 - fx) + v(c1, r0) * fx;
    let bottom = v(c0, r1) * (1.0 - fx) + v(c1, r1) * fx;
    (top * (1.0 - fy) + bottom * fy) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    use crate::shadow::kit::stsv::test_triangle as tri;

    fn sample(x: Vec3) -> LightSample {
        LightSample {
            x,
            st: Vec2::ZERO,
            inv_pdf_area: 1.0,
        }
    }

    fn samples(n: usize, seed: u64) -> Vec<LightSample> {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) as f32 * 4.0 - 2.0
        };
        (0..n)
            .map(|_| sample(Vec3::new(next(), 2.0 + next() * 0.2, next())))
            .collect()
    }

    #[test]
    fn simd_matches_scalar() {
        let t = tri([
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(1.5, 1.1, -0.7),
            DVec3::new(-0.2, 0.9, 1.3),
        ]);
        let s = samples(203, 7);
        for origin in [
            Vec3::new(0.1, 0.0, 0.2),
            Vec3::new(0.3, 0.0, -0.1),
            Vec3::new(-2.0, -1.0, 0.5),
        ] {
            let p = SampleProjector::new(&t, origin).unwrap();
            let (mut a, mut b) = (Vec::new(), Vec::new());
            p.for_each_hit(&s, |k, b1, b2| a.push((k, b1.to_bits(), b2.to_bits())));
            p.for_each_hit_scalar(&s, |k, b1, b2| b.push((k, b1.to_bits(), b2.to_bits())));
            assert_eq!(a, b);
            assert!(!a.is_empty() && a.len() < s.len(), "{}", a.len());
        }
    }

    #[test]
    fn barycentrics_match_f64_crossing() {
        let corners = [
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(1.5, 1.1, -0.7),
            DVec3::new(-0.2, 0.9, 1.3),
        ];
        let t = tri(corners);
        let origin = Vec3::new(0.1, 0.0, 0.2);
        let s = samples(500, 3);
        let p = SampleProjector::new(&t, origin).unwrap();
        let mut hits = vec![None; s.len()];
        p.for_each_hit(&s, |k, b1, b2| hits[k] = Some((b1, b2)));
        let f = t.frame;
        for (k, smp) in s.iter().enumerate() {
            let o = origin.as_dvec3();
            let dir = smp.x.as_dvec3() - o;
            let exact = f
                .hit(o, dir)
                .filter(|&(l, b1, b2)| l < 1.0 && b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0);
            match (exact, hits[k]) {
                (Some((_, e1, e2)), Some((b1, b2))) => {
                    assert!((e1 - f64::from(b1)).abs() < 1e-5, "{e1} {b1}");
                    assert!((e2 - f64::from(b2)).abs() < 1e-5, "{e2} {b2}");
                }
                (None, None) => {}
                (e, h) => {
                    // Only within rounding of an edge.
                    let (_, b1, b2) = f.hit(o, dir).unwrap();
                    let m = b1.min(b2).min(1.0 - b1 - b2).abs();
                    assert!(m < 1e-5, "{e:?} {h:?} {m}");
                }
            }
        }
    }

    #[test]
    fn origin_in_plane_or_degenerate_gives_none() {
        let t = tri([DVec3::ZERO, DVec3::X, DVec3::Z]);
        assert!(SampleProjector::new(&t, Vec3::new(0.2, 0.0, 0.2)).is_none());
        let flat = tri([DVec3::ZERO, DVec3::X, DVec3::X * 2.0]);
        assert!(SampleProjector::new(&flat, Vec3::Y).is_none());
        assert!(SampleProjector::new(&t, Vec3::new(f32::NAN, 1.0, 0.0)).is_none());
    }

    #[test]
    fn samples_on_the_origins_side_never_hit() {
        // Light straddling the plane y = 0: only samples below it can hit.
        let t = tri([
            DVec3::new(-1.0, 0.0, -1.0),
            DVec3::new(1.0, 0.0, -1.0),
            DVec3::new(0.0, 0.0, 1.0),
        ]);
        let origin = Vec3::new(0.0, 1.0, 0.0);
        let s: Vec<LightSample> = (0..64)
            .map(|k| sample(Vec3::new(0.01 * k as f32, 0.5 - 0.02 * k as f32, 0.0)))
            .collect();
        let p = SampleProjector::new(&t, origin).unwrap();
        let mut hits = 0;
        p.for_each_hit(&s, |k, _, _| {
            assert!(s[k].x.y < 0.0, "{k}");
            hits += 1;
        });
        assert!(hits > 10, "{hits}");
    }

    fn texture(w: u32, h: u32, d: Vec<f32>) -> Texture {
        Texture {
            path: "t.png".into(),
            width: w,
            height: h,
            data: TextureData::Scalar(d),
        }
    }

    #[test]
    fn bilinear_at_centres_is_nearest_and_interpolates_between() {
        let t = texture(4, 2, vec![0.0, 1.0, 0.5, 0.25, 1.0, 0.0, 0.75, 0.125]);
        for row in 0..2 {
            for col in 0..4 {
                let uv = Vec2::new((col as f32 + 0.5) / 4.0, 1.0 - (row as f32 + 0.5) / 2.0);
                assert_eq!(bilinear_scalar(&t, uv), t.lookup_scalar(uv), "{col} {row}");
            }
        }
        // Half-way between texel centres (0,0) and (1,0).
        let mid = bilinear_scalar(&t, Vec2::new(0.25, 0.75));
        assert!((mid - 0.5).abs() < 1e-6, "{mid}");
        // Wrapping: between the last and the first column.
        let wrap = bilinear_scalar(&t, Vec2::new(1.0, 0.75));
        assert!((wrap - 0.125).abs() < 1e-6, "{wrap}");
        assert_eq!(bilinear_scalar(&t, Vec2::new(f32::NAN, 0.0)), 0.0);
        assert!(bilinear_scalar(&t, Vec2::new(1e30, -1e30)).is_finite());
    }
}
