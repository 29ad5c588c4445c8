//! `penumbra import`: a starting scene for a model (OBJ, PLY, glTF) that
//! renders with visible soft shadows at once — a camera framing its
//! bounds, one rect light above it, and a ground quad unless the model
//! has a floor of its own.
//!
//! The model is loaded through the scene loader (so every check and
//! message of a scene's `obj = ...` applies), and the scene written is
//! loaded again before it is returned: what `import` writes always loads.

use super::{scene_from_toml, Scene};
use crate::error::{Error, Result};
use glam::DVec3;
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

/// Vertical field of view of the starting camera, degrees.
const FOV_Y: f64 = 40.0;

/// The light's half-size as a fraction of the model's bounding radius:
/// large enough that penumbrae are wide on the ground, small enough that
/// the shadow keeps its shape.
const LIGHT_HALF_SIZE: f64 = 0.25;

/// The light's height above the model's top, in bounding radii.
const LIGHT_HEIGHT: f64 = 2.0;

/// A floor of the model's own: horizontal triangles at its lowest point
/// covering at least this fraction of its footprint.
const FLOOR_COVER: f64 = 0.5;

/// The TOML text of a starting scene for `model`, to be written into
/// `scene_dir` (the model is referenced relative to it where it can be).
pub fn starting_scene(model: &Path, scene_dir: &Path) -> Result<String> {
    // Named here: past this point a missing model would be reported at the
    // line of a scene text the user never wrote.
    if let Err(e) = std::fs::metadata(model) {
        return Err(Error::param(
            "MODEL",
            format!("cannot read `{}`: {e}", model.display()),
        ));
    }
    let reference = model_reference(model, scene_dir);
    let quoted = toml_string(&reference);
    // Load the model alone (a placeholder camera and light: only its
    // geometry is used), with the scene file's own checks and messages.
    let probe = format!(
        "[camera]\neye = [0.0, 0.0, 1.0]\ntarget = [0.0, 0.0, 0.0]\nfov_y = 40\n\
         [[object]]\nobj = {quoted}\n"
    );
    let loaded = scene_from_toml(&probe, scene_dir)?;
    let (lo, hi) = world_bounds(&loaded)
        .ok_or_else(|| Error::param("MODEL", format!("`{}` has no triangles", model.display())))?;
    let centre = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-6);
    let has_floor = has_floor(&loaded, lo, hi);
    let n = Numbers::of(radius);

    let fov = FOV_Y.to_radians();
    let distance = radius / (fov * 0.5).sin() * 1.15;
    // From the front (+Z), above: a third of the way up.
    let eye = centre + DVec3::new(0.35, 0.55, 1.0).normalize() * distance;
    let half = LIGHT_HALF_SIZE * radius;
    let light_centre = DVec3::new(
        centre.x + 0.5 * radius,
        hi.y + LIGHT_HEIGHT * radius,
        centre.z + 0.3 * radius,
    );
    // Irradiance about π on the ground below (a white receiver shows
    // about its albedo): E ≈ L A / d² with A the light's area.
    let drop = light_centre.y - lo.y;
    let radiance = std::f64::consts::PI * drop * drop / (4.0 * half * half);

    let mut text = String::new();
    let name = model
        .file_stem()
        .map_or("model".into(), |s| s.to_string_lossy().into_owned());
    let _ = writeln!(
        text,
        "# A starting scene for `{}`, written by `penumbra import`: a camera\n\
         # framing the model's bounds, one rect light above it (its size sets\n\
         # the penumbrae's width: larger is softer){}. Edit freely;\n\
         # docs/scene-format.md lists every key.\n",
        model.display(),
        if has_floor {
            ""
        } else {
            ", and a ground quad under it"
        }
    );
    let _ = writeln!(text, "[scene]\nname = {}\n", toml_string(&name));
    let _ = writeln!(
        text,
        "[camera]\neye = {}\ntarget = {}\nup = [0.0, 1.0, 0.0]\nfov_y = {FOV_Y}\n\
         width = 768\nheight = 576\n",
        n.vector(eye),
        n.vector(centre)
    );
    let _ = writeln!(
        text,
        "[[light]]\ntype = \"rect\"\ncenter = {}\nu = {}\nv = {}\nradiance = {}\n",
        n.vector(light_centre),
        n.vector(DVec3::new(half, 0.0, 0.0)),
        n.vector(DVec3::new(0.0, 0.0, half)),
        Numbers::of(radiance).number(radiance)
    );
    if !has_floor {
        let size = 24.0 * radius;
        let _ = writeln!(
            text,
            "[[object]]\nname = \"ground\"\nshape = \"quad\"\nsize = [{}, {}]\n\
             translate = {}\n",
            n.number(size),
            n.number(size),
            n.vector(DVec3::new(centre.x, lo.y, centre.z))
        );
    }
    let _ = writeln!(
        text,
        "[[object]]\nname = {}\nobj = {quoted}",
        toml_string(&name)
    );
    // What is written must load: the same loader, the same directory.
    scene_from_toml(&text, scene_dir)?;
    Ok(text)
}

/// Bounds of every object in world coordinates (the scene's positions
/// are relative to its local origin).
fn world_bounds(scene: &Scene) -> Option<(DVec3, DVec3)> {
    let (lo, hi) = scene.bounds()?;
    Some((lo.as_dvec3() + scene.origin, hi.as_dvec3() + scene.origin))
}

/// True when the model has a floor of its own: horizontal triangles at
/// its lowest point covering at least [`FLOOR_COVER`] of its footprint.
fn has_floor(scene: &Scene, lo: DVec3, hi: DVec3) -> bool {
    let footprint = (hi.x - lo.x) * (hi.z - lo.z);
    let tolerance = 1e-3 * (hi - lo).length();
    if footprint <= 0.0 {
        return false;
    }
    let bottom = lo.y - scene.origin.y;
    let mut area = 0.0;
    for object in &scene.objects {
        for t in 0..object.mesh.triangle_count() {
            let [a, b, c] = object.mesh.corners(t).map(|p| p.as_dvec3());
            let n = (b - a).cross(c - a);
            let low = [a, b, c].iter().all(|p| (p.y - bottom).abs() <= tolerance);
            if low && n.y.abs() >= 0.99 * n.length() {
                area += 0.5 * n.length();
            }
        }
    }
    area >= FLOOR_COVER * footprint
}

/// `model` as the scene file in `scene_dir` should name it: relative to
/// that directory where both resolve, else absolute.
fn model_reference(model: &Path, scene_dir: &Path) -> String {
    let absolute = |p: &Path| std::fs::canonicalize(p).ok();
    let relative = match (absolute(model), absolute(scene_dir)) {
        (Some(m), Some(d)) => relative_path(&m, &d),
        _ => None,
    };
    relative
        .unwrap_or_else(|| absolute(model).unwrap_or_else(|| model.to_path_buf()))
        .to_string_lossy()
        .replace('\\', "/")
}

/// `path` relative to the directory `base` (both absolute and
/// canonical).
fn relative_path(path: &Path, base: &Path) -> Option<PathBuf> {
    let (p, b): (Vec<Component>, Vec<Component>) =
        (path.components().collect(), base.components().collect());
    let common = p.iter().zip(&b).take_while(|(x, y)| x == y).count();
    // Only the root in common: an absolute path reads better.
    if common <= 1 {
        return None;
    }
    let mut out = PathBuf::new();
    for _ in common..b.len() {
        out.push("..");
    }
    p[common..].iter().for_each(|c| out.push(c));
    Some(out)
}

/// A TOML basic string.
fn toml_string(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

/// Numbers as TOML writes them, rounded to a step of a ten-thousandth of
/// the model's size (a starting scene reads better without seventeen
/// digits, and keeps the precision that placing it needs, far from the
/// origin too).
struct Numbers {
    step: f64,
}

impl Numbers {
    fn of(size: f64) -> Self {
        Numbers {
            step: 10f64.powf((size.log10() - 4.0).floor()),
        }
    }

    fn number(&self, x: f64) -> String {
        let rounded = (x / self.step).round() * self.step;
        // The rounding's own error (0.1 steps as 0.1000000000001) goes
        // through f32's shortest form where that holds the value.
        let short: f64 = format!("{}", rounded as f32).parse().unwrap_or(rounded);
        let value = if (short - rounded).abs() <= 0.01 * self.step {
            short
        } else {
            rounded
        };
        toml::Value::Float(value).to_string()
    }

    fn vector(&self, v: DVec3) -> String {
        format!(
            "[{}, {}, {}]",
            self.number(v.x),
            self.number(v.y),
            self.number(v.z)
        )
    }
}
