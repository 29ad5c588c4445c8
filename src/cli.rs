//! The command line: argument parsing and the commands' top level.

use crate::compare::cache::default_cache_dir;
use crate::compare::shard::{run_shard, shard_listing, unsharded_command, ShardSpec};
use crate::compare::{
    check_verified, merge_partials, reference_only, scene_dir, sweep, sweep_listing, sweep_work,
    write_results, CompareOptions, SweepOutput,
};
use crate::error::{Error, Result};
use crate::output::{
    check_output, image_format, image_outputs, write_stderr, write_stdout, Format, OutputSet,
};
use crate::render::{
    progress_for_render, render_with, verify_render, with_threads, Aov, Render, RenderOptions,
};
use crate::report::convergence::{convergence_csv, write_convergence_chart};
use crate::report::Progress;
use crate::report::{diff_images, DiffOptions};
use crate::sampling::SamplePattern;
use crate::scene::{load_scene, LightShape, Scene};
use crate::shadow::registry::DEFAULT_TECHNIQUE;
use crate::shadow::verify::check_verifiable;
use crate::shadow::{Technique, TechniqueOptions};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};

/// penumbra: physically based soft shadows on the CPU.
#[derive(Debug, Parser)]
#[command(name = "penumbra", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
    /// The subcommand's options given on the command line (clap id and
    /// `--long` name), not defaulted: only those warn when they do not
    /// apply to the technique ([`main_with_args`] fills it in).
    #[arg(skip)]
    given: Vec<(String, String)>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Render a scene to PNG and/or EXR (with AOV layers).
    Render(RenderArgs),
    /// Assemble `render --tiles` parts into the PNG (and EXR) a single
    /// render writes, byte for byte.
    MergeTiles(crate::cluster::tiles::MergeArgs),
    /// Shard a compare (or a banded render) over a Slurm job array.
    Sweep(crate::cluster::slurm::SweepArgs),
    /// Time every technique at several quality settings and measure its
    /// error against a cached ray-traced reference at the same receiver
    /// points; writes results.csv/json/md, charts, images and heat maps.
    Compare(CompareArgs),
    /// List the shadow techniques with what each can honour.
    Techniques {
        /// Print the markdown table of the docs instead (links relative to
        /// docs/).
        #[arg(long)]
        markdown: bool,
        /// Print only the names, one per line (for scripts).
        #[arg(long, conflicts_with = "markdown")]
        names: bool,
        /// Print every technique and its capabilities as JSON (for
        /// programs).
        #[arg(long, conflicts_with_all = ["markdown", "names"])]
        json: bool,
    },
    /// Error metrics between two images (PNG or EXR), and with --flip the
    /// perceptual FLIP error; exits with 1 when a tolerance is exceeded, 2
    /// on an error.
    Diff(DiffArgs),
    /// Print a scene's statistics.
    Info {
        /// Scene file (TOML).
        scene: PathBuf,
    },
    /// Write a starting scene for a model (OBJ, PLY, glTF/GLB): a camera
    /// framing it, a rect light above it sized for visible penumbrae and a
    /// ground quad unless the model has a floor; it renders at once.
    Import {
        /// The model file.
        model: PathBuf,
        /// The scene file to write (TOML); the model is named relative to
        /// its folder.
        #[arg(short, long, value_name = "SCENE.toml")]
        output: PathBuf,
    },
}

/// `penumbra render`: its command line.
#[derive(Debug, clap::Args)]
struct RenderArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Output image, in the format of its extension: .png (radiance,
    /// clamped, sRGB) or .exr (linear radiance plus the --aov layers).
    /// With --tiles, the part file (any name).
    #[arg(short, long, help_heading = "Output")]
    output: PathBuf,
    /// Also an EXR (linear radiance plus the --aov layers), beside the
    /// -o image; all outputs are written, or none.
    #[arg(long, help_heading = "Output")]
    exr: Option<PathBuf>,
    /// Comma-separated AOV layers for the EXR: depth, position, normal,
    /// albedo, mask, vcoef; error (a progressive render's estimated
    /// standard error per pixel: error.Y of the radiance, error.V of the
    /// Vcoef).
    #[arg(long, value_delimiter = ',', help_heading = "Output")]
    aov: Vec<String>,
    /// Image width (overrides the scene's camera).
    #[arg(long, help_heading = "Image")]
    width: Option<u32>,
    /// Image height (overrides the scene's camera).
    #[arg(long, help_heading = "Image")]
    height: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Shadow technique (`penumbra techniques` lists them with their
    /// capabilities).
    #[arg(long, default_value = DEFAULT_TECHNIQUE, value_parser = technique_parser())]
    technique: Technique,
    /// Light samples per pixel and light (sampling techniques; wedges,
    /// wedge-blend and shadow-volumes: for S-triangles only).
    #[arg(long, default_value_t = 64, help_heading = "Light sampling")]
    samples: u32,
    /// Seed of the per-pixel random numbers.
    #[arg(long, default_value_t = 0, help_heading = "Light sampling")]
    seed: u64,
    /// Placement of light samples (reference, dcs, multi-map,
    /// penumbra-casting; S-triangles of the others): stratified,
    /// correlated, rotated, poisson, sobol (also 02, sobol02), grid,
    /// interleaved (4×4), interleavedN or interleaved:N (N in 2..=16).
    #[arg(long, default_value = "stratified", value_parser = SamplePattern::parse, help_heading = "Light sampling")]
    pattern: SamplePattern,
    #[command(flatten)]
    options: TechniqueOptions,
    /// Print each pass's time to stderr.
    #[arg(long, help_heading = "Diagnostics")]
    timings: bool,
    /// Print which passes ran and which buffers the render allocated
    /// (or left out, and why), with their memory.
    #[arg(long, help_heading = "Diagnostics")]
    explain: bool,
    /// Exactness certificate: re-cast this many random (pixel, light
    /// sample) relations, keyed by --seed, or `all` of them (every
    /// sample of every receiving pixel), with the reference's shadow
    /// rays and compare them with the technique's own decisions (dcs,
    /// penumbra-casting); a disagreement beyond the tie distance is an
    /// error, and then no output is written (verification runs before
    /// the outputs are).
    #[arg(long, value_name = "K|all", value_parser = crate::shadow::kit::verify::parse_amount, help_heading = "Diagnostics")]
    verify: Option<u64>,
    /// Render only band I of N (whole rows of 64-pixel tiles) into the
    /// part file -o; `merge-tiles` assembles the image.
    #[arg(long, value_name = "I/N", conflicts_with_all = ["exr", "verify", "target_error", "max_samples", "max_time"], help_heading = "Output")]
    tiles: Option<String>,
    /// Progressive: render independent sets of --samples (each with its
    /// own seed) and stop once the image's estimated radiance RMSE (from
    /// the sets' spread) is at most E. reference, dcs, penumbra-casting
    /// and multi-map.
    #[arg(long, value_name = "E", help_heading = "Progressive")]
    target_error: Option<f64>,
    /// Progressive: at most this many light samples per pixel and light
    /// in all (whole sets of --samples).
    #[arg(long, value_name = "N", help_heading = "Progressive")]
    max_samples: Option<u64>,
    /// Progressive: start no set that would end after this time (`90`,
    /// `90s`, `2m`, `1h`); the image then depends on the machine's speed.
    #[arg(long, value_name = "TIME", value_parser = parse_time, help_heading = "Progressive")]
    max_time: Option<std::time::Duration>,
    /// Progressive: rewrite this PNG every few seconds with the current
    /// mean image and, beside it, its estimated error (heat map scaled to
    /// the target error).
    #[arg(long, value_name = "PATH", help_heading = "Progressive")]
    preview: Option<PathBuf>,
    /// Progressive: write the estimated error after each set, as a
    /// log-log chart against time (.png) or a table (.csv).
    #[arg(long, value_name = "PATH", help_heading = "Progressive")]
    convergence: Option<PathBuf>,
}

/// A time as seconds, or with a unit: `90`, `90s`, `2m`, `1h`, `500ms`.
fn parse_time(s: &str) -> std::result::Result<std::time::Duration, String> {
    let t = s.trim();
    let (number, scale) = if let Some(n) = t.strip_suffix("ms") {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix('s') {
        (n, 1.0)
    } else if let Some(n) = t.strip_suffix('m') {
        (n, 60.0)
    } else if let Some(n) = t.strip_suffix('h') {
        (n, 3600.0)
    } else {
        (t, 1.0)
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a time (e.g. 90, 90s, 2m, 1h)"))?;
    let seconds = value * scale;
    if !(seconds.is_finite() && seconds > 0.0 && seconds < 1e9) {
        return Err(format!("`{s}` is not a time between 0 and 1e9 seconds"));
    }
    Ok(std::time::Duration::from_secs_f64(seconds))
}

/// `penumbra compare`: its command line.
#[derive(Debug, clap::Args)]
struct CompareArgs {
    /// Scene files (TOML); each gets its own subdirectory of --out when
    /// there are several.
    #[arg(required_unless_present = "merge")]
    scenes: Vec<PathBuf>,
    /// Run only shard I of N (I in 1..=N, 1-based: map a 0-based Slurm
    /// array index to I = index + 1) of the sweep's (scene, technique,
    /// setting) runs, balanced by an estimate of their cost, and write
    /// its partial result to --out as shard-I-of-N.json (with its
    /// images). The first shard to need a scene's reference computes it
    /// under a lock in the cache, which must be shared; the others wait
    /// and read it. Join the shards with --merge.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Only compute (or find in the cache) each scene's reference, for a
    /// job the shards depend on; with --shard I/N only scenes I, I+N, ...
    #[arg(long, conflicts_with = "merge")]
    references_only: bool,
    /// Merge the partial results in these directories (from --shard runs)
    /// into --out: the tables, charts, images and heat maps of one
    /// unsharded run. Scenes and options come from the partials; a
    /// missing shard or a mismatch is an error that names it.
    #[arg(long, value_name = "DIR", num_args = 1.., conflicts_with_all = ["shard", "references_only"])]
    merge: Vec<PathBuf>,
    /// Comma-separated techniques (`penumbra techniques` lists them);
    /// by default the exact ones: dcs (render's default), penumbra-casting
    /// and the reference. Each runs in its default configuration (what
    /// `penumbra render --technique T --samples N` renders, with the
    /// technique options given here) at every --samples count and
    /// --patterns pattern it takes; see --sweep-settings.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "dcs,penumbra-casting,reference",
        value_parser = technique_parser()
    )]
    techniques: Vec<Technique>,
    /// Comma-separated light-sample counts for sampling techniques.
    #[arg(long, value_delimiter = ',', default_value = "4,16,64,256")]
    samples: Vec<u32>,
    /// Samples per light of the reference (even: it is two halves).
    #[arg(long, default_value_t = 4096)]
    reference_samples: u32,
    /// Comma-separated sample patterns the sampling techniques are
    /// measured with (one curve each; the first is the reference's).
    #[arg(long, value_delimiter = ',', default_value = "stratified")]
    patterns: Vec<String>,
    /// Also run every other quality setting each technique sweeps: map
    /// sizes of the shadow-map techniques, DCS with centre silhouettes
    /// (per pattern) and summed opacity, PCSS's taps, adaptive maps'
    /// depths, soft shadow maps' passes. The list printed before the runs
    /// marks them [--sweep-settings].
    #[arg(long)]
    sweep_settings: bool,
    /// Also run each technique that renders progressively (reference,
    /// dcs, penumbra-casting, multi-map) in sets of 16 samples until its
    /// estimated radiance RMSE is at most E (at most --reference-samples
    /// in all): the techniques compared at equal estimated error, by the
    /// time each takes to reach it.
    #[arg(long, value_name = "E")]
    target_error: Option<f64>,
    /// Timed runs per setting; the median is reported.
    #[arg(long, default_value_t = 3)]
    repeat: u32,
    /// Image width (overrides the scene's camera).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (overrides the scene's camera).
    #[arg(long)]
    height: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Seed of the techniques' light samples.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output directory.
    #[arg(long, default_value = "compare")]
    out: PathBuf,
    /// Reference cache (default: $PENUMBRA_CACHE, $XDG_CACHE_HOME/penumbra
    /// or ~/.cache/penumbra).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Also write the markdown report here, with links relative to it
    /// (e.g. docs/results.md).
    #[arg(long)]
    report: Option<PathBuf>,
    /// Skip per-run images and heat maps (charts and tables only).
    #[arg(long)]
    no_images: bool,
    /// Exactness certificate per run of a technique that exposes its
    /// decisions (dcs, penumbra-casting): this many relations re-cast
    /// with shadow rays (a `verify` column; not timed). A run that
    /// declares itself exact and disagrees beyond the tie distance
    /// fails the command (exit 2) once the results are written: unlike
    /// render --verify, the results stay, with the failure in their
    /// verify column. `all` checks every relation of every pixel.
    #[arg(long, value_name = "K|all", value_parser = crate::shadow::kit::verify::parse_amount)]
    verify: Option<u64>,
    /// The techniques' own options, the base every quality setting
    /// starts from.
    #[command(flatten)]
    options: TechniqueOptions,
}

/// `penumbra diff`: its command line.
#[derive(Debug, clap::Args)]
struct DiffArgs {
    /// First image (the one under test).
    a: PathBuf,
    /// Second image (the reference).
    b: PathBuf,
    /// Channels of A, comma-separated (default: those both images have).
    #[arg(long, value_delimiter = ',')]
    channels_a: Vec<String>,
    /// Channels of B paired with --channels-a by position (default: the
    /// same names).
    #[arg(long, value_delimiter = ',')]
    channels_b: Vec<String>,
    /// Only pixels where this image's mask channel is > 0.5.
    #[arg(long)]
    mask: Option<PathBuf>,
    /// The mask image's channel (default: mask.Y, Y, R or its first).
    #[arg(long)]
    mask_channel: Option<String>,
    /// Fail when any absolute error exceeds this.
    #[arg(long)]
    max_abs: Option<f64>,
    /// Fail when the RMSE over all compared values exceeds this.
    #[arg(long)]
    rmse: Option<f64>,
    /// Also FLIP (NVlabs' perceptual error, 0..1) between the images'
    /// R, G, B: both tone-mapped as the PNG output (clamped, sRGB,
    /// 8-bit), 67 pixels per degree; A is the test, B the reference;
    /// pooled over the --mask pixels if given. Prints its mean,
    /// percentiles and max.
    #[arg(long)]
    flip: bool,
    /// Fail (exit 1) when the FLIP mean exceeds this (implies --flip).
    #[arg(long, value_name = "X")]
    flip_threshold: Option<f64>,
    /// Write FLIP's error map here as a PNG in its magma colours
    /// (implies --flip); never over an input.
    #[arg(long, value_name = "OUT.png")]
    flip_map: Option<PathBuf>,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

/// How a command ended without an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Done.
    Success,
    /// `diff`: a tolerance was exceeded.
    ToleranceExceeded,
}

/// Runs the parsed command line: checks the environment, then hands the
/// subcommand to its `run_*` function.
pub fn run(cli: Cli) -> Result<Outcome> {
    crate::simd::level::check_env().map_err(|e| Error::param("PENUMBRA_SIMD", e))?;
    match cli.command {
        Command::Render(args) => run_render(args, &cli.given),
        Command::MergeTiles(args) => {
            crate::cluster::tiles::run_merge(&args)?;
            Ok(Outcome::Success)
        }
        Command::Sweep(args) => {
            crate::cluster::slurm::run_sweep(args)?;
            Ok(Outcome::Success)
        }
        Command::Compare(args) => run_compare(args),
        Command::Diff(args) => run_diff(args),
        Command::Techniques {
            markdown,
            names,
            json,
        } => run_techniques(markdown, names, json),
        Command::Info { scene } => run_info(&scene),
        Command::Import { model, output } => run_import(&model, &output),
    }
}

/// `penumbra import`: the starting scene, written atomically (never over
/// the model itself).
fn run_import(model: &Path, output: &Path) -> Result<Outcome> {
    crate::output::check_not_input(output, &[model.to_path_buf()])?;
    check_output(output)?;
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let text = crate::scene::starter::starting_scene(model, dir)?;
    crate::output::write_atomically(output, |tmp| {
        std::fs::write(tmp, &text).map_err(|e| Error::io(tmp, e))
    })?;
    write_stderr(&format!(
        "penumbra: wrote {}; render it with `penumbra render {} -o image.png`\n",
        output.display(),
        output.display()
    ));
    Ok(Outcome::Success)
}

/// `penumbra render`.
fn run_render(args: RenderArgs, given: &[(String, String)]) -> Result<Outcome> {
    let plan = RenderPlan::check(args)?;
    let (threads, options) = (plan.threads, &plan.options);
    let loading = std::time::Instant::now();
    let scene = load_scene(&plan.scene)?;
    // Reading the scene (files, tessellation, placing) is part of the
    // geometry preparation users wait for; `--timings` shows it first.
    if plan.timings || plan.explain {
        let ms = loading.elapsed().as_secs_f64() * 1e3;
        write_stderr(&format!("{ms:>12.3} ms  load\n"));
    }
    warn_unread_options(options, &scene, given);
    if options.progressive.is_some() {
        return run_progressive(&plan, &scene);
    }
    let progress = with_threads(threads, || progress_for_render(&scene, options))??;
    if let Some((i, n)) = plan.band {
        with_threads(threads, || {
            crate::cluster::tiles::render_part(&scene, options, i, n, &plan.output, &progress)
        })??;
        progress.finish();
        return Ok(Outcome::Success);
    }
    let out = render_with(&scene, options, &progress)?;
    progress.finish();
    print_render_notes(&out, plan.timings, plan.explain);
    // Verified before anything is written: a failed certificate
    // leaves no unverified image behind.
    if let Some(k) = plan.verify {
        let report = with_threads(threads, || verify_render(&scene, options, k))??;
        write_stderr(&format!("penumbra: {report}\n"));
        report.check()?;
    }
    // All outputs or none: all are staged, then moved into place.
    let mut outputs = OutputSet::new();
    stage_images(&mut outputs, &plan, &out)?;
    outputs.commit()?;
    Ok(Outcome::Success)
}

/// A progressive render (`--target-error`, `--max-samples`,
/// `--max-time`): its live line and preview, then its outputs with how it
/// stopped in the EXR header.
fn run_progressive(plan: &RenderPlan, scene: &Scene) -> Result<Outcome> {
    let options = &plan.options;
    let progress = crate::render::ConvergenceProgress::new(true, plan.preview.clone());
    let out = with_threads(plan.threads, || render_with(scene, options, &progress))??;
    progress.finish();
    print_render_notes(&out, plan.timings, plan.explain);
    let convergence = out.explain.convergence.as_ref();
    if let Some(c) = convergence {
        write_stderr(&format!("penumbra: {}\n", c.summary()));
    }
    if let Some(k) = plan.verify {
        // The first set is the ordinary render at --seed: its decisions
        // are the ones certified.
        let first = RenderOptions {
            progressive: None,
            aovs: Vec::new(),
            ..options.clone()
        };
        let report = with_threads(plan.threads, || verify_render(scene, &first, k))??;
        write_stderr(&format!("penumbra: {report} (the first set)\n"));
        report.check()?;
    }
    let mut outputs = OutputSet::new();
    outputs.set_exr_metadata(convergence.map(|c| c.metadata()).unwrap_or_default());
    if let (Some(path), Some(c)) = (&plan.convergence, convergence) {
        let csv = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
        outputs.stage(path, |tmp| match csv {
            true => std::fs::write(tmp, convergence_csv(&c.curve)).map_err(|e| Error::io(tmp, e)),
            false => {
                let scene_name = plan.scene.file_stem().unwrap_or_default().to_string_lossy();
                let title = format!(
                    "{} on {scene_name}: {} sets of {} spp, stopped by {}",
                    options.technique.name(),
                    c.sets,
                    c.samples_per_set,
                    c.stop.name()
                );
                write_convergence_chart(tmp, &title, &c.curve, c.target_error)
            }
        })?;
    }
    stage_images(&mut outputs, plan, &out)?;
    outputs.commit()?;
    Ok(Outcome::Success)
}

/// Stages the plan's images (`-o`, `--exr`) of `out` into `outputs`.
fn stage_images(outputs: &mut OutputSet, plan: &RenderPlan, out: &Render) -> Result<()> {
    for (path, format) in &plan.images {
        outputs.image(
            path,
            *format,
            out.width,
            out.height,
            &out.radiance,
            &out.layers,
        )?;
    }
    Ok(())
}

/// A `render` command line checked before the scene is loaded.
struct RenderPlan {
    /// The scene file.
    scene: PathBuf,
    /// `-o`: the image, or with `--tiles` the part file.
    output: PathBuf,
    /// The images to write, with their formats (none for a part).
    images: Vec<(PathBuf, Format)>,
    /// `--tiles I/N`: render band I of N into the part file.
    band: Option<(u32, u32)>,
    options: RenderOptions,
    threads: Option<usize>,
    timings: bool,
    explain: bool,
    verify: Option<u64>,
    /// `--preview`: the PNG a progressive render rewrites as it goes.
    preview: Option<PathBuf>,
    /// `--convergence`: the error curve's chart (.png) or table (.csv).
    convergence: Option<PathBuf>,
}

impl RenderPlan {
    /// Checks `args` in the order the errors are reported (each option's
    /// own message), refusing what would fail only after the render.
    fn check(args: RenderArgs) -> Result<RenderPlan> {
        let RenderArgs {
            scene,
            output,
            exr,
            aov,
            width,
            height,
            threads,
            technique,
            samples,
            seed,
            pattern,
            options: technique_options,
            timings,
            explain,
            verify,
            tiles,
            target_error,
            max_samples,
            max_time,
            preview,
            convergence,
        } = args;
        let aovs = aov
            .iter()
            .map(|s| s.trim().parse())
            .collect::<Result<Vec<Aov>>>()?;
        let band = tiles
            .map(|t| crate::cluster::tiles::parse_share("--tiles", &t))
            .transpose()?;
        // Fail on a bad output path before the render, not after it;
        // a part (--tiles) takes any name, an image's extension decides
        // its format.
        let images = match band {
            Some(_) => {
                check_output(&output)?;
                Vec::new()
            }
            None => image_outputs(&output, exr.as_deref(), &[])?,
        };
        if !aovs.is_empty() && band.is_none() && !images.iter().any(|(_, f)| *f == Format::Exr) {
            return Err(Error::param(
                "--aov",
                "AOV layers need an EXR output (-o NAME.exr or --exr)",
            ));
        }
        let options = RenderOptions {
            width,
            height,
            aovs,
            technique,
            samples,
            seed,
            pattern,
            options: technique_options,
            threads,
            progressive: (target_error.is_some() || max_samples.is_some() || max_time.is_some())
                .then_some(crate::render::StopRule {
                    target_error,
                    max_samples,
                    max_time,
                }),
        };
        options.validate()?;
        if let Some(p) = &convergence {
            if options.progressive.is_none() {
                return Err(Error::param(
                    "--convergence",
                    "a convergence curve is of a progressive render: add --target-error, \
                     --max-samples or --max-time",
                ));
            }
            check_output(p)?;
            let ext = p
                .extension()
                .map(|e| e.to_string_lossy().to_ascii_lowercase());
            if !matches!(ext.as_deref(), Some("png" | "csv")) {
                return Err(Error::param(
                    "--convergence",
                    format!(
                        "{}: the extension decides: .png (chart) or .csv",
                        p.display()
                    ),
                ));
            }
        }
        if let Some(p) = &preview {
            if options.progressive.is_none() {
                return Err(Error::param(
                    "--preview",
                    "a preview is of a progressive render: add --target-error, --max-samples \
                     or --max-time",
                ));
            }
            if image_format("--preview", p)? != Format::Png {
                return Err(Error::param("--preview", "the preview is a PNG (.png)"));
            }
            if images.iter().any(|(path, _)| path == p) {
                return Err(Error::param("--preview", "must not be the output image"));
            }
        }
        if let Some(k) = verify {
            // Refused before the render, not after it.
            check_verifiable(options.technique, &options.build_params(), k)?;
        }
        Ok(RenderPlan {
            scene,
            output,
            images,
            band,
            options,
            threads,
            timings,
            explain,
            verify,
            preview,
            convergence,
        })
    }
}

/// The render's notes on stderr: pass times (`--timings`, `--explain`),
/// warnings, and with `--explain` the SIMD level and the buffers.
fn print_render_notes(out: &Render, timings: bool, explain: bool) {
    if timings || explain {
        for pass in &out.passes {
            let ms = pass.time.as_secs_f64() * 1e3;
            write_stderr(&format!("{ms:>12.3} ms  {}\n", pass.name));
        }
    }
    for warning in &out.warnings {
        write_stderr(&format!("penumbra: warning: {warning}\n"));
    }
    if explain {
        write_stderr(&format!("simd: {} (PENUMBRA_SIMD)\n", out.explain.simd));
        write_stderr("buffers:\n");
        for buffer in &out.explain.buffers {
            let size = if buffer.bytes == 0 {
                "-".to_string()
            } else {
                format!("{:.2} MiB", buffer.bytes as f64 / (1u64 << 20) as f64)
            };
            write_stderr(&format!("{size:>12}  {}: {}\n", buffer.name, buffer.detail));
        }
        for warning in &out.warnings {
            write_stderr(&format!("{:>12}  note: {warning}\n", "-"));
        }
        if let Some(c) = &out.explain.convergence {
            write_stderr(&format!(
                "progressive: {} (estimator: batch means over the sets; Vcoef RMSE {})\n",
                c.summary(),
                c.vcoef_error.map_or("none".into(), |v| format!("{v:.3e}"))
            ));
            for (k, p) in c.curve.iter().enumerate() {
                let e = p.error.map_or("-".into(), |e| format!("{e:.3e}"));
                write_stderr(&format!(
                    "{:>12}  set {}: {} spp, {:.3} s, est. RMSE {e}\n",
                    "-",
                    k + 1,
                    p.samples,
                    p.seconds
                ));
            }
        }
    }
}

/// `penumbra compare`: a merge of shards' partial results, the
/// references alone, one shard, or the whole sweep.
fn run_compare(args: CompareArgs) -> Result<Outcome> {
    let CompareArgs {
        scenes,
        shard,
        references_only,
        merge,
        techniques,
        samples,
        reference_samples,
        patterns,
        repeat,
        width,
        height,
        threads,
        seed,
        out,
        cache_dir,
        report,
        no_images,
        verify,
        sweep_settings,
        target_error,
        options: technique_options,
    } = args;
    if !merge.is_empty() {
        if !scenes.is_empty() {
            return Err(Error::param(
                "--merge",
                "takes the partial results' directories only: scenes and options come from the partials",
            ));
        }
        if let Some(report) = &report {
            check_output(report)?;
        }
        return merge_compare(&merge, &out, report.as_deref(), no_images);
    }
    let shard = shard.as_deref().map(ShardSpec::parse).transpose()?;
    if shard.is_some() && report.is_some() && !references_only {
        return Err(Error::param(
            "--report",
            "a shard writes a partial result: give --report to --merge",
        ));
    }
    let options = CompareOptions {
        techniques,
        technique_options,
        samples,
        reference_samples,
        repeat,
        width,
        height,
        seed,
        cache_dir: cache_dir.unwrap_or_else(|| default_cache_dir(&out.join("cache"))),
        images: !no_images,
        verify,
        patterns: patterns
            .iter()
            .map(|p| SamplePattern::parse(p.trim()).map_err(|e| Error::param("--patterns", e)))
            .collect::<Result<Vec<_>>>()?,
        // The sweep runs in the pool of `threads` below (the references
        // and shards too).
        threads: None,
        sweep_settings,
        target_error,
    };
    options.validate()?;
    if let Some(report) = &report {
        check_output(report)?;
    }
    let loaded = scenes
        .iter()
        .map(|p| load_scene(p))
        .collect::<Result<Vec<Scene>>>()?;
    if references_only {
        return compute_references(&loaded, &options, shard, threads);
    }
    if let Some(shard) = shard {
        return compare_shard(&loaded, &options, shard, &out, threads);
    }
    compare_scenes(&loaded, &options, &out, report.as_deref(), threads)
}

/// `compare --merge`: the shards' partial results in `partials` joined
/// into the results of one unsharded run in `out`.
fn merge_compare(
    partials: &[PathBuf],
    out: &Path,
    report: Option<&Path>,
    no_images: bool,
) -> Result<Outcome> {
    let merged = merge_partials(partials, out, !no_images)?;
    write_results(out, &merged.results, report, &merged.command)?;
    let runs: usize = merged.results.iter().map(|(r, _)| r.runs.len()).sum();
    write_stderr(&format!(
        "merged {} partial results: {} scenes, {runs} runs; results in {}\n",
        merged.partials,
        merged.results.len(),
        out.display()
    ));
    check_verified(&merged.results)?;
    Ok(Outcome::Success)
}

/// `compare --references-only`: each scene's reference computed into
/// the cache (or found there); with `--shard I/N` scenes I, I+N, ... only.
fn compute_references(
    scenes: &[Scene],
    options: &CompareOptions,
    shard: Option<ShardSpec>,
    threads: Option<usize>,
) -> Result<Outcome> {
    for (i, scene) in scenes.iter().enumerate() {
        if shard.is_some_and(|s| i as u32 % s.count != s.index - 1) {
            continue;
        }
        let (file, cached) = with_threads(threads, || {
            reference_only(scene, options, &Progress::hidden())
        })??;
        write_stderr(&format!(
            "{}: reference {} {}\n",
            scene.name,
            if cached {
                "already in"
            } else {
                "computed into"
            },
            file.display()
        ));
    }
    Ok(Outcome::Success)
}

/// `compare --shard I/N`: this shard's runs, written as a partial result
/// in `out`.
fn compare_shard(
    scenes: &[Scene],
    options: &CompareOptions,
    shard: ShardSpec,
    out: &Path,
    threads: Option<usize>,
) -> Result<Outcome> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    for line in shard_listing(scenes, options, shard)? {
        write_stderr(&format!("{line}\n"));
    }
    let summary = with_threads(threads, || {
        run_shard(scenes, options, shard, out, &unsharded_command(&args), true)
    })??;
    write_stderr(&format!(
        "shard {shard}: {} of the sweep's {} runs; partial result in {}\n",
        summary.runs,
        summary.sweep_runs,
        summary.partial.display()
    ));
    Ok(Outcome::Success)
}

/// The whole compare sweep over `scenes`, its results written to `out`.
fn compare_scenes(
    scenes: &[Scene],
    options: &CompareOptions,
    out: &Path,
    report: Option<&Path>,
    threads: Option<usize>,
) -> Result<Outcome> {
    // The list of runs before any starts: nothing runs that the user
    // cannot see coming.
    for line in sweep_listing(scenes, options)? {
        write_stderr(&format!("{line}\n"));
    }
    let progress = Progress::sweep(sweep_work(scenes, options)?, true);
    let command = command_line();
    let files = SweepOutput {
        dir: out,
        report,
        command: &command,
    };
    let results = with_threads(threads, || sweep(scenes, options, Some(&files), &progress))??;
    progress.finish();
    let results: Vec<_> = (results.into_iter())
        .map(|result| {
            let dir = scene_dir(out, &result.scene, scenes.len());
            (result, dir)
        })
        .collect();
    for (result, dir) in &results {
        write_stderr(&format!(
            "{}: {} runs; results in {}\n",
            result.scene,
            result.runs.len(),
            dir.display()
        ));
    }
    check_verified(&results)?;
    Ok(Outcome::Success)
}

/// `penumbra diff`.
fn run_diff(args: DiffArgs) -> Result<Outcome> {
    let DiffArgs {
        a,
        b,
        channels_a,
        channels_b,
        mask,
        mask_channel,
        max_abs,
        rmse,
        flip,
        flip_threshold,
        flip_map,
        json,
    } = args;
    for (name, v) in [
        ("--max-abs", max_abs),
        ("--rmse", rmse),
        ("--flip-threshold", flip_threshold),
    ] {
        if let Some(v) = v {
            if !(v >= 0.0) || !v.is_finite() {
                return Err(Error::param(
                    name,
                    format!("{v} is not a finite tolerance >= 0"),
                ));
            }
        }
    }
    let report = diff_images(
        &a,
        &b,
        &DiffOptions {
            channels_a,
            channels_b,
            mask,
            mask_channel,
            max_abs,
            rmse,
            flip,
            flip_threshold,
            flip_map,
        },
    )?;
    if json {
        let text = serde_json::to_string_pretty(&report)
            .map_err(|e| Error::param("--json", e.to_string()))?;
        write_stdout(&format!("{text}\n"))?;
    } else {
        write_stdout(&report.to_text())?;
    }
    Ok(if report.passed() {
        Outcome::Success
    } else {
        Outcome::ToleranceExceeded
    })
}

/// `penumbra techniques`.
fn run_techniques(markdown: bool, names: bool, json: bool) -> Result<Outcome> {
    // Checked writes, not print!: a full disk behind `>` is an
    // error, a closed pipe a quiet end (never a panic).
    let text = if json {
        let data = crate::shadow::registry::technique_data();
        serde_json::to_string_pretty(&data).map_err(|e| Error::param("--json", e.to_string()))?
            + "\n"
    } else if markdown {
        crate::shadow::registry::markdown_table("algorithms/")
    } else if names {
        let mut s = String::new();
        for name in crate::shadow::registry::names() {
            s.push_str(name);
            s.push('\n');
        }
        s
    } else {
        let listing = crate::shadow::registry::listing();
        // Wrapped on a terminal only: piped, each technique keeps its two
        // whole lines for grep and scripts.
        match console::Term::stdout().size_checked() {
            Some((_rows, columns)) => fit_listing(&listing, usize::from(columns)),
            None => listing,
        }
    };
    write_stdout(&text)?;
    Ok(Outcome::Success)
}

/// The narrowest text column [`fit_listing`] wraps into; a terminal with
/// less room gets the lines whole.
const MIN_LISTING_TEXT: usize = 24;

/// The `techniques` listing fitted to `columns`: a line too long breaks
/// at spaces and goes on under the text column (where the summaries
/// start), so that nothing runs into the names' column.
fn fit_listing(listing: &str, columns: usize) -> String {
    // The text column: the indentation of the capability lines.
    let column = listing
        .lines()
        .map(|line| line.len() - line.trim_start().len())
        .find(|&indent| indent > 0)
        .unwrap_or(0);
    let indent = " ".repeat(column);
    let mut fitted = String::new();
    for line in listing.lines() {
        let head = line.get(..column).filter(|head| head.ends_with(' '));
        match head {
            Some(head) if columns >= column + MIN_LISTING_TEXT => {
                let options = textwrap::Options::new(columns)
                    .initial_indent(head)
                    .subsequent_indent(&indent);
                for piece in textwrap::wrap(&line[column..], options) {
                    fitted.push_str(&piece);
                    fitted.push('\n');
                }
            }
            _ => {
                fitted.push_str(line);
                fitted.push('\n');
            }
        }
    }
    fitted
}

/// `penumbra info`.
fn run_info(scene: &Path) -> Result<Outcome> {
    let scene = load_scene(scene)?;
    write_stdout(&describe(&scene))?;
    Ok(Outcome::Success)
}

/// The `info` report.
pub fn describe(scene: &Scene) -> String {
    let mut s = String::new();
    let mut line = |l: String| {
        s.push_str(&l);
        s.push('\n');
    };
    // World positions: the scene's local positions plus its origin (zero
    // unless the scene was moved next to the origin on loading).
    let origin = scene.origin;
    let world = |p: glam::Vec3| -> String {
        if origin == glam::DVec3::ZERO {
            format!("{:?}", p.to_array())
        } else {
            format!("{:?}", (p.as_dvec3() + origin).to_array())
        }
    };
    line(format!(
        "scene      {} ({})",
        scene.name,
        scene.path.display()
    ));
    line(format!(
        "camera     {}x{}, fov_y {}°, eye {}",
        scene.camera.width,
        scene.camera.height,
        scene.camera.fov_y_degrees,
        world(scene.camera.eye)
    ));
    line(format!("objects    {}", scene.objects.len()));
    line(format!("triangles  {}", scene.triangle_count()));
    line(format!(
        "vertices   {}",
        scene
            .objects
            .iter()
            .map(|o| o.mesh.positions.len())
            .sum::<usize>()
    ));
    match scene.bounds() {
        Some((lo, hi)) => line(format!("bounds     {} .. {}", world(lo), world(hi))),
        None => line("bounds     (empty)".into()),
    }
    line(format!("materials  {}", scene.materials.len()));
    for m in &scene.materials {
        line(format!(
            "  {:<20} albedo {:?} opacity {}{}{}",
            m.name,
            m.albedo.to_array(),
            m.opacity,
            if m.albedo_texture.is_some() {
                " +albedo texture"
            } else {
                ""
            },
            if m.opacity_texture.is_some() {
                " +opacity texture"
            } else {
                ""
            },
        ));
    }
    line(format!("textures   {}", scene.textures.len()));
    line(format!("lights     {}", scene.lights.len()));
    for (k, l) in scene.lights.iter().enumerate() {
        let shape = match l.shape {
            LightShape::Rect {
                center,
                u,
                v,
                two_sided,
            } => format!(
                "rect centre {} u {:?} v {:?}{}",
                world(center),
                u.to_array(),
                v.to_array(),
                if two_sided { " two-sided" } else { "" }
            ),
            LightShape::Sphere { center, radius } => {
                format!("sphere centre {} radius {}", world(center), radius)
            }
        };
        line(format!(
            "  {k}: {shape}, radiance {:?}{}",
            l.radiance.to_array(),
            if l.texture.is_some() {
                ", textured"
            } else {
                ""
            }
        ));
    }
    s
}

/// Warns about each option the user gave that the render's technique does
/// not read on `scene` (the registry's [`crate::shadow::registry::options_read`]).
fn warn_unread_options(options: &RenderOptions, scene: &Scene, given: &[(String, String)]) {
    let ids: Vec<String> = given.iter().map(|(id, _)| id.clone()).collect();
    let unread =
        crate::shadow::registry::unread_options(options.technique, &options.options, scene, &ids);
    for (_, long) in given.iter().filter(|(id, _)| unread.contains(id)) {
        write_stderr(&format!(
            "penumbra: warning: {long} does not apply to `{}` and is ignored\n",
            options.technique.name()
        ));
    }
}

/// Entry point for `main`: parses the process's arguments, runs, prints
/// errors, returns the exit code.
pub fn main_with_args() -> std::process::ExitCode {
    main_with(std::env::args_os())
}

/// [`main_with_args`] on given arguments (the first is the program name).
/// The unit-test harness runs the command through it (CI's renders at
/// each SIMD level, `tests::command_lines_from_env`).
pub fn main_with<I, T>(args: I) -> std::process::ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    use clap::parser::ValueSource;
    use clap::{CommandFactory, FromArgMatches};
    let mut command = short_help_kept_short(Cli::command());
    let matches = match command.try_get_matches_from_mut(args) {
        Ok(m) => m,
        Err(e) => return clap_exit(e),
    };
    let mut cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => return clap_exit(e.format(&mut command)),
    };
    if let Some((name, sub)) = matches.subcommand() {
        let args = command.find_subcommand(name).map(|c| c.get_arguments());
        cli.given = (args.into_iter().flatten())
            .filter(|a| sub.value_source(a.get_id().as_str()) == Some(ValueSource::CommandLine))
            .map(|a| {
                let long = a
                    .get_long()
                    .map_or(a.get_id().to_string(), |l| format!("--{l}"));
                (a.get_id().to_string(), long)
            })
            .collect();
    }
    match run(cli) {
        Ok(Outcome::Success) => std::process::ExitCode::SUCCESS,
        Ok(Outcome::ToleranceExceeded) => std::process::ExitCode::from(1),
        Err(e) => {
            write_stderr(&format!("penumbra: error: {e}\n"));
            std::process::ExitCode::from(2)
        }
    }
}

/// The option groups `-h` shows; each technique's own options (under its
/// heading) are left to `--help`, so that the short help fits a screen.
const SHORT_HELP_HEADINGS: [&str; 4] = ["Output", "Image", "Light sampling", "Diagnostics"];

/// `command` with every technique's options hidden from `-h` (`--help`
/// lists them all, grouped by technique), and a line saying so.
fn short_help_kept_short(command: clap::Command) -> clap::Command {
    let hide = |a: clap::Arg| match a.get_help_heading() {
        Some(h) if !SHORT_HELP_HEADINGS.contains(&h) => a.hide_short_help(true),
        _ => a,
    };
    let note = "Each technique's own options (DCS, shadow maps, PCSS, penumbra casting, ...): \
                see --help.";
    command
        .mut_subcommand("render", |c| {
            c.mut_args(hide).after_help(note).after_long_help("")
        })
        .mut_subcommand("compare", |c| {
            c.mut_args(hide).after_help(note).after_long_help("")
        })
}

/// Ends on a clap "error": `--help` and `--version` go to stdout through
/// the checked writer (a full disk is an error, a closed pipe is not);
/// real usage errors go to stderr as clap prints them.
fn clap_exit(e: clap::Error) -> std::process::ExitCode {
    if e.use_stderr() {
        let _ = e.print();
        return std::process::ExitCode::from(e.exit_code().clamp(0, 255) as u8);
    }
    match write_stdout(&e.render().to_string()) {
        Ok(()) => std::process::ExitCode::from(e.exit_code().clamp(0, 255) as u8),
        Err(err) => {
            write_stderr(&format!("penumbra: error: {err}\n"));
            std::process::ExitCode::from(2)
        }
    }
}

/// The command line as typed, for reports ("regenerate with ...").
fn command_line() -> String {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quoted: Vec<String> = args
        .iter()
        .map(|a| {
            if a.is_empty() || a.contains(|c: char| c.is_whitespace() || "'\"$`".contains(c)) {
                format!("'{}'", a.replace('\'', "'\\''"))
            } else {
                a.clone()
            }
        })
        .collect();
    format!("penumbra {}", quoted.join(" "))
}

/// The `--technique` parser: the registry's names, listed in the help and
/// in the error for an unknown one.
fn technique_parser() -> impl clap::builder::TypedValueParser<Value = Technique> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(crate::shadow::registry::names()).map(
        |name: String| Technique::named(&name).expect("the parser offers registered names only"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs the `penumbra` command lines listed in the file that
    /// `PENUMBRA_COMMAND_LINES` names (one per line, shell words, without
    /// the program name), each of which must succeed. CI's check of the
    /// same bits at every SIMD level builds this harness at each level
    /// instead of the binary too: one build of the crate per level, not
    /// two, and the check that the harness's images equal the binary's at
    /// the baseline ties the two together (`.ci/run`).
    #[test]
    #[ignore = "run by .ci/run with PENUMBRA_COMMAND_LINES"]
    fn command_lines_from_env() {
        let path = std::env::var("PENUMBRA_COMMAND_LINES")
            .expect("PENUMBRA_COMMAND_LINES names no file of command lines");
        let text = std::fs::read_to_string(&path).expect("the command lines' file reads");
        let mut ran = 0;
        for line in text.lines().filter(|l| !l.trim().is_empty()) {
            let words = shlex::split(line).expect("the command line is shell words");
            let args = std::iter::once("penumbra".to_string()).chain(words);
            let code = main_with(args);
            assert_eq!(code, std::process::ExitCode::SUCCESS, "{line}");
            ran += 1;
        }
        assert!(ran > 0, "{path} lists no command line");
    }

    /// Fitted to 80 columns, the listing keeps every word in order, starts
    /// each technique's line with its name and indents the rest under the
    /// text column.
    #[test]
    fn the_techniques_listing_fits_a_terminal() {
        let listing = crate::shadow::registry::listing();
        let fitted = fit_listing(&listing, 80);
        assert!(fitted.lines().all(|l| l.chars().count() <= 80), "{fitted}");
        let words = |text: &str| {
            text.split_whitespace()
                .map(String::from)
                .collect::<Vec<_>>()
        };
        assert_eq!(words(&fitted), words(&listing));
        let names = crate::shadow::registry::names();
        let starts: Vec<&str> = fitted
            .lines()
            .filter(|l| !l.starts_with(' '))
            .map(|l| l.split_whitespace().next().unwrap_or(""))
            .collect();
        assert_eq!(starts, names);
        // Too narrow to wrap into: the lines stay whole.
        assert_eq!(fit_listing(&listing, 20), listing);
    }
}
