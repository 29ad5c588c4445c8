//! Shadow techniques, all behind one interface.
//!
//! A technique receives the resolved G-buffer, the scene depth buffer and
//! the scene, and returns for each light either a visibility coefficient
//! per pixel (the shading stage multiplies the unshadowed direct light by
//! it) or the shadowed direct radiance it integrated itself per light
//! sample. It may add AOV layers of its own and reports its passes' times.

pub mod adaptive_maps;
pub mod dcs;
pub mod kit;
pub mod multi_map;
pub mod pcss;
pub mod penumbra_casting;
pub mod reference;
pub mod registry;
pub mod shadow_map;
pub mod shadow_volumes;
pub mod soft_shadow_map;

pub mod wedges;

pub use kit::cache::ShadowCache;
pub use registry::{Technique, TechniqueOptions, Warning};

use crate::error::Result;
use crate::gbuffer::GBuffer;
use crate::geom::SceneGeometry;
use crate::output::Layer;
use crate::raster::Framebuffer;
use crate::scene::Scene;
use crate::view::View;
use glam::Vec3;
use std::time::Duration;

/// What a technique may read.
#[derive(Clone, Copy)]
pub struct ShadowContext<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// All triangles, concatenated.
    pub geometry: &'a SceneGeometry,
    /// The camera for this image.
    pub view: &'a View,
    /// The shading points.
    pub gbuffer: &'a GBuffer,
    /// The scene's depth (and stencil) after the G-buffer pass.
    pub depth: &'a Framebuffer,
    /// What several techniques and lights derive from the scene, computed
    /// once per render on first use.
    pub cache: &'a ShadowCache<'a>,
}

/// A technique's result for one light, per pixel (row-major).
#[derive(Debug, Clone, PartialEq)]
pub enum LightTerm {
    /// A visibility coefficient in [0, 1] per pixel (the `vcoef` AOV);
    /// shading multiplies the unshadowed direct light by it.
    Vcoef(Vec<f32>),
    /// Shadowed direct radiance per pixel, integrated by the technique per
    /// light sample (shading uses it as is), with the visibility
    /// coefficient it measured on the way (the `vcoef` AOV).
    Radiance {
        /// Shadowed direct radiance.
        radiance: Vec<Vec3>,
        /// Visibility coefficient.
        vcoef: Vec<f32>,
    },
}

impl LightTerm {
    /// The visibility coefficient per pixel.
    pub fn vcoef(&self) -> &[f32] {
        match self {
            LightTerm::Vcoef(v) | LightTerm::Radiance { vcoef: v, .. } => v,
        }
    }

    /// The integrated radiance, for techniques that integrate it.
    pub fn radiance(&self) -> Option<&[Vec3]> {
        match self {
            LightTerm::Vcoef(_) => None,
            LightTerm::Radiance { radiance, .. } => Some(radiance),
        }
    }
}

/// Wall-clock time of one named pass.
#[derive(Debug, Clone)]
pub struct PassTiming {
    /// Pass name, e.g. `gbuffer`, `stencil light 0`.
    pub name: String,
    /// Wall-clock duration.
    pub time: Duration,
}

/// One buffer (or pass) a render used, for `--explain`.
#[derive(Debug, Clone, PartialEq)]
pub struct BufferNote {
    /// What it is, e.g. `counters light 0`.
    pub name: String,
    /// Precision and why, or why it was left out.
    pub detail: String,
    /// Peak bytes it held (0 when left out).
    pub bytes: u64,
}

/// Everything a technique returns.
#[derive(Debug, Clone, Default)]
pub struct ShadowOutput {
    /// The buffers it allocated and the ones it left out, with sizes.
    pub buffers: Vec<BufferNote>,
    /// One term per light, in light order.
    pub lights: Vec<LightTerm>,
    /// Technique-specific AOV layers.
    pub layers: Vec<Layer>,
    /// Its passes, in execution order.
    pub passes: Vec<PassTiming>,
    /// What the result leaves out of the scene (the render adds those its
    /// capabilities declare).
    pub warnings: Vec<Warning>,
}

/// A shadow technique.
pub trait ShadowTechnique: Sync {
    /// Name as used on the command line.
    fn name(&self) -> &'static str;
    /// Computes the shadow term of every light.
    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput>;
    /// Its per-sample decisions for `--verify` ([`kit::verify`]), if it
    /// exposes them; `None` refuses `--verify` by name.
    fn sample_decisions(&self) -> Option<&dyn kit::verify::SampleDecisions> {
        None
    }
}

/// No shadows: every light fully visible everywhere.
#[derive(Debug, Clone, Copy, Default)]
pub struct Unshadowed;

/// `none` in the technique registry.
pub static UNSHADOWED: registry::TechniqueInfo = registry::TechniqueInfo {
    name: "none",
    summary: "no shadows: every light fully visible (the unshadowed baseline)",
    module: "shadow/mod.rs",
    page: None,
    // Ignoring every occluder is what `none` is asked for: nothing to warn.
    capabilities: |_| registry::Capabilities {
        rect_lights: registry::Support::Yes,
        sphere_lights: registry::Support::Yes,
        textured_lights: registry::Support::Yes,
        enclosed_lights: registry::Support::Yes,
        reached_lights: registry::Support::Yes,
        semi_opaque: registry::Support::Yes,
        s_triangles: registry::Support::Yes,
        output: registry::TermKind::Vcoef,
        exact: false,
        exact_image: false,
    },
    quality_settings: |s| vec![s.single("none", "unshadowed")],
    build: |_| Box::new(Unshadowed),
    // Per-pixel results from the pixel's own sample, the full-frame depth
    // buffer, the scene and per-pixel-keyed samples.
    bands: registry::Bands::Rows,
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

/// Runs `technique` on `ctx` the way every render does: checks the scene
/// against its declared capabilities (refusing, or warning), computes it,
/// and applies the shared add-ons it declares (soft textured shadow
/// volumes for S-triangles).
pub fn run_technique(
    technique: Technique,
    params: &registry::BuildParams,
    ctx: &ShadowContext,
) -> Result<ShadowOutput> {
    let warnings =
        registry::check_scene(technique, params.options, ctx.scene, ctx.geometry, ctx.view)?;
    let built = technique.build(params);
    let mut out = built.compute(ctx)?;
    if technique.capabilities(params.options).s_triangles == registry::Support::StsvAddOn {
        let sampling = kit::stsv::StsvSampling {
            samples: params.samples,
            seed: params.seed,
            pattern: params.pattern,
            filter: params.options.stsv.opacity_filter,
        };
        kit::stsv::addon::apply(ctx, technique.name(), sampling, &mut out)?;
    }
    out.warnings.extend(warnings);
    Ok(out)
}
