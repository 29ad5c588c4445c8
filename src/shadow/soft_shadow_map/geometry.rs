//! The geometry of one micro-patch (Atty et al. 2006, §3.3–3.4), in the
//! light view's own frame: the light centre at the origin, the light in the
//! plane `z = 0` spanning `[−hx, hx] × [−hy, hy]`, depth `z` along the
//! emitting normal, and tangent coordinates `t = x / z` (what a view's
//! texels are uniform in).
//!
//! **Back-projection.** A receiver `R = z_R (t_R, 1)` sees a point
//! `P = z_O (t_P, 1)` of a patch at depth `z_O < z_R`; the line from `R`
//! through `P` meets the light's plane at
//!
//! ```text
//! Q = R + (P − R) z_R / (z_R − z_O) = (t_P − t_R) / (1/z_O − 1/z_R)
//! ```
//!
//! (per axis). A patch spanning one texel `[t_c − Δ/2, t_c + Δ/2]`
//! back-projects onto `[a, b]` of the light normalised to `[0, 1]` with
//!
//! ```text
//! a = ½ − (m + ½) G,  b = ½ − (m − ½) G,  G = Δ z_O z_R / (2h (z_R − z_O)),
//! ```
//!
//! `m = (t_R − t_c) / Δ` the receiver's offset from the patch centre in
//! texels (an integer for a soft-shadow-map texel). Its occlusion is
//! `(sat b − sat a)(sat d − sat c)` (§3.4); the sign of `m` is irrelevant
//! because the light is symmetric about its centre.
//!
//! **Penumbra extent** (§3.3, derived here: the printed formulas are not
//! self-consistent). On the plane `z_R`, a patch `[p0, p1]` (world units at
//! `z_O`) shadows `x = l + (p − l) k`, `k = z_R / z_O ≥ 1`, for light points
//! `l ∈ [−h, h]`: extreme at the opposite corners,
//!
//! ```text
//! x ∈ [k p0 − (k − 1) h,  k p1 + (k − 1) h],
//! ```
//!
//! width `k w + 2(k − 1) h` (the paper prints `RR' = LL' (z_R − z_O)/z_O`,
//! which drops the `k w` term). Those two lines cross at the pyramid's apex,
//! at depth `z_a = z_O · 2h / (2h + w)` on the ray from the light centre
//! through the patch centre — the paper's `C_L O = r/(1+r) C_L C_P`,
//! `r = 2h/w`, which is right; its `C_L C_R = z_R/(z_R − z_O) C_L O` is not
//! (the extent's centre is `z_R / z_O · C_L C_P`). In tangent coordinates
//! the extent is the patch widened by `h (1/z_O − 1/z_R)` on each side, so
//! in texels a soft-shadow-map texel `m` texels away is touched iff
//! `|m| < ½ + h (1/z_O − 1/z_R) / Δ` — exactly where the occlusion above is
//! non-zero (both `sat`s differ iff `b > 0` and `a < 1`).

/// Largest `G` used: finite, so `(m ± ½) G` is never `0 · ∞` (a receiver
/// touching the patch, `z_R → z_O`, or a light of size 0), and large enough
/// that `sat` gives the limit (0 or 1) for any `|m ± ½| ≥ 1e-25`.
pub const MAX_G: f32 = 1e25;

/// Interval `[lo, hi]` of one axis of a patch's penumbra extent on the
/// plane `z_r`, world units: the patch spans `[p0, p1]` at depth `z_o`, the
/// light `[−h, h]` at depth 0 (see the module's derivation).
pub fn extent_on_plane(p0: f64, p1: f64, z_o: f64, z_r: f64, h: f64) -> (f64, f64) {
    let k = z_r / z_o;
    (k * p0 - (k - 1.0) * h, k * p1 + (k - 1.0) * h)
}

/// The pyramid's apex for one axis: `(x, z)` where the lines from the
/// light's corners through the patch's opposite edges cross.
pub fn apex(p0: f64, p1: f64, z_o: f64, h: f64) -> (f64, f64) {
    let w = p1 - p0;
    let z = z_o * 2.0 * h / (2.0 * h + w);
    (0.5 * (p0 + p1) * z / z_o, z)
}

/// Texels a patch reaches on each side on one axis, for receivers no
/// deeper than `z_r_max`: `⌊½ + h (1/z_o − 1/z_r_max) / Δ⌋` (conservative:
/// texels beyond it get exactly zero occlusion).
pub fn reach(h: f64, texel: f64, z_o: f64, z_r_max: f64) -> i64 {
    let r = 0.5 + h * (1.0 / z_o - 1.0 / z_r_max) / texel;
    if r.is_finite() {
        r.floor().clamp(0.0, 1e9) as i64
    } else {
        1_000_000_000
    }
}

/// `G / (Δ / 2h)`: the per-(patch, receiver) factor `z_O z_R / (z_R −
/// z_O)`, in f32 as the SIMD lanes compute it.
#[inline(always)]
pub fn depth_factor(z_o: f32, z_r: f32) -> f32 {
    (z_o * z_r) / (z_r - z_o)
}

/// `sat(x)`: clamp to `[0, 1]` as the SIMD facade's `min(1)` then
/// `max(0)` do it (a NaN would give 0; none reaches here).
#[inline(always)]
fn sat(x: f32) -> f32 {
    let x = if x < 1.0 { x } else { 1.0 };
    if x > 0.0 {
        x
    } else {
        0.0
    }
}

/// `min(x, MAX_G)` with the facade's rule.
#[inline(always)]
fn cap(x: f32) -> f32 {
    if x < MAX_G {
        x
    } else {
        MAX_G
    }
}

/// The occlusion of one patch for one receiver, f32, the same operations
/// in the same order as the SIMD path (`accumulate.rs`), so a gather at a
/// texel centre gives the texel's bits. `ax = Δx / 2hx`, `ay = Δy / 2hy`;
/// `mx, my` the receiver's offset from the patch centre in texels. The
/// caller has checked `z_o < z_r`.
#[inline(always)]
pub fn patch_occlusion(mx: f32, my: f32, z_o: f32, z_r: f32, ax: f32, ay: f32) -> f32 {
    let p = depth_factor(z_o, z_r);
    let gx = cap(ax * p);
    let gy = cap(ay * p);
    let wx = sat(0.5 - (mx - 0.5) * gx) - sat(0.5 - (mx + 0.5) * gx);
    let wy = sat(0.5 - (my - 0.5) * gy) - sat(0.5 - (my + 0.5) * gy);
    wx * wy
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tiny deterministic generator for the property tests.
    fn rng(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            // One SplitMix64 step from the previous draw.
            s = crate::sampling::SplitMix64::new(s).next_u64();
            (s >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// Every shadow point of light point × patch point lies in the extent,
    /// and the extent's ends are reached by the opposite corners.
    #[test]
    fn the_extent_holds_every_shadow_point_and_is_tight() {
        let mut r = rng(1);
        for _ in 0..200 {
            let h = 0.01 + r();
            let z_o = 0.1 + 3.0 * r();
            let z_r = z_o * (1.0 + 3.0 * r()) + 1e-3;
            let p0 = 4.0 * r() - 2.0;
            let p1 = p0 + 0.001 + 0.3 * r();
            let (lo, hi) = extent_on_plane(p0, p1, z_o, z_r, h);
            let shadow = |l: f64, p: f64| l + (p - l) * z_r / z_o;
            for _ in 0..50 {
                let x = shadow(h * (2.0 * r() - 1.0), p0 + (p1 - p0) * r());
                assert!(x >= lo - 1e-12 && x <= hi + 1e-12);
            }
            assert!((shadow(h, p0) - lo).abs() < 1e-12);
            assert!((shadow(-h, p1) - hi).abs() < 1e-12);
            // The apex: both extreme lines pass through it.
            let (ax, az) = apex(p0, p1, z_o, h);
            let line = |l: f64, p: f64, z: f64| l + (p - l) * z / z_o;
            assert!((line(h, p0, az) - ax).abs() < 1e-12);
            assert!((line(-h, p1, az) - ax).abs() < 1e-12);
            // The extent's width grows linearly from the apex, and its
            // centre is on the ray from the light centre through the
            // patch centre (not the paper's printed z_R/(z_R − z_O)).
            let w = p1 - p0;
            assert!(((hi - lo) - w * (z_r - az) / (z_o - az)).abs() < 1e-9);
            assert!((0.5 * (lo + hi) - 0.5 * (p0 + p1) * z_r / z_o).abs() < 1e-12);
            // The paper's printed width drops k·w: wrong unless w = 0.
            let printed = 2.0 * h * (z_r - z_o) / z_o;
            assert!((hi - lo) - printed > 0.99 * w * z_r / z_o);
        }
    }

    /// The texel reach is exactly where the occlusion formula is non-zero.
    #[test]
    fn the_reach_in_texels_is_where_occlusion_is_non_zero() {
        let mut r = rng(2);
        for _ in 0..300 {
            let h = 0.05 + r();
            let texel = 0.002 + 0.02 * r();
            let z_o = 0.5 + 3.0 * r();
            let z_r = z_o * (1.01 + 2.0 * r());
            let n = reach(h, texel, z_o, z_r);
            let a = (texel / (2.0 * h)) as f32;
            let rho = 0.5 + h * (1.0 / z_o - 1.0 / z_r) / texel;
            let occ = |m: i64| patch_occlusion(m as f32, 0.0, z_o as f32, z_r as f32, a, a);
            if (n as f64) < rho - 1e-4 {
                assert!(occ(n) > 0.0, "m {n} inside reach {rho}");
                assert!(occ(-n) > 0.0);
            }
            assert_eq!(occ(n + 1), 0.0, "m {} beyond reach {n}", n + 1);
            assert_eq!(occ(-n - 1), 0.0);
            // The centre texel is always occluded by its own patch.
            assert!(patch_occlusion(0.0, 0.0, z_o as f32, z_r as f32, a, a) > 0.0);
        }
    }

    /// The formula against a brute-force back-projection of the patch's
    /// corners onto the light in f64, clipped to the light.
    #[test]
    fn occlusion_is_the_overlap_of_the_back_projection() {
        let mut r = rng(3);
        for _ in 0..500 {
            let (hx, hy) = (0.05 + r(), 0.05 + r());
            let texel = 0.01 + 0.05 * r();
            let z_o = 0.5 + 2.0 * r();
            let z_r = z_o * (1.05 + 2.0 * r());
            let (mx, my) = ((40.0 * r() - 20.0).round(), (40.0 * r() - 20.0).round());
            // Receiver at tangent 0; patch centre at −m texels.
            let axis = |m: f64, h: f64| {
                let (t0, t1) = ((-m - 0.5) * texel, (-m + 0.5) * texel);
                let q = |t: f64| {
                    let (p, rr) = (z_o * t, 0.0);
                    rr + (p - rr) * z_r / (z_r - z_o)
                };
                let (lo, hi) = (q(t0).max(-h), q(t1).min(h));
                ((hi - lo) / (2.0 * h)).max(0.0)
            };
            let exact = axis(mx, hx) * axis(my, hy);
            let got = patch_occlusion(
                mx as f32,
                my as f32,
                z_o as f32,
                z_r as f32,
                (texel / (2.0 * hx)) as f32,
                (texel / (2.0 * hy)) as f32,
            );
            assert!((got as f64 - exact).abs() < 2e-6, "{got} vs {exact}");
        }
    }

    /// Touching the receiver or a zero-sized light: finite, the hard limit.
    #[test]
    fn degenerate_depths_give_no_nan() {
        for (z_o, z_r, a) in [
            (1.0f32, 1.0 + f32::EPSILON, 1.0f32),
            (1.0, 1.0000001, 1e30),
            (1e-30, 1.0, 1.0),
            (1.0, f32::MAX, f32::INFINITY),
        ] {
            for m in [-1.0f32, -0.5, 0.0, 0.5, 1.0] {
                let o = patch_occlusion(m, 0.0, z_o, z_r, a, a);
                assert!(o.is_finite() && (0.0..=1.0).contains(&o), "{o}");
            }
        }
        // Touching: the receiver straight behind its patch is fully
        // occluded, its neighbour not at all.
        let t = patch_occlusion(0.0, 0.0, 1.0, 1.0 + 1e-6, 0.01, 0.01);
        assert_eq!(t, 1.0);
        assert_eq!(patch_occlusion(1.0, 0.0, 1.0, 1.0 + 1e-6, 0.01, 0.01), 0.0);
    }
}
