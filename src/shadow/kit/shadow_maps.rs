//! Shared machinery of the shadow-map techniques (hard maps, PCSS,
//! multi-map, adaptive maps, soft shadow maps): the opaque-caster filter,
//! the view a map is rendered through, the receiver's projection with its
//! depth bias, the hard depth test and percentage-closer filters.
//!
//! Receivers are the G-buffer's exact points, so the "reprojection" of a
//! classic shadow map is a projection of each receiver into the light view,
//! not a second camera pass. Maps hold linear f32 depth along the light
//! view's axis ([`DepthMap`]); a receiver at depth `d` is lit by a tap when
//! `d − bias ≤ stored`, with
//!
//! - a constant bias relative to the depth (`--depth-bias`, a fraction of
//!   `d`: f32 depth has constant relative precision, so an absolute bias
//!   would be too large near the light and too small far away);
//! - a slope-scaled bias (`--slope-bias`, in texels): the depth change
//!   across one texel on the receiver's plane, `texel · tan θ` with `θ` the
//!   angle between the geometric normal and the direction to the light;
//! - a normal offset (`--normal-offset`, in texels): the receiver moved
//!   along its geometric normal by that many texel footprints before it is
//!   projected.

pub use super::map_options::{DepthBias, Pcf, ShadowMapOptions, MAX_MAP_SIZE};
use crate::error::Result;
use crate::gbuffer::{GBuffer, GSample};
use crate::geom::SceneGeometry;
use crate::scene::{Light, LightShape, Scene};
use crate::shadow::kit::light_view::{depth_map, Bounds, DepthMap, LightView};
use crate::view::View;
use glam::{DVec2, Vec3};
use rayon::prelude::*;

/// Whether triangle `t` is in the maps: an opaque caster (casters of
/// constant opacity below 1 are not; S-triangles are, as opaque, and the
/// soft-textured-shadow-volume add-on handles their texture).
pub fn opaque_caster<'a>(
    scene: &'a Scene,
    geometry: &'a SceneGeometry,
) -> impl Fn(u32) -> bool + Sync + 'a {
    move |t: u32| {
        let object = &scene.objects[geometry.triangle_object[t as usize] as usize];
        let material = &scene.materials[geometry.triangle_material[t as usize] as usize];
        object.cast_shadows && material.is_opaque()
    }
}

/// The point a light's single map is rendered from: a rect light's centre;
/// for a sphere light the point of its surface facing the casters' bounds.
pub fn centre_point(light: &Light, casters: Bounds) -> Vec3 {
    match light.shape {
        LightShape::Rect { center, .. } => center,
        LightShape::Sphere { center, radius } => {
            let target = 0.5 * (casters.0 + casters.1);
            let d = (target - center).normalize_or(Vec3::NEG_Y);
            center + d * radius
        }
    }
}

/// The light view from `point` (on the light) fitted to the casters the
/// receivers can see, `size` texels; `Ok(None)` when nothing of the casters
/// is in front of the point.
pub fn light_view_at(
    light: &Light,
    point: Vec3,
    casters: Bounds,
    receivers: Bounds,
    size: (u32, u32),
) -> Result<Option<LightView>> {
    match light.shape {
        LightShape::Rect { .. } => {
            LightView::from_rect_light(light, point, casters, receivers, size)
        }
        LightShape::Sphere { .. } => {
            LightView::from_sphere_light(light, point, casters, receivers, size)
        }
    }
}

/// The opaque casters' depth map from `view` (see [`DepthMap`]).
pub fn opaque_depth_map(scene: &Scene, geometry: &SceneGeometry, view: &View) -> Result<DepthMap> {
    depth_map(geometry, opaque_caster(scene, geometry), view)
}

/// A receiver projected into a map's view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapReceiver {
    /// Its position in texels (continuous; texel `(x, y)` covers
    /// `[x, x+1) × [y, y+1)`).
    pub uv: DVec2,
    /// Its depth along the view's axis after the normal offset, before the
    /// bias.
    pub depth: f64,
    /// The depth it is compared with: `depth − bias`.
    pub test_depth: f64,
    /// World size of one texel at its depth.
    pub texel: f64,
}

/// One map look-up pass over the image: `visibility(x, y, receiver)` for
/// every surface pixel, 0 for the background (it has no light term). Rows
/// go to rayon's workers; each pixel is written by one call whatever the
/// split, so the result does not depend on the thread count.
pub fn per_receiver(
    gbuffer: &GBuffer,
    width: usize,
    visibility: impl Fn(usize, usize, &GSample) -> f32 + Sync,
) -> Vec<f32> {
    let mut vcoef = vec![0.0f32; gbuffer.len()];
    vcoef
        .par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, v) in row.iter_mut().enumerate() {
                let g = gbuffer.sample(y * width + x);
                if g.is_surface() {
                    *v = visibility(x, y, &g);
                }
            }
        });
    vcoef
}

/// Projects receiver `g` into `view` with the biases applied; `None` when
/// it is behind the view's eye or outside its window (the light's
/// hemisphere from that point does not reach it: unlit by that point).
pub fn project_receiver(g: &GSample, view: &View, bias: &DepthBias) -> Option<MapReceiver> {
    let p = g.position.as_dvec3();
    let n = g.geo_normal.as_dvec3();
    let to_light = (view.eye - p).normalize_or_zero();
    let d0 = view.depth_of(p);
    if !(d0 > 0.0) {
        return None;
    }
    let texel = d0 * (view.window.right - view.window.left) / f64::from(view.width);
    let p = p + n * (bias.normal_offset * texel);
    let uv = view.pixel_of(p)?;
    let depth = view.depth_of(p);
    let cos = n.dot(to_light).abs().clamp(1e-3, 1.0);
    let tan = (1.0 - cos * cos).sqrt() / cos;
    let b = bias.constant * depth + bias.slope * texel * tan.min(10.0);
    Some(MapReceiver {
        uv,
        depth,
        test_depth: depth - b,
        texel,
    })
}

/// The hard depth test of one texel: 1 lit, 0 shadowed. Outside the map is
/// lit: the frustum holds every caster, so nothing there occludes.
#[inline]
pub fn hard_test(map: &DepthMap, x: i64, y: i64, test_depth: f64) -> f32 {
    if x < 0 || y < 0 || x >= i64::from(map.width) || y >= i64::from(map.height) {
        return 1.0;
    }
    if test_depth as f32 <= map.get(x as u32, y as u32) {
        1.0
    } else {
        0.0
    }
}

/// The per-pixel rotation angle of Poisson taps, from the seeded per-pixel
/// key of light `light` at pixel `(x, y)`.
pub fn pixel_rotation(seed: u64, light: usize, x: u32, y: u32) -> f64 {
    let key = crate::sampling::pixel_key(seed, light, (x, y));
    (key >> 11) as f64 / (1u64 << 53) as f64 * std::f64::consts::TAU
}

/// Percentage-closer filtered visibility of `r` in `map`, in [0, 1].
/// `taps` are the Poisson disk's (in texels, [`poisson_disk`]) when `pcf`
/// is [`Pcf::Poisson`]; `rotation` rotates them.
pub fn pcf_visibility(
    map: &DepthMap,
    r: &MapReceiver,
    pcf: Pcf,
    taps: &[DVec2],
    rotation: f64,
) -> f32 {
    let (uv, d) = (r.uv, r.test_depth);
    let (fx, fy) = (uv.x.floor() as i64, uv.y.floor() as i64);
    match pcf {
        Pcf::Nearest => hard_test(map, fx, fy, d),
        Pcf::Box3x3 => {
            let mut sum = 0.0;
            for dy in -1..=1 {
                for dx in -1..=1 {
                    sum += hard_test(map, fx + dx, fy + dy, d);
                }
            }
            sum / 9.0
        }
        Pcf::Bilinear2x2 => {
            let (sx, sy) = (uv.x - 0.5, uv.y - 0.5);
            let (x0, y0) = (sx.floor(), sy.floor());
            let (tx, ty) = ((sx - x0) as f32, (sy - y0) as f32);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let top = hard_test(map, x0, y0, d) * (1.0 - tx) + hard_test(map, x0 + 1, y0, d) * tx;
            let bottom =
                hard_test(map, x0, y0 + 1, d) * (1.0 - tx) + hard_test(map, x0 + 1, y0 + 1, d) * tx;
            top * (1.0 - ty) + bottom * ty
        }
        Pcf::Poisson(_) => {
            let (s, c) = rotation.sin_cos();
            let mut sum = 0.0;
            for t in taps {
                let q = DVec2::new(c * t.x - s * t.y, s * t.x + c * t.y);
                let (x, y) = ((uv.x + q.x).floor(), (uv.y + q.y).floor());
                sum += hard_test(map, x as i64, y as i64, d);
            }
            sum / taps.len() as f32
        }
    }
}

/// `n` Poisson-disk taps in a disk of `radius`: dart throwing with a fixed
/// seed, the same disk for every pixel (callers rotate it per pixel).
pub fn poisson_disk(n: u32, radius: f64) -> Vec<DVec2> {
    let mut state = crate::sampling::GOLDEN ^ u64::from(n);
    let mut next = || {
        // Each draw is one SplitMix64 step from the previous draw (not one
        // stream): the taps, and so the images, stay as they were.
        state = crate::sampling::SplitMix64::new(state).next_u64();
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let min_dist = radius * (0.75 / f64::from(n)).sqrt();
    let mut taps: Vec<DVec2> = Vec::new();
    let mut tries = 0;
    while taps.len() < n as usize {
        let p = DVec2::new(next() * 2.0 - 1.0, next() * 2.0 - 1.0) * radius;
        tries += 1;
        if p.length() > radius {
            continue;
        }
        // Give up on the spacing after many tries: N taps are promised.
        if tries < 10_000 && taps.iter().any(|q| q.distance(p) < min_dist) {
            continue;
        }
        taps.push(p);
    }
    taps
}
