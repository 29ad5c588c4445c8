//! Hard shadow volumes (thesis §2.2.1): per light, the volume of every
//! opaque caster from the light's centre, extruded to infinity and counted
//! in the 32-bit stencil with two-sided z-fail (default) or z-pass.
//!
//! Closed casters (every edge's face directions sum to zero) get the
//! classic volume: light-facing faces as the front cap, back-facing faces
//! at infinity as the back cap, and `m = Σ d` side quads per edge over the
//! light-facing faces using it. Open and non-manifold casters get
//! Bergeron's generalisation: every face is a two-sided occluder with its
//! own near and far caps, and each edge is extruded `m = Σ s·d` times
//! (s = ±1 the face's facing). The stencil then counts occluding layers;
//! zero means lit either way.

pub mod options;

use super::kit::timing::timed;
use super::kit::volumes::{build_volume, light_point, stencil_counts};
use super::technique::{Bands, Capabilities, Support, TechniqueInfo, TermKind};
use super::{LightTerm, ShadowContext, ShadowOutput, ShadowTechnique};
use crate::error::{Error, Result};
use crate::output::Layer;
pub use options::ShadowVolumeOptions;

/// Hard shadow volumes in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "shadow-volumes",
    summary: "hard shadow volumes from each light's centre: exact integer stencil counts, z-fail or z-pass (thesis §2.2.1)",
    module: "shadow/shadow_volumes/",
    page: Some("shadow-volumes.md"),
    capabilities: |_| Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: Support::Yes,
        textured_lights: Support::Yes,
        enclosed_lights: crate::shadow::technique::SILHOUETTES_MISS_ENCLOSURE,
        reached_lights: Support::Yes,
        semi_opaque: super::technique::OPAQUE_ONLY,
        s_triangles: Support::StsvAddOn,
        output: TermKind::Vcoef,
        exact: false,
        exact_image: false,
    },
    quality_settings: |s| {
        let label = if s.base.shadow_volumes.zpass {
            "hard (z-pass)"
        } else {
            "hard (z-fail)"
        };
        vec![s.single("shadow-volumes", label)]
    },
    build: |p| {
        Box::new(ShadowVolumes {
            zpass: p.options.shadow_volumes.zpass,
        })
    },
    // Per-pixel results from the pixel's own sample, the full-frame depth
    // buffer, the scene and per-pixel-keyed samples.
    bands: Bands::Rows,
    reads: {
        use crate::shadow::options::OptionGroup::*;
        &[ShadowVolumes]
    },
    cost: crate::shadow::technique::CostClass::Raster,
};

/// The hard-shadow technique.
#[derive(Debug, Clone, Copy, Default)]
pub struct ShadowVolumes {
    /// Count with z-pass (wrong when the camera is inside a volume)
    /// instead of z-fail.
    pub zpass: bool,
}

impl ShadowTechnique for ShadowVolumes {
    fn name(&self) -> &'static str {
        "shadow-volumes"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        let mut out = ShadowOutput::default();
        let adj = timed(&mut out.passes, "adjacency", || ctx.cache.casters());
        let mut framebuffer = ctx.depth.clone();
        let mut stencil_layer = Layer {
            name: "stencil".into(),
            channels: Vec::new(),
        };
        for (k, light) in ctx.scene.lights.iter().enumerate() {
            let volume = timed(&mut out.passes, format!("volume build light {k}"), || {
                build_volume(adj, ctx.view, light_point(&light.shape))
            });
            if self.zpass && !volume.eye_outside {
                // Z-pass counts wrongly wherever a volume reaches the eye
                // or the near plane; rather than a silently wrong image,
                // say so (z-fail, the default, is exact there).
                return Err(Error::param(
                    "--zpass",
                    format!(
                        "the eye may be inside the shadow volume of light {k} (or a volume \
                         reaches the near plane), where z-pass counts wrongly; use z-fail, \
                         the default"
                    ),
                ));
            }
            let counts = timed(&mut out.passes, format!("stencil light {k}"), || {
                stencil_counts(&mut framebuffer, &volume, self.zpass)
            })?;
            let vcoef = counts
                .iter()
                .enumerate()
                .map(|(i, &c)| {
                    if ctx.gbuffer.is_surface(i) && c == 0 {
                        1.0
                    } else {
                        0.0
                    }
                })
                .collect();
            stencil_layer
                .channels
                .push((k.to_string(), counts.iter().map(|&c| c as f32).collect()));
            out.lights.push(LightTerm::Vcoef(vcoef));
        }
        out.layers.push(stencil_layer);
        Ok(out)
    }
}
