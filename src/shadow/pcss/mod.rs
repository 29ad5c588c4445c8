//! Percentage-closer soft shadows (Fernando 2005, as in NVIDIA's
//! integration code): one hard map per light from its centre, then per
//! receiver a blocker search, the average blocker depth, the penumbra
//! width it implies, and a percentage-closer filter of that width.
//!
//! Depths `z` are along the map view's axis from its eye; for a rect light
//! the eye is the light's centre and the axis its normal, so `z` is the
//! distance from the light's plane, the quantity the similar-triangles
//! estimate needs. For a sphere light the eye is the surface point facing
//! the casters and the light is taken as a disk of its diameter through
//! its centre, `b` behind the eye along the axis: `z' = z + b`.
//!
//! With `h` the light's half-extent along a map axis (rect lights: per
//! axis, `|u·a| + |v·a|` for the map's right / up axis `a`, so `|u|` and
//! `|v|` for a rectangle; sphere lights: the radius on both), `z_r` the
//! receiver's depth, `z_s` the search plane (the nearest depth in the map)
//! and `z_b` the blockers' mean depth, in the map's tangent units:
//!
//! - search half-width `h · (z_r' − z_s') / (z_r' · z_s)`: the light seen
//!   from the receiver, cut by the search plane and projected from the
//!   eye (no caster is nearer to the light than `z_s`, so every caster
//!   that can occlude a point of the light lies in it);
//! - penumbra width on the receiver `w = (z_r' − z_b') · 2h / z_b'`
//!   (Fernando's estimate), filter half-width `(w / 2) / z_r`.
//!
//! Each tap is compared with the receiver's plane at the tap (the ray
//! through the tap meets the plane of the receiver's geometric normal),
//! not with the receiver's own depth: NVIDIA's receiver-plane depth bias,
//! exact, slope capped at 10 (`--pcss-flat-receiver` turns it off).
//!
//! Taps are a Poisson disk (`--pcss-kernel poisson`, rotated per pixel by
//! the seeded per-pixel key, the disk scaled per axis: an ellipse inscribed
//! in the light's rectangle) or a regular `k × k` grid over the whole
//! rectangle (`--pcss-kernel box`, `k = ⌈√N⌉`, not rotated: deterministic
//! and dense, the exact linear ramp of a straight edge).

pub mod options;

use crate::error::Result;
use crate::scene::{Light, LightShape};
use crate::shadow::kit::light_view::{fully_lit, map_bounds, DepthMap};
use crate::shadow::kit::map_fit::tight_light_view;
use crate::shadow::kit::shadow_maps::ShadowMapOptions;
use crate::shadow::kit::shadow_maps::{
    centre_point, hard_test, opaque_depth_map, per_receiver, pixel_rotation, poisson_disk,
    project_receiver, MapReceiver,
};
use crate::shadow::kit::PassTimer;
use crate::shadow::technique::{Bands, Capabilities, Support, TechniqueInfo, TermKind};
use crate::shadow::{BufferNote, LightTerm, ShadowContext, ShadowOutput, ShadowTechnique};
use crate::view::View;
use glam::DVec2;
pub use options::{PcssKernel, PcssOptions, MAX_PCSS_SAMPLES};

/// The PCSS technique.
#[derive(Debug, Clone, Copy)]
pub struct Pcss {
    /// The map's options (size, biases; `--pcf` is not used).
    pub map: ShadowMapOptions,
    /// PCSS's own.
    pub options: PcssOptions,
    /// Seed of the per-pixel rotation.
    pub seed: u64,
}

/// PCSS in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "pcss",
    summary: "percentage-closer soft shadows: one map from the light's centre, blocker search, penumbra estimate, variable-width PCF (Fernando 2005)",
    module: "shadow/pcss/",
    page: Some("shadow-maps.md"),
    capabilities: |_| Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: Support::Yes,
        textured_lights: Support::Yes,
        enclosed_lights: crate::shadow::technique::MAPS_MISS_ENCLOSURE,
        reached_lights: Support::Yes,
        semi_opaque: crate::shadow::technique::MAPS_OPAQUE_ONLY,
        s_triangles: Support::StsvAddOn,
        output: TermKind::Vcoef,
        exact: false,
        exact_image: false,
    },
    quality_settings: |s| {
        [(512u32, 16u32), (1024, 16), (1024, 32), (1024, 64), (2048, 64)]
            .into_iter()
            .map(|(size, n)| {
                let mut q = s.single("pcss", &format!("{size}² map, {n}/{n} taps"));
                q.options.shadow_map.map_size = size;
                q.options.pcss.pcss_blocker_samples = n;
                q.options.pcss.pcss_filter_samples = n;
                q
            })
            .collect()
    },
    build: |p| {
        Box::new(Pcss {
            map: p.options.shadow_map,
            options: p.options.pcss,
            seed: p.seed,
        })
    },
    // Per-pixel results from the pixel's own sample, the full-frame depth
    // buffer, the scene and per-pixel-keyed samples.
    bands: Bands::Rows,
    reads: {
        use crate::shadow::options::OptionGroup::*;
        &[Seed, ShadowMaps, Pcss]
    },
    cost: crate::shadow::technique::CostClass::Raster,
};

/// Unit taps of one stage: the Poisson disk of radius 1, or the regular
/// grid over `[-1, 1]²`.
fn unit_taps(kernel: PcssKernel, n: u32) -> Vec<DVec2> {
    match kernel {
        PcssKernel::Poisson => poisson_disk(n, 1.0),
        PcssKernel::Box => {
            let k = (f64::from(n).sqrt().ceil() as u32).max(1);
            let c = |i: u32| (f64::from(i) + 0.5) / f64::from(k) * 2.0 - 1.0;
            (0..k)
                .flat_map(|j| (0..k).map(move |i| DVec2::new(c(i), c(j))))
                .collect()
        }
    }
}

/// What one light's look-ups share.
struct LightSetup {
    /// Half-extent of the light along the map's right and up axes.
    half: DVec2,
    /// Texels per tangent unit along x and y.
    texels_per_tan: DVec2,
    /// Distance from the eye back to the plane the light is taken in.
    back: f64,
    /// The search plane: the nearest depth in the map.
    search_plane: f64,
}

impl LightSetup {
    fn new(light: &Light, view: &View, map: &DepthMap) -> LightSetup {
        let (half, back) = match light.shape {
            LightShape::Rect { u, v, .. } => {
                let (u, v) = (u.as_dvec3(), v.as_dvec3());
                let along = |a| u.dot(a).abs() + v.dot(a).abs();
                (DVec2::new(along(view.right), along(view.up)), 0.0)
            }
            LightShape::Sphere { center, radius } => (
                DVec2::splat(f64::from(radius)),
                // The eye is on the surface, the axis toward the casters:
                // the centre is behind it, never in front.
                (view.eye - center.as_dvec3()).dot(view.forward).max(0.0),
            ),
        };
        let w = &view.window;
        let texels_per_tan = DVec2::new(
            f64::from(view.width) / (w.right - w.left),
            f64::from(view.height) / (w.top - w.bottom),
        );
        // Every stored depth is beyond the near plane (> 0), so is the
        // minimum; the near plane also stands in for an empty map.
        let nearest = map
            .as_slice()
            .iter()
            .fold(f32::INFINITY, |m, &d| if d < m { d } else { m });
        let search_plane = if nearest.is_finite() {
            f64::from(nearest).max(view.near)
        } else {
            view.near
        };
        LightSetup {
            half,
            texels_per_tan,
            back,
            search_plane,
        }
    }
}

/// The receiver's plane seen from the map's eye (NVIDIA's receiver-plane
/// depth bias, exact instead of a depth gradient): the depth along the
/// map's axis where the ray through map position `q` (texels) meets the
/// plane through the (normal-offset) receiver point with its geometric
/// normal, minus the receiver's own bias. Taps compare against it, so a
/// receiver's own tilted surface around it is not taken for a blocker.
#[derive(Clone, Copy)]
struct ReceiverPlane {
    /// `n · (p − eye)`.
    k: f64,
    /// `n` in the map's frame (right, up, forward).
    n: [f64; 3],
    /// Window left / top and tangent units per texel along x and y.
    origin: DVec2,
    per_texel: DVec2,
    /// `depth − test_depth` of the receiver.
    bias: f64,
    /// The receiver's depth, where the plane gives no depth.
    flat: f64,
    /// The receiver's map position, depth and texel footprint.
    uv: DVec2,
    depth: f64,
    texel: f64,
}

/// Largest depth change per unit of lateral distance the receiver's
/// plane is extrapolated with (the slope-scaled bias's `tan θ` cap).
const MAX_PLANE_SLOPE: f64 = 10.0;

impl ReceiverPlane {
    fn new(g: &crate::gbuffer::GSample, view: &View, r: &MapReceiver, normal_offset: f64) -> Self {
        let p = g.position.as_dvec3();
        let n = g.geo_normal.as_dvec3();
        // As `project_receiver` moves the receiver: `normal_offset` texels
        // of the footprint at its depth before the offset.
        let texel0 =
            view.depth_of(p) * (view.window.right - view.window.left) / f64::from(view.width);
        let p = p + n * (normal_offset * texel0);
        let w = &view.window;
        ReceiverPlane {
            k: n.dot(p - view.eye),
            n: [n.dot(view.right), n.dot(view.up), n.dot(view.forward)],
            origin: DVec2::new(w.left, w.top),
            per_texel: DVec2::new(
                (w.right - w.left) / f64::from(view.width),
                (w.top - w.bottom) / f64::from(view.height),
            ),
            bias: r.depth - r.test_depth,
            flat: r.test_depth,
            uv: r.uv,
            depth: r.depth,
            texel: r.texel,
        }
    }

    /// The biased depth the receiver's plane has at map position `q`.
    #[inline]
    fn test_depth(&self, q: DVec2) -> f64 {
        let x = self.origin.x + q.x * self.per_texel.x;
        let y = self.origin.y - q.y * self.per_texel.y;
        let z = self.k / (self.n[2] + x * self.n[0] + y * self.n[1]);
        // Edge-on or behind the eye at that tap: no plane depth there.
        if !(z > 0.0 && z.is_finite()) {
            return self.flat;
        }
        // The slope capped as the slope-scaled bias caps it (tan θ ≤ 10):
        // a near-grazing plane extrapolated over a wide kernel would put
        // its depth far behind any surface.
        let reach = MAX_PLANE_SLOPE * (q - self.uv).length() * self.texel;
        let z = z.clamp(self.depth - reach, self.depth + reach);
        z - self.bias
    }
}

/// PCSS visibility of receiver `r` in `map`, in [0, 1]: blocker search
/// with `search` taps, penumbra estimate, filter with `filter` taps, both
/// rotated by `rotation` (unit taps; see [`unit_taps`]).
fn pcss_visibility(
    map: &DepthMap,
    setup: &LightSetup,
    r: &MapReceiver,
    search: &[DVec2],
    filter: &[DVec2],
    rotation: Option<(f64, f64)>,
    plane: Option<&ReceiverPlane>,
) -> f32 {
    let zr = r.depth;
    let zs = setup.search_plane;
    // A receiver nearer than every caster has nothing between it and the
    // light (this also keeps every division below away from zero).
    if !(zr > zs) {
        return 1.0;
    }
    let b = setup.back;
    let place = |t: &DVec2, radius: DVec2| {
        let t = match rotation {
            Some((s, c)) => DVec2::new(c * t.x - s * t.y, s * t.x + c * t.y),
            None => *t,
        };
        // Map texels: tangent up is image y down.
        DVec2::new(r.uv.x + t.x * radius.x, r.uv.y - t.y * radius.y)
    };
    let per_tan = setup.texels_per_tan;
    let search_tan = (zr - zs) / ((zr + b) * zs);
    let search_radius = setup.half * per_tan * search_tan;
    let (mut sum, mut count) = (0.0f64, 0u32);
    for t in search {
        let q = place(t, search_radius);
        let (x, y) = (q.x.floor(), q.y.floor());
        if x < 0.0 || y < 0.0 || x >= f64::from(map.width) || y >= f64::from(map.height) {
            continue;
        }
        let d = map.get(x as u32, y as u32);
        let test = plane.map_or(r.test_depth, |p| p.test_depth(q));
        if !(test as f32 <= d) {
            sum += f64::from(d);
            count += 1;
        }
    }
    if count == 0 {
        return 1.0;
    }
    // Blockers are nearer than the receiver and beyond the near plane, so
    // `zb` is in (0, zr): the width is finite and non-negative.
    let zb = (sum / f64::from(count)).clamp(zs, zr);
    let filter_tan = (zr - zb) / ((zb + b) * zr);
    let filter_radius = setup.half * per_tan * filter_tan;
    let mut lit = 0.0f32;
    for t in filter {
        let q = place(t, filter_radius);
        let test = plane.map_or(r.test_depth, |p| p.test_depth(q));
        lit += hard_test(map, q.x.floor() as i64, q.y.floor() as i64, test);
    }
    lit / filter.len() as f32
}

impl ShadowTechnique for Pcss {
    fn name(&self) -> &'static str {
        "pcss"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        let bias = self.map.bias();
        bias.validate()?;
        self.options.validate()?;
        let mut out = ShadowOutput::default();
        let size = self.map.map_size;
        let n = ctx.gbuffer.len();
        // Nothing casts or nothing receives: every light fully visible.
        let Some((casters, receivers)) = map_bounds(ctx.scene) else {
            return Ok(fully_lit(ctx));
        };
        let kernel = self.options.pcss_kernel;
        let receiver_plane = !self.options.pcss_flat_receiver;
        let search = unit_taps(kernel, self.options.pcss_blocker_samples);
        let filter = unit_taps(kernel, self.options.pcss_filter_samples);
        let width = ctx.gbuffer.width as usize;
        let mut rendered = 0;
        let mut peak = 0;
        for (k, light) in ctx.scene.lights.iter().enumerate() {
            let t = PassTimer::start(format!("pcss map light {k}"));
            let point = centre_point(light, casters);
            let Some(lv) =
                tight_light_view(ctx.scene, light, point, casters, receivers, (size, size))?
            else {
                out.lights.push(LightTerm::Vcoef(vec![1.0; n]));
                t.finish(&mut out.passes);
                continue;
            };
            let map = opaque_depth_map(ctx.scene, ctx.geometry, &lv.view)?;
            rendered += 1;
            peak = peak.max(map.memory_bytes());
            t.finish(&mut out.passes);

            let t = PassTimer::start(format!("pcss look-up light {k}"));
            let view = lv.view;
            let setup = LightSetup::new(light, &view, &map);
            let vcoef = per_receiver(ctx.gbuffer, width, |x, y, g| {
                // Behind the map's eye or outside its window: not lit from
                // the centre's hemisphere (as shadow-map).
                let Some(r) = project_receiver(g, &view, &bias) else {
                    return 0.0;
                };
                let rotation = match kernel {
                    PcssKernel::Poisson => {
                        Some(pixel_rotation(self.seed, k, x as u32, y as u32).sin_cos())
                    }
                    PcssKernel::Box => None,
                };
                let plane =
                    receiver_plane.then(|| ReceiverPlane::new(g, &view, &r, bias.normal_offset));
                pcss_visibility(&map, &setup, &r, &search, &filter, rotation, plane.as_ref())
            });
            t.finish(&mut out.passes);
            out.lights.push(LightTerm::Vcoef(vcoef));
        }
        out.buffers.push(BufferNote {
            name: "shadow maps".into(),
            detail: format!(
                "{rendered} rendered, one at a time ({size}² texels, f32 linear depth along the \
                 light view's axis: the blocker average and the penumbra estimate need linear \
                 depth); {} blocker-search and {} filter taps",
                search.len(),
                filter.len()
            ),
            bytes: peak,
        });
        Ok(out)
    }
}
