//! What `compare` runs: its options and their validation, and the quality
//! settings of each technique (from the technique registry).

use super::cache::default_cache_dir;
use crate::error::{Error, Result};
use crate::render::{RenderOptions, Technique};
use crate::sampling::{SamplePattern, SplitMix64};
use crate::shadow::technique::{QualitySetting, Sweep};
use crate::shadow::TechniqueOptions;
use std::path::{Path, PathBuf};

/// What `compare` runs. [`Default`] is `penumbra compare`'s defaults.
#[derive(Debug, Clone)]
pub struct CompareOptions {
    /// Techniques to measure, in order.
    pub techniques: Vec<Technique>,
    /// The techniques' options every quality setting starts from.
    pub technique_options: TechniqueOptions,
    /// Light-sample counts for techniques that sample.
    pub samples: Vec<u32>,
    /// Samples per light of the reference (even: two halves).
    pub reference_samples: u32,
    /// Timed runs per setting (the median is reported).
    pub repeat: u32,
    /// Image width override.
    pub width: Option<u32>,
    /// Image height override.
    pub height: Option<u32>,
    /// Seed of the techniques' samples (the reference derives its own).
    pub seed: u64,
    /// Where cached references live.
    pub cache_dir: PathBuf,
    /// Write per-run images and heat maps.
    pub images: bool,
    /// Sample patterns DCS is measured with (one curve each); the first
    /// is also the reference's and whole-light silhouettes' pattern.
    pub patterns: Vec<SamplePattern>,
    /// `--verify K`: relations re-cast with shadow rays per run of a
    /// technique that exposes its decisions (not timed).
    pub verify: Option<u64>,
    /// Worker threads of [`crate::compare::compare`] (all cores when
    /// `None`); the command line runs the sweep in its own pool.
    pub threads: Option<usize>,
}

impl Default for CompareOptions {
    /// `penumbra compare`'s defaults, in plain Rust (a test holds them to
    /// clap's): the exact techniques (dcs, the render default; penumbra
    /// casting; the reference), 4, 16, 64 and
    /// 256 samples, a 4096-sample reference, 3 timed runs, images on, the
    /// reference cache of [`default_cache_dir`] (falling back on
    /// `compare/cache`, as the command's default `--out compare` does).
    fn default() -> Self {
        CompareOptions {
            techniques: ["dcs", "penumbra-casting", "reference"]
                .into_iter()
                .filter_map(|name| Technique::named(name).ok())
                .collect(),
            technique_options: TechniqueOptions::default(),
            samples: vec![4, 16, 64, 256],
            reference_samples: 4096,
            repeat: 3,
            width: None,
            height: None,
            seed: 0,
            cache_dir: default_cache_dir(&Path::new("compare").join("cache")),
            images: true,
            patterns: vec![SamplePattern::Stratified],
            verify: None,
            threads: None,
        }
    }
}

impl CompareOptions {
    /// Checks the options before any work starts: the one place of
    /// `compare`'s range checks (the command and the library call it).
    pub fn validate(&self) -> Result<()> {
        if self.techniques.is_empty() {
            return Err(Error::param("--techniques", "name at least one technique"));
        }
        let max = crate::shadow::kit::verify::MAX_RELATIONS;
        if let Some(k) = self.verify.filter(|k| !(1..=max).contains(k)) {
            return Err(Error::param(
                "--verify",
                format!("{k} relations is outside 1..={max}"),
            ));
        }
        if self.samples.is_empty() {
            return Err(Error::param("--samples", "give at least one sample count"));
        }
        if self.patterns.is_empty() {
            return Err(Error::param(
                "--patterns",
                "give at least one sample pattern",
            ));
        }
        if let Some(&s) = self.samples.iter().find(|&&s| s == 0 || s > 1 << 20) {
            return Err(Error::param(
                "--samples",
                format!("{s} is outside 1..=1048576"),
            ));
        }
        let m = self.reference_samples;
        if m < 2 || !m.is_multiple_of(2) || m > 1 << 21 {
            return Err(Error::param(
                "--reference-samples",
                format!("{m} must be even and in 2..=2097152 (the reference is two halves)"),
            ));
        }
        if self.repeat == 0 || self.repeat > 1000 {
            return Err(Error::param(
                "--repeat",
                format!("{} is outside 1..=1000", self.repeat),
            ));
        }
        for (name, v) in [("--width", self.width), ("--height", self.height)] {
            if v == Some(0) {
                return Err(Error::param(name, "must be at least 1"));
            }
        }
        Ok(())
    }

    /// The two reference halves' seeds: distinct from each other and from
    /// the techniques' seed, so no technique shares the reference's noise.
    pub fn reference_seeds(&self) -> [u64; 2] {
        [
            SplitMix64::new(self.seed ^ 0x5245_4630).next_u64(),
            SplitMix64::new(self.seed ^ 0x5245_4631).next_u64(),
        ]
    }
}

/// The quality settings `compare` runs for `technique`, from the
/// registry, as render options on top of `base`.
pub fn quality_settings(
    technique: Technique,
    samples: &[u32],
    patterns: &[SamplePattern],
    semi_opaque: bool,
    base: &RenderOptions,
) -> Vec<(QualitySetting, RenderOptions)> {
    let sweep = Sweep {
        samples,
        patterns,
        semi_opaque,
        base: &base.options,
    };
    technique
        .quality_settings(&sweep)
        .into_iter()
        .map(|q| {
            let options = RenderOptions {
                technique,
                samples: q.samples.unwrap_or(base.samples),
                pattern: q.pattern,
                options: q.options.clone(),
                ..base.clone()
            };
            (q, options)
        })
        .collect()
}

/// Progress steps `compare_scene` takes with `options`.
pub fn progress_steps(options: &CompareOptions) -> u64 {
    let settings: usize = options
        .techniques
        .iter()
        .map(|&t| {
            quality_settings(
                t,
                &options.samples,
                &options.patterns,
                true,
                &RenderOptions {
                    options: options.technique_options.clone(),
                    ..RenderOptions::default()
                },
            )
            .len()
        })
        .sum();
    2 + settings as u64 * options.repeat as u64
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::{CommandFactory, FromArgMatches};

    /// `CompareOptions::default()` is what `penumbra compare SCENE` runs
    /// with: every option as clap parses it when none is given.
    #[test]
    fn defaults_match_the_command_line() {
        let matches = crate::internal::cli::Cli::command()
            .try_get_matches_from(["penumbra", "compare", "scene.toml"])
            .expect("`compare scene.toml` parses");
        let (name, args) = matches.subcommand().expect("a subcommand");
        assert_eq!(name, "compare");
        let many = |id: &str| -> Vec<String> {
            args.get_raw(id)
                .into_iter()
                .flatten()
                .map(|v| v.to_string_lossy().into_owned())
                .collect()
        };
        let defaults = CompareOptions::default();
        let names: Vec<&str> = defaults.techniques.iter().map(|t| t.name()).collect();
        assert_eq!(many("techniques").join(","), names.join(","));
        assert_eq!(
            args.get_many::<u32>("samples")
                .map(|v| v.copied().collect::<Vec<_>>()),
            Some(defaults.samples.clone())
        );
        let one = |id: &str| args.get_one::<u32>(id).copied();
        assert_eq!(one("reference_samples"), Some(defaults.reference_samples));
        assert_eq!(one("repeat"), Some(defaults.repeat));
        assert_eq!(one("width"), defaults.width);
        assert_eq!(one("height"), defaults.height);
        assert_eq!(args.get_one::<u64>("seed").copied(), Some(defaults.seed));
        assert_eq!(args.get_one::<u64>("verify").copied(), defaults.verify);
        assert_eq!(args.get_flag("no_images"), !defaults.images);
        let patterns: Vec<String> = defaults.patterns.iter().map(|p| p.name()).collect();
        assert_eq!(many("patterns"), patterns);
        // The command's cache falls back on `--out`'s `cache`.
        let out = args.get_one::<PathBuf>("out").expect("--out has a default");
        assert!(args.get_one::<PathBuf>("cache_dir").is_none());
        assert_eq!(defaults.cache_dir, default_cache_dir(&out.join("cache")));
        let technique_options =
            TechniqueOptions::from_arg_matches(args).expect("technique options parse");
        assert_eq!(defaults.technique_options, technique_options);
        defaults.validate().expect("the defaults are valid");
    }

    /// Each range check names its parameter.
    #[test]
    fn validate_names_the_parameter() {
        type Spoil = fn(&mut CompareOptions);
        let cases: [(&str, Spoil); 7] = [
            ("--techniques", |o| o.techniques.clear()),
            ("--samples", |o| o.samples = vec![4, 0]),
            ("--samples", |o| o.samples.clear()),
            ("--reference-samples", |o| o.reference_samples = 63),
            ("--repeat", |o| o.repeat = 0),
            ("--width", |o| o.width = Some(0)),
            ("--patterns", |o| o.patterns.clear()),
        ];
        for (param, spoil) in cases {
            let mut options = CompareOptions::default();
            spoil(&mut options);
            let error = options.validate().expect_err(param).to_string();
            assert!(error.contains(param), "{param}: {error}");
        }
    }
}
