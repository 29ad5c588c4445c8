//! The adapter: the only file of the Python package that names
//! `penumbra::` paths. Everything here speaks plain Rust (strings, `f32`
//! vectors, JSON text), so when the crate's public surface moves, this
//! file is the one to change.

use std::path::Path;

/// A loaded scene.
pub use penumbra::Scene;

/// The crate's error: file and line, or a parameter's name, in its
/// `Display`.
pub use penumbra::Error;

/// A render's cancel flag, shared with the thread that polls for Ctrl-C.
pub use penumbra::Cancel;

/// Result with the crate's error.
pub type Result<T> = std::result::Result<T, Error>;

/// Whether [`Cancel`] stops a render early (the prompt-cancellation test
/// runs when it does).
pub const CANCEL_WIRED: bool = true;

/// Loads a scene file (relative paths inside it resolve from its folder).
pub fn load_scene(path: &Path) -> Result<Scene> {
    penumbra::load_scene(path)
}

/// Parses scene TOML text; relative paths inside resolve from `base_dir`.
pub fn scene_from_toml(text: &str, base_dir: &Path) -> Result<Scene> {
    penumbra::scene_from_toml(text, base_dir)
}

/// What Python shows of a scene.
pub struct SceneSummary {
    /// `[scene] name`, or the file stem.
    pub name: String,
    /// The camera's width in pixels.
    pub width: u32,
    /// The camera's height in pixels.
    pub height: u32,
    /// Number of lights.
    pub lights: usize,
    /// Number of triangles.
    pub triangles: usize,
}

/// The scene's name, camera size and counts.
pub fn summary(scene: &Scene) -> SceneSummary {
    SceneSummary {
        name: scene.name.clone(),
        width: scene.camera.width,
        height: scene.camera.height,
        lights: scene.lights.len(),
        triangles: scene.triangle_count(),
    }
}

/// How an error reaches Python.
pub enum ErrorKind {
    /// A problem in a scene or other input file (file and line).
    File,
    /// A parameter out of range or unknown.
    Parameter,
    /// Reading or writing a path failed.
    Io,
    /// The render was cancelled (Python raises the interrupt instead).
    Cancelled,
}

/// The kind of `e`, and its message with parameter names as Python spells
/// them (`samples`, not `--samples`): the keyword arguments share the
/// command line's names with dashes turned into underscores.
pub fn describe_error(e: &Error) -> (ErrorKind, String) {
    match e {
        Error::File { .. } => (ErrorKind::File, e.to_string()),
        Error::Io { .. } => (ErrorKind::Io, e.to_string()),
        Error::Cancelled => (ErrorKind::Cancelled, e.to_string()),
        Error::Parameter { name, message } => {
            let name = python_name(name);
            (
                ErrorKind::Parameter,
                format!("parameter `{name}`: {message}"),
            )
        }
        // A kind added to the crate later: its words, as a parameter
        // error (ValueError) until it gets its own Python class.
        _ => (ErrorKind::Parameter, e.to_string()),
    }
}

/// `--map-size` → `map_size`, `--aov` → `aovs` (the
/// keyword's name); names that are no flag (`camera.fov_y`) stay.
fn python_name(name: &str) -> String {
    name.split('/')
        .map(|part| match part.strip_prefix("--") {
            Some("aov") => "aovs".to_string(),
            Some(flag) => flag.replace('-', "_"),
            None => part.to_string(),
        })
        .collect::<Vec<_>>()
        .join("/")
}

/// One render's settings as Python gives them.
pub struct Request {
    /// The technique's name.
    pub technique: String,
    /// Light samples per pixel and light.
    pub samples: u32,
    /// Width override.
    pub width: Option<u32>,
    /// Height override.
    pub height: Option<u32>,
    /// The seed.
    pub seed: u64,
    /// AOV layer names.
    pub aovs: Vec<String>,
    /// Worker threads (all cores when `None`).
    pub threads: Option<usize>,
    /// The sample pattern's name (the default when `None`).
    pub pattern: Option<String>,
    /// The techniques' own options as command-line words
    /// (`["--map-size", "1024"]`), parsed by the CLI's parser.
    pub option_args: Vec<String>,
    /// Progressive rendering: the target radiance RMSE.
    pub target_error: Option<f64>,
    /// Progressive rendering: at most this many samples in all.
    pub max_samples: Option<u64>,
    /// Progressive rendering: at most this many seconds.
    pub max_time: Option<f64>,
}

/// One output layer: its name and `(channel, values)` pairs, row-major.
pub struct LayerData {
    /// Layer name (`depth`, `normal`, `vcoef`, ...).
    pub name: String,
    /// Channel names and their `width × height` values.
    pub channels: Vec<(String, Vec<f32>)>,
}

/// A finished render, as plain data.
pub struct RenderData {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear radiance, RGB interleaved, row 0 at the top.
    pub radiance: Vec<f32>,
    /// The requested AOV layers and the technique's own.
    pub layers: Vec<LayerData>,
    /// Visibility coefficient per light (as the technique returned it:
    /// background pixels are not zeroed, unlike the `vcoef` layer).
    pub vcoef: Vec<Vec<f32>>,
    /// Pass name and seconds, in order.
    pub timings: Vec<(String, f64)>,
    /// The `--explain` report as JSON text.
    pub explain_json: String,
    /// What the result leaves out of the scene, in words.
    pub warnings: Vec<String>,
}

/// The render options of `request`, checked as the command line checks
/// them.
fn render_options(request: &Request) -> Result<penumbra::RenderOptions> {
    use clap::{Args, FromArgMatches};
    use penumbra::{Aov, RenderOptions, TechniqueOptions};
    let aovs = request
        .aovs
        .iter()
        .map(|s| s.parse())
        .collect::<Result<Vec<Aov>>>()?;
    let pattern = match &request.pattern {
        None => RenderOptions::default().pattern,
        Some(p) => p.parse().map_err(|e| Error::param("--pattern", e))?,
    };
    let words = std::iter::once("penumbra".to_string()).chain(request.option_args.iter().cloned());
    let options = TechniqueOptions::augment_args(clap::Command::new("penumbra"))
        .try_get_matches_from(words)
        .and_then(|m| TechniqueOptions::from_arg_matches(&m))
        .map_err(|e| {
            let text = e.render().to_string();
            let first = text.lines().next().unwrap_or_default();
            Error::param("technique options", first.trim_start_matches("error: "))
        })?;
    let options = RenderOptions {
        width: request.width,
        height: request.height,
        aovs,
        technique: request.technique.parse()?,
        samples: request.samples,
        seed: request.seed,
        pattern,
        options,
        threads: request.threads,
        progressive: progressive_rule(request)?,
    };
    options.validate()?;
    Ok(options)
}

/// The stop rule of a progressive render, if the request asks for one.
fn progressive_rule(request: &Request) -> Result<Option<penumbra::StopRule>> {
    let max_time = match request.max_time {
        None => None,
        Some(t) if t.is_finite() && t > 0.0 && t < 1e9 => {
            Some(std::time::Duration::from_secs_f64(t))
        }
        Some(t) => {
            return Err(Error::param(
                "max_time",
                format!("{t} is not a number of seconds in (0, 1e9)"),
            ))
        }
    };
    let rule = penumbra::StopRule {
        target_error: request.target_error,
        max_samples: request.max_samples,
        max_time,
    };
    Ok((rule != penumbra::StopRule::default()).then_some(rule))
}

/// Renders `scene` with `request` on `request.threads` threads, stopping
/// with [`Error::Cancelled`] once `cancel` is raised.
pub fn render(scene: &Scene, request: &Request, cancel: &Cancel) -> Result<RenderData> {
    let options = render_options(request)?;
    let out = penumbra::render_with(scene, &options, cancel)?;
    let mut timings: Vec<(String, f64)> = Vec::new();
    for pass in &out.passes {
        let seconds = pass.time.as_secs_f64();
        // A pass run twice (per light, say) sums under its one name.
        match timings.iter_mut().find(|(name, _)| *name == pass.name) {
            Some((_, total)) => *total += seconds,
            None => timings.push((pass.name.clone(), seconds)),
        }
    }
    Ok(RenderData {
        width: out.width,
        height: out.height,
        radiance: out.radiance.iter().flat_map(|c| [c.x, c.y, c.z]).collect(),
        layers: out
            .layers
            .into_iter()
            .map(|l| LayerData {
                name: l.name,
                channels: l.channels,
            })
            .collect(),
        vcoef: out.lights.iter().map(|l| l.vcoef().to_vec()).collect(),
        timings,
        explain_json: serde_json::to_string(&out.explain).expect("the explain report serializes"),
        warnings: out.warnings.iter().map(|w| w.to_string()).collect(),
    })
}

/// The crate's defaults of the arguments Python writes out in its
/// signatures (`RenderOptions::default()`, `CompareOptions::default()`),
/// as JSON text: a test holds the signatures to them.
pub fn defaults_json() -> String {
    let render = penumbra::RenderOptions::default();
    let compare = penumbra::CompareOptions::default();
    serde_json::json!({
        "render": {
            "technique": render.technique.name(),
            "samples": render.samples,
            "seed": render.seed,
            "pattern": render.pattern.name(),
        },
        "compare": {
            "techniques": compare.techniques.iter().map(|t| t.name()).collect::<Vec<_>>(),
            "samples": compare.samples,
            "reference_samples": compare.reference_samples,
            "patterns": compare.patterns.iter().map(|p| p.name()).collect::<Vec<_>>(),
            "repeat": compare.repeat,
            "seed": compare.seed,
            "images": compare.images,
            "sweep_settings": compare.sweep_settings,
        },
    })
    .to_string()
}

/// Every registered technique and its capabilities, as JSON text (what
/// `penumbra techniques --json` prints).
pub fn techniques_json() -> String {
    serde_json::to_string(&penumbra::techniques()).expect("the registry serializes")
}

/// Whether [`compare_json`] runs (the notebook's last cell needs it).
pub const COMPARE_WIRED: bool = true;

/// A `compare` sweep's settings as Python gives them.
pub struct CompareRequest {
    /// Scene files.
    pub scenes: Vec<String>,
    /// Technique names.
    pub techniques: Vec<String>,
    /// Light-sample counts of the sampling techniques.
    pub samples: Vec<u32>,
    /// Samples per light of the reference.
    pub reference_samples: u32,
    /// Sample patterns DCS is measured with.
    pub patterns: Vec<String>,
    /// Timed runs per setting.
    pub repeat: u32,
    /// Width override.
    pub width: Option<u32>,
    /// Height override.
    pub height: Option<u32>,
    /// Worker threads.
    pub threads: Option<usize>,
    /// The seed.
    pub seed: u64,
    /// Output directory (`None`: no files but the reference cache).
    pub out: Option<String>,
    /// Reference cache directory (`None`: the command line's default).
    pub cache_dir: Option<String>,
    /// Skip per-run images and heat maps.
    pub no_images: bool,
    /// Also every other quality setting each technique sweeps
    /// (`--sweep-settings`).
    pub sweep_settings: bool,
}

/// Runs a `compare` sweep and returns its records (results.csv's rows) as
/// a JSON array of objects with results.csv's column names; stops with
/// [`Error::Cancelled`] once `cancel` is raised.
pub fn compare_json(request: &CompareRequest, cancel: &Cancel) -> Option<Result<String>> {
    Some(compare_records(request, cancel))
}

fn compare_records(request: &CompareRequest, cancel: &Cancel) -> Result<String> {
    use penumbra::{CompareOptions, SamplePattern, Technique};
    let scenes = (request.scenes.iter())
        .map(|p| penumbra::load_scene(Path::new(p)))
        .collect::<Result<Vec<_>>>()?;
    let techniques = (request.techniques.iter())
        .map(|t| Technique::named(t.trim()))
        .collect::<Result<Vec<_>>>()?;
    let patterns = (request.patterns.iter())
        .map(|p| SamplePattern::parse(p.trim()).map_err(|e| Error::param("--patterns", e)))
        .collect::<Result<Vec<_>>>()?;
    let out = request.out.as_deref().map(Path::new);
    let defaults = CompareOptions::default();
    // The command line's cache unless one is given ($PENUMBRA_CACHE,
    // then the user's cache folder): references are shared with it.
    let cache_dir =
        (request.cache_dir.as_ref()).map_or_else(|| defaults.cache_dir.clone(), Into::into);
    let options = CompareOptions {
        techniques,
        samples: request.samples.clone(),
        reference_samples: request.reference_samples,
        patterns,
        repeat: request.repeat,
        width: request.width,
        height: request.height,
        threads: request.threads,
        seed: request.seed,
        cache_dir,
        images: !request.no_images,
        sweep_settings: request.sweep_settings,
        ..defaults
    };
    let records = penumbra::compare_with(&scenes, &options, out, cancel)?;
    Ok(serde_json::to_string(&records).expect("the records serialize"))
}
