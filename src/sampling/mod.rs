//! Light samples, in one place for every technique.
//!
//! Every technique that integrates over a light's area takes its sample
//! points from here, so two techniques given the same
//! `(seed, light index, pixel, N)` see exactly the same points and their
//! results can be compared sample by sample.
//!
//! # Random numbers
//!
//! There is no generator state: sample `k` of pixel `(x, y)` for light `l`
//! is a pure function of `(seed, l, x, y, k)` (a counter-based generator).
//! [`pixel_key`] hashes `(seed, l, x, y)` into a 64-bit key with the
//! SplitMix64 finaliser (one round per field), and the two uniforms of
//! sample `k` are outputs `2k` and `2k + 1` of the SplitMix64 sequence
//! started at that key ([`uniform_pair`]). Results therefore never depend on
//! thread scheduling or on the order pixels are visited.
//!
//! # Layout (the oracle's estimator definitions)
//!
//! `N` samples fill a stratified, jittered `a × b` grid on `[0, 1)²`, with
//! `a` the largest divisor of `N` not above `√N` and `b = N / a`
//! ([`Strata`]); sample `k` lies in column `i = k mod a`, row `j = k div a`,
//! at `s = (i + ξ) / a`, `t = (j + ξ') / b`. Then:
//!
//! - **Rect lights**: `x = center + (2s − 1) u + (1 − 2t) v` (the contract's
//!   texture mapping), uniform in area: `inv_pdf_area = |A| = 4 |u × v|`.
//! - **Sphere lights**: uniform in solid angle over the cone the sphere
//!   subtends from the receiver `p`: `cos θ = 1 − s (1 − cos θmax)`,
//!   `φ = 2π t` around the axis `p → center`; `x` is the near intersection
//!   of that direction with the sphere. The solid-angle pdf `1/Ω` becomes
//!   the area pdf `cos_x / (Ω r²)`, so `inv_pdf_area = Ω r² / cos_x` and
//!   [`crate::shade::PreparedLight::direct_from_samples`] (which multiplies
//!   by `cos_x / r²`) reduces to `Ω Le f_r cos_p` per sample. A receiver
//!   inside (or on) the sphere gets no samples.
//!
//! # Sample patterns
//!
//! The layout above is [`SamplePattern::Stratified`], the default and the
//! only one [`LightSampler::samples_into`] and [`light_samples`] use. A
//! [`PatternSampler`] (built once per pattern, `N`, seed and light) gives
//! the unit points of any [`SamplePattern`], and
//! [`LightSampler::samples_with`] maps them to the light exactly as above,
//! so a technique and the reference handed the same `PatternSampler` see
//! the same samples at every pixel:
//!
//! | pattern | set | decorrelated between pixels by |
//! |---|---|---|
//! | `stratified` | jittered `a × b` grid | fresh jitter (key per pixel) |
//! | `correlated` | one jittered grid | nothing: every pixel shares it |
//! | `rotated` | the correlated grid | Cranley–Patterson rotation (toroidal shift per pixel) |
//! | `poisson` | one Poisson-disk set (dart throwing on the torus) | Cranley–Patterson rotation |
//! | `sobol` | first `N` points of the Sobol' (0,2)-sequence | random digital shift (XOR per pixel) |
//! | `interleaved:n` | `n²` jittered grids, one per `(x mod n, y mod n)` | the pixel's place in the `n × n` tile |
//! | `grid` | the regular `a × b` grid including the light's edges (17 × 17 for 289) | nothing: every pixel shares it |
//!
//! For the depth-complexity technique, [`LightSampler::chart_points`] gives
//! each sample's coordinates in a planar chart of the light (rect: the
//! light's own `(2s − 1, 1 − 2t)`; sphere: the gnomonic chart of the cone,
//! [`ConeFrame`]). See `docs/algorithms/sample-patterns.md`.

use crate::scene::{Light, LightShape};
use glam::{DVec3, Vec2, Vec3};
use std::f64::consts::PI;

use crate::shade::LightSample;

mod patterns;

pub use patterns::{
    grid_coordinate, max_packing_distance, poisson_dart_budget, poisson_dart_throwing,
    poisson_relative_radius, poisson_target_distance, sobol02, toroidal_distance2, PatternSampler,
    PoissonSet, SamplePattern, DEFAULT_INTERLEAVE, POISSON_MAX_LEVELS, POISSON_MIN_RELATIVE_RADIUS,
    POISSON_RESTARTS, POISSON_SHRINK, POISSON_THESIS_DISTANCES,
};

/// SplitMix64's increment (the golden ratio in 64-bit fixed point).
pub(crate) const GOLDEN: u64 = 0x9e37_79b9_7f4a_7c15;

/// SplitMix64's output function: a bijective 64-bit mixer with full
/// avalanche, so neighbouring keys give unrelated outputs.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(MIX_1);
    z = (z ^ (z >> 27)).wrapping_mul(MIX_2);
    z ^ (z >> 31)
}

/// [`mix64`]'s two multipliers (for SIMD copies of it).
pub(crate) const MIX_1: u64 = 0xbf58_476d_1ce4_e5b9;
pub(crate) const MIX_2: u64 = 0x94d0_49bb_1331_11eb;

/// The SplitMix64 generator (Steele, Lea and Flood 2014): the state
/// advances by [`GOLDEN`] and each output is [`mix64`] of it. The one
/// seeded sequence for places that want a stream of numbers rather than
/// the counter-based [`uniform_pair`] (fixed tap sets, derived seeds,
/// random test inputs).
#[derive(Debug, Clone)]
pub(crate) struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// The generator whose first output is `mix64(seed + GOLDEN)`.
    #[inline]
    pub(crate) const fn new(seed: u64) -> SplitMix64 {
        SplitMix64 { state: seed }
    }

    /// The next output.
    #[inline]
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN);
        mix64(self.state)
    }
}

/// The key of all samples of one light at one pixel: a hash of
/// `(seed, light_index, x, y)`. Each field is folded in with its own
/// multiplier before a full mixing round, so swapping `x` and `y` (or the
/// light index and a coordinate) gives a different key.
#[inline]
pub fn pixel_key(seed: u64, light_index: usize, pixel: (u32, u32)) -> u64 {
    let mut h = mix64(seed ^ 0x6a09_e667_f3bc_c909);
    h = mix64(h ^ (light_index as u64).wrapping_mul(0xbb67_ae85_84ca_a73b));
    h = mix64(h ^ u64::from(pixel.0).wrapping_mul(0x3c6e_f372_fe94_f82b));
    mix64(h ^ u64::from(pixel.1).wrapping_mul(0xa54f_f53a_5f1d_36f1))
}

/// The two uniforms in `[0, 1)` of sample `k` under `key`: outputs `2k`
/// and `2k + 1` of the SplitMix64 sequence seeded with `key`. They have
/// 32-bit resolution, so `i + ξ` is exact in `f64` for any stratum index.
#[inline]
pub fn uniform_pair(key: u64, k: u32) -> (f64, f64) {
    let c = 2 * u64::from(k);
    // Through i64: the value is below 2³², so the signed conversion (one
    // instruction on x86-64, where u64 has none) is exact, the same bits.
    let to_unit = |h: u64| ((h >> 32) as i64) as f64 * (1.0 / 4_294_967_296.0);
    (
        to_unit(mix64(key.wrapping_add((c + 1).wrapping_mul(GOLDEN)))),
        to_unit(mix64(key.wrapping_add((c + 2).wrapping_mul(GOLDEN)))),
    )
}

/// The stratified `a × b` grid of `N = a b` samples: `a` is the largest
/// divisor of `N` with `a ≤ √N` (16 × 16 for 256, 2 × 8 for 16, 1 × 7 for 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Strata {
    /// Columns (along `s`).
    pub a: u32,
    /// Rows (along `t`).
    pub b: u32,
}

impl Strata {
    /// The grid for `n` samples; `n = 0` gives an empty `0 × 0` grid.
    pub fn new(n: u32) -> Strata {
        if n == 0 {
            return Strata { a: 0, b: 0 };
        }
        // Integer square root, corrected for the float estimate's rounding.
        let mut a = f64::from(n).sqrt() as u32;
        while u64::from(a) * u64::from(a) > u64::from(n) {
            a -= 1;
        }
        while u64::from(a + 1) * u64::from(a + 1) <= u64::from(n) {
            a += 1;
        }
        while !n.is_multiple_of(a) {
            a -= 1;
        }
        Strata { a, b: n / a }
    }

    /// Number of samples `a b`.
    pub fn count(&self) -> u32 {
        self.a * self.b
    }

    /// Stratum `(i, j)` of sample `k`: column `k mod a`, row `k div a`.
    #[inline]
    pub fn cell(&self, k: u32) -> (u32, u32) {
        if self.a == 0 {
            return (0, 0);
        }
        (k % self.a, k / self.a)
    }

    /// The samples `k` in blocks of `w × h` neighbouring strata (blocks
    /// row by row, each block row by row), into `out` (cleared first): the
    /// inverse of [`Strata::cell`] walked block-wise. Sample order when
    /// `w` does not divide `a` or `h` does not divide `b`.
    pub fn block_order(&self, w: u32, h: u32, out: &mut Vec<u32>) {
        out.clear();
        let (a, b) = (self.a, self.b);
        if w == 0 || h == 0 || !a.is_multiple_of(w) || !b.is_multiple_of(h) {
            out.extend(0..self.count());
            return;
        }
        for j0 in (0..b).step_by(h as usize) {
            for i0 in (0..a).step_by(w as usize) {
                for j in j0..j0 + h {
                    out.extend((i0..i0 + w).map(|i| j * a + i));
                }
            }
        }
    }

    /// The jittered point `(s, t) ∈ [0, 1)²` of sample `k` under `key`.
    #[inline]
    pub fn point(&self, key: u64, k: u32) -> (f64, f64) {
        let (i, j) = self.cell(k);
        let (xi, xi2) = uniform_pair(key, k);
        (
            (f64::from(i) + xi) / f64::from(self.a.max(1)),
            (f64::from(j) + xi2) / f64::from(self.b.max(1)),
        )
    }
}

/// A light with the per-light constants of its sampling precomputed, so
/// sampling many pixels does not redo them.
#[derive(Debug, Clone, Copy)]
pub enum LightSampler {
    /// A parallelogram light.
    Rect {
        /// Centre.
        center: DVec3,
        /// Half-edge vector along `s`.
        u: DVec3,
        /// Half-edge vector along `t` (row 0 at `center + v`).
        v: DVec3,
        /// `|A| = 4 |u × v|`, the inverse area pdf of every sample.
        area: f32,
    },
    /// A sphere light.
    Sphere {
        /// Centre.
        center: DVec3,
        /// Radius.
        radius: f64,
    },
}

impl LightSampler {
    /// Precomputes `light`'s sampling constants.
    pub fn new(light: &Light) -> LightSampler {
        match light.shape {
            LightShape::Rect { center, u, v, .. } => {
                let (u, v) = (u.as_dvec3(), v.as_dvec3());
                LightSampler::Rect {
                    center: center.as_dvec3(),
                    u,
                    v,
                    area: (4.0 * u.cross(v).length()) as f32,
                }
            }
            LightShape::Sphere { center, radius } => LightSampler::Sphere {
                center: center.as_dvec3(),
                radius: f64::from(radius),
            },
        }
    }

    /// Writes the `n` samples of light `light_index` seen from receiver `p`
    /// at `pixel` into `out` (cleared first). Sphere lights give no samples
    /// for a receiver inside or on the sphere (the contract defines nothing
    /// there), or one that is not finite. This is
    /// [`LightSampler::samples_with`] for [`SamplePattern::Stratified`].
    pub fn samples_into(
        &self,
        light_index: usize,
        p: Vec3,
        pixel: (u32, u32),
        n: u32,
        seed: u64,
        out: &mut Vec<LightSample>,
    ) {
        let stratified = PatternSampler::new(SamplePattern::Stratified, n, seed, light_index);
        self.samples_with(&stratified, p, pixel, out);
    }

    /// Writes the samples of `pattern`'s light (its `N`, seed and light
    /// index) seen from receiver `p` at `pixel` into `out` (cleared first):
    /// unit point `k` ([`PatternSampler::unit_points`]) is mapped to the
    /// light as the module documentation says for `(s, t)`. Sphere lights
    /// give no samples for a receiver inside or on the sphere, or one that
    /// is not finite. `pattern` must have been built for this light.
    pub fn samples_with(
        &self,
        pattern: &PatternSampler,
        p: Vec3,
        pixel: (u32, u32),
        out: &mut Vec<LightSample>,
    ) {
        out.clear();
        let n = pattern.len();
        let points = pattern.pixel_points(pixel);
        match *self {
            LightSampler::Rect { center, u, v, area } => {
                // Written in place rather than pushed: `push` re-reads the
                // vector's length and capacity around every store.
                out.resize(n as usize, LightSample::default());
                let mut slots = out.iter_mut();
                points.for_each(n, |(s, t)| {
                    if let Some(slot) = slots.next() {
                        *slot = LightSample {
                            x: (center + u * (2.0 * s - 1.0) + v * (1.0 - 2.0 * t)).as_vec3(),
                            st: Vec2::new(s as f32, t as f32),
                            inv_pdf_area: area,
                        };
                    }
                });
            }
            LightSampler::Sphere { center, radius } => {
                if let Some(cone) = Cone::new(center, radius, p.as_dvec3()) {
                    out.reserve(n as usize);
                    points.for_each(n, |p| out.push(cone.sample(p)));
                }
            }
        }
    }

    /// The frame of the cone a sphere light subtends from receiver `p`:
    /// `None` for a rect light, or a receiver inside or on the sphere (or
    /// not finite), exactly when [`LightSampler::samples_with`] gives no
    /// samples.
    pub fn cone_frame(&self, p: DVec3) -> Option<ConeFrame> {
        match *self {
            LightSampler::Rect { .. } => None,
            LightSampler::Sphere { center, radius } => {
                Cone::new(center, radius, p).map(|c| c.frame())
            }
        }
    }

    /// The light-chart coordinates of the samples whose unit points are
    /// `unit` (as [`PatternSampler::unit_points`] gives them), seen from
    /// receiver `p`, written to `out` (cleared first), in `f64`:
    ///
    /// - **Rect**: `[2s − 1, 1 − 2t]`, the coordinates `(a, b)` of the
    ///   sample `x = center + a u + b v` in the light's own frame; the
    ///   light is the square `[−1, 1]²`. Independent of `p`.
    /// - **Sphere**: the gnomonic chart of the cone from `p`
    ///   ([`LightSampler::cone_frame`]): `[tan θ cos φ, tan θ sin φ]` with
    ///   `cos θ = 1 − s (1 − cos θmax)`, `φ = 2π t` as in the sampling,
    ///   so the sample's direction is `w ∝ axis + a t1 + b t2` (the
    ///   central projection of the direction onto the plane tangent to the
    ///   unit sphere at `axis`) and the light is the disk of radius
    ///   `tan θmax`. Straight lines through `p` (and planes through `p`)
    ///   stay straight in this chart. Empty when the receiver is inside or
    ///   on the sphere.
    pub fn chart_points(&self, unit: &[(f64, f64)], p: DVec3, out: &mut Vec<[f64; 2]>) {
        out.clear();
        match *self {
            LightSampler::Rect { .. } => {
                out.extend(unit.iter().map(|&(s, t)| [2.0 * s - 1.0, 1.0 - 2.0 * t]));
            }
            LightSampler::Sphere { center, radius } => {
                if let Some(cone) = Cone::new(center, radius, p) {
                    out.extend(unit.iter().map(|&st| cone.chart(st)));
                }
            }
        }
    }
}

/// The frame of the cone a sphere light subtends from a receiver, and the
/// extent of the light in its gnomonic chart
/// ([`LightSampler::chart_points`]): chart point `(a, b)` is the direction
/// `normalize(axis + a t1 + b t2)`, and the light covers the disk
/// `a² + b² ≤ tan²θmax`. `(t1, t2)` is the basis the sampling uses around
/// the axis (Duff et al. 2017), so `φ = 0` lies along `t1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConeFrame {
    /// Unit axis from the receiver to the sphere's centre.
    pub axis: DVec3,
    /// First unit vector perpendicular to the axis (`φ = 0`).
    pub t1: DVec3,
    /// Second unit vector perpendicular to both (`φ = π/2`).
    pub t2: DVec3,
    /// `tan θmax = R / √(d² − R²)`, the chart radius of the light.
    pub tan_max: f64,
}

/// The cone a sphere light subtends from a receiver outside it.
struct Cone {
    p: DVec3,
    center: DVec3,
    radius: f64,
    /// Distance from `p` to the centre.
    d: f64,
    /// Unit axis `p → center` and two unit vectors completing a frame.
    axis: DVec3,
    t1: DVec3,
    t2: DVec3,
    /// `1 − cos θmax`, computed as `sin²θmax / (1 + cos θmax)` so that
    /// small cones (distant lights) keep their precision.
    h: f64,
    /// The cone's solid angle `Ω = 2π (1 − cos θmax)`.
    omega: f64,
}

impl Cone {
    fn new(center: DVec3, radius: f64, p: DVec3) -> Option<Cone> {
        let rel = center - p;
        let d = rel.length();
        if !(d > radius && d.is_finite()) {
            return None;
        }
        let axis = rel / d;
        let sin2 = (radius / d) * (radius / d);
        let h = sin2 / (1.0 + (1.0 - sin2).max(0.0).sqrt());
        let (t1, t2) = orthonormal_basis(axis);
        Some(Cone {
            p,
            center,
            radius,
            d,
            axis,
            t1,
            t2,
            h,
            omega: 2.0 * PI * h,
        })
    }

    /// The frame and chart radius of the cone.
    fn frame(&self) -> ConeFrame {
        ConeFrame {
            axis: self.axis,
            t1: self.t1,
            t2: self.t2,
            tan_max: self.radius / ((self.d - self.radius) * (self.d + self.radius)).sqrt(),
        }
    }

    /// The gnomonic chart coordinates `[tan θ cos φ, tan θ sin φ]` of the
    /// unit point `(s, t)`, with `θ` and `φ` computed as [`Cone::sample`]
    /// does.
    fn chart(&self, (s, t): (f64, f64)) -> [f64; 2] {
        let one_minus_cos = s * self.h;
        let cos_t = 1.0 - one_minus_cos;
        let sin_t = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
        let tan_t = sin_t / cos_t;
        let phi = 2.0 * PI * t;
        [tan_t * phi.cos(), tan_t * phi.sin()]
    }

    /// The sample for the grid point `(s, t)`: direction uniform in solid
    /// angle inside the cone, `x` on the near cap.
    fn sample(&self, (s, t): (f64, f64)) -> LightSample {
        let one_minus_cos = s * self.h;
        let cos_t = 1.0 - one_minus_cos;
        // sin² = (1 − cos)(1 + cos), without cancellation near the axis.
        let sin_t = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
        let phi = 2.0 * PI * t;
        let w = self.axis * cos_t + (self.t1 * phi.cos() + self.t2 * phi.sin()) * sin_t;
        // Near root of |p + τ w − c| = R; the discriminant reaches 0 on the
        // cone's edge (tangent ray) and may round below it there.
        let disc = (self.radius * self.radius - self.d * self.d * sin_t * sin_t).max(0.0);
        let tau = self.d * cos_t - disc.sqrt();
        let x = (self.p + w * tau).as_vec3();
        LightSample {
            x,
            st: Vec2::new(s as f32, t as f32),
            inv_pdf_area: self.inv_pdf_area(x),
        }
    }

    /// `Ω r² / cos_x`, evaluated at the stored (f32) `x` with the same
    /// expressions the estimator uses for `r²` and `cos_x`, so that their
    /// product `cos_x / r² · inv_pdf_area` is `Ω` up to the final f32
    /// rounding even where `cos_x` is tiny (the cone's edge). Where the
    /// rounding of `x` makes `cos_x ≤ 0` the estimator drops the sample
    /// anyway; 0 is returned.
    fn inv_pdf_area(&self, x: Vec3) -> f32 {
        let xd = x.as_dvec3();
        let d = xd - self.p;
        let r2 = d.length_squared();
        if !(r2 > 0.0) {
            return 0.0;
        }
        let w = d / r2.sqrt();
        let cos_x = -(xd - self.center).dot(w) * (1.0 / self.radius);
        if cos_x > 0.0 {
            (self.omega * r2 / cos_x) as f32
        } else {
            0.0
        }
    }
}

/// An orthonormal basis perpendicular to the unit vector `n` (Duff et al.,
/// "Building an Orthonormal Basis, Revisited", 2017): branch on the sign
/// only, no normalisation, so it is exact to rounding for every `n`.
fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// The `n` samples of light `light_index` for the receiver `p` at `pixel`,
/// written into `out` (cleared first): see the module documentation for
/// the layout. Techniques sampling many pixels should build a
/// [`LightSampler`] once per light and call
/// [`LightSampler::samples_into`] instead.
pub fn light_samples_into(
    light: &Light,
    light_index: usize,
    p: Vec3,
    pixel: (u32, u32),
    n: u32,
    seed: u64,
    out: &mut Vec<LightSample>,
) {
    LightSampler::new(light).samples_into(light_index, p, pixel, n, seed, out);
}

/// [`light_samples_into`] into a new vector.
pub fn light_samples(
    light: &Light,
    light_index: usize,
    p: Vec3,
    pixel: (u32, u32),
    n: u32,
    seed: u64,
) -> Vec<LightSample> {
    let mut out = Vec::with_capacity(n as usize);
    light_samples_into(light, light_index, p, pixel, n, seed, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The published SplitMix64 sequence from seed 0 (the reference C
    /// code's first outputs).
    #[test]
    fn splitmix64_gives_the_reference_sequence() {
        let mut rng = SplitMix64::new(0);
        assert_eq!(rng.next_u64(), 0xe220_a839_7b1d_cdaf);
        assert_eq!(rng.next_u64(), 0x6e78_9e6a_a1b9_65f4);
        assert_eq!(rng.next_u64(), 0x06c4_5d18_8009_454f);
    }
}
