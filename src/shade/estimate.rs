//! The Monte-Carlo estimator behind
//! [`direct_from_samples`](super::direct_from_samples), four samples at a
//! time.
//!
//! Per sample the geometry term `cos_p cos_x / r²` is the costliest part
//! of the reference's per-sample work after the shadow ray itself. For a
//! rect light it is computed as `(n·d)(−m·d) / (r²)²` with `d = x − p`
//! (`m` the light's normal): one division, where the unit direction
//! `w = d/|d|` took a square root and four (on bunny.toml at 1024², 64
//! samples, that scalar loop was 15 % of the light pass's instructions).
//! Sphere lights keep the unit direction, as `inv_pdf_area` does (see the
//! sampling module: the product of the two is `Ω` to one rounding even at
//! the cone's edge). The lane version computes the term for four samples
//! with visibility > 0 at once on the facade's `f64x4`, every lane the
//! scalar twin's own IEEE operations in the same order, then adds the
//! samples' contributions to the sum one by one in sample order, so the
//! two give the same bits (the tests hold them equal in `f64`). The lane
//! body is compiled at both `simd::level` levels.

use super::brdf::{to_vec3, Lobe};
use super::{texel_at, LightSample, SurfacePoint};
use crate::scene::{Light, LightShape, Texture};
use crate::simd::f64x4;
use crate::simd::level::{level, Level};
use glam::{DVec3, Vec3};

/// Samples per lane group.
const LANES: usize = 4;

/// Per-shape emitter normal at `x`.
#[derive(Clone, Copy)]
enum Emitter {
    /// A rect's fixed normal; `two_sided` emits from both faces.
    Rect { normal: DVec3, two_sided: bool },
    /// A sphere: normal `(x − center) / R`.
    Sphere { center: DVec3, inv_radius: f64 },
}

/// The per-receiver constants of the estimate; `None` when the receiver
/// is inside or on a sphere light (no defined value: the estimate is 0).
fn emitter(light: &Light, p: DVec3) -> Option<Emitter> {
    match light.shape {
        LightShape::Rect {
            u, v, two_sided, ..
        } => Some(Emitter::Rect {
            normal: u.as_dvec3().cross(v.as_dvec3()).normalize_or_zero(),
            two_sided,
        }),
        LightShape::Sphere { center, radius } => {
            let c = center.as_dvec3();
            (c.distance(p) > f64::from(radius)).then(|| Emitter::Sphere {
                center: c,
                inv_radius: 1.0 / f64::from(radius),
            })
        }
    }
}

/// The per-receiver constants both versions of the estimate start from.
struct Receiver {
    lobe: Lobe,
    p: DVec3,
    radiance: DVec3,
    emitter: Emitter,
}

/// `None` when the estimate is 0 before any sample: no samples, or a
/// receiver inside or on a sphere light.
#[inline(always)]
fn receiver(light: &Light, sp: &SurfacePoint, samples: &[LightSample]) -> Option<Receiver> {
    if samples.is_empty() {
        return None;
    }
    let p = sp.p.as_dvec3();
    Some(Receiver {
        lobe: Lobe::new(sp),
        p,
        radiance: light.radiance.as_dvec3(),
        emitter: emitter(light, p)?,
    })
}

/// `(1/N) Σ Le f_r cos_p cos_x / r² · inv_pdf_area · visibility` over the
/// samples (see [`direct_from_samples`](super::direct_from_samples)), at
/// the run-time SIMD level.
///
/// # Panics
///
/// If `visibility.len() != samples.len()`.
pub(super) fn estimate(
    light: &Light,
    texture: Option<&Texture>,
    sp: &SurfacePoint,
    samples: &[LightSample],
    visibility: &[f32],
) -> Vec3 {
    estimate_at(level(), light, texture, sp, samples, visibility)
}

/// [`estimate`] compiled for `level` (the baseline copy where this CPU
/// lacks it): the same bits at every level.
pub(super) fn estimate_at(
    level: Level,
    light: &Light,
    texture: Option<&Texture>,
    sp: &SurfacePoint,
    samples: &[LightSample],
    visibility: &[f32],
) -> Vec3 {
    to_vec3(mean_at(level, light, texture, sp, samples, visibility))
}

/// The estimate in `f64`, before its conversion to `f32` (which would
/// hide most differences from the tests).
fn mean_at(
    level: Level,
    light: &Light,
    texture: Option<&Texture>,
    sp: &SurfacePoint,
    samples: &[LightSample],
    visibility: &[f32],
) -> DVec3 {
    assert_eq!(
        samples.len(),
        visibility.len(),
        "direct_from_samples: one visibility per sample"
    );
    #[cfg(target_arch = "x86_64")]
    if level == Level::V3 && level.supported() {
        // SAFETY: the CPU has every feature the v3 copy enables
        // (`Level::supported`), its one requirement.
        return unsafe { mean_v3(light, texture, sp, samples, visibility) };
    }
    let _ = level;
    mean_lanes(light, texture, sp, samples, visibility)
}

/// [`mean_lanes`] compiled for `Level::V3`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,bmi1,bmi2,lzcnt,popcnt")]
fn mean_v3(
    light: &Light,
    texture: Option<&Texture>,
    sp: &SurfacePoint,
    samples: &[LightSample],
    visibility: &[f32],
) -> DVec3 {
    mean_lanes(light, texture, sp, samples, visibility)
}

/// The estimate four samples at a time, inlined into each level's copy.
#[inline(always)]
fn mean_lanes(
    light: &Light,
    texture: Option<&Texture>,
    sp: &SurfacePoint,
    samples: &[LightSample],
    visibility: &[f32],
) -> DVec3 {
    let Some(Receiver {
        lobe,
        p,
        radiance,
        emitter,
    }) = receiver(light, sp, samples)
    else {
        return DVec3::ZERO;
    };
    // `Le f_r` when it depends on no sample (no texture, no lobe): the
    // scalar loop's `le * lobe.eval(w)` with `le = radiance`, and `eval`
    // without a lobe ignores `w`.
    let constant = (texture.is_none() && !lobe.has_spec).then(|| radiance * lobe.eval(DVec3::ZERO));
    let splat3 = |v: DVec3| [f64x4::splat(v.x), f64x4::splat(v.y), f64x4::splat(v.z)];
    let [px, py, pz] = splat3(p);
    let [nx, ny, nz] = splat3(lobe.n);
    let zero = f64x4::ZERO;
    let mut sum = DVec3::ZERO;
    // The lanes take the samples with visibility > 0 only, in sample
    // order (the scalar loop skips the others before any arithmetic, and
    // occluded samples come in runs): an umbra costs no division.
    let mut next = 0;
    loop {
        let mut group = [0usize; LANES];
        let mut count = 0;
        while count < LANES && next < visibility.len() {
            // Without a branch: in a penumbra lit and blocked samples
            // alternate.
            group[count] = next;
            count += usize::from(visibility[next] > 0.0);
            next += 1;
        }
        if count == 0 {
            break;
        }
        // Lanes past `count` are zeros, masked off below.
        let mut xs = [[0.0f64; LANES]; 3];
        let mut inv_pdf = [0.0f64; LANES];
        let mut v = [0.0f64; LANES];
        for (i, &k) in group[..count].iter().enumerate() {
            let s = &samples[k];
            xs[0][i] = f64::from(s.x.x);
            xs[1][i] = f64::from(s.x.y);
            xs[2][i] = f64::from(s.x.z);
            inv_pdf[i] = f64::from(s.inv_pdf_area);
            v[i] = f64::from(visibility[k]);
        }
        let [sx, sy, sz] = xs.map(f64x4::new);
        let v = f64x4::new(v);
        // `d = x − p`, `r2 = d·d` (glam's dot: `(x x' + y y') + z z'`).
        let (dx, dy, dz) = (sx - px, sy - py, sz - pz);
        let r2 = dx * dx + dy * dy + dz * dz;
        let unit = || {
            let len = r2.sqrt();
            (dx / len, dy / len, dz / len)
        };
        // The geometry term `cos_p cos_x / r²`, whether `cos_p` and `cos_x`
        // are non-zero, and the unit direction where it was needed.
        // `zero − a` is `−a` for every `a ≠ +0`; where `a = +0` the lane is
        // skipped either way.
        let (geometry, lit_geometry, w) = match emitter {
            Emitter::Rect { normal, two_sided } => {
                // `(n·d)(−m·d) / r2²`: the cosines' `1/|d|` folded into the
                // one division (no square root, one division instead of
                // five per sample).
                let [mx, my, mz] = splat3(normal);
                let nd = nx * dx + ny * dy + nz * dz;
                let md = mx * dx + my * dy + mz * dz;
                let c = if two_sided { md.abs() } else { zero - md };
                let lit_x = c.cmp_gt(zero);
                (nd * c / (r2 * r2), nd.cmp_gt(zero) & lit_x, None)
            }
            Emitter::Sphere { center, inv_radius } => {
                // In the unit direction, as `inv_pdf_area` computes `cos_x`
                // (their product is then `Ω` to one rounding even where
                // `cos_x` is tiny, at the cone's edge).
                let (wx, wy, wz) = unit();
                let cos_p = nx * wx + ny * wy + nz * wz;
                let [cx, cy, cz] = splat3(center);
                let dot = (sx - cx) * wx + (sy - cy) * wy + (sz - cz) * wz;
                let c = (zero - dot) * f64x4::splat(inv_radius);
                (
                    cos_p * c / r2,
                    cos_p.cmp_gt(zero) & c.cmp_gt(zero),
                    Some((wx, wy, wz)),
                )
            }
        };
        let g = geometry * f64x4::new(inv_pdf) * v;
        // The skips (visibility NaN or ≤ 0 never entered the lanes): r²
        // NaN or ≤ 0, cos_p or cos_x NaN or 0 (or, one-sided, negative),
        // and the lanes past `count`.
        let lit = r2.cmp_gt(zero) & lit_geometry;
        let mut mask = lit.move_mask() & ((1 << count) - 1);
        if mask == 0 {
            continue;
        }
        let g = g.to_array();
        match constant {
            Some(k) => {
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    sum += k * g[i];
                }
            }
            None => {
                // The lobe needs the unit direction; without one `eval`
                // ignores it.
                let (wx, wy, wz) = match w {
                    Some(w) => w,
                    None if lobe.has_spec => unit(),
                    None => (zero, zero, zero),
                };
                let (wx, wy, wz) = (wx.to_array(), wy.to_array(), wz.to_array());
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let le = match texture {
                        Some(t) => radiance * texel_at(t, samples[group[i]].st),
                        None => radiance,
                    };
                    sum += le * lobe.eval(DVec3::new(wx[i], wy[i], wz[i])) * g[i];
                }
            }
        }
    }
    sum / samples.len() as f64
}

/// The scalar twin of [`mean_lanes`]: one sample at a time, the
/// definition the lane version is held to.
#[cfg(test)]
fn mean_scalar(
    light: &Light,
    texture: Option<&Texture>,
    sp: &SurfacePoint,
    samples: &[LightSample],
    visibility: &[f32],
) -> DVec3 {
    assert_eq!(samples.len(), visibility.len());
    let Some(Receiver {
        lobe,
        p,
        radiance,
        emitter,
    }) = receiver(light, sp, samples)
    else {
        return DVec3::ZERO;
    };
    let mut sum = DVec3::ZERO;
    for (s, &vis) in samples.iter().zip(visibility) {
        if vis.is_nan() || vis <= 0.0 {
            continue;
        }
        let d = s.x.as_dvec3() - p;
        let r2 = d.length_squared();
        if r2.is_nan() || r2 <= 0.0 {
            continue;
        }
        let w = d / r2.sqrt();
        let geometry = match emitter {
            Emitter::Rect { normal, two_sided } => {
                let nd = lobe.n.dot(d);
                let md = normal.dot(d);
                let c = if two_sided { md.abs() } else { -md };
                if !(nd > 0.0) || !(c > 0.0) {
                    continue;
                }
                nd * c / (r2 * r2)
            }
            Emitter::Sphere { center, inv_radius } => {
                let cos_p = lobe.n.dot(w);
                let cos_x = -(s.x.as_dvec3() - center).dot(w) * inv_radius;
                if !(cos_p > 0.0) || !(cos_x > 0.0) {
                    continue;
                }
                cos_p * cos_x / r2
            }
        };
        let le = match texture {
            Some(t) => radiance * texel_at(t, s.st),
            None => radiance,
        };
        let g = geometry * f64::from(s.inv_pdf_area) * f64::from(vis);
        sum += le * lobe.eval(w) * g;
    }
    sum / samples.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::TextureData;
    use glam::Vec2;

    /// A 64-bit LCG; `unit` in [0, 1).
    struct Lcg(u64);

    impl Lcg {
        fn next(&mut self) -> u64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            self.0 >> 11
        }

        fn unit(&mut self) -> f32 {
            (self.next() >> 29) as f32 / (1u64 << 24) as f32
        }

        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.unit()
        }

        fn vec(&mut self, r: f32) -> Vec3 {
            Vec3::new(self.range(-r, r), self.range(-r, r), self.range(-r, r))
        }
    }

    fn texture() -> Texture {
        let mut rng = Lcg(7);
        Texture {
            path: "t.png".into(),
            width: 5,
            height: 3,
            data: TextureData::Rgb((0..15).map(|_| rng.vec(1.0).abs()).collect()),
        }
    }

    /// Visibilities, including the values the estimate must skip.
    fn visibility(rng: &mut Lcg) -> f32 {
        match rng.next() % 12 {
            0 => 0.0,
            1 => -0.0,
            2 => f32::NAN,
            3 => -0.25,
            4 => f32::MIN_POSITIVE / 8.0,
            5 => 1.0,
            _ => rng.unit(),
        }
    }

    /// A sample point: mostly on the light, sometimes on the receiver
    /// (`r² = 0`), behind it, far away, or on the light's edge plane.
    fn sample_point(rng: &mut Lcg, light: &Light, p: Vec3) -> Vec3 {
        let on_light = match light.shape {
            LightShape::Rect { center, u, v, .. } => {
                center + u * rng.range(-1.0, 1.0) + v * rng.range(-1.0, 1.0)
            }
            LightShape::Sphere { center, radius } => {
                center + rng.vec(1.0).normalize_or(Vec3::X) * radius
            }
        };
        match rng.next() % 16 {
            0 => p,
            1 => p - rng.vec(1.0),
            2 => on_light * 1e18,
            3 => Vec3::new(f32::NAN, 0.0, 1.0),
            _ => on_light,
        }
    }

    #[test]
    fn lane_estimate_is_the_scalar_estimate() {
        let tex = texture();
        let mut rng = Lcg(1);
        let levels: Vec<Level> = [Level::Baseline, Level::V3]
            .into_iter()
            .filter(|l| l.supported())
            .collect();
        let mut lit = 0;
        for case in 0..4000 {
            let shape = match case % 4 {
                0 | 1 => LightShape::Rect {
                    center: rng.vec(3.0) + Vec3::Y * 4.0,
                    u: rng.vec(1.0),
                    v: rng.vec(1.0),
                    two_sided: case % 4 == 1,
                },
                2 => LightShape::Rect {
                    // A degenerate light: zero normal.
                    center: Vec3::Y * 3.0,
                    u: Vec3::X,
                    v: Vec3::X * 2.0,
                    two_sided: false,
                },
                _ => LightShape::Sphere {
                    center: rng.vec(3.0) + Vec3::Y * 4.0,
                    radius: rng.range(0.01, 2.0),
                },
            };
            let light = Light {
                shape,
                radiance: rng.vec(5.0).abs(),
                texture: None,
            };
            let spec = case % 3 == 0;
            let sp = SurfacePoint {
                p: rng.vec(2.0),
                n: rng.vec(1.0).normalize_or(Vec3::Y),
                ng: Vec3::Y,
                wo: rng.vec(1.0).normalize_or(Vec3::Y),
                albedo: rng.vec(1.0).abs(),
                specular: if spec { rng.vec(1.0).abs() } else { Vec3::ZERO },
                shininess: rng.range(-2.0, 200.0),
            };
            let n = (rng.next() % 14) as usize;
            let samples: Vec<LightSample> = (0..n)
                .map(|_| LightSample {
                    x: sample_point(&mut rng, &light, sp.p),
                    st: Vec2::new(rng.range(-0.1, 1.1), rng.range(-0.1, 1.1)),
                    inv_pdf_area: rng.range(0.0, 10.0),
                })
                .collect();
            let vis: Vec<f32> = (0..n).map(|_| visibility(&mut rng)).collect();
            let texture =
                (case % 5 == 0 && matches!(light.shape, LightShape::Rect { .. })).then_some(&tex);
            let want = mean_scalar(&light, texture, &sp, &samples, &vis);
            if want != DVec3::ZERO {
                lit += 1;
            }
            for &level in &levels {
                let got = mean_at(level, &light, texture, &sp, &samples, &vis);
                assert_eq!(
                    got.to_array().map(f64::to_bits),
                    want.to_array().map(f64::to_bits),
                    "case {case}, {level:?}: {got} against {want}"
                );
            }
        }
        // The cases must reach the sums, not only the skips.
        assert!(lit > 1000, "{lit}");
    }
}
