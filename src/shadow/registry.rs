//! The technique registry: the list of every shadow technique, and the
//! queries `render`, `compare`, `--explain`, the CLI help and
//! `penumbra techniques` make of it. Each technique describes itself once,
//! in its own folder, as a [`TechniqueInfo`] static (name, summary,
//! capabilities, options read, cost, quality settings for `compare`, how
//! it is built); this file only lists them.
//!
//! Adding a technique is its folder under `src/shadow/` (with a leaf
//! `options.rs` and one line in [`super::options`] if it brings options of
//! its own), `pub mod` in `shadow/mod.rs` and one line in [`TECHNIQUES`]
//! (docs/architecture.md, "How to add a technique"; `tests/it/registry.rs`
//! fails when the list and the folders disagree).

use super::options::{OptionGroup, TechniqueOptions};
use super::technique::{
    has_s_triangles, BuildParams, Capabilities, CostClass, QualitySetting, ShadowTechnique,
    Support, Sweep, TechniqueInfo, TermKind,
};
use crate::error::{Error, Result};
use crate::scene::Scene;
use std::fmt;

/// Every technique, in the order `penumbra techniques` and the docs list
/// them.
pub static TECHNIQUES: &[&TechniqueInfo] = &[
    &super::none::TECHNIQUE,
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

/// One technique as data: what `penumbra techniques --json` prints and
/// what a program (or the Python package) reads instead of the listing.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TechniqueData {
    /// The command-line name.
    pub name: &'static str,
    /// One line on what it does.
    pub summary: &'static str,
    /// Its module under `src/`.
    pub module: &'static str,
    /// Its page under docs/algorithms, if it has one.
    pub page: Option<&'static str>,
    /// Per-sample visibility equals the shadow rays' (with the default
    /// options).
    pub exact: bool,
    /// The image converges to the contract's radiance (default options).
    pub exact_image: bool,
    /// `Vcoef` or `radiance`, as the listing says.
    pub output: &'static str,
    /// Per kind of scene content (`rect_lights`, `sphere_lights`,
    /// `textured_lights`, `enclosed_lights`, `reached_lights`,
    /// `semi_opaque`, `s_triangles`): the listing's words (`yes`,
    /// `yes (STSV add-on)`, `ignored (warning): why`, `refused: why`).
    pub support: std::collections::BTreeMap<&'static str, String>,
    /// How its time grows with the light samples: `free`, `raster` or
    /// `rays`.
    pub cost: &'static str,
}

/// Every registered technique as data, in registry order, with the
/// default options.
pub fn technique_data() -> Vec<TechniqueData> {
    let options = TechniqueOptions::default();
    Technique::all()
        .map(|t| {
            let info = t.info();
            let caps = t.capabilities(&options);
            // The listing's words, with the reason where there is one.
            let words = |s: Support| match s {
                Support::Ignored(why) | Support::Refused { why, .. } => {
                    format!("{}: {why}", support_name(s))
                }
                _ => support_name(s).to_string(),
            };
            let support = [
                ("rect_lights", caps.rect_lights),
                ("sphere_lights", caps.sphere_lights),
                ("textured_lights", caps.textured_lights),
                ("enclosed_lights", caps.enclosed_lights),
                ("reached_lights", caps.reached_lights),
                ("semi_opaque", caps.semi_opaque),
                ("s_triangles", caps.s_triangles),
            ]
            .into_iter()
            .map(|(content, s)| (content, words(s)))
            .collect();
            TechniqueData {
                name: info.name,
                summary: info.summary,
                module: info.module,
                page: info.page,
                exact: caps.exact,
                exact_image: caps.exact_image,
                output: term_name(caps.output),
                support,
                cost: match info.cost {
                    CostClass::Free => "free",
                    CostClass::Raster => "raster",
                    CostClass::Rays => "rays",
                },
            }
        })
        .collect()
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

/// The option groups `technique` reads on `scene`: its own, and the
/// S-triangle add-on's when it shadows the scene's S-triangles with it.
pub fn options_read(
    technique: Technique,
    options: &TechniqueOptions,
    scene: &Scene,
) -> Vec<OptionGroup> {
    let mut groups: Vec<OptionGroup> = technique.info().reads.to_vec();
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
    let technique_specific: Vec<String> = (OptionGroup::ALL.iter().copied())
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

    /// The option groups name the options they hold.
    #[test]
    fn option_groups_name_their_options() {
        assert!(OptionGroup::Dcs.arg_ids().contains(&"mode".to_string()));
        assert_eq!(OptionGroup::Samples.arg_ids(), ["samples"]);
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
