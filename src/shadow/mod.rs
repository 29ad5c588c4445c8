//! Shadow techniques, all behind one interface.
//!
//! A technique receives the resolved G-buffer, the scene depth buffer and
//! the scene, and returns for each light either a visibility coefficient
//! per pixel (the shading stage multiplies the unshadowed direct light by
//! it) or the shadowed direct radiance it integrated itself per light
//! sample. It may add AOV layers of its own and reports its passes' times.

pub mod dcs;
pub mod light_view;
pub mod reference;
pub mod shadow_volumes;
pub mod stsv;
pub mod wedges;

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
}

/// A technique's result for one light, per pixel (row-major).
#[derive(Debug, Clone, Default)]
pub struct LightTerm {
    /// Visibility coefficient in [0, 1] per pixel (the `vcoef` AOV). When
    /// `radiance` is absent, shading multiplies the unshadowed direct light
    /// by it.
    pub vcoef: Option<Vec<f32>>,
    /// Shadowed direct radiance per pixel, integrated by the technique per
    /// light sample; shading uses it as is.
    pub radiance: Option<Vec<Vec3>>,
}

impl LightTerm {
    /// A visibility-coefficient-only term.
    pub fn vcoef(v: Vec<f32>) -> Self {
        LightTerm {
            vcoef: Some(v),
            radiance: None,
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
}

/// A shadow technique.
pub trait ShadowTechnique: Sync {
    /// Name as used on the command line.
    fn name(&self) -> &'static str;
    /// Computes the shadow term of every light.
    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput>;
}

/// No shadows: every light fully visible everywhere.
#[derive(Debug, Clone, Copy, Default)]
pub struct Unshadowed;

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
                .map(|_| LightTerm::vcoef(vec![1.0; n]))
                .collect(),
            ..ShadowOutput::default()
        })
    }
}
