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
    hard_test, light_view_at, opaque_depth_map, pcf_visibility, pixel_rotation, project_receiver,
    DepthBias, Pcf,
};
use crate::shadow::ShadowContext;
use crate::simd::f64x4;
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
        self.consume_batch(&[map], pcf, active, state, per_receiver, |_, v, slot| {
            f(v, slot)
        });
    }

    /// [`MapSetup::consume`] of several maps in one pass over the
    /// receivers: each receiver is read once and `f(k, visibility, slot)`
    /// is called for map `k` of `maps`, in order. The hard test without a
    /// slope bias (the many-map techniques' default) runs four receivers
    /// at a time in f64 lanes ([`HardLanes`], the same bits as
    /// [`project_receiver`]); filters and the slope bias take the scalar
    /// path.
    pub fn consume_batch<T: Send>(
        &self,
        maps: &[Option<&RenderedMap>],
        pcf: Pcf,
        active: &[bool],
        state: &mut [T],
        per_receiver: usize,
        f: impl Fn(usize, f32, &mut [T]) + Sync,
    ) {
        let gb = self.ctx.gbuffer;
        let width = gb.width as usize;
        if width == 0 || per_receiver == 0 || maps.is_empty() {
            return;
        }
        let lanes: Option<Vec<Option<HardLanes>>> = (pcf == Pcf::Nearest && self.bias.slope == 0.0)
            .then(|| {
                maps.iter()
                    .map(|m| m.map(|m| HardLanes::new(&m.view, &self.bias)))
                    .collect()
            });
        state
            .par_chunks_mut(width * per_receiver)
            .enumerate()
            .for_each(|(y, row)| {
                let row_points = &self.points[y * width..(y + 1) * width];
                let row_active = &active[y * width..(y + 1) * width];
                if let Some(lanes) = &lanes {
                    for (c, slots) in row.chunks_mut(4 * per_receiver).enumerate() {
                        let x0 = 4 * c;
                        let count = slots.len() / per_receiver;
                        if !row_active[x0..x0 + count].iter().any(|&a| a) {
                            continue;
                        }
                        // Short chunks repeat their last receiver (ignored).
                        let at = |l: usize| row_points[x0 + l.min(count - 1)];
                        let quad = [at(0), at(1), at(2), at(3)];
                        for (k, (m, l)) in maps.iter().zip(lanes).enumerate() {
                            let v = match (m, l) {
                                (Some(m), Some(l)) => l.visibility(&m.map, &quad),
                                _ => [1.0; 4],
                            };
                            for (lane, slot) in slots.chunks_mut(per_receiver).enumerate() {
                                if row_active[x0 + lane] {
                                    f(k, v[lane], slot);
                                }
                            }
                        }
                    }
                    return;
                }
                for (x, slot) in row.chunks_mut(per_receiver).enumerate() {
                    if !row_active[x] {
                        continue;
                    }
                    let (position, geo_normal) = row_points[x];
                    let g = GSample {
                        position,
                        geo_normal,
                        ..GSample::BACKGROUND
                    };
                    for (k, map) in maps.iter().enumerate() {
                        let v = match map {
                            None => 1.0,
                            Some(m) => match project_receiver(&g, &m.view, &self.bias) {
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
                            },
                        };
                        f(k, v, slot);
                    }
                }
            });
    }
}

/// One map's receiver projection and hard test without a slope bias, four
/// receivers at a time: [`project_receiver`]'s arithmetic with the view's
/// constants hoisted, each step the same correctly rounded IEEE operation
/// in the same order on f64 lanes (no FMA, no reciprocal), so each lane
/// equals the scalar result to the bit. With a zero slope bias the scalar
/// code's slope term is `0 · texel · tan θ = +0` (both factors finite and
/// non-negative), so it is left out here. The depth after the normal
/// offset is the `z` the window projection divides by (the same
/// expression).
pub struct HardLanes {
    eye: [f64x4; 3],
    forward: [f64x4; 3],
    right: [f64x4; 3],
    up: [f64x4; 3],
    left: f64x4,
    span_x: f64x4,
    top: f64x4,
    span_y: f64x4,
    width: f64x4,
    height: f64x4,
    constant: f64x4,
    offset: f64x4,
}

impl HardLanes {
    /// The constants of `view` and `bias` (whose slope term is ignored:
    /// callers use this only when it is 0).
    pub fn new(view: &View, bias: &DepthBias) -> HardLanes {
        let v3 = |v: DVec3| [f64x4::splat(v.x), f64x4::splat(v.y), f64x4::splat(v.z)];
        let w = &view.window;
        HardLanes {
            eye: v3(view.eye),
            forward: v3(view.forward),
            right: v3(view.right),
            up: v3(view.up),
            left: f64x4::splat(w.left),
            span_x: f64x4::splat(w.right - w.left),
            top: f64x4::splat(w.top),
            span_y: f64x4::splat(w.top - w.bottom),
            width: f64x4::splat(f64::from(view.width)),
            height: f64x4::splat(f64::from(view.height)),
            constant: f64x4::splat(bias.constant),
            offset: f64x4::splat(bias.normal_offset),
        }
    }

    /// The hard-test visibility in `map` of four receivers `(position,
    /// geometric normal)`: 0 behind the view, else the texel's test.
    #[inline]
    pub fn visibility(&self, map: &DepthMap, quad: &[(Vec3, Vec3); 4]) -> [f32; 4] {
        let lane = |f: &dyn Fn(usize) -> f32| f64x4::new([0, 1, 2, 3].map(|l| f64::from(f(l))));
        let p = [
            lane(&|l| quad[l].0.x),
            lane(&|l| quad[l].0.y),
            lane(&|l| quad[l].0.z),
        ];
        let n = [
            lane(&|l| quad[l].1.x),
            lane(&|l| quad[l].1.y),
            lane(&|l| quad[l].1.z),
        ];
        let dot = |a: &[f64x4; 3], b: &[f64x4; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let sub = |a: &[f64x4; 3], b: &[f64x4; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let d0 = dot(&sub(&p, &self.eye), &self.forward);
        let texel = d0 * self.span_x / self.width;
        let s = self.offset * texel;
        let q = [p[0] + n[0] * s, p[1] + n[1] * s, p[2] + n[2] * s];
        let d = sub(&q, &self.eye);
        let z = dot(&d, &self.forward);
        let x = dot(&d, &self.right) / z;
        let y = dot(&d, &self.up) / z;
        let u = (x - self.left) / self.span_x * self.width;
        let v = (self.top - y) / self.span_y * self.height;
        let test = z - self.constant * z;
        let (d0, z) = (d0.to_array(), z.to_array());
        let (u, v, test) = (u.to_array(), v.to_array(), test.to_array());
        [0, 1, 2, 3].map(|l| {
            // `project_receiver`'s two refusals (NaN-safe: `!(x > 0)`).
            if !(d0[l] > 0.0 && z[l] > 0.0) {
                0.0
            } else {
                hard_test(map, u[l].floor() as i64, v[l].floor() as i64, test[l])
            }
        })
    }
}
