//! Shading: direct lighting from area lights at one receiver point, per the
//! contract's "What the renderer computes"
//! (`L = Σ_lights ∫ Le f_r V T cos_p cos_x / r² dA`).
//!
//! Two entry points per light:
//!
//! - [`unshadowed_direct`]: the integral with `V = T = 1`, evaluated
//!   deterministically to near `f32` precision where a closed form exists
//!   (the Lambertian part of rect and sphere lights) and by a fixed
//!   quadrature where none does (the specular lobe, textured radiance
//!   finer than 16×16). Techniques that produce a visibility coefficient
//!   multiply it by this.
//! - [`direct_from_samples`]: the Monte-Carlo estimator over given light
//!   samples with per-sample visibility × transmittance, for techniques
//!   that integrate the full product per sample.
//!
//! Both are deterministic (no RNG, no threads, no fused multiply-add),
//! compute in `f64` internally and never return NaN or infinity.
//! `docs/shading.md` gives the formulas and the error of each
//! approximation.

#[forbid(unsafe_code)]
mod brdf;
mod estimate;
#[forbid(unsafe_code)]
mod rect;
#[forbid(unsafe_code)]
mod sphere;

#[forbid(unsafe_code)]
pub mod gather;

pub use brdf::brdf;

use crate::scene::{Light, LightShape, Texture};
use brdf::{lobe_cells, to_vec3, Lobe};
use estimate::estimate;
use glam::{DVec3, Vec2, Vec3};
use rect::{Grid, RectGeom};

/// What the shading stage knows about a visible point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// World-space position.
    pub p: Vec3,
    /// Shading normal: unit, flipped to face the viewer. This is the `n` of
    /// the contract's `cos_p = max(0, n·w)` and of the lobe's `n·h`.
    pub n: Vec3,
    /// Geometric normal: unit, facing the viewer. Shading does not use it
    /// (the contract's formula has only `n`); it is here for techniques
    /// that offset shadow rays or test light leaks.
    pub ng: Vec3,
    /// Unit direction toward the eye.
    pub wo: Vec3,
    /// Lambertian albedo (texture already applied), linear RGB.
    pub albedo: Vec3,
    /// Specular colour `Ks` of the normalised Blinn-Phong lobe.
    pub specular: Vec3,
    /// Blinn-Phong exponent `Ns` (negative values count as 0).
    pub shininess: f32,
}

/// One sample point on a light, for [`direct_from_samples`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LightSample {
    /// The point on the light's surface.
    pub x: Vec3,
    /// Rect lights: the texture coordinates `(s, t)` of `x`
    /// (`x = center + (2s − 1) u + (1 − 2t) v`), used to look up a light
    /// texture. Unused for sphere lights.
    pub st: Vec2,
    /// `1 / pdf(x)`, the pdf with respect to area on the light. For `N`
    /// uniformly distributed (or uniformly stratified) samples this is the
    /// light's area: `4 |u × v|` for a rect, `4π R²` for a sphere (samples
    /// on the far side of a sphere then contribute 0 through `cos_x`).
    pub inv_pdf_area: f32,
}

/// A light prepared for shading many points: the sub-rectangle grids of a
/// rect light (mean texel radiance per cell) are built once here instead
/// of on every call. Renderers should build one per light and frame.
#[derive(Debug, Clone)]
pub struct PreparedLight<'a> {
    light: &'a Light,
    texture: Option<&'a Texture>,
    kind: Kind,
}

#[derive(Debug, Clone)]
enum Kind {
    Rect {
        geom: RectGeom,
        radiance: DVec3,
        /// Textured lights: the cell grids, for the diffuse-only case and
        /// for when the lobe is integrated too. Untextured lights need no
        /// grid (every cell emits `radiance`) and size it per point.
        grids: Option<(Grid, Grid)>,
    },
    Sphere {
        center: DVec3,
        radius: f64,
    },
}

impl<'a> PreparedLight<'a> {
    /// Prepares `light`, whose texture index (if any) refers into
    /// `textures`. A texture index out of range, or a texture with no
    /// texels, counts as no texture (a validated scene has neither).
    pub fn new(light: &'a Light, textures: &'a [Texture]) -> Self {
        let texture = light_texture(light, textures);
        let radiance = light.radiance.as_dvec3();
        let kind = match light.shape {
            LightShape::Rect {
                center,
                u,
                v,
                two_sided,
            } => {
                let (u, v) = (u.as_dvec3(), v.as_dvec3());
                let geom = RectGeom {
                    center: center.as_dvec3(),
                    u,
                    v,
                    normal: u.cross(v).normalize_or_zero(),
                    two_sided,
                };
                let grids = texture.map(|t| {
                    let ((dx, dy), (sx, sy)) = rect::grid_sizes(t);
                    (
                        Grid::textured(dx, dy, radiance, t),
                        Grid::textured(sx, sy, radiance, t),
                    )
                });
                Kind::Rect {
                    geom,
                    radiance,
                    grids,
                }
            }
            LightShape::Sphere { center, radius } => Kind::Sphere {
                center: center.as_dvec3(),
                radius: radius.into(),
            },
        };
        PreparedLight {
            light,
            texture,
            kind,
        }
    }

    /// `∫_light Le f_r cos_p cos_x / r² dA` at `sp` with `V = T = 1`; see
    /// [`unshadowed_direct`].
    pub fn unshadowed_direct(&self, sp: &SurfacePoint) -> Vec3 {
        let lobe = Lobe::new(sp);
        let p = sp.p.as_dvec3();
        let out = match &self.kind {
            Kind::Rect {
                geom,
                radiance,
                grids,
            } => match grids {
                Some((diffuse, specular)) => {
                    let grid = if lobe.has_spec { specular } else { diffuse };
                    let le = |k: usize| grid.le[k];
                    rect::integrate(geom, (grid.nx, grid.ny), le, &lobe, p, lobe.has_spec)
                }
                None => {
                    let cells = if lobe.has_spec {
                        rect_lobe_cells(geom, p, lobe.shininess())
                    } else {
                        (1, 1)
                    };
                    rect::integrate(geom, cells, |_| *radiance, &lobe, p, lobe.has_spec)
                }
            },
            Kind::Sphere { center, radius } => sphere::integrate(
                *center,
                *radius,
                self.light.radiance.as_dvec3(),
                &lobe,
                p,
                lobe.has_spec,
            ),
        };
        to_vec3(out)
    }

    /// Whether the light has a texture (its radiance varies over it).
    pub fn is_textured(&self) -> bool {
        self.texture.is_some()
    }

    /// The emitted radiance at a sample, `Le(x)` (the light's radiance
    /// times its texel for a textured rect).
    pub fn sample_radiance(&self, sample: &LightSample) -> Vec3 {
        let le = self.light.radiance;
        match self.texture {
            Some(t) => le * t.texel_st(sample.st.x, sample.st.y),
            None => le,
        }
    }

    /// [`PreparedLight::direct_from_samples`] for an untextured rect
    /// light's samples at chart points `(xs, ys)`, sample `k` at
    /// `center + xs_k u + ys_k v` (padded to whole steps of eight),
    /// evaluated in f32 lanes: see `estimate::estimate_rect_chart`. `None`
    /// for a textured or sphere light, a receiver with a specular lobe, or
    /// one the lanes do not suit (take the samples' path there).
    pub fn direct_from_rect_chart(
        &self,
        sp: &SurfacePoint,
        chart: (&[f32], &[f32]),
        visibility: &[f32],
    ) -> Option<Vec3> {
        if self.texture.is_some() {
            return None;
        }
        estimate::estimate_rect_chart(self.light, sp, chart, visibility)
    }

    /// The Monte-Carlo estimate from given samples; see
    /// [`direct_from_samples`].
    pub fn direct_from_samples(
        &self,
        sp: &SurfacePoint,
        samples: &[LightSample],
        visibility: &[f32],
    ) -> Vec3 {
        estimate(self.light, self.texture, sp, samples, visibility)
    }
}

/// Unshadowed direct lighting: `∫_light Le(x) f_r(x → p → wo) cos_p cos_x
/// / |x − p|² dA(x)` with `V = T = 1`, `cos_p = max(0, n·w)`,
/// `cos_x = max(0, n_x·−w)` (`|n_x·−w|` for a two-sided rect).
///
/// - Rect, diffuse part: Lambert's closed form for the polygon clipped to
///   the receiver's hemisphere (exact for untextured lights; textured
///   lights are cut into up to 16×16 cells of mean texel radiance).
/// - Rect, specular lobe (only when `Ks ≠ 0`): a grid of cells, each's
///   exact clipped projected solid angle times the lobe's mean over it (a
///   centre-and-corners rule). Untextured lights size the grid per point
///   to the lobe's width and the light's angular size (1 to 16 per axis);
///   textured lights use up to 16×16 texel-aligned cells.
/// - Sphere: closed form for the diffuse part, horizon-crossing included;
///   the same kind of rule on up to 16×16 equal-solid-angle cone cells for
///   the lobe. Zero when `p` is inside or on the sphere (the contract
///   defines no value there).
///
/// A point behind a one-sided rect, or in its plane, receives 0.
///
/// This builds a [`PreparedLight`] on every call, which for a textured
/// light reads every texel: shade many points through
/// [`PreparedLight::unshadowed_direct`] instead.
pub fn unshadowed_direct(light: &Light, textures: &[Texture], sp: &SurfacePoint) -> Vec3 {
    PreparedLight::new(light, textures).unshadowed_direct(sp)
}

/// The Monte-Carlo estimator of the contract's direct lighting from light
/// samples with per-sample visibility × transmittance:
///
/// `L ≈ (1/N) Σ_k Le(x_k) f_r(w_k) cos_p cos_x / r_k² · inv_pdf_area_k · visibility_k`
///
/// with `N = samples.len()`, `Le(x_k) = radiance × texel(st_k)` for a
/// textured rect (nearest texel), `cos_x` as in [`unshadowed_direct`]
/// (`n_x = (x − center)/R` on a sphere). Unbiased whenever the samples are
/// distributed with the area pdf their weights state; with `visibility`
/// all 1 and stratified samples it converges to [`unshadowed_direct`].
/// Zero for `p` inside a sphere light, and for no samples.
///
/// # Panics
///
/// If `visibility.len() != samples.len()` (a caller bug, not bad input).
pub fn direct_from_samples(
    light: &Light,
    textures: &[Texture],
    sp: &SurfacePoint,
    samples: &[LightSample],
    visibility: &[f32],
) -> Vec3 {
    estimate(
        light,
        light_texture(light, textures),
        sp,
        samples,
        visibility,
    )
}

/// Cells per axis for the lobe on an untextured rect seen from `p`: the
/// angle each half-edge subtends from `p` (as if centred in front of it,
/// an upper bound; π when `p` is within reach of the light) against the
/// lobe's width.
fn rect_lobe_cells(geom: &RectGeom, p: DVec3, ns: f64) -> (usize, usize) {
    let dist = geom.center.distance(p);
    let extent = |half: DVec3| 2.0 * half.length().atan2(dist);
    (
        lobe_cells(extent(geom.u), ns, rect::MAX_GRID),
        lobe_cells(extent(geom.v), ns, rect::MAX_GRID),
    )
}

/// The light's texture, if it has a usable one.
fn light_texture<'a>(light: &Light, textures: &'a [Texture]) -> Option<&'a Texture> {
    match light.shape {
        LightShape::Rect { .. } => light
            .texture
            .and_then(|k| textures.get(k))
            .filter(|t| t.width > 0 && t.height > 0),
        // Version 1 of the contract has no sphere textures.
        LightShape::Sphere { .. } => None,
    }
}

/// Nearest texel at light coordinates `st` (clamped to the texture).
fn texel_at(t: &Texture, st: Vec2) -> DVec3 {
    let index = |x: f32, size: u32| -> usize {
        // NaN → 0 by `as`; clamp keeps s = 1 on the last texel.
        ((x.clamp(0.0, 1.0) * size as f32) as usize).min(size as usize - 1)
    };
    rect::texel(t, index(st.x, t.width), index(st.y, t.height))
}

/// The shading point of G-buffer sample `g` seen from `eye`, as the
/// shading pass builds it (material specular terms looked up; a material
/// index out of range counts as diffuse).
pub fn surface_point(
    scene: &crate::scene::Scene,
    g: &crate::gbuffer::GSample,
    eye: Vec3,
) -> SurfacePoint {
    let (specular, shininess) = scene
        .materials
        .get(g.material as usize)
        .map_or((Vec3::ZERO, 0.0), |m| (m.specular, m.shininess));
    SurfacePoint {
        p: g.position,
        n: g.normal,
        ng: g.geo_normal,
        wo: (eye - g.position).normalize_or_zero(),
        albedo: g.albedo,
        specular,
        shininess,
    }
}
