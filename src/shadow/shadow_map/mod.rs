//! Hard shadow maps with percentage-closer filtering (Williams 1978;
//! Reeves et al. 1987): per light, one depth map of the opaque casters from
//! the light's centre, rendered by our rasterizer through a light view
//! ([`crate::shadow::kit::light_view`]), then a per-receiver look-up.
//!
//! Receivers are the G-buffer's exact points, so the "reprojection" is a
//! projection of each receiver into the light view, not a second camera
//! pass. The map stores linear f32 depth along the light view's axis (see
//! [`DepthMap`]); a receiver at depth `d` is lit by a tap when
//! `d − bias ≤ stored`, with
//!
//! - a constant bias, relative to the depth (`--depth-bias`, a fraction of
//!   `d`: f32 depth has constant relative precision, so an absolute bias
//!   would be too large near the light and too small far away);
//! - a slope-scaled bias (`--slope-bias`, in texels): the depth change
//!   across one texel on the receiver's plane, `texel · tan θ` with `θ`
//!   the angle between the geometric normal and the direction to the light;
//! - a normal offset (`--normal-offset`, in texels): the receiver moved
//!   along its geometric normal by that many texel footprints before it is
//!   projected.
//!
//! PCF (`--pcf`): `1` one tap (the nearest texel), `2x2` the four nearest
//! texels weighted bilinearly (what shadow-map hardware filters), `3x3` a
//! box of nine, `poisson:N` N taps of a fixed Poisson disk of radius 1.5
//! texels rotated per pixel by the seeded per-pixel key.
//!
//! Semi-opaque casters are not in the map (the warning says so);
//! S-triangles are shadowed by the soft-textured-shadow-volume add-on.

use crate::error::{Error, Result};
use crate::gbuffer::GSample;
use crate::scene::{Light, LightShape};
use crate::shadow::kit::light_view::{
    caster_bounds, depth_map, receiver_bounds, DepthMap, LightView,
};
use crate::shadow::kit::PassTimer;
use crate::shadow::registry::{Capabilities, Support, TechniqueInfo, TermKind};
use crate::shadow::{BufferNote, LightTerm, ShadowContext, ShadowOutput, ShadowTechnique};
use glam::{DVec2, Vec3};
use rayon::prelude::*;
use std::fmt;
use std::str::FromStr;

/// The percentage-closer filter of the map look-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Pcf {
    /// One tap: the texel holding the receiver's projection.
    #[default]
    Nearest,
    /// The four nearest texels, weighted bilinearly.
    Bilinear2x2,
    /// A 3×3 box of texels around the nearest.
    Box3x3,
    /// `n` taps of a Poisson disk (radius 1.5 texels), rotated per pixel.
    Poisson(u32),
}

impl FromStr for Pcf {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Pcf, String> {
        match s.trim() {
            "1" | "none" => Ok(Pcf::Nearest),
            "2x2" => Ok(Pcf::Bilinear2x2),
            "3x3" => Ok(Pcf::Box3x3),
            other => {
                let n = other
                    .strip_prefix("poisson:")
                    .and_then(|n| n.parse::<u32>().ok())
                    .ok_or_else(|| {
                        format!("unknown filter `{other}` (known: 1, 2x2, 3x3, poisson:N)")
                    })?;
                if n == 0 || n > 256 {
                    return Err(format!("poisson:{n}: N must be in 1..=256"));
                }
                Ok(Pcf::Poisson(n))
            }
        }
    }
}

impl fmt::Display for Pcf {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Pcf::Nearest => f.write_str("1"),
            Pcf::Bilinear2x2 => f.write_str("2x2"),
            Pcf::Box3x3 => f.write_str("3x3"),
            Pcf::Poisson(n) => write!(f, "poisson:{n}"),
        }
    }
}

/// Largest map side `--map-size` accepts (the light view's own limit).
pub const MAX_MAP_SIZE: u32 = 16384;

/// Shadow maps' command-line options.
#[derive(Debug, Clone, Copy, PartialEq, clap::Args)]
pub struct ShadowMapOptions {
    /// Shadow maps: texels per side of each light's depth map.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=MAX_MAP_SIZE as i64))]
    pub map_size: u32,
    /// Shadow maps: percentage-closer filter, 1 | 2x2 | 3x3 | poisson:N.
    #[arg(long, default_value = "1")]
    pub pcf: Pcf,
    /// Shadow maps: constant depth bias, a fraction of the receiver's depth.
    #[arg(long, default_value_t = 1e-4)]
    pub depth_bias: f64,
    /// Shadow maps: slope-scaled depth bias, in texels.
    #[arg(long, default_value_t = 1.0)]
    pub slope_bias: f64,
    /// Shadow maps: normal offset of the receiver, in texels.
    #[arg(long, default_value_t = 1.0)]
    pub normal_offset: f64,
}

impl Default for ShadowMapOptions {
    /// The command line's defaults.
    fn default() -> Self {
        crate::shadow::TechniqueOptions::default().shadow_map
    }
}

impl ShadowMapOptions {
    fn validate(&self) -> Result<()> {
        for (name, v, max) in [
            ("--depth-bias", self.depth_bias, 1.0),
            ("--slope-bias", self.slope_bias, 1e3),
            ("--normal-offset", self.normal_offset, 1e3),
        ] {
            if !(v >= 0.0 && v <= max) {
                return Err(Error::param(name, format!("{v} is outside 0..={max}")));
            }
        }
        Ok(())
    }
}

/// The hard shadow-map technique.
#[derive(Debug, Clone, Copy)]
pub struct ShadowMap {
    /// Its options.
    pub options: ShadowMapOptions,
    /// Seed of the per-pixel Poisson rotation.
    pub seed: u64,
}

/// Hard shadow maps in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "shadow-map",
    summary: "one hard shadow map per light from its centre, depth bias and optional PCF (the image-based baseline)",
    module: "shadow/shadow_map/",
    page: Some("shadow-maps.md"),
    capabilities: |_| Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: Support::Yes,
        textured_lights: Support::Yes,
        semi_opaque: Support::Ignored(
            "the depth map holds opaque casters only; casters of constant opacity below 1 \
             cast no shadow here (use dcs or reference)",
        ),
        s_triangles: Support::StsvAddOn,
        output: TermKind::Vcoef,
        exact: false,
    },
    quality_settings: |s| {
        let pcf = s.base.shadow_map.pcf;
        [256u32, 512, 1024, 2048]
            .into_iter()
            .map(|size| {
                let mut q = s.single("shadow-map", &format!("{size}² map, pcf {pcf}"));
                q.options.shadow_map.map_size = size;
                q
            })
            .collect()
    },
    build: |p| {
        Box::new(ShadowMap {
            options: p.options.shadow_map,
            seed: p.seed,
        })
    },
};

/// The point a light's map is rendered from: a rect light's centre; for a
/// sphere light the point of its surface facing the casters' bounds.
fn map_point(light: &Light, casters: (Vec3, Vec3)) -> Vec3 {
    match light.shape {
        LightShape::Rect { center, .. } => center,
        LightShape::Sphere { center, radius } => {
            let target = 0.5 * (casters.0 + casters.1);
            let d = (target - center).normalize_or(Vec3::NEG_Y);
            center + d * radius
        }
    }
}

/// Poisson-disk taps of radius 1.5 texels: dart throwing with a fixed seed,
/// the same disk for every pixel (rotated per pixel).
fn poisson_disk(n: u32) -> Vec<DVec2> {
    let mut state = 0x9e37_79b9_7f4a_7c15u64 ^ u64::from(n);
    let mut next = || {
        state = crate::sampling::mix64(state.wrapping_add(0x9e37_79b9_7f4a_7c15));
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let radius = 1.5;
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

impl ShadowMap {
    /// Visibility of one receiver from one light's map, in [0, 1].
    fn visibility(
        &self,
        g: &GSample,
        view: &crate::view::View,
        map: &DepthMap,
        taps: &[DVec2],
        rotation: f64,
    ) -> f32 {
        let o = &self.options;
        let p = g.position.as_dvec3();
        let n = g.geo_normal.as_dvec3();
        let to_light = (view.eye - p).normalize_or_zero();
        let d0 = view.depth_of(p);
        if !(d0 > 0.0) {
            // Behind the light's view: its hemisphere does not reach it.
            return 0.0;
        }
        // World size of one texel at the receiver's depth.
        let texel = d0 * (view.window.right - view.window.left) / f64::from(view.width);
        let p = p + n * (o.normal_offset * texel);
        let Some(uv) = view.pixel_of(p) else {
            return 0.0;
        };
        let d = view.depth_of(p);
        let cos = n.dot(to_light).abs().clamp(1e-3, 1.0);
        let tan = (1.0 - cos * cos).sqrt() / cos;
        let bias = o.depth_bias * d + o.slope_bias * texel * tan.min(10.0);
        let test = |x: i64, y: i64| -> f32 {
            // Outside the map: the frustum holds every caster, so nothing
            // there occludes.
            if x < 0 || y < 0 || x >= i64::from(map.width) || y >= i64::from(map.height) {
                return 1.0;
            }
            let stored = map.get(x as u32, y as u32);
            if (d - bias) as f32 <= stored {
                1.0
            } else {
                0.0
            }
        };
        let (fx, fy) = (uv.x.floor() as i64, uv.y.floor() as i64);
        match o.pcf {
            Pcf::Nearest => test(fx, fy),
            Pcf::Box3x3 => {
                let mut sum = 0.0;
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        sum += test(fx + dx, fy + dy);
                    }
                }
                sum / 9.0
            }
            Pcf::Bilinear2x2 => {
                let (sx, sy) = (uv.x - 0.5, uv.y - 0.5);
                let (x0, y0) = (sx.floor(), sy.floor());
                let (tx, ty) = ((sx - x0) as f32, (sy - y0) as f32);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let top = test(x0, y0) * (1.0 - tx) + test(x0 + 1, y0) * tx;
                let bottom = test(x0, y0 + 1) * (1.0 - tx) + test(x0 + 1, y0 + 1) * tx;
                top * (1.0 - ty) + bottom * ty
            }
            Pcf::Poisson(_) => {
                let (s, c) = rotation.sin_cos();
                let mut sum = 0.0;
                for t in taps {
                    let q = DVec2::new(c * t.x - s * t.y, s * t.x + c * t.y);
                    let (x, y) = ((uv.x + q.x).floor(), (uv.y + q.y).floor());
                    sum += test(x as i64, y as i64);
                }
                sum / taps.len() as f32
            }
        }
    }
}

impl ShadowTechnique for ShadowMap {
    fn name(&self) -> &'static str {
        "shadow-map"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        self.options.validate()?;
        let mut out = ShadowOutput::default();
        let size = self.options.map_size;
        let n = ctx.gbuffer.len();
        let (Some(casters), Some(receivers)) =
            (caster_bounds(ctx.scene), receiver_bounds(ctx.scene))
        else {
            // Nothing casts or nothing receives: every light fully visible.
            out.lights = ctx
                .scene
                .lights
                .iter()
                .map(|_| LightTerm::Vcoef(vec![1.0; n]))
                .collect();
            return Ok(out);
        };
        let geometry = ctx.geometry;
        let opaque_caster = |t: u32| {
            let object = &ctx.scene.objects[geometry.triangle_object[t as usize] as usize];
            let material = &ctx.scene.materials[geometry.triangle_material[t as usize] as usize];
            object.cast_shadows && material.is_opaque()
        };
        let taps = match self.options.pcf {
            Pcf::Poisson(k) => poisson_disk(k),
            _ => Vec::new(),
        };
        let width = ctx.gbuffer.width as usize;
        let mut rendered = 0;
        let mut peak = 0;
        for (k, light) in ctx.scene.lights.iter().enumerate() {
            let t = PassTimer::start(format!("shadow map light {k}"));
            let point = map_point(light, casters);
            let lv = match light.shape {
                LightShape::Rect { .. } => {
                    LightView::from_rect_light(light, point, casters, receivers, (size, size))?
                }
                LightShape::Sphere { .. } => {
                    LightView::from_sphere_light(light, point, casters, receivers, (size, size))?
                }
            };
            let Some(lv) = lv else {
                // No caster in front of the light: nothing to shadow.
                out.lights.push(LightTerm::Vcoef(vec![1.0; n]));
                t.finish(&mut out.passes);
                continue;
            };
            let map = depth_map(geometry, opaque_caster, &lv.view)?;
            rendered += 1;
            peak = peak.max(map.memory_bytes());
            t.finish(&mut out.passes);

            let t = PassTimer::start(format!("shadow map look-up light {k}"));
            let view = lv.view;
            let mut vcoef = vec![0.0f32; n];
            vcoef
                .par_chunks_mut(width.max(1))
                .enumerate()
                .for_each(|(y, row)| {
                    for (x, v) in row.iter_mut().enumerate() {
                        let g = ctx.gbuffer.sample(y * width + x);
                        if !g.is_surface() {
                            continue;
                        }
                        let key = crate::sampling::pixel_key(self.seed, k, (x as u32, y as u32));
                        let rotation =
                            (key >> 11) as f64 / (1u64 << 53) as f64 * std::f64::consts::TAU;
                        *v = self.visibility(&g, &view, &map, &taps, rotation);
                    }
                });
            t.finish(&mut out.passes);
            out.lights.push(LightTerm::Vcoef(vcoef));
        }
        out.buffers.push(BufferNote {
            name: "shadow maps".into(),
            detail: format!(
                "{rendered} rendered, one at a time ({size}² texels, f32 linear depth along the \
                 light view's axis: compared with the receiver's own depth and filtered, both \
                 meaningful for linear depth; f32 keeps constant relative precision)"
            ),
            bytes: peak,
        });
        Ok(out)
    }
}
