//! Sphere lights: a uniform sphere of radiance `Le` seen from `p` is a cone
//! of half-angle `α` (`sin α = R / d`) filled with radiance `Le`, so the
//! diffuse part is `Le · albedo/π · (projected solid angle of the cone)`,
//! in closed form even where the cone crosses the receiver's horizon
//! (Snyder 1996). The specular lobe is integrated by a deterministic
//! centre-and-corners rule over equal-solid-angle cells of the cone.
//!
//! See `docs/shading.md` for the formulas and their error.

use super::brdf::{lobe_cells, Lobe};
use glam::DVec3;
use std::f64::consts::PI;

/// Most rings (equal steps of `cos`) and sectors (equal steps of
/// azimuth) of the cone quadrature for the lobe; fewer where the lobe is
/// wide compared with the cone ([`lobe_cells`]).
pub(crate) const MAX_CONE_CELLS: usize = 16;

/// `∫_light Le f_r cos_p cos_x / r² dA` for a sphere light of `radiance`
/// at `center` with `radius`, seen from `p` (visibility 1). Zero for `p`
/// inside or on the sphere, where the contract defines no value.
pub(crate) fn integrate(
    center: DVec3,
    radius: f64,
    radiance: DVec3,
    lobe: &Lobe,
    p: DVec3,
    with_spec: bool,
) -> DVec3 {
    let rel = center - p;
    let d = rel.length();
    if !(d > radius && d.is_finite()) {
        return DVec3::ZERO;
    }
    let axis = rel / d;
    let sin2a = (radius / d) * (radius / d);
    let cos_t = lobe.n.dot(axis);
    let cap = cap_projected_solid_angle(cos_t, sin2a);
    let mut out = radiance * lobe.diffuse * cap;
    if with_spec && cap > 0.0 {
        out += radiance * cone_specular(axis, sin2a, cap, lobe);
    }
    out
}

/// Projected solid angle `∫_cone max(0, n·w) dω` of a cone with
/// `sin²α = sin2a` (< 1) whose axis makes `cos θ = cos_t` with the normal.
///
/// Cone above the horizon (`θ + α ≤ π/2`): `π sin²α cos θ`. Below it: 0.
/// Crossing it: Snyder's closed form (as written in Lagarde & de Rousiers,
/// "Moving Frostbite to PBR", 2014, eq. 18) with `x = cot α`,
/// `y = −x cot θ`:
/// `(cos θ · acos y − x sin θ √(1−y²)) sin²α + atan(sin θ √(1−y²) / x)`.
pub(crate) fn cap_projected_solid_angle(cos_t: f64, sin2a: f64) -> f64 {
    let cos_t = cos_t.clamp(-1.0, 1.0);
    let sin2a = sin2a.clamp(0.0, 1.0);
    if cos_t * cos_t >= sin2a {
        // Entirely above (cos θ > 0) or entirely below the horizon.
        return PI * sin2a * cos_t.max(0.0);
    }
    // Here cos²θ < sin²α ≤ 1, so sin θ ≥ cos α > 0 unless α = π/2.
    let sin_t = (1.0 - cos_t * cos_t).sqrt();
    let x = ((1.0 - sin2a) / sin2a).sqrt(); // cot α
    let y = if sin_t > 0.0 {
        (-x * cos_t / sin_t).clamp(-1.0, 1.0)
    } else {
        0.0
    };
    let s = sin_t * (1.0 - y * y).sqrt();
    // atan2 rather than atan(s / x): x = 0 (p on the sphere) stays finite.
    let e = (cos_t * y.acos() - x * s) * sin2a + s.atan2(x);
    e.max(0.0)
}

/// `∫_cone f_spec(w) max(0, n·w) dω` (without `Le`) on `n × n` cells of
/// equal solid angle (equal steps of `cos` and of azimuth, a
/// parametrisation that preserves solid angle), `n` rings from
/// [`lobe_cells`] (1 to [`MAX_CONE_CELLS`]) and `max(n, 4)` sectors.
/// Each cell takes `(2 · centre + corner mean) / 3` of the integrand: the
/// midpoint
/// and the corner rule have h² error terms of opposite signs that this
/// cancels (for any cell aspect), so the error is O(h⁴) where the lobe
/// is smooth.
///
/// Where the horizon cuts the cone, `max(0, n·w)` has a kink the rule
/// does not resolve; so the lobe's value at the axis is taken out as a
/// control variate, integrated exactly against `cap` (the cone's projected
/// solid angle), and only the remainder `(f(w) − f(axis)) max(0, n·w)`,
/// which is small near the axis, goes through the quadrature.
fn cone_specular(axis: DVec3, sin2a: f64, cap: f64, lobe: &Lobe) -> DVec3 {
    let cos_a = (1.0 - sin2a).max(0.0).sqrt();
    // 1 − cos α without cancellation for small cones.
    let one_minus_cos = sin2a / (1.0 + cos_a);
    let alpha = sin2a.sqrt().min(1.0).asin();
    let cells = lobe_cells(2.0 * alpha, lobe.shininess(), MAX_CONE_CELLS);
    // At least 4 sectors: the corner and centre rules in azimuth are
    // trapezoid rules on a periodic function, exact for harmonics below
    // the sector count, so 4 integrate the lobe's first three exactly
    // however small the cone.
    let (rings, sectors) = (cells, cells.max(4));
    let (t1, t2) = basis(axis);
    let f_axis = lobe.spec_shape(axis);

    // Ring positions in half steps (even: boundaries, odd: centres) as
    // (cos, sin) from the axis; sector positions likewise in azimuth.
    const HALF: usize = 2 * MAX_CONE_CELLS + 1;
    let mut ring = [(0.0f64, 0.0f64); HALF];
    for (k, r) in ring.iter_mut().enumerate().take(2 * rings + 1) {
        let q = k as f64 / (2 * rings) as f64 * one_minus_cos; // 1 − cos
        *r = (1.0 - q, (q * (2.0 - q)).max(0.0).sqrt());
    }
    let mut sector = [(0.0f64, 0.0f64); HALF];
    for (m, s) in sector.iter_mut().enumerate().take(2 * sectors) {
        let phi = PI * m as f64 / sectors as f64;
        *s = (phi.cos(), phi.sin());
    }
    // The integrand (minus the control variate) at half-step positions.
    let g = |k: usize, m: usize| -> f64 {
        let (cos_k, sin_k) = ring[k];
        let (c, s) = sector[m % (2 * sectors)];
        let w = axis * cos_k + (t1 * c + t2 * s) * sin_k;
        let cos_p = lobe.n.dot(w);
        if cos_p > 0.0 {
            (lobe.spec_shape(w) - f_axis) * cos_p
        } else {
            0.0
        }
    };
    // Corner values: ring boundaries 0..=rings × sector boundaries
    // (azimuth wraps, so `sectors` of them).
    let mut corner = [[0.0f64; MAX_CONE_CELLS]; MAX_CONE_CELLS + 1];
    for (k, row) in corner.iter_mut().enumerate().take(rings + 1) {
        for (m, c) in row.iter_mut().enumerate().take(sectors) {
            *c = g(2 * k, 2 * m);
        }
    }
    let mut acc = 0.0;
    for k in 0..rings {
        for m in 0..sectors {
            let m1 = (m + 1) % sectors;
            let corners = corner[k][m] + corner[k][m1] + corner[k + 1][m] + corner[k + 1][m1];
            acc += 2.0 * g(2 * k + 1, 2 * m + 1) + 0.25 * corners;
        }
    }
    let d_omega = 2.0 * PI * one_minus_cos / (rings * sectors) as f64;
    // The remainder can be negative, the total cannot (rounding aside).
    lobe.specular_scale() * (f_axis * cap + acc / 3.0 * d_omega).max(0.0)
}

/// An orthonormal basis perpendicular to unit `n` (Duff et al. 2017).
fn basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cap_formula_is_continuous_at_the_horizon_boundary() {
        for sin2a in [1e-6f64, 0.01, 0.25, 0.81, 0.999] {
            // θ = π/2 − α: the cone touches the horizon.
            let c = sin2a.sqrt(); // cos θ = sin α
            let above = cap_projected_solid_angle(c + 1e-12, sin2a);
            let crossing = cap_projected_solid_angle(c - 1e-12, sin2a);
            assert!((above - crossing).abs() <= 1e-6 * above, "{sin2a}");
            // θ = π/2 + α: the cone leaves the horizon.
            assert!(cap_projected_solid_angle(-c + 1e-12, sin2a).abs() < 1e-9);
        }
    }

    #[test]
    fn basis_is_orthonormal() {
        for n in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::X,
            DVec3::new(1.0, 2.0, -3.0).normalize(),
        ] {
            let (a, b) = basis(n);
            assert!(a.dot(b).abs() < 1e-12 && a.dot(n).abs() < 1e-12 && b.dot(n).abs() < 1e-12);
            assert!((a.length() - 1.0).abs() < 1e-12 && (b.length() - 1.0).abs() < 1e-12);
        }
    }
}
