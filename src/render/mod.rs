//! One render from start to end: G-buffer, shadow technique, shading, AOVs.

mod estimate;
mod live;
mod progressive;
mod shading;

pub use estimate::{estimate_render, progress_for_render};
pub use live::ConvergenceProgress;
pub use progressive::{set_seed, Convergence, SetPoint, SetStatus, StopReason, StopRule};
pub use shading::shade;

use crate::error::{Error, Result};
use crate::gbuffer::{gbuffer_pass, GBuffer};
use crate::geom::SceneGeometry;
use crate::observe::{Observer, Silent};
use crate::output::Layer;
use crate::raster::DrawStats;
use crate::sampling::SamplePattern;
use crate::scene::Scene;
use crate::shadow::kit::verify::VerifyReport;
use crate::shadow::kit::PassTimer;
use crate::shadow::technique::BuildParams;
use crate::shadow::verify;
use crate::shadow::{
    run_technique, BufferNote, LightTerm, PassTiming, ShadowCache, ShadowContext, TechniqueOptions,
    Warning,
};
use crate::view::{near_for_bounds, View};
use glam::Vec3;
use std::str::FromStr;

/// An output layer besides radiance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Aov {
    /// `depth.Z`: view-space depth along the camera's forward axis.
    Depth,
    /// `position.X/Y/Z`: world position.
    Position,
    /// `normal.X/Y/Z`: shading normal facing the viewer.
    Normal,
    /// `albedo.R/G/B`.
    Albedo,
    /// `mask.Y`: 1 where a surface is seen.
    Mask,
    /// `vcoef.<k>`: visibility coefficient per light.
    Vcoef,
    /// `error.Y` and `error.V`: a progressive render's estimated standard
    /// error per pixel, of the radiance (RMS over R, G, B) and of the
    /// Vcoef (RMS over the lights).
    Error,
}

impl Aov {
    /// Every AOV any render produces, in output order.
    pub const ALL: [Aov; 6] = [
        Aov::Depth,
        Aov::Position,
        Aov::Normal,
        Aov::Albedo,
        Aov::Mask,
        Aov::Vcoef,
    ];

    /// The AOVs only a progressive render produces, after [`Aov::ALL`].
    pub const PROGRESSIVE: [Aov; 1] = [Aov::Error];

    /// The layer name.
    pub fn name(self) -> &'static str {
        match self {
            Aov::Depth => "depth",
            Aov::Position => "position",
            Aov::Normal => "normal",
            Aov::Albedo => "albedo",
            Aov::Mask => "mask",
            Aov::Vcoef => "vcoef",
            Aov::Error => "error",
        }
    }
}

impl FromStr for Aov {
    type Err = Error;
    fn from_str(s: &str) -> Result<Aov> {
        let all = || Aov::ALL.into_iter().chain(Aov::PROGRESSIVE);
        all().find(|a| a.name() == s).ok_or_else(|| {
            let names: Vec<_> = all().map(|a| a.name()).collect();
            Error::param(
                "--aov",
                format!("unknown layer `{s}` (known: {})", names.join(", ")),
            )
        })
    }
}

pub use crate::shadow::registry::Technique;

/// Options of one render.
#[derive(Debug, Clone)]
pub struct RenderOptions {
    /// Overrides the camera's width.
    pub width: Option<u32>,
    /// Overrides the camera's height.
    pub height: Option<u32>,
    /// AOV layers to produce.
    pub aovs: Vec<Aov>,
    /// The shadow technique.
    pub technique: Technique,
    /// Light samples per pixel and light, for techniques that sample.
    pub samples: u32,
    /// Seed of every random choice (per-pixel keyed).
    pub seed: u64,
    /// Placement of light samples (sampling techniques).
    pub pattern: SamplePattern,
    /// Every technique's own options (only the chosen one's matter).
    pub options: TechniqueOptions,
    /// Worker threads of [`render_with`] (all cores when `None`); the
    /// image is the same for any count.
    pub threads: Option<usize>,
    /// Render independent sets of `samples` until this rule stops
    /// (progressive rendering to a target error); one set when `None`.
    pub progressive: Option<StopRule>,
}

/// Most worker threads a render takes.
pub const MAX_THREADS: usize = 1024;

/// Most light samples per pixel and light a render takes.
pub const MAX_SAMPLES: u32 = 1 << 20;

impl RenderOptions {
    /// Every range check of the options, in one place: the command line
    /// calls it before it loads the scene and [`render`] before it renders,
    /// so the library refuses exactly what the command line refuses. The
    /// chosen technique's own option groups are checked too (the map
    /// techniques' depth bias, PCSS's sample counts); options it does not
    /// read are not.
    pub fn validate(&self) -> Result<()> {
        if !(1..=MAX_SAMPLES).contains(&self.samples) {
            return Err(Error::param(
                "--samples",
                format!("{} is outside 1..={MAX_SAMPLES}", self.samples),
            ));
        }
        // One limit for the CLI and scene files: the rasterizer's.
        for (name, v) in [("--width", self.width), ("--height", self.height)] {
            if let Some(v) = v.filter(|v| !(1..=crate::raster::MAX_SIDE).contains(v)) {
                return Err(Error::param(
                    name,
                    format!("{v} is outside 1..={}", crate::raster::MAX_SIDE),
                ));
            }
        }
        if let Some(n) = self.threads.filter(|n| !(1..=MAX_THREADS).contains(n)) {
            return Err(Error::param(
                "--threads",
                format!("{n} is outside 1..={MAX_THREADS}"),
            ));
        }
        if let Some(rule) = &self.progressive {
            rule.validate(self.technique, self.samples)?;
        } else if self.aovs.contains(&Aov::Error) {
            return Err(Error::param(
                "--aov",
                "the error layer needs two or more sample sets: add --target-error, \
                 --max-samples or --max-time",
            ));
        }
        self.options.validate(self.technique.info().reads)
    }

    /// What the technique is built from.
    pub fn build_params(&self) -> BuildParams<'_> {
        BuildParams {
            samples: self.samples,
            seed: self.seed,
            pattern: self.pattern,
            options: &self.options,
        }
    }
}

impl Default for RenderOptions {
    /// The command line's defaults.
    fn default() -> Self {
        RenderOptions {
            width: None,
            height: None,
            aovs: Vec::new(),
            technique: Technique::default(),
            samples: 64,
            seed: 0,
            pattern: SamplePattern::Stratified,
            options: TechniqueOptions::default(),
            threads: None,
            progressive: None,
        }
    }
}

/// A finished render: the image, its layers and per-light terms as typed
/// buffers (row-major, row 0 at the top), and how it was made.
#[derive(Debug, Clone)]
pub struct Render {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear radiance.
    pub radiance: Vec<Vec3>,
    /// The requested AOV layers, in [`Aov::ALL`] order, then the
    /// technique's own; each channel is one `f32` per pixel.
    pub layers: Vec<Layer>,
    /// The technique's result per light, in light order.
    pub lights: Vec<LightTerm>,
    /// Every pass with its wall-clock time, in order.
    pub passes: Vec<PassTiming>,
    /// Raster counters of the G-buffer pass.
    pub gbuffer_stats: DrawStats,
    /// What the result leaves out of the scene.
    pub warnings: Vec<Warning>,
    /// How the render was made (`--explain`), as data.
    pub explain: Explain,
}

/// How a render was made: what `render --explain` prints.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Explain {
    /// The technique's name.
    pub technique: String,
    /// Light samples per pixel and light.
    pub samples: u32,
    /// The SIMD level the kernels ran at, in words.
    pub simd: String,
    /// Worker threads the render ran on.
    pub threads: usize,
    /// The buffers the render used, and those it left out (0 bytes).
    pub buffers: Vec<BufferNote>,
    /// The warnings, in words.
    pub notes: Vec<String>,
    /// How a progressive render converged and why it stopped.
    pub convergence: Option<Convergence>,
}

impl Render {
    /// The layer named `name` (`depth`, `vcoef`, ...), if produced.
    pub fn layer(&self, name: &str) -> Option<&Layer> {
        self.layers.iter().find(|l| l.name == name)
    }
}

/// The view a render of `scene` with `options` uses.
pub fn view_for(scene: &Scene, options: &RenderOptions) -> Result<View> {
    let width = options.width.unwrap_or(scene.camera.width);
    let height = options.height.unwrap_or(scene.camera.height);
    View::new(
        &scene.camera,
        width,
        height,
        near_for_bounds(scene.camera.eye, scene.bounds()),
    )
}

/// Bytes a render holds per pixel at its peak: the G-buffer sample, the
/// visibility and depth tiles, radiance, one Vcoef per light and the AOV
/// layers (f32 channels), rounded up.
fn bytes_per_pixel(scene: &Scene, options: &RenderOptions) -> u64 {
    let gbuffer = GBuffer::bytes_per_pixel(scene) as u64;
    let lights = scene.lights.len() as u64;
    let sets = match options.progressive {
        Some(_) => progressive::accumulator_bytes_per_pixel(scene.lights.len()) + 12 + 8,
        None => 0,
    };
    gbuffer + 8 + 12 + 12 + lights * 8 + 16 * 4 + options.aovs.len() as u64 * 12 + sets
}

/// Refuses a render that cannot fit in memory, before allocating it:
/// against [`crate::allocator::memory_budget`], which honours an
/// address-space limit (`ulimit -v`) as well as the machine's memory.
pub fn check_memory(scene: &Scene, options: &RenderOptions, view: &View) -> Result<()> {
    let pixels = view.width as u64 * view.height as u64;
    let need = pixels * bytes_per_pixel(scene, options);
    if let Some(have) = crate::allocator::memory_budget() {
        if need > have {
            return Err(Error::param(
                "--width/--height",
                format!(
                    "{}x{} needs about {:.1} GiB, more than the {:.1} GiB available",
                    view.width,
                    view.height,
                    need as f64 / (1u64 << 30) as f64,
                    have as f64 / (1u64 << 30) as f64
                ),
            ));
        }
    }
    Ok(())
}

/// Renders a scene: checks the options ([`RenderOptions::validate`]), then
/// runs the G-buffer, the technique and shading on `options.threads`
/// worker threads.
pub fn render(scene: &Scene, options: &RenderOptions) -> Result<Render> {
    render_with(scene, options, &Silent)
}

/// [`render`], telling `observer` each stage as it starts and ends and
/// stopping with [`Error::Cancelled`] once it reports
/// [`Observer::cancelled`].
pub fn render_with(
    scene: &Scene,
    options: &RenderOptions,
    observer: &dyn Observer,
) -> Result<Render> {
    options.validate()?;
    with_threads(options.threads, || {
        render_rows(scene, options, observer, None)
    })?
}

/// Renders a scene with only the pixels of `rows` as receivers (all when
/// `None`): the G-buffer pass still covers the whole frame, so clipping,
/// binning and depth are the full render's, and the pixels outside `rows`
/// become background before the shadow technique runs (`render --tiles`,
/// [`crate::cluster::tiles`]).
pub fn render_rows(
    scene: &Scene,
    options: &RenderOptions,
    progress: &dyn Observer,
    rows: Option<std::ops::Range<u32>>,
) -> Result<Render> {
    options.validate()?;
    let view = view_for(scene, options)?;
    check_memory(scene, options, &view)?;
    let mut passes = Vec::new();
    // Each top-level pass is one progress step, and a point to stop at.
    let timed = |t: PassTimer, passes: &mut Vec<PassTiming>| {
        t.finish(passes);
        progress.step();
        match progress.cancelled() {
            true => Err(Error::Cancelled),
            false => Ok(()),
        }
    };

    progress.stage("geometry");
    let t = PassTimer::start("geometry");
    let geometry = SceneGeometry::new(scene);
    timed(t, &mut passes)?;

    progress.stage("g-buffer");
    let t = PassTimer::start("gbuffer");
    let (mut gbuffer, depth, gbuffer_stats) = gbuffer_pass(scene, &geometry, &view)?;
    if let Some(rows) = rows {
        gbuffer.keep_rows(rows);
    }
    timed(t, &mut passes)?;

    progress.stage("shadows");
    let cache = ShadowCache::new(scene, &geometry);
    let ctx = ShadowContext {
        scene,
        geometry: &geometry,
        view: &view,
        gbuffer: &gbuffer,
        depth: &depth,
        cache: &cache,
        observer: progress,
    };
    let (mut shadows, radiance, error_layer, convergence) = match &options.progressive {
        None => {
            let mut shadows = run_technique(options.technique, &options.build_params(), &ctx)?;
            unshadow_non_receivers(scene, &gbuffer, &mut shadows.lights);
            passes.extend(shadows.passes.iter().cloned());
            progress.step();
            // The long passes stop early when cancelled, leaving their
            // buffers unfinished: nothing of them may be used.
            if progress.cancelled() {
                return Err(Error::Cancelled);
            }
            progress.stage("shading");
            let t = PassTimer::start("shading");
            let radiance = shade(scene, &view, &gbuffer, &shadows.lights);
            timed(t, &mut passes)?;
            (shadows, radiance, None, None)
        }
        Some(rule) => {
            let c = progressive::converge(
                options.technique,
                &options.build_params(),
                rule,
                &ctx,
                progress,
            )?;
            passes.extend(c.output.passes.iter().cloned());
            progress.step();
            progress.step();
            (
                c.output,
                c.radiance,
                Some(c.error_layer),
                Some(c.convergence),
            )
        }
    };

    let mut layers = aov_layers(&gbuffer, &shadows.lights, &options.aovs, scene.origin);
    if options.aovs.contains(&Aov::Error) {
        layers.extend(error_layer);
    }
    layers.extend(std::mem::take(&mut shadows.layers));
    let pixels = u64::from(view.width) * u64::from(view.height);
    let mut buffers = vec![
        BufferNote {
            name: "g-buffer".into(),
            detail: "compact per-pixel points (f32 position, packed normals, ids)".into(),
            bytes: gbuffer.memory_bytes(),
        },
        BufferNote {
            name: "depth".into(),
            detail: "f32 reversed Z per pixel (exact for the stencil's tie rule)".into(),
            bytes: pixels * 4,
        },
    ];
    buffers.extend(shadows.buffers);
    buffers.push(match geometry.adjacency_built() {
        true => BufferNote {
            name: "edge adjacency".into(),
            detail: "welded vertices, edges and their face uses (u32 ids), for silhouettes".into(),
            bytes: geometry.adjacency().memory_bytes(),
        },
        false => BufferNote {
            name: "edge adjacency".into(),
            detail:
                "not built: no pass walked edges (closedness came from a welding table per object)"
                    .into(),
            bytes: 0,
        },
    });
    let warnings: Vec<Warning> = (crate::scene::lint::warnings(scene).into_iter())
        .map(Warning::Scene)
        .chain(shadows.warnings)
        .collect();
    let explain = Explain {
        technique: options.technique.name().to_string(),
        samples: options.samples,
        simd: crate::simd::level::describe(),
        threads: rayon::current_num_threads(),
        buffers,
        notes: warnings.iter().map(|w| w.to_string()).collect(),
        convergence,
    };
    Ok(Render {
        lights: shadows.lights,
        warnings,
        width: view.width,
        height: view.height,
        radiance,
        layers,
        passes,
        gbuffer_stats,
        explain,
    })
}

/// Sets the Vcoef of every surface pixel of an object with
/// `receive_shadows = false` to 1, as the scene contract says, whatever
/// the technique computed there: shading already ignores it, but the
/// `vcoef` AOV and `compare`'s Vcoef errors read it. One place for every
/// technique (the reference and penumbra casting write 1 themselves).
pub(crate) fn unshadow_non_receivers(scene: &Scene, gbuffer: &GBuffer, lights: &mut [LightTerm]) {
    if scene.objects.iter().all(|o| o.receive_shadows) {
        return;
    }
    let keeps: Vec<bool> = (0..gbuffer.len())
        .map(|i| {
            !gbuffer.is_surface(i)
                || scene
                    .objects
                    .get(gbuffer.sample(i).object as usize)
                    .is_none_or(|o| o.receive_shadows)
        })
        .collect();
    for term in lights {
        let vcoef = match term {
            LightTerm::Vcoef(v) | LightTerm::Radiance { vcoef: v, .. } => v,
        };
        for (v, &keep) in vcoef.iter_mut().zip(&keeps) {
            if !keep {
                *v = 1.0;
            }
        }
    }
}

/// `--verify k`: the G-buffer of the render `options` asks for, and `k` of
/// its technique's (pixel, light, sample) relations re-cast with shadow
/// rays ([`crate::shadow::kit::verify`]). An error if the technique does
/// not expose its decisions; a failed check is a report, not an error
/// ([`VerifyReport::check`]).
pub fn verify_render(scene: &Scene, options: &RenderOptions, k: u64) -> Result<VerifyReport> {
    let params = options.build_params();
    verify::check_verifiable(options.technique, &params, k)?;
    let view = view_for(scene, options)?;
    check_memory(scene, options, &view)?;
    let geometry = SceneGeometry::new(scene);
    let (gbuffer, depth, _) = gbuffer_pass(scene, &geometry, &view)?;
    let cache = ShadowCache::new(scene, &geometry);
    let ctx = ShadowContext {
        scene,
        geometry: &geometry,
        view: &view,
        gbuffer: &gbuffer,
        depth: &depth,
        cache: &cache,
        observer: &Silent,
    };
    crate::shadow::technique::check_scene(
        options.technique.info(),
        &options.options,
        scene,
        &geometry,
        &view,
    )?;
    verify::verify(options.technique, &params, &ctx, k)
}

/// Builds the requested standard AOV layers. Background pixels hold 0 in
/// every layer (`mask.Y` tells them apart). Positions are world positions:
/// `origin` (the scene's [`Scene::origin`]) is added back.
pub fn aov_layers(
    gbuffer: &GBuffer,
    terms: &[LightTerm],
    aovs: &[Aov],
    origin: glam::DVec3,
) -> Vec<Layer> {
    let channel = |name: &str, f: &dyn Fn(&crate::gbuffer::GSample) -> f32| {
        (
            name.to_string(),
            gbuffer
                .samples()
                .map(|g| if g.is_surface() { f(&g) } else { 0.0 })
                .collect::<Vec<f32>>(),
        )
    };
    let mut layers = Vec::new();
    for aov in Aov::ALL.into_iter().filter(|a| aovs.contains(a)) {
        let channels = match aov {
            Aov::Depth => vec![channel("Z", &|g| g.depth)],
            Aov::Position => vec![
                channel("X", &|g| (f64::from(g.position.x) + origin.x) as f32),
                channel("Y", &|g| (f64::from(g.position.y) + origin.y) as f32),
                channel("Z", &|g| (f64::from(g.position.z) + origin.z) as f32),
            ],
            Aov::Normal => vec![
                channel("X", &|g| g.normal.x),
                channel("Y", &|g| g.normal.y),
                channel("Z", &|g| g.normal.z),
            ],
            Aov::Albedo => vec![
                channel("R", &|g| g.albedo.x),
                channel("G", &|g| g.albedo.y),
                channel("B", &|g| g.albedo.z),
            ],
            Aov::Mask => vec![channel("Y", &|_| 1.0)],
            // A progressive render's own layer, added after these.
            Aov::Error => continue,
            Aov::Vcoef => terms
                .iter()
                .enumerate()
                .map(|(k, t)| {
                    (
                        k.to_string(),
                        t.vcoef()
                            .iter()
                            .enumerate()
                            .map(|(i, v)| if gbuffer.is_surface(i) { *v } else { 0.0 })
                            .collect(),
                    )
                })
                .collect(),
        };
        layers.push(Layer {
            name: aov.name().to_string(),
            channels,
        });
    }
    layers
}

/// Runs `f` on a thread pool of `threads` threads, or where it is called
/// (rayon's global pool: all cores) when `None`; the bits are the same.
pub fn with_threads<R: Send>(threads: Option<usize>, f: impl FnOnce() -> R + Send) -> Result<R> {
    let Some(n) = threads else {
        return Ok(f());
    };
    if !(1..=MAX_THREADS).contains(&n) {
        return Err(Error::param(
            "--threads",
            format!("{n} is outside 1..={MAX_THREADS}"),
        ));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .map_err(|e| Error::param("--threads", e.to_string()))?;
    Ok(pool.install(f))
}
