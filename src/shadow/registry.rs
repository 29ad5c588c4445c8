//! The technique registry: every shadow technique describes itself once —
//! name, one-line summary, options, capabilities, quality settings for
//! `compare`, and how it is built — and `render`, `compare`, `--explain`,
//! the CLI help and `penumbra techniques` all read it from here.
//!
//! Adding a technique is one folder under `src/shadow/` that exports a
//! [`TechniqueInfo`] static, one line in [`TECHNIQUES`] and, if it has
//! options of its own, one flattened field in [`TechniqueOptions`]
//! (see docs/architecture.md, "How to add a technique").

use super::adaptive_maps::AdaptiveMapsOptions;
use super::dcs::DcsOptions;
use super::kit::stsv::StsvOptions;
use super::pcss::PcssOptions;
use super::penumbra_casting::PenumbraCastingOptions;
use super::shadow_map::ShadowMapOptions;
use super::shadow_volumes::ShadowVolumeOptions;
use super::soft_shadow_map::SsmOptions;
use super::ShadowTechnique;
use crate::error::{Error, Result};
use crate::geom::SceneGeometry;
use crate::sampling::SamplePattern;
use crate::scene::{LightShape, Scene};
use crate::view::View;
use std::fmt;

/// Every technique, in the order `penumbra techniques` and the docs list
/// them.
pub static TECHNIQUES: &[&TechniqueInfo] = &[
    &super::UNSHADOWED,
    &super::reference::TECHNIQUE,
    &super::shadow_volumes::TECHNIQUE,
    &super::wedges::TECHNIQUE,
    &super::wedges::blend::TECHNIQUE,
    &super::dcs::TECHNIQUE,
    &super::shadow_map::TECHNIQUE,
    &super::pcss::TECHNIQUE,
    &super::multi_map::TECHNIQUE,
    &super::adaptive_maps::TECHNIQUE,
    &super::soft_shadow_map::TECHNIQUE,
    &super::penumbra_casting::TECHNIQUE,
];

/// The name `render` uses when no `--technique` is given: exact depth
/// complexity sampling, the exact soft-shadow technique.
pub const DEFAULT_TECHNIQUE: &str = "dcs";

/// Every technique's own options, flattened into `render` and `compare`.
/// One field per technique that has options.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct TechniqueOptions {
    /// Hard shadow volumes.
    #[command(flatten, next_help_heading = "Shadow volumes")]
    pub shadow_volumes: ShadowVolumeOptions,
    /// Depth complexity sampling.
    #[command(flatten, next_help_heading = "DCS")]
    pub dcs: DcsOptions,
    /// Shadow maps.
    #[command(flatten, next_help_heading = "Shadow maps")]
    pub shadow_map: ShadowMapOptions,
    /// Percentage-closer soft shadows (with the shadow-map options).
    #[command(flatten, next_help_heading = "PCSS")]
    pub pcss: PcssOptions,
    /// Adaptive light-source sampling (the map options are the shadow
    /// maps').
    #[command(flatten, next_help_heading = "Adaptive maps")]
    pub adaptive_maps: AdaptiveMapsOptions,
    /// Soft shadow maps.
    #[command(flatten, next_help_heading = "Soft shadow maps")]
    pub ssm: SsmOptions,
    /// Hierarchical penumbra casting.
    #[command(flatten, next_help_heading = "Penumbra casting")]
    pub penumbra_casting: PenumbraCastingOptions,
    /// Soft textured shadow volumes (every technique that shadows
    /// S-triangles through the add-on, and DCS).
    #[command(
        flatten,
        next_help_heading = "S-triangles (soft textured shadow volumes)"
    )]
    pub stsv: StsvOptions,
}

impl Default for TechniqueOptions {
    /// The command line's defaults, so that the library and the CLI can
    /// never disagree on them.
    fn default() -> Self {
        #[derive(clap::Parser)]
        struct Defaults {
            #[command(flatten)]
            options: TechniqueOptions,
        }
        <Defaults as clap::Parser>::parse_from(["penumbra"]).options
    }
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

/// A registered technique: a cheap handle to its [`TechniqueInfo`].
#[derive(Clone, Copy)]
pub struct Technique(&'static TechniqueInfo);

impl Technique {
    /// The technique called `name`, or an error that lists the known ones.
    pub fn named(name: &str) -> Result<Technique> {
        TECHNIQUES
            .iter()
            .find(|t| t.name == name)
            .map(|t| Technique(t))
            .ok_or_else(|| {
                Error::param(
                    "--technique",
                    format!("unknown technique `{name}` (known: {})", names().join(", ")),
                )
            })
    }

    /// Every registered technique, in registry order.
    pub fn all() -> impl Iterator<Item = Technique> {
        TECHNIQUES.iter().map(|t| Technique(t))
    }

    /// The command-line name.
    pub fn name(self) -> &'static str {
        self.0.name
    }

    /// Its description.
    pub fn info(self) -> &'static TechniqueInfo {
        self.0
    }

    /// Its capabilities with `options`.
    pub fn capabilities(self, options: &TechniqueOptions) -> Capabilities {
        (self.0.capabilities)(options)
    }

    /// Builds it.
    pub fn build(self, params: &BuildParams) -> Box<dyn ShadowTechnique> {
        (self.0.build)(params)
    }

    /// Its quality settings in `compare`.
    pub fn quality_settings(self, sweep: &Sweep) -> Vec<QualitySetting> {
        (self.0.quality_settings)(sweep)
    }
}

impl Default for Technique {
    fn default() -> Self {
        Technique::named(DEFAULT_TECHNIQUE).expect("the default technique is registered")
    }
}

impl PartialEq for Technique {
    fn eq(&self, other: &Self) -> bool {
        self.0.name == other.0.name
    }
}

impl Eq for Technique {}

impl fmt::Debug for Technique {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Technique({})", self.0.name)
    }
}

impl fmt::Display for Technique {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.0.name)
    }
}

impl std::str::FromStr for Technique {
    type Err = Error;
    fn from_str(s: &str) -> Result<Technique> {
        Technique::named(s)
    }
}

/// Every technique's name, in registry order.
pub fn names() -> Vec<&'static str> {
    TECHNIQUES.iter().map(|t| t.name).collect()
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
    technique: Technique,
    options: &TechniqueOptions,
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
) -> Result<Vec<Warning>> {
    let caps = technique.capabilities(options);
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
                    technique: technique.name(),
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
                        technique.name(),
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

/// The techniques table of docs/architecture.md and the README, generated
/// from the registry (`penumbra techniques --markdown`); pages are linked
/// as `{pages}{page}` (`algorithms/` from docs/, `docs/algorithms/` from
/// the README).
pub fn markdown_table(pages: &str) -> String {
    let mut s = String::from(
        "| name | what it does | exact visibility | exact image | output | sphere lights | semi-opaque | S-triangles | module | page |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
    );
    for t in Technique::all() {
        let info = t.info();
        let caps = t.capabilities(&TechniqueOptions::default());
        let page = info
            .page
            .map(|p| format!("[{p}]({pages}{p})"))
            .unwrap_or_else(|| "—".into());
        s.push_str(&format!(
            "| `{}` | {} | {} | {} | {} | {} | {} | {} | `{}` | {} |\n",
            info.name,
            info.summary,
            if caps.exact { "yes" } else { "no" },
            if caps.exact_image { "yes" } else { "no" },
            term_name(caps.output),
            support_name(caps.sphere_lights),
            support_name(caps.semi_opaque),
            support_name(caps.s_triangles),
            info.module,
            page
        ));
    }
    s
}

/// The `penumbra techniques` listing.
pub fn listing() -> String {
    // The name column fits the longest name plus two spaces, so that no
    // name runs into its summary ("penumbra-casting" is 16 characters).
    let width = Technique::all().map(|t| t.name().len()).max().unwrap_or(0) + 2;
    let mut s = String::new();
    for t in Technique::all() {
        let caps = t.capabilities(&TechniqueOptions::default());
        s.push_str(&format!("{:<width$}{}\n", t.name(), t.info().summary));
        s.push_str(&format!(
            "{:<width$}{}, {}; rect lights: {}, sphere lights: {}, textured lights: {}, semi-opaque casters: {}, S-triangles: {}\n",
            "",
            exactness(&caps),
            term_name(caps.output),
            support_name(caps.rect_lights),
            support_name(caps.sphere_lights),
            support_name(caps.textured_lights),
            support_name(caps.semi_opaque),
            support_name(caps.s_triangles),
        ));
    }
    s
}

/// Whether the visibility and the image are exact, in words.
fn exactness(caps: &Capabilities) -> &'static str {
    match (caps.exact, caps.exact_image) {
        (true, true) => "exact visibility and image",
        (true, false) => "exact visibility, approximate image",
        _ => "approximate",
    }
}

fn term_name(t: TermKind) -> &'static str {
    match t {
        TermKind::Vcoef => "Vcoef",
        TermKind::Radiance => "radiance",
    }
}

fn support_name(s: Support) -> &'static str {
    match s {
        Support::Yes => "yes",
        Support::StsvAddOn => "yes (STSV add-on)",
        Support::Ignored(_) => "ignored (warning)",
        Support::Refused { .. } => "refused",
    }
}

/// A group of `render` options that only some techniques read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OptionGroup {
    /// `--samples`.
    Samples,
    /// `--pattern`.
    Pattern,
    /// `--seed`.
    Seed,
    /// [`ShadowVolumeOptions`].
    ShadowVolumes,
    /// [`DcsOptions`].
    Dcs,
    /// [`ShadowMapOptions`] (every map technique's).
    ShadowMaps,
    /// [`PcssOptions`].
    Pcss,
    /// [`AdaptiveMapsOptions`].
    AdaptiveMaps,
    /// [`SsmOptions`].
    Ssm,
    /// [`PenumbraCastingOptions`].
    PenumbraCasting,
    /// [`StsvOptions`] (DCS, penumbra casting and the S-triangle add-on).
    Stsv,
}

impl OptionGroup {
    /// Every group.
    pub const ALL: [OptionGroup; 11] = [
        OptionGroup::Samples,
        OptionGroup::Pattern,
        OptionGroup::Seed,
        OptionGroup::ShadowVolumes,
        OptionGroup::Dcs,
        OptionGroup::ShadowMaps,
        OptionGroup::Pcss,
        OptionGroup::AdaptiveMaps,
        OptionGroup::Ssm,
        OptionGroup::PenumbraCasting,
        OptionGroup::Stsv,
    ];
}

impl OptionGroup {
    /// The clap ids of the group's arguments (a field's name, which is
    /// also what `ArgMatches` reports).
    pub fn arg_ids(self) -> Vec<String> {
        use clap::Args;
        let augment: fn(clap::Command) -> clap::Command = match self {
            OptionGroup::Samples => return vec!["samples".into()],
            OptionGroup::Pattern => return vec!["pattern".into()],
            OptionGroup::Seed => return vec!["seed".into()],
            OptionGroup::ShadowVolumes => ShadowVolumeOptions::augment_args,
            OptionGroup::Dcs => DcsOptions::augment_args,
            OptionGroup::ShadowMaps => ShadowMapOptions::augment_args,
            OptionGroup::Pcss => PcssOptions::augment_args,
            OptionGroup::AdaptiveMaps => AdaptiveMapsOptions::augment_args,
            OptionGroup::Ssm => SsmOptions::augment_args,
            OptionGroup::PenumbraCasting => PenumbraCastingOptions::augment_args,
            OptionGroup::Stsv => StsvOptions::augment_args,
        };
        augment(clap::Command::new("options"))
            .get_arguments()
            .map(|a| a.get_id().to_string())
            .collect()
    }
}

/// Which option groups each technique reads (by name, in [`TECHNIQUES`]
/// order). The S-triangle add-on's (`--samples`, `--pattern`, `--seed`
/// and the stsv options) come on top where it runs ([`options_read`]).
static OPTIONS_READ: &[(&str, &[OptionGroup])] = {
    use OptionGroup::*;
    &[
        ("none", &[]),
        ("reference", &[Samples, Pattern, Seed]),
        ("shadow-volumes", &[ShadowVolumes]),
        ("wedges", &[]),
        ("wedge-blend", &[]),
        ("dcs", &[Samples, Pattern, Seed, Dcs, Stsv]),
        ("shadow-map", &[Seed, ShadowMaps]),
        ("pcss", &[Seed, ShadowMaps, Pcss]),
        ("multi-map", &[Samples, Pattern, Seed, ShadowMaps]),
        ("adaptive-maps", &[Seed, ShadowMaps, AdaptiveMaps]),
        ("soft-shadow-map", &[ShadowMaps, Ssm]),
        (
            "penumbra-casting",
            &[Samples, Pattern, Seed, PenumbraCasting, Stsv],
        ),
    ]
};

/// The option groups `technique` reads on `scene`: its own, and the
/// S-triangle add-on's when it shadows the scene's S-triangles with it.
pub fn options_read(
    technique: Technique,
    options: &TechniqueOptions,
    scene: &Scene,
) -> Vec<OptionGroup> {
    let mut groups: Vec<OptionGroup> = OPTIONS_READ
        .iter()
        .find(|(name, _)| *name == technique.name())
        .map_or(&[][..], |(_, g)| g)
        .to_vec();
    if technique.capabilities(options).s_triangles == Support::StsvAddOn && has_s_triangles(scene) {
        use OptionGroup::*;
        for g in [Samples, Pattern, Seed, Stsv] {
            if !groups.contains(&g) {
                groups.push(g);
            }
        }
    }
    groups
}

/// Of the options the user gave (`given`: clap ids), those that
/// `technique` does not read on `scene`, in the order given.
pub fn unread_options(
    technique: Technique,
    options: &TechniqueOptions,
    scene: &Scene,
    given: &[String],
) -> Vec<String> {
    let read: Vec<String> = (options_read(technique, options, scene).into_iter())
        .flat_map(OptionGroup::arg_ids)
        .collect();
    let technique_specific: Vec<String> = (OptionGroup::ALL.into_iter())
        .flat_map(OptionGroup::arg_ids)
        .collect();
    given
        .iter()
        .filter(|id| technique_specific.contains(id) && !read.contains(id))
        .cloned()
        .collect()
}

#[cfg(test)]
mod option_tests {
    use super::*;

    /// Every registered technique says which options it reads.
    #[test]
    fn every_technique_lists_the_options_it_reads() {
        for t in TECHNIQUES {
            assert!(
                OPTIONS_READ.iter().any(|(name, _)| *name == t.name),
                "{} is missing from OPTIONS_READ",
                t.name
            );
        }
        assert_eq!(OPTIONS_READ.len(), TECHNIQUES.len());
        assert!(OptionGroup::Dcs.arg_ids().contains(&"mode".to_string()));
    }

    /// Every name is followed by at least two spaces before its summary.
    #[test]
    fn listing_columns_do_not_run_together() {
        let text = listing();
        for t in TECHNIQUES {
            let line = text.lines().find(|l| l.starts_with(t.name)).unwrap();
            assert!(line[t.name.len()..].starts_with("  "), "{line}");
        }
    }
}
