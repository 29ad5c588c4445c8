//! Hard shadow maps with percentage-closer filtering (Williams 1978;
//! Reeves et al. 1987): per light, one depth map of the opaque casters from
//! the light's centre, rendered by our rasterizer through a light view
//! ([`crate::shadow::kit::light_view`]), then a per-receiver look-up.
//!
//! Receivers are the G-buffer's exact points, projected into the light
//! view with the depth biases of [`crate::shadow::kit::shadow_maps`].
//!
//! PCF (`--pcf`): `1` one tap (the nearest texel), `2x2` the four nearest
//! texels weighted bilinearly (what shadow-map hardware filters), `3x3` a
//! box of nine, `poisson:N` N taps of a fixed Poisson disk of radius 1.5
//! texels rotated per pixel by the seeded per-pixel key.
//!
//! Semi-opaque casters are not in the map (the warning says so);
//! S-triangles are shadowed by the soft-textured-shadow-volume add-on.

use crate::error::Result;
use crate::shadow::kit::light_view::{fully_lit, map_bounds};
use crate::shadow::kit::map_fit::tight_light_view;
pub use crate::shadow::kit::shadow_maps::ShadowMapOptions;
use crate::shadow::kit::shadow_maps::{
    centre_point, opaque_depth_map, pcf_visibility, per_receiver, pixel_rotation, poisson_disk,
    project_receiver,
};
pub use crate::shadow::kit::shadow_maps::{Pcf, MAX_MAP_SIZE};
use crate::shadow::kit::PassTimer;
use crate::shadow::technique::{Bands, Capabilities, Support, TechniqueInfo, TermKind};
use crate::shadow::{BufferNote, LightTerm, ShadowContext, ShadowOutput, ShadowTechnique};

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
        enclosed_lights: crate::shadow::technique::MAPS_MISS_ENCLOSURE,
        reached_lights: Support::Yes,
        semi_opaque: crate::shadow::technique::MAPS_OPAQUE_ONLY,
        s_triangles: Support::StsvAddOn,
        output: TermKind::Vcoef,
        exact: false,
        exact_image: false,
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
    // Per-pixel results from the pixel's own sample, the full-frame depth
    // buffer, the scene and per-pixel-keyed samples.
    bands: Bands::Rows,
    reads: {
        use crate::shadow::options::OptionGroup::*;
        &[Seed, ShadowMaps]
    },
    cost: crate::shadow::technique::CostClass::Raster,
};

impl ShadowTechnique for ShadowMap {
    fn name(&self) -> &'static str {
        "shadow-map"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        let bias = self.options.bias();
        bias.validate()?;
        let mut out = ShadowOutput::default();
        let size = self.options.map_size;
        let n = ctx.gbuffer.len();
        // Nothing casts or nothing receives: every light fully visible.
        let Some((casters, receivers)) = map_bounds(ctx.scene) else {
            return Ok(fully_lit(ctx));
        };
        let pcf = self.options.pcf;
        let taps = match pcf {
            Pcf::Poisson(k) => poisson_disk(k, 1.5),
            _ => Vec::new(),
        };
        let width = ctx.gbuffer.width as usize;
        let mut rendered = 0;
        let mut peak = 0;
        for (k, light) in ctx.scene.lights.iter().enumerate() {
            let t = PassTimer::start(format!("shadow map light {k}"));
            let point = centre_point(light, casters);
            let lv = tight_light_view(ctx.scene, light, point, casters, receivers, (size, size))?;
            let Some(lv) = lv else {
                // No caster in front of the light: nothing to shadow.
                out.lights.push(LightTerm::Vcoef(vec![1.0; n]));
                t.finish(&mut out.passes);
                continue;
            };
            let map = opaque_depth_map(ctx.scene, ctx.geometry, &lv.view)?;
            rendered += 1;
            peak = peak.max(map.memory_bytes());
            t.finish(&mut out.passes);

            let t = PassTimer::start(format!("shadow map look-up light {k}"));
            let view = lv.view;
            let vcoef = per_receiver(ctx.gbuffer, width, |x, y, g| {
                // Behind the view or outside it: that point of the light
                // does not reach the receiver.
                let Some(r) = project_receiver(g, &view, &bias) else {
                    return 0.0;
                };
                let rotation = pixel_rotation(self.seed, k, x as u32, y as u32);
                pcf_visibility(&map, &r, pcf, &taps, rotation)
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
