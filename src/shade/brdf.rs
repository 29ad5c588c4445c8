//! The contract's BRDF: Lambertian plus a normalised Blinn-Phong lobe,
//! `f_r = albedo / π + Ks (Ns + 8) / (8π) max(0, n·h)^Ns`.
//!
//! The public [`brdf`] works in `f32` for callers; the integrators use
//! [`Lobe`], the same function in `f64`, so that quadrature sums over many
//! cells do not lose precision.

use super::SurfacePoint;
use glam::{DVec3, Vec3};
use std::f64::consts::PI;

/// Evaluates the contract's BRDF at `sp` for the incident direction `wi`
/// (unit, pointing away from the surface toward the light).
///
/// Returns `albedo / π + Ks (Ns + 8) / (8π) max(0, n·h)^Ns` with
/// `h = normalize(wi + wo)`. The cosine factor `max(0, n·wi)` is *not*
/// included (the integrators apply it). When `Ks` is zero the lobe is not
/// evaluated at all; when `wi = -wo` (no half vector) the lobe counts
/// `n·h = 0`. The result is always finite for finite inputs.
pub fn brdf(sp: &SurfacePoint, wi: Vec3) -> Vec3 {
    let lobe = Lobe::new(sp);
    to_vec3(lobe.eval(wi.as_dvec3()))
}

/// The BRDF of one surface point, prepared in `f64`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Lobe {
    /// Shading normal (unit).
    pub n: DVec3,
    /// Direction toward the eye (unit).
    wo: DVec3,
    /// `albedo / π`.
    pub diffuse: DVec3,
    /// `Ks (Ns + 8) / (8π)`.
    spec: DVec3,
    /// `Ns`, clamped to be non-negative so `0^Ns` never becomes infinite.
    ns: f64,
    /// `Ks != 0`: whether the lobe needs evaluating at all.
    pub has_spec: bool,
}

impl Lobe {
    /// Prepares the BRDF of `sp`.
    pub fn new(sp: &SurfacePoint) -> Self {
        let ns = f64::from(sp.shininess).max(0.0);
        let ks = sp.specular.as_dvec3();
        Lobe {
            n: sp.n.as_dvec3(),
            wo: sp.wo.as_dvec3(),
            diffuse: sp.albedo.as_dvec3() / PI,
            spec: ks * ((ns + 8.0) / (8.0 * PI)),
            ns,
            has_spec: ks != DVec3::ZERO,
        }
    }

    /// `max(0, n·h)^Ns` for the incident direction `wi` (unit).
    pub fn spec_shape(&self, wi: DVec3) -> f64 {
        let h = wi + self.wo;
        let len = h.length();
        // wi = -wo has no half vector; any direction is as good as another,
        // and the grazing configuration it describes carries no energy.
        let nh = if len > 1e-12 {
            self.n.dot(h) / len
        } else {
            0.0
        };
        nh.clamp(0.0, 1.0).powf(self.ns)
    }

    /// `Ns` (non-negative).
    pub fn shininess(&self) -> f64 {
        self.ns
    }

    /// `Ks (Ns + 8) / (8π)`: the lobe's colour and normalisation, so that
    /// `specular(w) = specular_scale() · spec_shape(w)`.
    pub fn specular_scale(&self) -> DVec3 {
        self.spec
    }

    /// The specular part `Ks (Ns + 8)/(8π) max(0, n·h)^Ns` (zero if `Ks = 0`).
    pub fn specular(&self, wi: DVec3) -> DVec3 {
        if self.has_spec {
            self.spec * self.spec_shape(wi)
        } else {
            DVec3::ZERO
        }
    }

    /// The whole BRDF for the incident direction `wi` (unit).
    pub fn eval(&self, wi: DVec3) -> DVec3 {
        self.diffuse + self.specular(wi)
    }
}

/// Quadrature cells across the lobe's width: the cell rules' error falls
/// as the fourth power of cell size over lobe width (measured figures in
/// `docs/shading.md`).
pub(crate) const CELLS_PER_LOBE: f64 = 4.0;

/// Cells per radian the light subtends, whatever the lobe: `cos_p`, `cos_x`
/// and the distance vary across a large light too, and where the horizon
/// cuts it a cell is clipped (its lobe taken at one point).
pub(crate) const CELLS_PER_RADIAN: f64 = 9.0;

/// Cells per axis for integrating a lobe of exponent `ns` over a light
/// that subtends `extent` radians along that axis, from 1 to `max`.
///
/// The lobe `(n·h)^Ns` falls to `e^{-1/2}` about `1/√Ns` radians from its
/// peak in `h`, which is twice that in the incident direction: its width
/// in `wi` is taken as `2/√(Ns + 1)`.
pub(crate) fn lobe_cells(extent: f64, ns: f64, max: usize) -> usize {
    let width = 2.0 / (ns.max(0.0) + 1.0).sqrt();
    let n = (CELLS_PER_LOBE * extent / width)
        .max(CELLS_PER_RADIAN * extent)
        .ceil();
    if n.is_nan() {
        return max;
    }
    (n.min(max as f64) as usize).clamp(1, max)
}

/// Converts an `f64` radiance to `f32`, mapping anything non-finite or
/// negative (which the integrators never produce for valid input, but a
/// distance of 1e-40 could overflow `f32`) into `[0, f32::MAX]`.
pub(crate) fn to_vec3(c: DVec3) -> Vec3 {
    let f = |x: f64| -> f32 {
        if x.is_nan() || x <= 0.0 {
            0.0
        } else {
            x.min(f64::from(f32::MAX)) as f32
        }
    };
    Vec3::new(f(c.x), f(c.y), f(c.z))
}
