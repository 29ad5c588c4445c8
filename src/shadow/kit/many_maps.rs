//! What the many-map techniques (multi-map, adaptive maps) share: the point
//! of a light a unit sample `(s, t)` stands for, which receivers get map
//! work, one hard map rendered and consumed by every receiver, and the
//! exact integer accumulation of weighted per-map visibilities.
//!
//! Maps are rendered one at a time and dropped once every receiver has
//! read it: memory does not grow with the number of maps. Per-map
//! visibilities are quantised to `1/QSCALE` and summed, with integer
//! weights, in a `u64` per receiver: the sum does not depend on the order
//! the maps were rendered in, so two techniques that render the same maps
//! in different orders agree to the bit (the adaptive subdivision forced to
//! split everywhere and the 17 × 17 multi-map).

use crate::error::Result;
use crate::gbuffer::{GBuffer, GSample};
use crate::scene::{Light, LightShape, Scene};
use crate::shadow::kit::light_view::{Bounds, DepthMap};
use crate::shadow::kit::shadow_maps::{
    light_view_at, opaque_depth_map, pcf_visibility, pixel_rotation, project_receiver, DepthBias,
    Pcf,
};
use crate::shadow::ShadowContext;
use crate::view::View;
use glam::{DVec2, DVec3, Vec3};
use rayon::prelude::*;

/// Quantisation of one map's visibility: `round(v · QSCALE)`. Hard tests
/// (0 or 1) are exact; a PCF value moves by at most `1 / (2 QSCALE)`
/// (7.6e-6, below the f32 Vcoef's own step near 1 only by a factor 128).
pub const QSCALE: u64 = 65535;

/// `v ∈ [0, 1]` quantised to `0..=QSCALE`.
#[inline]
pub fn quantize(v: f32) -> u64 {
    (f64::from(v.clamp(0.0, 1.0)) * QSCALE as f64).round() as u64
}

/// The Vcoef of an accumulated receiver: `acc / (total · QSCALE)`, one
/// IEEE division of two integers (exact in f64 below 2^53, so a sum with
/// all weights equal to `w` gives the same bits as with all weights 1).
#[inline]
pub fn resolve(acc: u64, total_weight: u64) -> f32 {
    if total_weight == 0 {
        return 0.0;
    }
    (acc as f64 / (total_weight as f64 * QSCALE as f64)) as f32
}

/// The point on `light` that unit sample `(s, t)` stands for, the same for
/// every receiver.
///
/// - **Rect**: `center + (2s − 1) u + (1 − 2t) v`, the sampling module's
///   mapping (so `(0, 0)`, `(1, 0)`, `(0, 1)`, `(1, 1)` are the corners).
/// - **Sphere**: a receiver-independent stand-in (the reference samples
///   the cone each receiver sees): `(s, t)` mapped to the unit disc by the
///   concentric map (area-uniform), placed on the sphere's great disc
///   facing the centre of the casters' bounds and lifted onto the facing
///   hemisphere. Seen from far along that axis the lifted points are
///   area-uniform over the sphere's silhouette; closer receivers see them
///   foreshortened.
pub fn point_on_light(light: &Light, (s, t): (f64, f64), casters: Bounds) -> Vec3 {
    match light.shape {
        LightShape::Rect { center, u, v, .. } => {
            let (c, u, v) = (center.as_dvec3(), u.as_dvec3(), v.as_dvec3());
            (c + u * (2.0 * s - 1.0) + v * (1.0 - 2.0 * t)).as_vec3()
        }
        LightShape::Sphere { center, radius } => {
            let c = center.as_dvec3();
            let target = (0.5 * (casters.0 + casters.1)).as_dvec3();
            let w = (target - c).normalize_or(DVec3::NEG_Y);
            let (t1, t2) = w.any_orthonormal_pair();
            let (a, b) = concentric(2.0 * s - 1.0, 2.0 * t - 1.0);
            let h = (1.0 - a * a - b * b).max(0.0).sqrt();
            (c + (t1 * a + t2 * b + w * h) * f64::from(radius)).as_vec3()
        }
    }
}

/// Shirley and Chiu's concentric map of `[−1, 1]²` onto the unit disc.
fn concentric(x: f64, y: f64) -> (f64, f64) {
    if x == 0.0 && y == 0.0 {
        return (0.0, 0.0);
    }
    let q = std::f64::consts::FRAC_PI_4;
    let (r, phi) = if x.abs() > y.abs() {
        (x, q * (y / x))
    } else {
        (y, 2.0 * q - q * (x / y))
    };
    (r * phi.cos(), r * phi.sin())
}

/// Which pixels of the G-buffer get map work for `light`: surface points
/// whose geometric normal faces some point of the light (a rect light's
/// four corners span it; a sphere light's centre within its radius).
/// Receivers facing away from the whole light receive nothing from it and
/// get Vcoef 0 without a map look-up.
pub fn active_receivers(gbuffer: &GBuffer, light: &Light) -> Vec<bool> {
    let corners: Vec<DVec3> = match light.shape {
        LightShape::Rect { center, u, v, .. } => {
            let (c, u, v) = (center.as_dvec3(), u.as_dvec3(), v.as_dvec3());
            vec![c + u + v, c + u - v, c - u + v, c - u - v]
        }
        LightShape::Sphere { .. } => Vec::new(),
    };
    (0..gbuffer.len())
        .into_par_iter()
        .map(|i| {
            let g = gbuffer.sample(i);
            if !g.is_surface() {
                return false;
            }
            let (p, n) = (g.position.as_dvec3(), g.geo_normal.as_dvec3());
            match light.shape {
                LightShape::Rect { .. } => corners.iter().any(|&c| n.dot(c - p) > 0.0),
                LightShape::Sphere { center, radius } => {
                    n.dot(center.as_dvec3() - p) > -f64::from(radius)
                }
            }
        })
        .collect()
}

/// What every map of one light is rendered and read with.
pub struct MapSetup<'a, 'b> {
    /// The render's context.
    pub ctx: &'a ShadowContext<'b>,
    /// Light index.
    pub light: usize,
    /// Casters' bounds (the frusta are fitted to them).
    pub casters: Bounds,
    /// Receivers' bounds.
    pub receivers: Bounds,
    /// Texels per side.
    pub size: u32,
    /// Depth biases.
    pub bias: DepthBias,
    /// Seed of the per-pixel Poisson rotation.
    pub seed: u64,
    /// Poisson taps, when a filter needs them.
    pub taps: Vec<DVec2>,
    /// Per pixel the receiver's position and geometric normal, expanded
    /// from the G-buffer once rather than once per map.
    pub points: &'a [(Vec3, Vec3)],
}

/// One rendered map and its view; `None`: nothing of the casters is in
/// front of the point (it shadows nothing).
pub struct RenderedMap {
    /// The light view's camera.
    pub view: View,
    /// Linear depth of the opaque casters.
    pub map: DepthMap,
}

/// Per pixel `(position, geometric normal)`, what a map look-up reads.
pub fn receiver_points(gbuffer: &GBuffer) -> Vec<(Vec3, Vec3)> {
    (0..gbuffer.len())
        .into_par_iter()
        .map(|i| {
            let g = gbuffer.sample(i);
            (g.position, g.geo_normal)
        })
        .collect()
}

impl MapSetup<'_, '_> {
    /// The scene.
    pub fn scene(&self) -> &Scene {
        self.ctx.scene
    }

    /// Renders the opaque casters' map from `point` on the light.
    pub fn render(&self, point: Vec3) -> Result<Option<RenderedMap>> {
        let light = &self.scene().lights[self.light];
        let Some(lv) = light_view_at(
            light,
            point,
            self.casters,
            self.receivers,
            (self.size, self.size),
        )?
        else {
            return Ok(None);
        };
        let map = opaque_depth_map(self.ctx.scene, self.ctx.geometry, &lv.view)?;
        Ok(Some(RenderedMap { view: lv.view, map }))
    }

    /// Reads `map` at every active receiver with filter `pcf` and calls
    /// `f(visibility, slot)` with the receiver's `per_receiver` entries of
    /// `state` (row-parallel; each receiver's slot is touched by one
    /// thread). A receiver behind the view or outside its window gets 0
    /// (that point of the light does not reach it); `map = None` (nothing
    /// in front of the point) gives 1.
    pub fn consume<T: Send>(
        &self,
        map: Option<&RenderedMap>,
        pcf: Pcf,
        active: &[bool],
        state: &mut [T],
        per_receiver: usize,
        f: impl Fn(f32, &mut [T]) + Sync,
    ) {
        let gb = self.ctx.gbuffer;
        let width = gb.width as usize;
        if width == 0 || per_receiver == 0 {
            return;
        }
        state
            .par_chunks_mut(width * per_receiver)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, slot) in row.chunks_mut(per_receiver).enumerate() {
                    let i = y * width + x;
                    if !active[i] {
                        continue;
                    }
                    let v = match map {
                        None => 1.0,
                        Some(m) => {
                            let (position, geo_normal) = self.points[i];
                            let g = GSample {
                                position,
                                geo_normal,
                                ..GSample::BACKGROUND
                            };
                            match project_receiver(&g, &m.view, &self.bias) {
                                None => 0.0,
                                Some(r) => {
                                    let rotation = match pcf {
                                        Pcf::Poisson(_) => pixel_rotation(
                                            self.seed, self.light, x as u32, y as u32,
                                        ),
                                        _ => 0.0,
                                    };
                                    pcf_visibility(&m.map, &r, pcf, &self.taps, rotation)
                                }
                            }
                        }
                    };
                    f(v, slot);
                }
            });
    }
}
