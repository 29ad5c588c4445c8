//! Every technique's options, gathered into the one [`TechniqueOptions`]
//! that `render` and `compare` flatten into their command lines, and the
//! [`OptionGroup`]s a technique declares it reads. Written once: one line
//! per options group below yields the struct's field, its help heading
//! and its group. Each group's type lives in a leaf `options.rs` beside
//! the code that reads it, so this file imports no technique. Each
//! group's `Default` is written out in plain Rust; a test holds it to
//! clap's.

use super::adaptive_maps::options::AdaptiveMapsOptions;
use super::dcs::options::DcsOptions;
use super::kit::map_options::ShadowMapOptions;
use super::kit::stsv::options::StsvOptions;
use super::pcss::options::PcssOptions;
use super::penumbra_casting::options::PenumbraCastingOptions;
use super::shadow_volumes::options::ShadowVolumeOptions;
use super::soft_shadow_map::options::SsmOptions;

/// Declares [`TechniqueOptions`] (one flattened field per group, in help
/// order) and [`OptionGroup`] (the render-wide sampling options, then one
/// variant per group) from one line per group.
macro_rules! option_groups {
    ($( $(#[doc = $doc:literal])* $variant:ident $field:ident: $ty:ty, $heading:literal; )*) => {
        /// Every technique's own options, flattened into `render` and
        /// `compare`: one field per options group.
        #[derive(Debug, Clone, PartialEq, clap::Args)]
        pub struct TechniqueOptions {
            $(
                $(#[doc = $doc])*
                #[command(flatten, next_help_heading = $heading)]
                pub $field: $ty,
            )*
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
            $( $(#[doc = $doc])* $variant, )*
        }

        impl OptionGroup {
            /// Every group.
            pub const ALL: &'static [OptionGroup] = &[
                OptionGroup::Samples,
                OptionGroup::Pattern,
                OptionGroup::Seed,
                $( OptionGroup::$variant, )*
            ];

            /// The clap ids of the group's arguments (a field's name,
            /// which is also what `ArgMatches` reports).
            pub fn arg_ids(self) -> Vec<String> {
                use clap::Args;
                let augment: fn(clap::Command) -> clap::Command = match self {
                    OptionGroup::Samples => return vec!["samples".into()],
                    OptionGroup::Pattern => return vec!["pattern".into()],
                    OptionGroup::Seed => return vec!["seed".into()],
                    $( OptionGroup::$variant => <$ty>::augment_args, )*
                };
                augment(clap::Command::new("options"))
                    .get_arguments()
                    .map(|a| a.get_id().to_string())
                    .collect()
            }
        }
    };
}

option_groups! {
    /// Hard shadow volumes.
    ShadowVolumes shadow_volumes: ShadowVolumeOptions, "Shadow volumes";
    /// Depth complexity sampling.
    Dcs dcs: DcsOptions, "DCS";
    /// Shadow maps (every map technique's).
    ShadowMaps shadow_map: ShadowMapOptions, "Shadow maps";
    /// Percentage-closer soft shadows (with the shadow-map options).
    Pcss pcss: PcssOptions, "PCSS";
    /// Adaptive light-source sampling (the map options are the shadow
    /// maps').
    AdaptiveMaps adaptive_maps: AdaptiveMapsOptions, "Adaptive maps";
    /// Soft shadow maps.
    Ssm ssm: SsmOptions, "Soft shadow maps";
    /// Hierarchical penumbra casting.
    PenumbraCasting penumbra_casting: PenumbraCastingOptions, "Penumbra casting";
    /// Soft textured shadow volumes (every technique that shadows
    /// S-triangles through the add-on, and DCS).
    Stsv stsv: StsvOptions, "S-triangles (soft textured shadow volumes)";
}

impl Default for TechniqueOptions {
    /// The command line's defaults, from each group's own plain-Rust
    /// `Default` (tested below against clap's, so that the library and the
    /// CLI can never disagree on them).
    fn default() -> Self {
        TechniqueOptions {
            shadow_volumes: Default::default(),
            dcs: Default::default(),
            shadow_map: Default::default(),
            pcss: Default::default(),
            adaptive_maps: Default::default(),
            ssm: Default::default(),
            penumbra_casting: Default::default(),
            stsv: Default::default(),
        }
    }
}

impl TechniqueOptions {
    /// The range checks of `groups` (those a technique reads): the map
    /// techniques' depth bias, PCSS's sample counts. Groups whose ranges
    /// clap's parsers already hold have none.
    pub fn validate(&self, groups: &[OptionGroup]) -> crate::error::Result<()> {
        for group in groups {
            match group {
                OptionGroup::ShadowMaps => self.shadow_map.bias().validate()?,
                OptionGroup::Pcss => self.pcss.validate()?,
                _ => {}
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plain-Rust defaults are the command line's, group by group.
    #[test]
    fn plain_defaults_are_the_command_lines() {
        use clap::{Args, FromArgMatches};
        let matches = TechniqueOptions::augment_args(clap::Command::new("defaults"))
            .get_matches_from(["defaults"]);
        let clap =
            TechniqueOptions::from_arg_matches(&matches).expect("every option has a default");
        assert_eq!(TechniqueOptions::default(), clap);
    }
}
