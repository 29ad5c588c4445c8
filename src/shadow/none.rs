//! `none`: no shadows, every light fully visible everywhere (the
//! unshadowed baseline every other technique is measured against).

use super::technique::{
    Bands, Capabilities, CostClass, LightTerm, ShadowContext, ShadowOutput, ShadowTechnique,
    Support, TechniqueInfo, TermKind,
};
use crate::error::Result;

/// No shadows: every light fully visible everywhere.
#[derive(Debug, Clone, Copy, Default)]
pub struct Unshadowed;

/// `none` in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "none",
    summary: "no shadows: every light fully visible (the unshadowed baseline)",
    module: "shadow/none.rs",
    page: None,
    // Ignoring every occluder is what `none` is asked for: nothing to warn.
    capabilities: |_| Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: Support::Yes,
        textured_lights: Support::Yes,
        enclosed_lights: Support::Yes,
        reached_lights: Support::Yes,
        semi_opaque: Support::Yes,
        s_triangles: Support::Yes,
        output: TermKind::Vcoef,
        exact: false,
        exact_image: false,
    },
    quality_settings: |s| vec![s.single("none", "unshadowed")],
    build: |_| Box::new(Unshadowed),
    // Per-pixel results from the pixel's own sample, the full-frame depth
    // buffer, the scene and per-pixel-keyed samples.
    bands: Bands::Rows,
    reads: &[],
    cost: CostClass::Free,
};

impl ShadowTechnique for Unshadowed {
    fn name(&self) -> &'static str {
        "none"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        let n = ctx.gbuffer.len();
        Ok(ShadowOutput {
            lights: ctx
                .scene
                .lights
                .iter()
                .map(|_| LightTerm::Vcoef(vec![1.0; n]))
                .collect(),
            ..ShadowOutput::default()
        })
    }
}
