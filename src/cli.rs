//! The command line: argument parsing and the commands' top level.

use crate::error::{Error, Result};
use crate::output::{write_exr, write_png};
use crate::render::{render, with_threads, Aov, RenderOptions, Technique};
use crate::report::Progress;
use crate::scene::{load_scene, LightShape, Scene};
use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// penumbra: physically based soft shadows on the CPU.
#[derive(Debug, Parser)]
#[command(name = "penumbra", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Render a scene to PNG (and optionally EXR with AOV layers).
    Render {
        /// Scene file (TOML).
        scene: PathBuf,
        /// Output PNG (radiance, clamped, sRGB).
        #[arg(short, long)]
        output: PathBuf,
        /// Output EXR (linear radiance plus the --aov layers).
        #[arg(long)]
        exr: Option<PathBuf>,
        /// Comma-separated AOV layers for the EXR: depth, position, normal,
        /// albedo, mask, vcoef.
        #[arg(long, value_delimiter = ',')]
        aov: Vec<String>,
        /// Image width (overrides the scene's camera).
        #[arg(long)]
        width: Option<u32>,
        /// Image height (overrides the scene's camera).
        #[arg(long)]
        height: Option<u32>,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Shadow technique.
        #[arg(long, default_value = "none")]
        technique: String,
        /// Light samples per pixel and light (sampling techniques).
        #[arg(long, default_value_t = 64)]
        samples: u32,
        /// Seed of the per-pixel random numbers.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Shadow volumes: count with z-pass instead of z-fail.
        #[arg(long)]
        zpass: bool,
        /// Print each pass's time to stderr.
        #[arg(long)]
        timings: bool,
    },
    /// Print a scene's statistics.
    Info {
        /// Scene file (TOML).
        scene: PathBuf,
    },
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render {
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
            zpass,
            timings,
        } => {
            let aovs = aov
                .iter()
                .map(|s| s.trim().parse())
                .collect::<Result<Vec<Aov>>>()?;
            if !aovs.is_empty() && exr.is_none() {
                return Err(Error::param(
                    "--aov",
                    "AOV layers need an EXR output (--exr)",
                ));
            }
            let options = RenderOptions {
                width,
                height,
                aovs,
                technique: technique.parse::<Technique>()?,
                samples,
                seed,
                zpass,
            };
            if samples == 0 || samples > 1 << 20 {
                return Err(Error::param(
                    "--samples",
                    format!("{samples} is outside 1..=1048576"),
                ));
            }
            for (name, v) in [("--width", width), ("--height", height)] {
                if v == Some(0) {
                    return Err(Error::param(name, "must be at least 1"));
                }
            }
            let scene = load_scene(&scene)?;
            let progress = Progress::new(5, true);
            let out = with_threads(threads, || render(&scene, &options, &progress))??;
            progress.finish();
            if timings {
                for p in &out.passes {
                    eprintln!("{:>12.3} ms  {}", p.time.as_secs_f64() * 1e3, p.name);
                }
            }
            write_png(&output, out.width, out.height, &out.radiance)?;
            if let Some(exr) = exr {
                write_exr(&exr, out.width, out.height, &out.radiance, &out.layers)?;
            }
            Ok(())
        }
        Command::Info { scene } => {
            let scene = load_scene(&scene)?;
            print!("{}", describe(&scene));
            Ok(())
        }
    }
}

/// The `info` report.
pub fn describe(scene: &Scene) -> String {
    let mut s = String::new();
    let mut line = |l: String| {
        s.push_str(&l);
        s.push('\n');
    };
    line(format!(
        "scene      {} ({})",
        scene.name,
        scene.path.display()
    ));
    line(format!(
        "camera     {}x{}, fov_y {}°, eye {:?}",
        scene.camera.width,
        scene.camera.height,
        scene.camera.fov_y_degrees,
        scene.camera.eye.to_array()
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
        Some((lo, hi)) => line(format!(
            "bounds     {:?} .. {:?}",
            lo.to_array(),
            hi.to_array()
        )),
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
                "rect centre {:?} u {:?} v {:?}{}",
                center.to_array(),
                u.to_array(),
                v.to_array(),
                if two_sided { " two-sided" } else { "" }
            ),
            LightShape::Sphere { center, radius } => {
                format!("sphere centre {:?} radius {}", center.to_array(), radius)
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

/// Entry point for `main`: parses, runs, prints errors, returns the exit
/// code.
pub fn main_with_args() -> std::process::ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("penumbra: error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
