//! The interface every shadow technique implements, and the vocabulary
//! they describe themselves with: what a technique reads
//! ([`ShadowContext`]), returns ([`ShadowOutput`], one [`LightTerm`] per
//! light), can honour ([`Capabilities`]), costs ([`CostClass`]) and how it
//! is built and swept ([`TechniqueInfo`]). This file names no technique:
//! the list of techniques is [`super::registry`], which depends on it, and
//! never the other way round.

use super::kit::cache::ShadowCache;
use super::options::{OptionGroup, TechniqueOptions};
use crate::error::{Error, Result};
use crate::gbuffer::GBuffer;
use crate::geom::SceneGeometry;
use crate::observe::Observer;
use crate::output::Layer;
use crate::raster::Framebuffer;
use crate::sampling::SamplePattern;
use crate::scene::{LightShape, Scene};
use crate::shade::LightSample;
use crate::view::View;
use glam::Vec3;
use std::fmt;
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
    /// Who watches the render: the long passes poll
    /// [`Observer::cancelled`] between tiles and stop early (the render
    /// then discards everything).
    pub observer: &'a dyn Observer,
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
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
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
    /// Its per-sample decisions for `--verify` ([`super::verify`]), if it
    /// exposes them; `None` refuses `--verify` by name.
    fn sample_decisions(&self) -> Option<&dyn SampleDecisions> {
        None
    }
}

/// One pixel's per-sample decisions as the technique made them.
#[derive(Debug, Clone, PartialEq)]
pub struct PixelVisibility {
    /// Pixel index (row-major).
    pub pixel: usize,
    /// The light samples it used, in its sample order.
    pub samples: Vec<LightSample>,
    /// Its visibility `V·T` per sample (0 blocked, 1 visible).
    pub visibility: Vec<f64>,
}

/// A technique's per-sample decisions, for `--verify`.
pub trait SampleDecisions: Sync {
    /// The decisions of light `light` at `pixels` (sorted, no duplicates,
    /// surface pixels of shadow receivers); pixels the technique has no
    /// samples for may be left out.
    fn sample_visibility(
        &self,
        ctx: &ShadowContext,
        light: usize,
        pixels: &[usize],
    ) -> Result<Vec<PixelVisibility>>;
}

/// What a technique is built from: the render's sampling parameters and
/// every technique's options.
#[derive(Debug, Clone, Copy)]
pub struct BuildParams<'a> {
    /// Light samples per pixel and light.
    pub samples: u32,
    /// Seed of the per-pixel random numbers.
    pub seed: u64,
    /// Placement of light samples.
    pub pattern: SamplePattern,
    /// The techniques' own options.
    pub options: &'a TechniqueOptions,
}

/// How a technique handles one kind of scene content.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Support {
    /// Handled as the scene contract says.
    Yes,
    /// S-triangles only: shadowed by the shared soft-textured-shadow-volume
    /// add-on, which the render applies to the technique's Vcoef.
    StsvAddOn,
    /// Not handled, but the result is still meaningful without it: a
    /// warning, and an `--explain` note.
    Ignored(&'static str),
    /// Not handled: the render is refused with this reason, naming the
    /// parameter that asked for it.
    Refused {
        /// The parameter to change (`--technique`, `--coverage`, ...).
        param: &'static str,
        /// Why.
        why: &'static str,
    },
}

/// What shadow volumes and the wedge techniques built on their stencil
/// counts say of semi-opaque casters.
pub const OPAQUE_ONLY: Support = Support::Ignored(
    "it counts opaque occluders only; casters of constant opacity below 1 cast no shadow \
     here (use dcs or reference)",
);

/// What the shadow-map techniques say of semi-opaque casters.
pub const MAPS_OPAQUE_ONLY: Support = Support::Ignored(
    "the depth maps hold opaque casters only; casters of constant opacity below 1 cast no \
     shadow here (use dcs or reference)",
);

/// What the silhouette-based techniques say of a light inside a closed
/// caster.
pub const SILHOUETTES_MISS_ENCLOSURE: Support = Support::Refused {
    param: "--technique",
    why: "from inside a closed caster its edges are no silhouettes, so the shadow it casts on \
          everything outside it would be lost (use reference)",
};

/// What DCS says of a caster reaching into a light.
pub const COUNTS_MISS_REACHED_LIGHT: Support = Support::Refused {
    param: "--technique",
    why: "its counts start on the segment to the light's centre and its edges stop at the \
          light, so a caster part beyond the light's surface or inside its ball would be \
          counted as the shadow rays never see it (use penumbra-casting or reference, or move \
          the caster out of the light)",
};

/// What the shadow-map techniques say of a light inside a closed caster.
pub const MAPS_MISS_ENCLOSURE: Support = Support::Refused {
    param: "--technique",
    why: "a map from a point inside a closed caster cannot hold the casters all around it, so \
          the shadow it casts on everything outside it would be lost (use reference)",
};

/// What a technique returns per light.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TermKind {
    /// A visibility coefficient modulating the unshadowed light.
    Vcoef,
    /// Shadowed direct radiance it integrated itself (and its Vcoef).
    Radiance,
}

/// What a technique can honour, given its options.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Capabilities {
    /// Rectangular area lights.
    pub rect_lights: Support,
    /// Spherical lights.
    pub sphere_lights: Support,
    /// Lights with a radiance texture.
    pub textured_lights: Support,
    /// Lights inside (or touching) a closed caster
    /// ([`crate::shadow::kit::enclosure`]).
    pub enclosed_lights: Support,
    /// Lights a caster reaches into ([`crate::shadow::kit::enclosure::reached_lights`]).
    pub reached_lights: Support,
    /// Casters of constant opacity below 1.
    pub semi_opaque: Support,
    /// Casters with an opacity texture (S-triangles).
    pub s_triangles: Support,
    /// Its per-light result.
    pub output: TermKind,
    /// Per-sample visibility equals the shadow rays' (up to ties).
    pub exact: bool,
    /// The image converges to the contract's per-sample radiance: exact
    /// visibility, and each sample's light weighted by its own visibility
    /// (no Vcoef modulation of the unshadowed light, which is biased
    /// wherever the shadow and the light's shading vary together).
    pub exact_image: bool,
}

/// One quality setting of a technique in `compare`.
#[derive(Debug, Clone)]
pub struct QualitySetting {
    /// The curve it belongs to on the charts (the technique's name, plus
    /// a variant such as the silhouettes used).
    pub curve: String,
    /// Short label, e.g. `16 spp` or `hard`.
    pub label: String,
    /// Light samples, where the technique samples.
    pub samples: Option<u32>,
    /// Sample pattern.
    pub pattern: SamplePattern,
    /// The technique options of this setting.
    pub options: TechniqueOptions,
}

/// What `compare` sweeps a technique over.
#[derive(Debug, Clone, Copy)]
pub struct Sweep<'a> {
    /// Light-sample counts.
    pub samples: &'a [u32],
    /// Sample patterns (the first is the reference's).
    pub patterns: &'a [SamplePattern],
    /// The scene has semi-opaque casters.
    pub semi_opaque: bool,
    /// The options given on the command line.
    pub base: &'a TechniqueOptions,
}

impl Sweep<'_> {
    /// The first pattern (the reference's).
    pub fn first_pattern(&self) -> SamplePattern {
        self.patterns.first().copied().unwrap_or_default()
    }

    /// One setting of `curve` without light samples.
    pub fn single(&self, curve: &str, label: &str) -> QualitySetting {
        QualitySetting {
            curve: curve.into(),
            label: label.into(),
            samples: None,
            pattern: self.first_pattern(),
            options: self.base.clone(),
        }
    }

    /// One setting per sample count on `curve`, labelled `N spp{suffix}`,
    /// with `set` applied to the options.
    pub fn per_sample_count(
        &self,
        curve: &str,
        suffix: &str,
        pattern: SamplePattern,
        set: impl Fn(&mut TechniqueOptions),
    ) -> Vec<QualitySetting> {
        self.samples
            .iter()
            .map(|&n| {
                let mut options = self.base.clone();
                set(&mut options);
                QualitySetting {
                    curve: curve.into(),
                    label: format!("{n} spp{suffix}"),
                    samples: Some(n),
                    pattern,
                    options,
                }
            })
            .collect()
    }
}

/// A technique's description: everything the program needs to know of it.
pub struct TechniqueInfo {
    /// The command-line name.
    pub name: &'static str,
    /// One line for `penumbra techniques` and the docs table.
    pub summary: &'static str,
    /// Its module, for the docs table.
    pub module: &'static str,
    /// Its page under docs/algorithms, if it has one.
    pub page: Option<&'static str>,
    /// What it can honour with these options.
    pub capabilities: fn(&TechniqueOptions) -> Capabilities,
    /// Its settings in `compare`.
    pub quality_settings: fn(&Sweep) -> Vec<QualitySetting>,
    /// Builds it.
    pub build: fn(&BuildParams) -> Box<dyn ShadowTechnique>,
    /// Whether a band of the frame renders on its own (`render --tiles`).
    pub bands: Bands,
    /// The option groups it reads. The S-triangle add-on's (`--samples`,
    /// `--pattern`, `--seed` and the stsv options) come on top where it
    /// runs ([`super::registry::options_read`]).
    pub reads: &'static [OptionGroup],
    /// How its time grows with the light samples.
    pub cost: CostClass,
}

/// How a technique's time grows with the light samples: what `compare`
/// balances its shards by (only ratios matter, and never a timing).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CostClass {
    /// No per-sample work.
    Free,
    /// Each sample is rasterised, counted or looked up in a map.
    Raster,
    /// Each sample casts a shadow ray, which costs far more.
    Rays,
}

impl CostClass {
    /// Relative cost of one light sample at one pixel.
    pub fn per_sample(self) -> u64 {
        match self {
            CostClass::Free => 0,
            CostClass::Raster => 1,
            CostClass::Rays => 8,
        }
    }
}

/// Whether a technique can render one horizontal band of the frame on its
/// own, as `render --tiles` does ([`crate::cluster`]): the band's pixels
/// must come out as in a whole-frame render.
#[derive(Debug, Clone, Copy)]
pub enum Bands {
    /// Each pixel's result depends only on its own G-buffer sample, the
    /// scene and per-pixel-keyed samples: a band renders its own rows.
    Rows,
    /// Pixels depend on the square screen chunk they lie in, of this side
    /// in pixels with these options: a band is widened to whole chunks.
    Chunks(fn(&TechniqueOptions) -> u32),
    /// Cannot: a band's result depends on pixels outside it (why).
    Refused(&'static str),
}

/// Scene content a technique may not honour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneContent {
    /// A rectangular light.
    RectLight,
    /// A spherical light.
    SphereLight,
    /// A light with a radiance texture.
    TexturedLight,
    /// Casters of constant opacity below 1.
    SemiOpaqueCasters,
    /// Casters with an opacity texture.
    STriangles,
    /// A light inside or touching a closed caster.
    EnclosedLight,
    /// A light some caster reaches into.
    ReachedLight,
}

impl SceneContent {
    /// What it is, in words.
    pub fn describe(self) -> &'static str {
        match self {
            SceneContent::RectLight => "rect lights",
            SceneContent::SphereLight => "sphere lights",
            SceneContent::TexturedLight => "textured lights",
            SceneContent::SemiOpaqueCasters => "semi-opaque casters",
            SceneContent::STriangles => "opacity-textured casters (S-triangles)",
            SceneContent::EnclosedLight => "a light inside or touching a closed caster",
            SceneContent::ReachedLight => "a caster reaching into a light",
        }
    }
}

/// A warning of a render whose result is meaningful but not all the scene
/// asks for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Warning {
    /// The technique ignores some of the scene's content.
    Ignored {
        /// The technique.
        technique: &'static str,
        /// What it ignores.
        content: SceneContent,
        /// What happens instead and what to use.
        why: &'static str,
    },
    /// The scene renders (partly) black for a reason its author may not
    /// expect ([`crate::scene::lint`]).
    Scene(String),
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Warning::Ignored {
                technique,
                content,
                why,
            } => write!(
                f,
                "{}: NOT shadowed by `{technique}`: {why}",
                content.describe()
            ),
            Warning::Scene(message) => write!(f, "scene: {message}"),
        }
    }
}

/// Whether `scene` has casters of constant partial opacity.
pub fn has_semi_opaque_casters(scene: &Scene) -> bool {
    scene.objects.iter().any(|o| {
        o.cast_shadows
            && o.mesh.material_ids.iter().any(|&m| {
                scene.materials.get(m as usize).is_some_and(|m| {
                    m.opacity_texture.is_none() && m.opacity > 0.0 && m.opacity < 1.0
                })
            })
    })
}

/// Whether `scene` has shadow-casting triangles with an opacity texture.
pub fn has_s_triangles(scene: &Scene) -> bool {
    scene.objects.iter().any(|o| {
        o.cast_shadows
            && o.mesh.material_ids.iter().any(|&m| {
                scene
                    .materials
                    .get(m as usize)
                    .is_some_and(|m| m.opacity_texture.is_some())
            })
    })
}

/// Answers, from `technique`'s declared capabilities, whether it can
/// render `scene`: an error for content it refuses, a warning for content
/// it ignores. The same rule for every technique.
pub fn check_scene(
    technique: &TechniqueInfo,
    options: &TechniqueOptions,
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
) -> Result<Vec<Warning>> {
    let caps = (technique.capabilities)(options);
    let mut present = Vec::new();
    for light in &scene.lights {
        present.push(match light.shape {
            LightShape::Rect { .. } => (SceneContent::RectLight, caps.rect_lights),
            LightShape::Sphere { .. } => (SceneContent::SphereLight, caps.sphere_lights),
        });
        if light.texture.is_some() {
            present.push((SceneContent::TexturedLight, caps.textured_lights));
        }
    }
    if has_semi_opaque_casters(scene) {
        present.push((SceneContent::SemiOpaqueCasters, caps.semi_opaque));
    }
    if has_s_triangles(scene) {
        present.push((SceneContent::STriangles, caps.s_triangles));
    }
    // Only computed when it would change the answer.
    let mut enclosed = String::new();
    if caps.enclosed_lights != Support::Yes {
        if let Some(e) =
            crate::shadow::kit::enclosure::enclosed_lights(scene, geometry, view.eye).first()
        {
            enclosed = format!(" (light {} is in `{}`)", e.light, e.object);
            present.push((SceneContent::EnclosedLight, caps.enclosed_lights));
        }
    }
    let mut reached = String::new();
    if caps.reached_lights != Support::Yes {
        if let Some(e) = crate::shadow::kit::enclosure::reached_lights(scene, geometry).first() {
            reached = format!(" (`{}` reaches into light {})", e.object, e.light);
            present.push((SceneContent::ReachedLight, caps.reached_lights));
        }
    }
    let mut warnings = Vec::new();
    for (content, support) in present {
        match support {
            Support::Yes | Support::StsvAddOn => {}
            Support::Ignored(why) => {
                let w = Warning::Ignored {
                    technique: technique.name,
                    content,
                    why,
                };
                if !warnings.contains(&w) {
                    warnings.push(w);
                }
            }
            Support::Refused { param, why } => {
                return Err(Error::param(
                    param,
                    format!(
                        "`{}` cannot render {}{}: {why}",
                        technique.name,
                        content.describe(),
                        match content {
                            SceneContent::EnclosedLight => enclosed.as_str(),
                            SceneContent::ReachedLight => reached.as_str(),
                            _ => "",
                        }
                    ),
                ))
            }
        }
    }
    Ok(warnings)
}
