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

/// Eight chart points per step for [`estimate_rect_chart`].
pub const CHART_LANES: usize = 8;

/// The per-receiver constants of [`estimate_rect_chart`]: the sample at
/// chart point `(a, b)` is `d = e + a u + b v` from the receiver, in
/// units of the receiver's distance to the light's centre (so that
/// `r²` and its square stay well inside f32's range from a light's
/// surface to far away); `n` the shading normal; `out` turns the sum
/// of `(n·d) V / r⁴` in those units into radiance.
struct ChartShading {
    e: [f32; 3],
    u: [f32; 3],
    v: [f32; 3],
    n: [f32; 3],
    out: DVec3,
}

impl ChartShading {
    /// `None` where the chart-point estimate does not apply: not a rect
    /// light, a specular lobe, or a receiver at the light's centre or
    /// so close to it that the light's extent in its units leaves f32's
    /// comfortable range. `Some(Err(()))`: the estimate is 0 (no
    /// samples, or the receiver behind a one-sided light or in its
    /// plane).
    fn new(light: &Light, sp: &SurfacePoint, n: usize) -> Option<Result<Self, ()>> {
        let LightShape::Rect {
            center,
            u,
            v,
            two_sided,
        } = light.shape
        else {
            return None;
        };
        if n == 0 {
            return Some(Err(()));
        }
        let lobe = Lobe::new(sp);
        if lobe.has_spec {
            return None;
        }
        let (u, v) = (u.as_dvec3(), v.as_dvec3());
        let e = center.as_dvec3() - sp.p.as_dvec3();
        let dist = e.length();
        let scale = 1.0 / dist;
        let reach = (u.length() + v.length()) * scale;
        if !(dist > 0.0 && scale.is_finite() && reach < 1e6) {
            return None;
        }
        // `cos_x r` is the same for every point of the light: `m · d =
        // m · e` (`m ⊥ u, v`).
        let uv = u.cross(v);
        let m = uv.normalize_or_zero();
        let md = m.dot(e);
        let cos_x_r = if two_sided { md.abs() } else { -md };
        if !(cos_x_r > 0.0) {
            return Some(Err(()));
        }
        let area = 4.0 * uv.length();
        let f32s = |w: DVec3| (w * scale).as_vec3().to_array();
        let k = light.radiance.as_dvec3() * lobe.eval(DVec3::ZERO);
        Some(Ok(ChartShading {
            e: f32s(e),
            u: f32s(u),
            v: f32s(v),
            n: lobe.n.as_vec3().to_array(),
            // `Σ nd' / r'⁴` in scaled units is `Σ nd / r⁴ · dist³`.
            out: k * (cos_x_r * scale * scale * scale * area / n as f64),
        }))
    }
}

/// The direct light from an untextured rect light at a receiver without
/// a specular lobe, from its samples' light-chart points `(a, b)` (sample
/// `k` at `center + a_k u + b_k v`; `xs` and `ys` padded with anything to
/// a multiple of [`CHART_LANES`]) and their visibilities: the estimate of
/// [`direct_from_samples`](super::direct_from_samples) over those points,
/// evaluated in f32 lanes, eight samples per step, summed in f64 (lane
/// sums combined in one fixed order, so the same bits at every SIMD
/// level). `None` where it does not apply (see `ChartShading::new`) or
/// the sum is not finite: take the samples' path there.
///
/// Why not the samples' path: exact DCS makes the chart points anyway for
/// its visibility counts, and the f64 estimate over world points cost as
/// much as the counts themselves at 256 samples (its divisions, and a
/// second walk over the pattern's hashes to place the points). Here
/// `cos_x · r` is one constant of the receiver and the rest is a dozen
/// lane operations and one division per eight samples. It agrees with the
/// f64 estimate at the same points to f32's rounding (the tests hold it
/// within 1e-6 of the estimate with every sample facing the receiver),
/// closer than the reference's own f32 world points come.
///
/// # Panics
///
/// If `xs` or `ys` hold fewer than `visibility.len()` rounded up to
/// [`CHART_LANES`].
pub(super) fn estimate_rect_chart(
    light: &Light,
    sp: &SurfacePoint,
    (xs, ys): (&[f32], &[f32]),
    visibility: &[f32],
) -> Option<Vec3> {
    rect_chart_at(level(), light, sp, (xs, ys), visibility)
}

/// [`estimate_rect_chart`] at `level`.
fn rect_chart_at(
    level: Level,
    light: &Light,
    sp: &SurfacePoint,
    (xs, ys): (&[f32], &[f32]),
    visibility: &[f32],
) -> Option<Vec3> {
    let n = visibility.len();
    let padded = n.div_ceil(CHART_LANES) * CHART_LANES;
    assert!(
        xs.len() >= padded && ys.len() >= padded,
        "estimate_rect_chart: chart points padded to whole steps"
    );
    let shading = match ChartShading::new(light, sp, n)? {
        Ok(s) => s,
        Err(()) => return Some(Vec3::ZERO),
    };
    #[cfg(target_arch = "x86_64")]
    let sum = if level == Level::V3 && level.supported() {
        // SAFETY: the CPU has every feature the v3 copy enables
        // (`Level::supported`, AVX among them), its one requirement.
        unsafe { rect_chart_sum_avx(&shading, (xs, ys), visibility) }
    } else {
        rect_chart_sum(&shading, (xs, ys), visibility)
    };
    #[cfg(not(target_arch = "x86_64"))]
    let sum = {
        let _ = level;
        rect_chart_sum(&shading, (xs, ys), visibility)
    };
    let radiance = shading.out * sum;
    radiance.is_finite().then(|| to_vec3(radiance))
}

/// `Σ_k V_k (n·d_k)⁺ / r_k⁴` over the samples in `ChartShading`'s
/// units, on lane type `$f32` (eight `f32`) accumulating in two `$f64`
/// (four `f64`): the one body of both copies.
macro_rules! rect_chart_kernel {
    ($f32:ty, $f64:ty, $splat:path, $load:expr, $zero64:expr, $k:expr, $xs:expr, $ys:expr, $vis:expr) => {{
        let k: &ChartShading = $k;
        let (xs, ys, vis): (&[f32], &[f32], &[f32]) = ($xs, $ys, $vis);
        let load = $load;
        let [ex, ey, ez] = k.e.map(|x| $splat(x));
        let [ux, uy, uz] = k.u.map(|x| $splat(x));
        let [vx, vy, vz] = k.v.map(|x| $splat(x));
        let [nx, ny, nz] = k.n.map(|x| $splat(x));
        let zero: $f32 = $splat(0.0);
        let mut acc: [$f64; 2] = [$zero64, $zero64];
        let n = vis.len();
        let mut start = 0;
        while start < n {
            let end = start + CHART_LANES;
            let mut step = [0.0f32; CHART_LANES];
            let v: $f32 = if end <= n {
                load(&vis[start..end])
            } else {
                // The last step's lanes past `n`: visibility 0, left out.
                step[..n - start].copy_from_slice(&vis[start..]);
                load(&step[..])
            };
            let (a, b): ($f32, $f32) = (load(&xs[start..end]), load(&ys[start..end]));
            let dx = ex.add(ux.mul(a)).add(vx.mul(b));
            let dy = ey.add(uy.mul(a)).add(vy.mul(b));
            let dz = ez.add(uz.mul(a)).add(vz.mul(b));
            let r2 = dx.mul(dx).add(dy.mul(dy)).add(dz.mul(dz));
            let nd = nx.mul(dx).add(ny.mul(dy)).add(nz.mul(dz));
            let w = nd.mul(v).div(r2.mul(r2));
            // Samples below the receiver's horizon, hidden ones (and NaN
            // in either) add nothing; `nd > 0` means `r² > 0`.
            let keep = nd.cmp_gt(zero).bitand(v.cmp_gt(zero));
            let [lo, hi] = keep.blend(w, zero).widen();
            acc = [acc[0].add(lo), acc[1].add(hi)];
            start = end;
        }
        let (lo, hi) = (acc[0].to_array(), acc[1].to_array());
        ((lo[0] + hi[0]) + (lo[1] + hi[1])) + ((lo[2] + hi[2]) + (lo[3] + hi[3]))
    }};
}

/// The kernel on the facade's lanes: the baseline, and the scalar
/// semantics the AVX copy is held to.
fn rect_chart_sum(k: &ChartShading, (xs, ys): (&[f32], &[f32]), vis: &[f32]) -> f64 {
    use crate::simd::f32x8;
    use std::ops::{Add, BitAnd, Div, Mul};
    rect_chart_kernel!(
        f32x8,
        f64x4,
        f32x8::splat,
        |s: &[f32]| f32x8::load(s),
        f64x4::ZERO,
        k,
        xs,
        ys,
        vis
    )
}

/// The kernel on AVX registers.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
fn rect_chart_sum_avx(k: &ChartShading, (xs, ys): (&[f32], &[f32]), vis: &[f32]) -> f64 {
    use crate::simd::avx::{F32x8, F64x4};
    rect_chart_kernel!(
        F32x8,
        F64x4,
        F32x8::splat,
        |s: &[f32]| F32x8::load(s[..CHART_LANES].try_into().expect("eight lanes")),
        F64x4::splat(0.0),
        k,
        xs,
        ys,
        vis
    )
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

    /// The chart-point estimate agrees with the estimate evaluated in f64
    /// throughout at the same chart points within 1e-6 of the estimate
    /// with every sample facing the receiver (f32's rounding, stated; the
    /// samples' path, whose points are rounded to f32 world coordinates,
    /// is up to 1.4e-5 away on these cases, most near the light), gives
    /// the same bits at every SIMD level, and declines what it cannot do
    /// (spheres, specular lobes, a receiver at the light's centre).
    #[test]
    fn chart_estimate_is_the_sample_estimate() {
        let mut rng = Lcg(3);
        let levels: Vec<Level> = [Level::Baseline, Level::V3]
            .into_iter()
            .filter(|l| l.supported())
            .collect();
        let (mut lit, mut worst) = (0, 0.0f64);
        for case in 0..3000 {
            let chart = ChartCase::random(case, &mut rng);
            let frame = SamplerFrame::of(&chart.light);
            let samples = frame.samples(&chart);
            let sampled = mean_scalar(&chart.light, None, &chart.sp, &samples, &chart.vis);
            let want = frame.f64_estimate(&chart);
            let facing = frame.facing_scale(&chart, &samples);
            if want != DVec3::ZERO {
                lit += 1;
            }
            let err = assert_levels_match(case, &levels, &chart, (want, facing, sampled));
            worst = worst.max(err);
        }
        assert!(lit > 1000, "{lit}");
        eprintln!("worst relative difference {worst:e}");
        assert_chart_declines_sphere_and_light_centre();
    }

    /// One case of [`chart_estimate_is_the_sample_estimate`]: a random
    /// rect light, a receiver and its chart points.
    struct ChartCase {
        light: Light,
        sp: SurfacePoint,
        /// The receiver has a specular lobe (the chart must decline).
        spec: bool,
        /// The light is two-sided.
        two_sided: bool,
        /// Chart points in use; the lanes past them are padding.
        n: usize,
        /// Chart coordinates along `u`, padded to whole lanes.
        xs: Vec<f32>,
        /// Along `v`.
        ys: Vec<f32>,
        /// Visibility per chart point.
        vis: Vec<f32>,
    }

    impl ChartCase {
        fn random(case: usize, rng: &mut Lcg) -> ChartCase {
            let center = rng.vec(3.0) + Vec3::Y * 4.0;
            let two_sided = case % 2 == 1;
            let light = Light {
                shape: LightShape::Rect {
                    center,
                    u: rng.vec(1.0),
                    v: rng.vec(1.0),
                    two_sided,
                },
                radiance: rng.vec(5.0).abs(),
                texture: None,
            };
            let spec = case.is_multiple_of(7);
            let p = match case % 13 {
                // Close to the light (and to some of its samples).
                0 => center + rng.vec(0.05),
                _ => rng.vec(2.0),
            };
            let sp = SurfacePoint {
                p,
                n: rng.vec(1.0).normalize_or(Vec3::Y),
                ng: Vec3::Y,
                wo: rng.vec(1.0).normalize_or(Vec3::Y),
                albedo: rng.vec(1.0).abs(),
                specular: if spec { rng.vec(1.0).abs() } else { Vec3::ZERO },
                shininess: 20.0,
            };
            let n = (rng.next() % 40) as usize;
            let padded = n.div_ceil(CHART_LANES) * CHART_LANES;
            let point = |rng: &mut Lcg| -> f32 {
                match rng.next() % 10 {
                    0 => -1.0,
                    1 => 1.0,
                    2 => 0.0,
                    _ => rng.range(-1.0, 1.0),
                }
            };
            // Padding lanes hold garbage, as a reused buffer may.
            let mut xs: Vec<f32> = (0..padded).map(|_| point(rng) * 1e3).collect();
            let mut ys: Vec<f32> = (0..padded).map(|_| f32::NAN).collect();
            for k in 0..n {
                xs[k] = point(rng);
                ys[k] = point(rng);
            }
            let vis: Vec<f32> = (0..n).map(|_| visibility(rng)).collect();
            ChartCase {
                light,
                sp,
                spec,
                two_sided,
                n,
                xs,
                ys,
                vis,
            }
        }
    }

    /// A rect light as the sampler holds it, in f64.
    struct SamplerFrame {
        center: DVec3,
        u: DVec3,
        v: DVec3,
        area: f32,
    }

    impl SamplerFrame {
        fn of(light: &Light) -> SamplerFrame {
            let crate::sampling::LightSampler::Rect { center, u, v, area } =
                crate::sampling::LightSampler::new(light)
            else {
                unreachable!()
            };
            SamplerFrame { center, u, v, area }
        }

        /// Chart point `k` on the light, in f64.
        fn point(&self, chart: &ChartCase, k: usize) -> DVec3 {
            self.center + self.u * f64::from(chart.xs[k]) + self.v * f64::from(chart.ys[k])
        }

        /// The chart points as the samples' path takes them (rounded to f32
        /// world coordinates).
        fn samples(&self, chart: &ChartCase) -> Vec<LightSample> {
            (0..chart.n)
                .map(|k| LightSample {
                    x: self.point(chart, k).as_vec3(),
                    st: Vec2::ZERO,
                    inv_pdf_area: self.area,
                })
                .collect()
        }

        /// The estimate in f64 throughout, at the chart points exactly
        /// (the sampler's points are rounded to f32 world coordinates).
        fn f64_estimate(&self, chart: &ChartCase) -> DVec3 {
            let (u, v, area, n) = (self.u, self.v, self.area, chart.n);
            let p = chart.sp.p.as_dvec3();
            let light_normal = u.cross(v).normalize();
            let lobe = Lobe::new(&chart.sp);
            let radiance_brdf = chart.light.radiance.as_dvec3() * lobe.eval(DVec3::ZERO);
            let mut sum = DVec3::ZERO;
            for k in 0..n {
                let to_point = self.point(chart, k) - p;
                let r2 = to_point.length_squared();
                let light_side = light_normal.dot(to_point);
                let cos_light = if chart.two_sided {
                    light_side.abs()
                } else {
                    -light_side
                };
                let cos_receiver = lobe.n.dot(to_point);
                if chart.vis[k] > 0.0 && cos_receiver > 0.0 && cos_light > 0.0 && r2 > 0.0 {
                    sum += radiance_brdf
                        * (cos_receiver * cos_light / (r2 * r2)
                            * f64::from(area)
                            * f64::from(chart.vis[k]));
                }
            }
            if n == 0 {
                sum
            } else {
                sum / n as f64
            }
        }

        /// The scale of f32's rounding: the estimate if every sample
        /// faced the receiver (`cos_p = 1`), unshadowed. Near the
        /// receiver's horizon `cos_p` is a difference of terms of this
        /// size in both estimates (the f64 one's points are f32 too).
        fn facing_scale(&self, chart: &ChartCase, samples: &[LightSample]) -> f64 {
            let p = chart.sp.p.as_dvec3();
            let light_normal = self.u.cross(self.v).normalize();
            let radiance_albedo = (chart.light.radiance * chart.sp.albedo)
                .as_dvec3()
                .max_element()
                / std::f64::consts::PI;
            let sum: f64 = samples
                .iter()
                .map(|sample| {
                    let to_sample = sample.x.as_dvec3() - p;
                    let r2 = to_sample.length_squared();
                    r2.sqrt() * light_normal.dot(to_sample).abs() / (r2 * r2)
                })
                .sum();
            radiance_albedo * sum * f64::from(self.area) / chart.n.max(1) as f64
        }
    }

    /// Every level gives the same bits; each declines a specular lobe and
    /// otherwise is within 1e-6 of `want` relative to `facing` (`sampled`:
    /// the samples' path, for the message). Returns the worst relative
    /// difference.
    fn assert_levels_match(
        case: usize,
        levels: &[Level],
        chart: &ChartCase,
        (want, facing, sampled): (DVec3, f64, DVec3),
    ) -> f64 {
        let (n, p) = (chart.n, chart.sp.p);
        let mut worst = 0.0f64;
        let mut first: Option<Option<Vec3>> = None;
        for &level in levels {
            let got = rect_chart_at(
                level,
                &chart.light,
                &chart.sp,
                (&chart.xs, &chart.ys),
                &chart.vis,
            );
            match first {
                None => first = Some(got),
                Some(f) => assert_eq!(
                    f.map(|v| v.to_array().map(f32::to_bits)),
                    got.map(|v| v.to_array().map(f32::to_bits)),
                    "case {case}: levels differ"
                ),
            }
            if chart.spec && n > 0 {
                assert!(got.is_none(), "case {case}: a lobe must decline");
                continue;
            }
            let got = got
                .unwrap_or_else(|| panic!("case {case}: declined; n {n} p {p} want {want}"))
                .as_dvec3();
            let err = (got - want).abs().max_element() / facing.max(f64::MIN_POSITIVE);
            worst = worst.max(err);
            assert!(
                err <= 1e-6,
                "case {case}, {level:?}: {got} against {want} (facing {facing}, the \\
                 samples' path {sampled})"
            );
        }
        worst
    }

    /// The chart declines a sphere light and a receiver at the light's
    /// centre.
    fn assert_chart_declines_sphere_and_light_centre() {
        let sphere = Light {
            shape: LightShape::Sphere {
                center: Vec3::Y * 4.0,
                radius: 1.0,
            },
            radiance: Vec3::ONE,
            texture: None,
        };
        let at = |p: Vec3| SurfacePoint {
            p,
            n: Vec3::Y,
            ng: Vec3::Y,
            wo: Vec3::Y,
            albedo: Vec3::ONE,
            specular: Vec3::ZERO,
            shininess: 1.0,
        };
        let lanes = [0.0f32; CHART_LANES];
        let one = (&lanes[..], &lanes[..]);
        assert!(rect_chart_at(Level::Baseline, &sphere, &at(Vec3::ZERO), one, &[1.0]).is_none());
        let rect = Light {
            shape: LightShape::Rect {
                center: Vec3::Y * 4.0,
                u: Vec3::X,
                v: Vec3::Z,
                two_sided: false,
            },
            radiance: Vec3::ONE,
            texture: None,
        };
        let centre = at(Vec3::Y * 4.0);
        assert!(rect_chart_at(Level::Baseline, &rect, &centre, one, &[1.0]).is_none());
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
