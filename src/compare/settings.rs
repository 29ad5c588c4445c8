//! What `compare` runs: its options and their validation, and the quality
//! settings of each technique (from the technique registry).

use super::cache::default_cache_dir;
use crate::error::{Error, Result};
use crate::render::{RenderOptions, Technique};
use crate::sampling::{SamplePattern, SplitMix64};
use crate::shadow::options::OptionGroup;
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
    /// `--sweep-settings`: besides each technique's default configuration
    /// (at every sample count and pattern asked for), every other quality
    /// setting its registry entry sweeps (map sizes, DCS's centre
    /// silhouettes and summed opacity, ...). Off by default: only the
    /// runs asked for.
    pub sweep_settings: bool,
    /// `--target-error E`: also each technique that renders
    /// progressively, in sets of [`TARGET_SET_SAMPLES`] until its
    /// estimated radiance RMSE is at most E (at most the reference's
    /// samples in all): equal estimated error, compared by time.
    pub target_error: Option<f64>,
}

/// The set size of `compare --target-error`'s progressive runs.
pub const TARGET_SET_SAMPLES: u32 = 16;

impl Default for CompareOptions {
    /// `penumbra compare`'s defaults, in plain Rust (a test holds them to
    /// clap's): the exact techniques (dcs, the render default; penumbra
    /// casting; the reference), 4, 16, 64 and
    /// 256 samples, a 4096-sample reference, 3 timed runs, images on, the
    /// reference cache of [`default_cache_dir`] (falling back on
    /// `compare/cache`, as the command's default `--out compare` does),
    /// each technique in its default configuration only (no
    /// `--sweep-settings`).
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
            sweep_settings: false,
            target_error: None,
        }
    }
}

impl CompareOptions {
    /// The view every run of `scene` renders: the scene's camera at the
    /// comparison's size.
    pub(crate) fn view(&self, scene: &crate::scene::Scene) -> Result<crate::view::View> {
        crate::render::view_for(
            scene,
            &RenderOptions {
                width: self.width,
                height: self.height,
                ..RenderOptions::default()
            },
        )
    }

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
        if let Some(e) = self.target_error.filter(|e| !(e.is_finite() && *e > 0.0)) {
            return Err(Error::param(
                "--target-error",
                format!("{e} is not a positive finite RMSE"),
            ));
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

/// What added a run the user did not name: the option that asked for
/// the registry's extra quality settings.
pub const SWEEP_SETTINGS: &str = "--sweep-settings";

/// One run `compare` makes of a technique: its quality setting, the
/// render options it runs with and, for a run beyond the technique's
/// default configuration, the option that added it.
#[derive(Debug, Clone)]
pub struct SettingRun {
    /// The setting (curve and label).
    pub setting: QualitySetting,
    /// Its render options.
    pub options: RenderOptions,
    /// `None` for the runs asked for (the technique in its default
    /// configuration at a sample count and pattern given); otherwise the
    /// option that added it ([`SWEEP_SETTINGS`]).
    pub added_by: Option<&'static str>,
}

/// The runs `compare` makes of `technique`, as render options on top of
/// `base`: its default configuration (what `penumbra render --technique
/// T --samples N --pattern P` renders with `base`'s options) at every
/// sample count of `samples` and pattern of `patterns` it reads (one run
/// for a technique that reads neither); with `sweep_settings`, then every
/// other setting of its registry entry's sweep.
///
/// A default run takes the registry's curve and label where its sweep
/// holds the same configuration (e.g. `1024² map, pcf 1`), else the
/// technique's name (with the pattern when it is not the first) and
/// `N spp` or `as given`.
pub fn quality_settings(
    technique: Technique,
    samples: &[u32],
    patterns: &[SamplePattern],
    semi_opaque: bool,
    base: &RenderOptions,
    sweep_settings: bool,
) -> Vec<SettingRun> {
    let sweep = Sweep {
        samples,
        patterns,
        semi_opaque,
        base: &base.options,
    };
    let swept = technique.quality_settings(&sweep);
    let defaults = default_settings(technique, &sweep, &swept);
    let same = |a: &QualitySetting, b: &QualitySetting| {
        a.samples == b.samples && a.pattern == b.pattern && a.options == b.options
    };
    let extra: Vec<QualitySetting> = match sweep_settings {
        true => (swept.into_iter())
            .filter(|q| !defaults.iter().any(|d| same(d, q)))
            .collect(),
        false => Vec::new(),
    };
    let run = |q: QualitySetting, added_by: Option<&'static str>| SettingRun {
        options: RenderOptions {
            technique,
            samples: q.samples.unwrap_or(base.samples),
            pattern: q.pattern,
            options: q.options.clone(),
            ..base.clone()
        },
        setting: q,
        added_by,
    };
    (defaults.into_iter().map(|q| run(q, None)))
        .chain(extra.into_iter().map(|q| run(q, Some(SWEEP_SETTINGS))))
        .collect()
}

/// `technique`'s default configuration (`sweep.base`) at every sample
/// count and pattern it reads, labelled as its registry entry's sweep
/// (`swept`) labels the same configuration.
fn default_settings(
    technique: Technique,
    sweep: &Sweep,
    swept: &[QualitySetting],
) -> Vec<QualitySetting> {
    let reads = technique.info().reads;
    let first = sweep.first_pattern();
    let patterns: Vec<SamplePattern> = match reads.contains(&OptionGroup::Pattern) {
        true if !sweep.patterns.is_empty() => sweep.patterns.to_vec(),
        _ => vec![first],
    };
    let counts: Vec<Option<u32>> = match reads.contains(&OptionGroup::Samples) {
        true => sweep.samples.iter().map(|&n| Some(n)).collect(),
        false => vec![None],
    };
    let name = technique.name();
    let mut out = Vec::new();
    for &pattern in &patterns {
        for &samples in &counts {
            let own = swept
                .iter()
                .find(|q| q.samples == samples && q.pattern == pattern && q.options == *sweep.base);
            out.push(match own {
                Some(q) => q.clone(),
                None => {
                    let curve = match pattern == first {
                        true => name.to_string(),
                        false => format!("{name} {pattern}"),
                    };
                    QualitySetting {
                        curve,
                        label: match samples {
                            Some(n) => format!("{n} spp"),
                            None => "as given".to_string(),
                        },
                        samples,
                        pattern,
                        options: sweep.base.clone(),
                    }
                }
            });
        }
    }
    out
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
        assert_eq!(args.get_flag("sweep_settings"), defaults.sweep_settings);
        assert!(
            !defaults.sweep_settings,
            "only the runs asked for by default"
        );
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

    /// The runs of every technique at two sample counts and two
    /// patterns, with and without `--sweep-settings`.
    fn runs_of(technique: Technique, sweep_settings: bool) -> Vec<SettingRun> {
        let base = RenderOptions {
            width: Some(64),
            height: Some(48),
            ..RenderOptions::default()
        };
        let patterns = [SamplePattern::Stratified, SamplePattern::Sobol02];
        quality_settings(technique, &[4, 64], &patterns, true, &base, sweep_settings)
    }

    /// Without `--sweep-settings` a technique runs what `penumbra render
    /// --technique T --samples N --pattern P` renders (the given options,
    /// untouched) at each sample count and pattern it reads, and nothing
    /// else; no run says an option added it.
    #[test]
    fn by_default_each_technique_runs_its_default_configuration() {
        let base = TechniqueOptions::default();
        for technique in Technique::all() {
            let runs = runs_of(technique, false);
            let reads = technique.info().reads;
            let samples = reads.contains(&OptionGroup::Samples);
            let patterns = reads.contains(&OptionGroup::Pattern);
            let expected = if samples { 2 } else { 1 } * if patterns { 2 } else { 1 };
            assert_eq!(runs.len(), expected, "{technique}");
            for run in &runs {
                let o = &run.options;
                assert_eq!(run.added_by, None, "{technique}");
                assert_eq!(o.technique, technique);
                assert_eq!(o.options, base, "{technique} {}", run.setting.label);
                assert_eq!(run.setting.options, base);
                assert_eq!(o.pattern, run.setting.pattern);
                match run.setting.samples {
                    Some(n) => assert!(samples && [4, 64].contains(&n) && o.samples == n),
                    None => assert!(!samples && o.samples == RenderOptions::default().samples),
                }
                if !patterns {
                    assert_eq!(o.pattern, SamplePattern::Stratified, "{technique}");
                }
                assert!(run.setting.curve.starts_with(technique.name()));
            }
        }
    }

    /// With `--sweep-settings`, the default runs first, then every other
    /// setting of the registry's sweep, each marked as added by the
    /// option; no configuration twice, no (curve, label) twice.
    #[test]
    fn sweep_settings_adds_the_registry_settings_marked() {
        let base = TechniqueOptions::default();
        for technique in Technique::all() {
            let plain = runs_of(technique, false);
            let swept = runs_of(technique, true);
            assert!(swept.len() >= plain.len(), "{technique}");
            for (a, b) in plain.iter().zip(&swept) {
                assert_eq!(
                    (&a.setting.curve, &a.setting.label),
                    (&b.setting.curve, &b.setting.label)
                );
                assert_eq!(b.added_by, None);
            }
            for extra in &swept[plain.len()..] {
                assert_eq!(extra.added_by, Some(SWEEP_SETTINGS), "{technique}");
            }
            let sweep = Sweep {
                samples: &[4, 64],
                patterns: &[SamplePattern::Stratified, SamplePattern::Sobol02],
                semi_opaque: true,
                base: &base,
            };
            for q in technique.quality_settings(&sweep) {
                assert!(
                    swept.iter().any(|r| r.setting.samples == q.samples
                        && r.setting.pattern == q.pattern
                        && r.setting.options == q.options),
                    "{technique}: {} {} is run",
                    q.curve,
                    q.label
                );
            }
            let mut names: Vec<(&str, &str)> = (swept.iter())
                .map(|r| (r.setting.curve.as_str(), r.setting.label.as_str()))
                .collect();
            names.sort_unstable();
            let n = names.len();
            names.dedup();
            assert_eq!(names.len(), n, "{technique}: {names:?}");
        }
        // DCS: its centre silhouettes and summed opacity only with the
        // option.
        let dcs = Technique::named("dcs").expect("registered");
        let labels = |runs: Vec<SettingRun>| -> Vec<String> {
            runs.iter()
                .map(|r| format!("{} {}", r.setting.curve, r.setting.label))
                .collect()
        };
        assert_eq!(
            labels(runs_of(dcs, false)),
            [
                "dcs 4 spp",
                "dcs 64 spp",
                "dcs sobol 4 spp",
                "dcs sobol 64 spp"
            ]
        );
        let swept = labels(runs_of(dcs, true));
        assert!(swept.iter().any(|l| l.contains("centre")), "{swept:?}");
        assert!(swept.iter().any(|l| l.contains("summed")), "{swept:?}");
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
