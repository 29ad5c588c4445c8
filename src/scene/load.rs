//! Scene loading: the TOML contract (`shared/spec/scene-format.md`) into a
//! validated [`Scene`]. What we accept beyond the contract, and every error
//! we detect, is listed in `docs/scene-format.md`.
//!
//! Parsing is serde with `deny_unknown_fields`; every value that a semantic
//! check can reject is a `toml::Spanned`, so each error names the scene file
//! and the line of the offending key.

use super::assets::{Assets, TextureKind, DEFAULT_MATERIAL};
use super::{
    shapes, Camera, Light, LightShape, Material, MeshData, Object, Scene, MAX_MAGNITUDE,
    MIN_MAGNITUDE,
};
use crate::error::{Error, Result};
use crate::geom::Mesh;
use crate::raster::MAX_SIDE;
use glam::{DVec3, Mat3, Vec3};
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;
use std::collections::HashMap;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// Image size used when `[camera]` gives none.
const DEFAULT_IMAGE_SIZE: u32 = 1024;
/// Largest accepted image width or height: the rasterizer's limit, the
/// same one `--width`/`--height` have.
const MAX_IMAGE_SIDE: i64 = MAX_SIDE as i64;
/// Accepted sphere tessellations.
const SEGMENTS: Range<i64> = 3..4097;
const RINGS: Range<i64> = 2..4097;

// ---------------------------------------------------------------- TOML ----

/// Exactly three numbers (integers accepted), kept as TOML's `f64` so that
/// range checks see the value as written, before any rounding to `f32`.
#[derive(Debug, Clone, Copy)]
struct Arr3([f64; 3]);

/// A number (the same on all three components) or an array of three.
#[derive(Debug, Clone, Copy)]
struct Triple([f64; 3]);

/// One number of an array (integers accepted; anything else is a type
/// error saying "a number").
struct Num(f64);

impl<'de> Deserialize<'de> for Num {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Num;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number")
            }
            fn visit_f64<E: de::Error>(self, x: f64) -> std::result::Result<Num, E> {
                Ok(Num(x))
            }
            fn visit_i64<E: de::Error>(self, x: i64) -> std::result::Result<Num, E> {
                Ok(Num(x as f64))
            }
            fn visit_u64<E: de::Error>(self, x: u64) -> std::result::Result<Num, E> {
                Ok(Num(x as f64))
            }
        }
        d.deserialize_any(V)
    }
}

/// The visitor of [`Arr3`] and [`Triple`]: an array of exactly three
/// numbers, and for a triple also one number standing for all three.
struct ThreeNumbers {
    scalar_ok: bool,
}

impl ThreeNumbers {
    fn scalar<E: de::Error>(
        self,
        x: f64,
        what: de::Unexpected,
    ) -> std::result::Result<[f64; 3], E> {
        match self.scalar_ok {
            true => Ok([x; 3]),
            false => Err(de::Error::invalid_type(what, &self)),
        }
    }
}

impl<'de> Visitor<'de> for ThreeNumbers {
    type Value = [f64; 3];
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self.scalar_ok {
            true => f.write_str("a number or an array of 3 numbers"),
            false => f.write_str("an array of 3 numbers"),
        }
    }
    fn visit_f64<E: de::Error>(self, x: f64) -> std::result::Result<[f64; 3], E> {
        self.scalar(x, de::Unexpected::Float(x))
    }
    fn visit_i64<E: de::Error>(self, x: i64) -> std::result::Result<[f64; 3], E> {
        self.scalar(x as f64, de::Unexpected::Signed(x))
    }
    fn visit_u64<E: de::Error>(self, x: u64) -> std::result::Result<[f64; 3], E> {
        self.scalar(x as f64, de::Unexpected::Unsigned(x))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<[f64; 3], A::Error> {
        let mut out = [0.0; 3];
        for (i, slot) in out.iter_mut().enumerate() {
            *slot = seq
                .next_element::<Num>()?
                .ok_or_else(|| de::Error::invalid_length(i, &self))?
                .0;
        }
        // Extra elements (of any type) are an error too; count them for
        // the message.
        let mut len = 3;
        while seq.next_element::<de::IgnoredAny>()?.is_some() {
            len += 1;
        }
        match len {
            3 => Ok(out),
            _ => Err(de::Error::invalid_length(len, &self)),
        }
    }
}

impl<'de> Deserialize<'de> for Arr3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        d.deserialize_any(ThreeNumbers { scalar_ok: false })
            .map(Arr3)
    }
}

impl<'de> Deserialize<'de> for Triple {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        d.deserialize_any(ThreeNumbers { scalar_ok: true })
            .map(Triple)
    }
}

type Sp<T> = Spanned<T>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default)]
    scene: SceneSection,
    camera: Sp<CameraSection>,
    #[serde(default)]
    light: Vec<Sp<LightEntry>>,
    #[serde(default)]
    object: Vec<Sp<ObjectEntry>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct SceneSection {
    name: Option<String>,
    ambient: Option<Sp<Triple>>,
    background: Option<Sp<Triple>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraSection {
    eye: Option<Sp<Arr3>>,
    target: Option<Sp<Arr3>>,
    up: Option<Sp<Arr3>>,
    fov_y: Option<Sp<f64>>,
    width: Option<Sp<i64>>,
    height: Option<Sp<i64>>,
    /// A glTF file whose camera this is (instead of eye, target, up and
    /// fov_y).
    from: Option<Sp<String>>,
    /// Which of the file's cameras (default: its first perspective one).
    name: Option<Sp<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightEntry {
    #[serde(rename = "type")]
    kind: Sp<String>,
    center: Option<Sp<Arr3>>,
    radiance: Option<Sp<Triple>>,
    /// A glTF file whose point or spot light this sphere light stands for
    /// (instead of `center` and `radiance`).
    from: Option<Sp<String>>,
    /// Which of the file's lights (default: its first point or spot light).
    name: Option<Sp<String>>,
    u: Option<Sp<Arr3>>,
    v: Option<Sp<Arr3>>,
    radius: Option<Sp<f64>>,
    texture: Option<Sp<String>>,
    two_sided: Option<Sp<bool>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectEntry {
    name: Option<String>,
    obj: Option<Sp<String>>,
    shape: Option<Sp<String>>,
    radius: Option<Sp<f64>>,
    segments: Option<Sp<i64>>,
    rings: Option<Sp<i64>>,
    size: Option<Sp<Vec<f64>>>,
    translate: Option<Sp<Arr3>>,
    rotate: Option<Sp<Arr3>>,
    scale: Option<Sp<Triple>>,
    material: Option<Sp<MaterialEntry>>,
    cast_shadows: Option<bool>,
    receive_shadows: Option<bool>,
    /// glTF objects: emissive quads become rect lights.
    lights_from_emissive: Option<Sp<bool>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialEntry {
    albedo: Option<Sp<Triple>>,
    albedo_texture: Option<Sp<String>>,
    specular: Option<Sp<Triple>>,
    shininess: Option<Sp<f64>>,
    opacity: Option<Sp<f64>>,
    opacity_texture: Option<Sp<String>>,
}

// ------------------------------------------------------------- context ----

/// The scene file being loaded: turns spans into lines and relative paths
/// into paths next to the scene.
struct Ctx<'a> {
    path: &'a Path,
    dir: &'a Path,
    line_starts: Vec<usize>,
    /// In-memory meshes of a built scene, by object index: such an
    /// object's `obj` stands for its mesh rather than a file.
    meshes: &'a MemoryMeshes<'a>,
}

/// The in-memory meshes of a scene built in code, by object index.
pub(super) type MemoryMeshes<'a> = HashMap<usize, &'a MeshData>;

impl Ctx<'_> {
    /// 1-based line of a byte offset.
    fn line(&self, offset: usize) -> usize {
        self.line_starts.partition_point(|&s| s <= offset)
    }

    fn err(&self, span: Range<usize>, message: impl Into<String>) -> Error {
        Error::file(self.path, Some(self.line(span.start)), message)
    }

    /// The numbers of a value converted to `f32`: each must be finite,
    /// within `f32` and of magnitude at most [`MAX_MAGNITUDE`] (the
    /// supported range, documented in docs/scene-format.md).
    fn checked<const N: usize>(
        &self,
        span: Range<usize>,
        key: &str,
        xs: [f64; N],
    ) -> Result<[f32; N]> {
        for &x in &xs {
            let why = if !x.is_finite() {
                format!("`{key}` must be finite")
            } else if x.abs() > f64::from(f32::MAX) {
                format!(
                    "`{key}`: {} is out of range for f32 (max 3.4e38); \
                     the supported range is ±{MAX_MAGNITUDE:e}",
                    show(x)
                )
            } else if x.abs() > MAX_MAGNITUDE {
                format!(
                    "`{key}`: {} is beyond the supported range of scene values, ±{MAX_MAGNITUDE:e}",
                    show(x)
                )
            } else {
                continue;
            };
            return Err(self.err(span, why));
        }
        Ok(xs.map(|x| x as f32))
    }

    fn vec3(&self, v: &Sp<Arr3>, key: &str) -> Result<Vec3> {
        self.checked(v.span(), key, v.get_ref().0).map(Vec3::from)
    }

    fn triple(&self, v: &Sp<Triple>, key: &str) -> Result<Vec3> {
        self.checked(v.span(), key, v.get_ref().0).map(Vec3::from)
    }

    fn number(&self, v: &Sp<f64>, key: &str) -> Result<f32> {
        self.checked(v.span(), key, [*v.get_ref()]).map(|[x]| x)
    }

    /// A length-like magnitude (`|x|` of a size, radius, half-edge or scale
    /// factor, `what` naming it) that is not zero: it must be at least
    /// [`MIN_MAGNITUDE`], so that products of lengths (areas, normals)
    /// stay normal `f32` numbers.
    fn not_tiny(&self, span: Range<usize>, key: &str, what: &str, x: f64) -> Result<()> {
        match x == 0.0 || x.abs() >= MIN_MAGNITUDE {
            true => Ok(()),
            false => Err(self.err(
                span,
                format!(
                    "`{key}`: {what} {} is below the supported range of lengths, \
                     {MIN_MAGNITUDE:e} to {MAX_MAGNITUDE:e}",
                    show(x)
                ),
            )),
        }
    }

    /// A colour-like triple that must not be negative, or `default`.
    fn color(&self, v: Option<&Sp<Triple>>, key: &str, default: Vec3) -> Result<Vec3> {
        let Some(v) = v else { return Ok(default) };
        let c = self.triple(v, key)?;
        match c.min_element() >= 0.0 {
            true => Ok(c),
            false => Err(self.err(v.span(), format!("`{key}` must not be negative"))),
        }
    }

    /// An integer in `range`, or `default`.
    fn int(&self, v: &Option<Sp<i64>>, key: &str, range: Range<i64>, default: i64) -> Result<i64> {
        let Some(v) = v else { return Ok(default) };
        match range.contains(v.get_ref()) {
            true => Ok(*v.get_ref()),
            false => Err(self.err(
                v.span(),
                format!(
                    "`{key}` = {} is outside {}..={}",
                    v.get_ref(),
                    range.start,
                    range.end - 1
                ),
            )),
        }
    }

    /// A path from the scene file, relative to the scene's directory.
    fn resolve(&self, p: &str) -> PathBuf {
        self.dir.join(p)
    }

    /// The index of a texture named in the scene file, if one is given.
    fn texture(
        &self,
        assets: &mut Assets,
        file: Option<&Sp<String>>,
        kind: TextureKind,
    ) -> Result<Option<usize>> {
        file.map(|t| {
            let line = Some(self.line(t.span().start));
            assets.texture(&self.resolve(t.get_ref()), kind, self.path, line)
        })
        .transpose()
    }
}

/// A number for a message: as written for ordinary magnitudes, in
/// scientific notation for huge and tiny ones (`1e38`, not 39 digits).
fn show(x: f64) -> String {
    match x != 0.0 && !(1e-4..1e6).contains(&x.abs()) {
        true => format!("{x:e}"),
        false => format!("{x}"),
    }
}

// -------------------------------------------------------------- assets ----

// ------------------------------------------------------------- builders ----

/// The camera a glTF file places: `camera.from`'s file, the one named
/// `camera.name` or else its first perspective camera, as (eye, target,
/// up, vertical field of view in degrees, width / height if given).
fn camera_from_gltf(
    ctx: &Ctx,
    from: &Sp<String>,
    name: Option<&Sp<String>>,
) -> Result<(Vec3, Vec3, Vec3, f32, Option<f32>)> {
    let path = ctx.resolve(from.get_ref());
    let line = ctx.line(from.span().start);
    if mesh_format(&path) != MeshFormat::Gltf {
        return Err(ctx.err(
            from.span(),
            format!(
                "`camera.from` = \"{}\": cameras are read from glTF files (`.gltf`, `.glb`)",
                from.get_ref()
            ),
        ));
    }
    // The file's materials and textures are read into a scratch table:
    // the camera needs none of them.
    let model = super::gltf::load_gltf(&path, ctx.path, line, None, &mut Assets::new())?;
    let names = || {
        let list: Vec<String> = (model.cameras.iter())
            .map(|c| {
                c.name
                    .clone()
                    .map_or("(unnamed)".into(), |n| format!("\"{n}\""))
            })
            .collect();
        if list.is_empty() {
            "it has no camera placed by a node".to_string()
        } else {
            format!("its cameras: {}", list.join(", "))
        }
    };
    let camera = match name {
        Some(wanted) => {
            let found = (model.cameras.iter())
                .find(|c| c.name.as_deref() == Some(wanted.get_ref().as_str()));
            let Some(found) = found else {
                return Err(ctx.err(
                    wanted.span(),
                    format!(
                        "`camera.name` = \"{}\": `{}` has no camera of that name; {}",
                        wanted.get_ref(),
                        path.display(),
                        names()
                    ),
                ));
            };
            if let Some(why) = &found.unsupported {
                return Err(ctx.err(wanted.span(), format!("`camera.name`: {why}")));
            }
            found
        }
        None => match model.cameras.iter().find(|c| c.unsupported.is_none()) {
            Some(found) => found,
            None => {
                return Err(ctx.err(
                    from.span(),
                    format!(
                        "`camera.from`: `{}` has no perspective camera; {}",
                        path.display(),
                        names()
                    ),
                ))
            }
        },
    };
    let target = camera.eye + camera.forward;
    Ok((
        camera.eye,
        target,
        camera.up,
        camera.yfov_degrees,
        camera.aspect,
    ))
}

fn camera(ctx: &Ctx, c: &Sp<CameraSection>) -> Result<Camera> {
    let section_span = c.span();
    let c = c.get_ref();
    let required = |v: &Option<Sp<Arr3>>, key: &str| -> Result<Vec3> {
        match v {
            Some(v) => ctx.vec3(v, key),
            None => Err(ctx.err(
                section_span.clone(),
                format!("`{key}` is missing (or give `camera.from`, a glTF file's camera)"),
            )),
        }
    };
    let (eye, target, up, fov, aspect) = match &c.from {
        Some(from) => {
            let given = [
                ("eye", c.eye.as_ref().map(Sp::span)),
                ("target", c.target.as_ref().map(Sp::span)),
                ("up", c.up.as_ref().map(Sp::span)),
                ("fov_y", c.fov_y.as_ref().map(Sp::span)),
            ];
            if let Some((key, Some(span))) = given.into_iter().find(|(_, s)| s.is_some()) {
                return Err(ctx.err(
                    span,
                    format!("`camera.{key}` and `camera.from` exclude each other"),
                ));
            }
            camera_from_gltf(ctx, from, c.name.as_ref())?
        }
        None => {
            if let Some(name) = &c.name {
                return Err(ctx.err(name.span(), "`camera.name` needs `camera.from`"));
            }
            let eye = required(&c.eye, "camera.eye")?;
            let target = required(&c.target, "camera.target")?;
            let up =
                c.up.as_ref()
                    .map_or(Ok(Vec3::Y), |u| ctx.vec3(u, "camera.up"))?;
            let Some(fov_y) = &c.fov_y else {
                return Err(ctx.err(
                    section_span,
                    "`camera.fov_y` is missing (or give `camera.from`, a glTF file's camera)",
                ));
            };
            let fov = ctx.number(fov_y, "camera.fov_y")?;
            if !(fov > 0.0 && fov < 180.0) {
                return Err(ctx.err(
                    fov_y.span(),
                    format!("`camera.fov_y` = {fov} must be in (0, 180) degrees"),
                ));
            }
            (eye, target, up, fov, None)
        }
    };
    let target_span = (c.target.as_ref().or(c.eye.as_ref())).map_or(section_span.clone(), Sp::span);
    // In f64, as the view computes its basis: no overflow or underflow
    // for any values in the supported range.
    let forward = target.as_dvec3() - eye.as_dvec3();
    if forward == DVec3::ZERO {
        return Err(ctx.err(target_span, "`camera.target` must differ from `camera.eye`"));
    }
    // Parallel (or zero) up leaves `right = normalize(forward × up)` undefined.
    let up64 = up.as_dvec3();
    if forward.normalize().cross(up64).length() <= 1e-6 * up64.length() {
        let span = c.up.as_ref().map_or(target_span, Sp::span);
        return Err(ctx.err(
            span,
            "`camera.up` must not be parallel to the view direction",
        ));
    }
    let side = 1..MAX_IMAGE_SIDE + 1;
    let default = i64::from(DEFAULT_IMAGE_SIZE);
    let width = ctx.int(&c.width, "camera.width", side.clone(), default)?;
    // A glTF camera's aspect ratio gives the height the width implies.
    let default_height = match (aspect, &c.height) {
        (Some(a), None) if a.is_finite() && a > 0.0 => {
            ((width as f64 / f64::from(a)).round() as i64).clamp(1, MAX_IMAGE_SIDE)
        }
        _ => default,
    };
    let height = ctx.int(&c.height, "camera.height", side, default_height)?;
    Ok(Camera {
        eye,
        target,
        up,
        fov_y_degrees: fov,
        // In range by the checks above.
        width: width as u32,
        height: height as u32,
    })
}

/// A sphere light standing for a glTF file's point or spot light
/// (`from`, `name`): glTF has no area lights, so the scene gives the
/// sphere's `radius`; its radiance `colour × intensity / (π r²)` gives it
/// the file's intensity (candela, taken as the scene's radiance units per
/// steradian) in every direction. A spot light's cone is not modelled (a
/// sphere light emits everywhere; a warning says so); a directional light
/// has no position and is refused.
fn light_from_gltf(
    ctx: &Ctx,
    i: usize,
    entry: &Sp<LightEntry>,
    from: &Sp<String>,
) -> Result<Light> {
    let l = entry.get_ref();
    let key = |k: &str| format!("light[{i}].{k}");
    if l.kind.get_ref() != "sphere" {
        return Err(ctx.err(
            l.kind.span(),
            format!(
                "`{}`: a glTF light becomes a sphere light (glTF has no area lights): \
                 `type = \"sphere\"` with a `radius`",
                key("type")
            ),
        ));
    }
    let present = [
        ("center", span(&l.center)),
        ("radiance", span(&l.radiance)),
        ("u", span(&l.u)),
        ("v", span(&l.v)),
        ("texture", span(&l.texture)),
        ("two_sided", span(&l.two_sided)),
    ];
    only(ctx, "lights read from a glTF file", &[], &present)?;
    let Some(r) = &l.radius else {
        return Err(ctx.err(
            entry.span(),
            "a light read from a glTF file needs `radius`: glTF lights are points",
        ));
    };
    let radius = ctx.number(r, &key("radius"))?;
    if radius <= 0.0 {
        return Err(ctx.err(r.span(), "sphere light `radius` must be positive"));
    }
    ctx.not_tiny(r.span(), &key("radius"), "radius", *r.get_ref())?;
    let path = ctx.resolve(from.get_ref());
    let line = ctx.line(from.span().start);
    if mesh_format(&path) != MeshFormat::Gltf {
        return Err(ctx.err(
            from.span(),
            format!(
                "`{}` = \"{}\": lights are read from glTF files (`.gltf`, `.glb`)",
                key("from"),
                from.get_ref()
            ),
        ));
    }
    let model = super::gltf::load_gltf(&path, ctx.path, line, None, &mut Assets::new())?;
    let usable =
        |g: &&super::gltf::GltfLight| !matches!(g.kind, super::gltf::GltfLightKind::Directional);
    let found = match &l.name {
        Some(name) => model
            .lights
            .iter()
            .find(|g| g.name.as_deref() == Some(name.get_ref().as_str())),
        None => model.lights.iter().find(usable),
    };
    let Some(found) = found else {
        let at = l.name.as_ref().map_or(from.span(), Sp::span);
        return Err(ctx.err(
            at,
            format!(
                "`{}` has no {} (KHR_lights_punctual, placed by a node)",
                path.display(),
                match &l.name {
                    Some(n) => format!("light named \"{}\"", n.get_ref()),
                    None => "point or spot light".to_string(),
                }
            ),
        ));
    };
    if !usable(&found) {
        return Err(ctx.err(
            l.name.as_ref().map_or(from.span(), Sp::span),
            "a directional glTF light has no position; only point and spot lights \
             become sphere lights",
        ));
    }
    if matches!(found.kind, super::gltf::GltfLightKind::Spot { .. }) {
        eprintln!(
            "warning: {}:{line}: `{}`'s spot light becomes a sphere light that emits in \
             every direction (its cone is not modelled)",
            ctx.path.display(),
            path.display()
        );
    }
    let center = found.position;
    let radiance = found.color * found.intensity / (std::f32::consts::PI * radius * radius);
    if !(center.is_finite() && radiance.is_finite()) {
        return Err(ctx.err(
            from.span(),
            format!(
                "`{}`'s light gives a non-finite position or radiance",
                path.display()
            ),
        ));
    }
    Ok(Light {
        shape: LightShape::Sphere { center, radius },
        radiance,
        texture: None,
    })
}

/// Rejects keys that do not apply to this kind of light or object.
fn only(
    ctx: &Ctx,
    what: &str,
    allowed: &[&str],
    present: &[(&str, Option<Range<usize>>)],
) -> Result<()> {
    match present
        .iter()
        .find(|(k, s)| s.is_some() && !allowed.contains(k))
    {
        Some((key, Some(span))) => {
            Err(ctx.err(span.clone(), format!("`{key}` does not apply to {what}")))
        }
        _ => Ok(()),
    }
}

fn span<T>(v: &Option<Sp<T>>) -> Option<Range<usize>> {
    v.as_ref().map(Sp::span)
}

fn light(ctx: &Ctx, assets: &mut Assets, i: usize, entry: &Sp<LightEntry>) -> Result<Light> {
    let l = entry.get_ref();
    let key = |k: &str| format!("light[{i}].{k}");
    if let Some(from) = &l.from {
        return light_from_gltf(ctx, i, entry, from);
    }
    if let Some(name) = &l.name {
        return Err(ctx.err(name.span(), format!("`{}` needs `from`", key("name"))));
    }
    let (Some(center), Some(radiance)) = (&l.center, &l.radiance) else {
        let missing = if l.center.is_none() {
            "center"
        } else {
            "radiance"
        };
        return Err(ctx.err(
            entry.span(),
            format!(
                "`{}` is missing (or give `from`, a glTF file's light)",
                key(missing)
            ),
        ));
    };
    let center = ctx.vec3(center, &key("center"))?;
    let radiance = ctx.color(Some(radiance), &key("radiance"), Vec3::ZERO)?;
    let present = [
        ("u", span(&l.u)),
        ("v", span(&l.v)),
        ("texture", span(&l.texture)),
        ("two_sided", span(&l.two_sided)),
        ("radius", span(&l.radius)),
    ];
    let shape = match l.kind.get_ref().as_str() {
        "rect" => {
            only(
                ctx,
                "rect lights",
                &["u", "v", "texture", "two_sided"],
                &present,
            )?;
            let (Some(u_sp), Some(v_sp)) = (&l.u, &l.v) else {
                return Err(ctx.err(entry.span(), "a rect light needs `u` and `v`"));
            };
            let (u, v) = (ctx.vec3(u_sp, &key("u"))?, ctx.vec3(v_sp, &key("v"))?);
            let (u64, v64) = (u.as_dvec3(), v.as_dvec3());
            ctx.not_tiny(u_sp.span(), &key("u"), "length", u64.length())?;
            ctx.not_tiny(v_sp.span(), &key("v"), "length", v64.length())?;
            // Relative test (also true for a zero u or v): a sliver with
            // |u × v| ≪ |u| |v| has no usable normal or area either. In
            // f64, so that no value in the supported range overflows.
            if u64.cross(v64).length() <= 1e-6 * u64.length() * v64.length() {
                let at = if u == Vec3::ZERO { u_sp } else { v_sp };
                return Err(ctx.err(
                    at.span(),
                    "rect light has zero area (`u` and `v` are zero or parallel)",
                ));
            }
            LightShape::Rect {
                center,
                u,
                v,
                two_sided: l.two_sided.as_ref().is_some_and(|t| *t.get_ref()),
            }
        }
        "sphere" => {
            only(
                ctx,
                "sphere lights (no texture in version 1)",
                &["radius"],
                &present,
            )?;
            let Some(r) = &l.radius else {
                return Err(ctx.err(entry.span(), "a sphere light needs `radius`"));
            };
            let radius = ctx.number(r, &key("radius"))?;
            if radius <= 0.0 {
                return Err(ctx.err(r.span(), "sphere light `radius` must be positive"));
            }
            ctx.not_tiny(r.span(), &key("radius"), "radius", *r.get_ref())?;
            LightShape::Sphere { center, radius }
        }
        other => {
            return Err(ctx.err(
                l.kind.span(),
                format!("unknown light type `{other}` (expected \"rect\" or \"sphere\")"),
            ))
        }
    };
    let texture = ctx.texture(assets, l.texture.as_ref(), TextureKind::Color)?;
    Ok(Light {
        shape,
        radiance,
        texture,
    })
}

fn inline_material(
    ctx: &Ctx,
    assets: &mut Assets,
    i: usize,
    m: &MaterialEntry,
) -> Result<Material> {
    let key = |k: &str| format!("object[{i}].material.{k}");
    let d = Material::default();
    let scalar =
        |v: &Option<Sp<f64>>, k: &str, default: f32, ok: fn(f32) -> bool, range: &str| match v {
            Some(v) => {
                let x = ctx.number(v, &key(k))?;
                match ok(x) {
                    true => Ok(x),
                    false => Err(ctx.err(v.span(), format!("`{}` = {x} must be {range}", key(k)))),
                }
            }
            None => Ok(default),
        };
    Ok(Material {
        name: "inline".into(),
        albedo: ctx.color(m.albedo.as_ref(), &key("albedo"), d.albedo)?,
        albedo_texture: ctx.texture(assets, m.albedo_texture.as_ref(), TextureKind::Color)?,
        specular: ctx.color(m.specular.as_ref(), &key("specular"), d.specular)?,
        shininess: scalar(&m.shininess, "shininess", d.shininess, |x| x >= 0.0, "≥ 0")?,
        opacity: scalar(
            &m.opacity,
            "opacity",
            d.opacity,
            |x| (0.0..=1.0).contains(&x),
            "in [0, 1]",
        )?,
        opacity_texture: ctx.texture(assets, m.opacity_texture.as_ref(), TextureKind::Opacity)?,
    })
}

/// Object-to-world transform: scale, then rotate (X, then Y, then Z), then
/// translate.
struct Transform {
    linear: Mat3,
    normal: Mat3,
    translate: Vec3,
    /// An odd number of negative scale factors mirrors the mesh.
    mirror: bool,
}

fn transform(ctx: &Ctx, i: usize, o: &ObjectEntry) -> Result<Transform> {
    let key = |k: &str| format!("object[{i}].{k}");
    let translate = o
        .translate
        .as_ref()
        .map_or(Ok(Vec3::ZERO), |t| ctx.vec3(t, &key("translate")))?;
    let [rx, ry, rz] = match &o.rotate {
        Some(r) => ctx.vec3(r, &key("rotate"))?.to_array().map(f32::to_radians),
        None => [0.0; 3],
    };
    let scale = match &o.scale {
        Some(s) => {
            let v = ctx.triple(s, &key("scale"))?;
            if v.cmpeq(Vec3::ZERO).any() {
                return Err(ctx.err(s.span(), format!("`{}` must not be zero", key("scale"))));
            }
            for x in s.get_ref().0 {
                ctx.not_tiny(s.span(), &key("scale"), "factor", x)?;
            }
            v
        }
        None => Vec3::ONE,
    };
    // Column vectors: R = Rz Ry Rx applies X first.
    let rotation =
        Mat3::from_rotation_z(rz) * Mat3::from_rotation_y(ry) * Mat3::from_rotation_x(rx);
    let linear = rotation * Mat3::from_diagonal(scale);
    Ok(Transform {
        linear,
        normal: linear.inverse().transpose(),
        translate,
        mirror: scale.x * scale.y * scale.z < 0.0,
    })
}

/// Moves a mesh to world space and drops its degenerate triangles,
/// returning how many were dropped. Fails (at `span`) if the result is not
/// finite.
fn place(
    ctx: &Ctx,
    span: Range<usize>,
    what: &str,
    mesh: &mut Mesh,
    t: &Transform,
) -> Result<usize> {
    let too_big = || {
        ctx.err(
            span.clone(),
            format!("{what}: transformed geometry is not finite (values too large)"),
        )
    };
    // In parallel chunks (a scanned or finely tessellated object has
    // millions of vertices); every error is the one a serial walk meets
    // first, so the message does not depend on the thread count.
    use rayon::prelude::*;
    const CHUNK: usize = 8192;
    mesh.positions.par_chunks_mut(CHUNK).for_each(|chunk| {
        for p in chunk {
            *p = t.linear * *p + t.translate;
        }
    });
    let out_of_range =
        |p: &Vec3| !p.is_finite() || f64::from(p.abs().max_element()) > MAX_MAGNITUDE;
    if let Some(i) = mesh
        .positions
        .par_iter()
        .with_min_len(CHUNK)
        .position_first(out_of_range)
    {
        let p = mesh.positions[i];
        if !p.is_finite() {
            return Err(too_big());
        }
        return Err(ctx.err(
            span.clone(),
            format!(
                "{what}: a vertex lands at {:?} after the transform, beyond the \
                 supported range of coordinates, ±{MAX_MAGNITUDE:e}",
                p.to_array()
            ),
        ));
    }
    if let Some(normals) = mesh.normals.as_mut() {
        normals.par_chunks_mut(CHUNK).for_each(|chunk| {
            for n in chunk {
                *n = (t.normal * *n).normalize();
            }
        });
        if normals
            .par_iter()
            .with_min_len(CHUNK)
            .any(|n| !n.is_finite())
        {
            return Err(too_big());
        }
    }
    if t.mirror {
        // Keep counter-clockwise = outside, consistent with the normals.
        mesh.triangles
            .par_iter_mut()
            .with_min_len(CHUNK)
            .for_each(|tri| tri.swap(1, 2));
    }
    let before = mesh.triangles.len();
    // Per triangle: `None` for a corner out of range or a non-finite
    // normal (an error), else whether it has area.
    let positions = &mesh.positions;
    let area = |tri: &[u32; 3]| -> Option<bool> {
        let [a, b, c] = [0, 1, 2].map(|k| positions.get(tri[k] as usize).copied());
        let n = (b? - a?).cross(c? - a?);
        n.is_finite().then_some(n != Vec3::ZERO)
    };
    let flags: Vec<Option<bool>> = mesh
        .triangles
        .par_iter()
        .with_min_len(CHUNK)
        .map(area)
        .collect();
    if flags.iter().any(Option::is_none) {
        return Err(too_big());
    }
    if flags.contains(&Some(false)) {
        let mut keep = flags.iter().map(|f| *f == Some(true));
        mesh.triangles.retain(|_| keep.next().unwrap_or(false));
        let mut keep = flags.iter().map(|f| *f == Some(true));
        mesh.material_ids.retain(|_| keep.next().unwrap_or(false));
    }
    Ok(before - mesh.triangles.len())
}

/// The reader a mesh file's extension picks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MeshFormat {
    /// Anything not named below (the OBJ reader refuses other formats by
    /// their content).
    Obj,
    /// `.ply`.
    Ply,
    /// `.gltf`, `.glb`.
    Gltf,
}

fn mesh_format(path: &Path) -> MeshFormat {
    match path.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("ply") => MeshFormat::Ply,
        Some(e) if e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb") => {
            MeshFormat::Gltf
        }
        _ => MeshFormat::Obj,
    }
}

/// Reads an object's mesh file, referenced from `from:line`. The reader
/// is chosen by the file's extension (`.ply`, `.gltf`, `.glb`; anything
/// else is read as OBJ), and each reader checks that the content is its
/// format: the OBJ reader refuses a PLY, glTF, STL or OFF file by what it
/// holds.
fn load_mesh_file(
    path: &Path,
    from: &Path,
    line: usize,
    material: Option<u32>,
    assets: &mut Assets,
) -> Result<(Mesh, Vec<super::gltf::EmissiveQuad>)> {
    match mesh_format(path) {
        MeshFormat::Ply => Ok((
            super::ply::load_ply(path, from, line, material, assets)?,
            Vec::new(),
        )),
        MeshFormat::Gltf => {
            let model = super::gltf::load_gltf(path, from, line, material, assets)?;
            for warning in &model.warnings {
                eprintln!("warning: {warning}");
            }
            Ok((model.mesh, model.emissive_quads))
        }
        MeshFormat::Obj => Ok((
            super::obj::load_obj(path, from, line, material, assets)?,
            Vec::new(),
        )),
    }
}

/// Builds object `i`; `before` is the triangle count of the objects loaded
/// before it (for the memory estimate of built-in shapes and in-memory
/// meshes).
fn object(
    ctx: &Ctx,
    assets: &mut Assets,
    i: usize,
    entry: &Sp<ObjectEntry>,
    before: u64,
    origin: glam::DVec3,
) -> Result<(Object, Vec<Light>)> {
    let o = entry.get_ref();
    if let Some(flag) = &o.lights_from_emissive {
        let gltf = (o.obj.as_ref())
            .is_some_and(|f| mesh_format(Path::new(f.get_ref())) == MeshFormat::Gltf);
        if !gltf || ctx.meshes.contains_key(&i) {
            return Err(ctx.err(
                flag.span(),
                format!(
                    "`object[{i}].lights_from_emissive` applies to glTF objects (`obj = \"*.gltf\"` \
                     or `*.glb`), whose emissive quads it turns into rect lights"
                ),
            ));
        }
    }
    let mut emissive = Vec::new();
    let material = match &o.material {
        Some(m) => {
            let m = inline_material(ctx, assets, i, m.get_ref())?;
            Some(assets.material(m)?)
        }
        None => None,
    };
    let mut transform = transform(ctx, i, o)?;
    // Into the scene's local frame before the mesh is placed, so that a
    // built-in shape far from the origin rounds as it would at the origin.
    transform.translate = super::frame::shift(transform.translate, origin);
    let (mut mesh, origin, name) = match (&o.obj, &o.shape) {
        (Some(_), Some(shape)) => {
            return Err(ctx.err(
                shape.span(),
                "an object has either `obj` or `shape`, not both",
            ))
        }
        (None, None) => return Err(ctx.err(entry.span(), "an object needs `obj` or `shape`")),
        (Some(file), None) => {
            only(ctx, "obj objects", &[], &present_shape_keys(o))?;
            let m = material.unwrap_or(DEFAULT_MATERIAL);
            if let Some(data) = ctx.meshes.get(&i) {
                let mesh = memory_mesh(ctx, i, file.span(), data, m, before)?;
                (mesh, file, "mesh".to_string())
            } else {
                let path = ctx.resolve(file.get_ref());
                let line = ctx.line(file.span().start);
                let (mut mesh, quads) = load_mesh_file(&path, ctx.path, line, material, assets)?;
                if let Some(flag) = o.lights_from_emissive.as_ref().filter(|f| *f.get_ref()) {
                    emissive = emissive_lights(ctx, flag, &path, &mut mesh, quads)?;
                }
                let stem = path
                    .file_stem()
                    .map_or("obj".into(), |s| s.to_string_lossy().into_owned());
                (mesh, file, stem)
            }
        }
        (None, Some(shape)) => {
            let m = material.unwrap_or(DEFAULT_MATERIAL);
            let mesh = shape_mesh(ctx, i, o, shape, m, before)?;
            (mesh, shape, shape.get_ref().clone())
        }
    };
    let name = o.name.clone().unwrap_or_else(|| format!("{name}#{i}"));
    let dropped = place(ctx, origin.span(), &name, &mut mesh, &transform)?;
    if dropped > 0 {
        // A built scene has no file, so no line to point at.
        let at = match ctx.path == Path::new(BUILT_SCENE) {
            true => String::new(),
            false => format!("{}:{}: ", ctx.path.display(), ctx.line(origin.span().start)),
        };
        crate::output::write_stderr(&format!(
            "note: {at}object `{name}`: dropped {dropped} degenerate triangle(s)\n"
        ));
    }
    // The quads as the object is placed: its transform, in the scene's
    // local frame (the translation is already shifted into it).
    let lights = (emissive.into_iter())
        .map(|q: super::gltf::EmissiveQuad| {
            let (mut u, v) = (transform.linear * q.u, transform.linear * q.v);
            // A mirroring transform turns u × v away from the (re-wound)
            // front face: turn it back.
            if transform.mirror {
                u = -u;
            }
            Light {
                shape: LightShape::Rect {
                    center: transform.linear * q.center + transform.translate,
                    u,
                    v,
                    two_sided: q.two_sided,
                },
                radiance: q.radiance,
                texture: None,
            }
        })
        .collect();
    let object = Object {
        name,
        mesh,
        cast_shadows: o.cast_shadows.unwrap_or(true),
        receive_shadows: o.receive_shadows.unwrap_or(true),
    };
    Ok((object, lights))
}

/// `lights_from_emissive = true` (`flag`) on the glTF object read from
/// `path`: its emissive quads leave the mesh (a light does not block
/// light) and are returned, to become rect lights once placed.
fn emissive_lights(
    ctx: &Ctx,
    flag: &Sp<bool>,
    path: &Path,
    mesh: &mut Mesh,
    quads: Vec<super::gltf::EmissiveQuad>,
) -> Result<Vec<super::gltf::EmissiveQuad>> {
    if quads.is_empty() {
        eprintln!(
            "warning: {}:{}: `lights_from_emissive`: `{}` has no emissive quad (a primitive of \
             two triangles forming a parallelogram, with an emissive material)",
            ctx.path.display(),
            ctx.line(flag.span().start),
            path.display()
        );
        return Ok(quads);
    }
    let mut gone = vec![false; mesh.triangles.len()];
    quads
        .iter()
        .flat_map(|q| q.triangles)
        .for_each(|t| gone[t] = true);
    let mut keep = gone.iter().map(|g| !g);
    mesh.triangles.retain(|_| keep.next().unwrap_or(true));
    let mut keep = gone.iter().map(|g| !g);
    mesh.material_ids.retain(|_| keep.next().unwrap_or(true));
    if mesh.triangles.is_empty() {
        return Err(ctx.err(
            flag.span(),
            format!(
                "`lights_from_emissive`: every triangle of `{}` is an emissive quad, so the \
                 object would have none left (give its lights as `[[light]]` instead)",
                path.display()
            ),
        ));
    }
    Ok(quads)
}

/// The shape keys an object entry gives, where they are (for [`only`]).
fn present_shape_keys(o: &ObjectEntry) -> [(&'static str, Option<Range<usize>>); 4] {
    [
        ("radius", span(&o.radius)),
        ("segments", span(&o.segments)),
        ("rings", span(&o.rings)),
        ("size", span(&o.size)),
    ]
}

/// The object-space mesh of built-in shape `shape` of object `i`, every
/// triangle with material `m`.
fn shape_mesh(
    ctx: &Ctx,
    i: usize,
    o: &ObjectEntry,
    shape: &Sp<String>,
    m: u32,
    before: u64,
) -> Result<Mesh> {
    let key = |k: &str| format!("object[{i}].{k}");
    let present = present_shape_keys(o);
    let positive = |v: &Sp<f64>, k: &str| -> Result<f32> {
        let x = ctx.number(v, &key(k))?;
        match x > 0.0 {
            true => ctx.not_tiny(v.span(), &key(k), k, *v.get_ref()).map(|()| x),
            false => Err(ctx.err(v.span(), format!("`{}` must be positive", key(k)))),
        }
    };
    // `size` of the box or quad: `n` positive numbers, default all 1.
    let size = |n: usize| -> Result<Vec<f32>> {
        let Some(s) = &o.size else {
            return Ok(vec![1.0; n]);
        };
        if s.get_ref().len() != n || !s.get_ref().iter().all(|&x| x > 0.0) {
            return Err(ctx.err(
                s.span(),
                format!("`{}` must be {n} positive numbers", key("size")),
            ));
        }
        let mut out = Vec::with_capacity(n);
        for &x in s.get_ref() {
            let [x32] = ctx.checked(s.span(), &key("size"), [x])?;
            ctx.not_tiny(s.span(), &key("size"), "size", x)?;
            out.push(x32);
        }
        Ok(out)
    };
    let mesh = match shape.get_ref().as_str() {
        "sphere" => {
            only(ctx, "spheres", &["radius", "segments", "rings"], &present)?;
            let r = o
                .radius
                .as_ref()
                .map_or(Ok(1.0), |r| positive(r, "radius"))?;
            let segments = ctx.int(&o.segments, &key("segments"), SEGMENTS, 20)?;
            let rings = ctx.int(&o.rings, &key("rings"), RINGS, 20)?;
            // In range by the checks above.
            let (segments, rings) = (segments as u32, rings as u32);
            let at = o
                .rings
                .as_ref()
                .or(o.segments.as_ref())
                .map_or(shape.span(), Sp::span);
            let triangles = shapes::sphere_triangle_count(segments, rings);
            check_geometry_memory(
                ctx,
                at,
                &format!("a sphere of {segments} segments × {rings} rings"),
                triangles,
                before,
            )?;
            shapes::sphere(r, segments, rings, m)
        }
        "box" => {
            only(ctx, "boxes", &["size"], &present)?;
            shapes::cuboid(Vec3::from_slice(&size(3)?), m)
        }
        "quad" => {
            only(ctx, "quads", &["size"], &present)?;
            let s = size(2)?;
            shapes::quad(s[0], s[1], m)
        }
        other => {
            return Err(ctx.err(
                shape.span(),
                format!("unknown shape `{other}` (expected \"sphere\", \"box\" or \"quad\")"),
            ))
        }
    };
    Ok(mesh)
}

/// The object-space mesh of object `i` given in memory (`at`: its
/// entry), every triangle with material `m`, checked as the OBJ path checks
/// a loaded mesh: finite numbers, indices in range, some triangles, the
/// memory estimate, and unusable normals replaced by their face's; the
/// transform's range check and dropping degenerate triangles are
/// [`place`]'s, as for every object.
fn memory_mesh(
    ctx: &Ctx,
    i: usize,
    at: Range<usize>,
    data: &MeshData,
    m: u32,
    before: u64,
) -> Result<Mesh> {
    let key = |k: &str| format!("object[{i}].{k}");
    let err = |message: String| ctx.err(at.clone(), message);
    let triangles = data.triangles.len() as u64;
    check_geometry_memory(
        ctx,
        at.clone(),
        &format!("a mesh of {triangles} triangles"),
        triangles,
        before,
    )?;
    if data.triangles.is_empty() {
        // As an OBJ without faces: refused rather than an invisible object.
        return Err(err(format!(
            "`{}` is empty: nothing to render",
            key("triangles")
        )));
    }
    let n = data.positions.len();
    for (len, what) in [
        (data.normals.as_ref().map(Vec::len), "normals"),
        (data.uvs.as_ref().map(Vec::len), "uvs"),
    ] {
        if let Some(len) = len.filter(|&len| len != n) {
            return Err(err(format!(
                "`{}` has {len} entries for {n} positions (one per position)",
                key(what)
            )));
        }
    }
    // As the OBJ scan refuses a non-finite `v` or `vt` number (normals
    // are replaced below, as the OBJ path replaces them).
    let uvs = data.uvs.as_deref().unwrap_or_default();
    for (what, bad) in [
        ("positions", first_not_finite(&data.positions)),
        ("uvs", first_not_finite(uvs)),
    ] {
        if let Some(k) = bad {
            return Err(err(format!("`{}[{k}]` must be finite", key(what))));
        }
    }
    if let Some((t, bad)) = (data.triangles.iter().enumerate())
        .find_map(|(t, tri)| tri.iter().find(|&&v| v as usize >= n).map(|&v| (t, v)))
    {
        return Err(err(format!(
            "`{}[{t}]`: vertex index {bad} out of range: the mesh has {n} positions \
             (indices start at 0)",
            key("triangles")
        )));
    }
    let mut mesh = Mesh {
        positions: data.positions.iter().map(|&p| Vec3::from(p)).collect(),
        normals: (data.normals.as_ref()).map(|ns| ns.iter().map(|&v| Vec3::from(v)).collect()),
        uvs: (data.uvs.as_ref()).map(|uvs| uvs.iter().map(|&v| glam::Vec2::from(v)).collect()),
        triangles: data.triangles.clone(),
        material_ids: vec![m; data.triangles.len()],
    };
    let corners = super::obj::replace_unusable_normals(&mut mesh);
    if corners > 0 {
        eprintln!(
            "warning: object[{i}]: zero or non-finite normals; the {corners} triangle \
             corner(s) using them take their face's geometric normal"
        );
    }
    Ok(mesh)
}

/// The index of the first vector of `xs` with a non-finite component.
fn first_not_finite<const N: usize>(xs: &[[f32; N]]) -> Option<usize> {
    xs.iter().position(|x| !x.iter().all(|x| x.is_finite()))
}

/// Bytes a triangle of a built-in shape costs from loading through the
/// most demanding render, measured (`/usr/bin/time -v`) on a 1024 × 1024
/// sphere at 16 × 16 pixels: about 60 at load (mesh and transform) and 490
/// at the peak of a reference render (scene geometry, adjacency, BVH),
/// rounded up.
const BYTES_PER_TRIANGLE: u64 = 576;

/// Refuses geometry that cannot fit in memory before generating it, as
/// `render::check_memory` does for images: `what` (at `span`) adds
/// `triangles` to the `before` of earlier objects.
fn check_geometry_memory(
    ctx: &Ctx,
    span: Range<usize>,
    what: &str,
    triangles: u64,
    before: u64,
) -> Result<()> {
    let need = (triangles + before).saturating_mul(BYTES_PER_TRIANGLE);
    let Some(have) = crate::allocator::memory_budget() else {
        return Ok(());
    };
    if need <= have {
        return Ok(());
    }
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    let earlier = match before {
        0 => String::new(),
        n => format!(" (with the {n} of the objects before it)"),
    };
    Err(ctx.err(
        span,
        format!(
            "{what} has {triangles} triangles; loading and rendering them{earlier} \
             needs about {:.1} GiB, more than the {:.1} GiB available",
            gib(need),
            gib(have)
        ),
    ))
}

/// The key whose value contains byte `offset` of `text`: the word before
/// the last `=` (outside strings) on that line before `offset`. Good for
/// `key = value`, inline tables and arrays on one line; `None` elsewhere.
fn key_of_value(text: &str, offset: usize) -> Option<&str> {
    let offset = offset.min(text.len());
    let start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
    let prefix = text.get(start..offset)?;
    let mut in_string = None;
    let mut equals = None;
    for (i, c) in prefix.char_indices() {
        match (in_string, c) {
            (None, '"' | '\'') => in_string = Some(c),
            (Some(q), _) if c == q => in_string = None,
            (None, '=') => equals = Some(i),
            (None, '#') => return None,
            _ => {}
        }
    }
    let before = prefix[..equals?].trim_end();
    let key_start = before
        .rfind(|c: char| !(c.is_ascii_alphanumeric() || "_-.".contains(c)))
        .map_or(0, |i| i + 1);
    let key = &before[key_start..];
    (!key.is_empty()).then_some(key)
}

/// Load and validate a scene file.
///
/// Every problem is an [`Error::File`] naming the file at fault and, for
/// the scene file, the line of the offending key (an OBJ/MTL problem names
/// that file and its line; a texture problem names the texture and points
/// at the line that references it). Only failing to read the scene file
/// itself is an [`Error::Io`].
pub fn load_scene(path: &Path) -> Result<Scene> {
    let bytes = super::input::read(path).map_err(|e| Error::io(path, e))?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned());
    let stem = stem.as_deref().unwrap_or("scene");
    parse_scene(&bytes, path, dir, stem, &MemoryMeshes::new())
}

/// What errors of a scene given as text name as its file.
pub const TOML_TEXT: &str = "<scene text>";

/// A scene from TOML text, validated exactly as [`load_scene`] validates a
/// file, with the same messages: they name [`TOML_TEXT`] and the line
/// where the file would be named. Relative paths in it (OBJ models,
/// textures) are resolved against `base_dir`, as a file's are against its
/// folder.
pub fn scene_from_toml(text: &str, base_dir: &Path) -> Result<Scene> {
    let meshes = MemoryMeshes::new();
    parse_scene(
        text.as_bytes(),
        Path::new(TOML_TEXT),
        base_dir,
        "scene",
        &meshes,
    )
}

/// What a scene built in code ([`super::SceneBuilder`]) is named as its
/// [`Scene::path`]. Its errors name no file: the builder turns them into
/// parameter errors that name the item at fault.
pub const BUILT_SCENE: &str = "<built scene>";

/// Parses and validates scene `bytes`, named `path` in messages, with
/// relative paths resolved against `dir`; `name` unless the scene names
/// itself. `meshes` gives the objects whose geometry is in memory.
pub(super) fn parse_scene(
    bytes: &[u8],
    path: &Path,
    dir: &Path,
    name: &str,
    meshes: &MemoryMeshes,
) -> Result<Scene> {
    let line_starts: Vec<usize> = std::iter::once(0)
        .chain(
            bytes
                .iter()
                .enumerate()
                .filter(|(_, &b)| b == b'\n')
                .map(|(i, _)| i + 1),
        )
        .collect();
    let ctx = Ctx {
        path,
        dir,
        line_starts,
        meshes,
    };
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let at = e.valid_up_to();
        ctx.err(at..at, "not valid UTF-8 text")
    })?;
    let file: SceneFile = toml::from_str(text).map_err(|e| {
        // toml gives a span for everything it can place; the rest is at the top.
        let line = e.span().map_or(1, |s| ctx.line(s.start));
        let mut message = e.message().trim().replace('\n', ": ");
        if message.is_empty() {
            // toml has no words for some syntax errors (a value missing at
            // the end of the file); say where.
            let column = e.span().map_or(1, |s| {
                let start = ctx.line_starts[ctx.line(s.start) - 1];
                text.get(start..s.start)
                    .map_or(1, |t| t.chars().count() + 1)
            });
            message = format!("invalid TOML: a value is missing or malformed at column {column}");
        }
        // A wrong value ("invalid length 5, expected an array of 3
        // numbers") does not say whose; the source line does.
        if message.starts_with("invalid ") {
            if let Some(key) = e.span().and_then(|s| key_of_value(text, s.start)) {
                message = format!("`{key}`: {message}");
            }
        }
        Error::file(path, Some(line), message)
    })?;

    let section = &file.scene;
    let name = section.name.clone().unwrap_or_else(|| name.to_string());
    let ambient = ctx.color(section.ambient.as_ref(), "scene.ambient", Vec3::ZERO)?;
    let background = ctx.color(section.background.as_ref(), "scene.background", Vec3::ZERO)?;
    let mut camera = camera(&ctx, &file.camera)?;
    let mut assets = Assets::new();
    let mut lights: Vec<Light> = (file.light.iter().enumerate())
        .map(|(i, l)| light(&ctx, &mut assets, i, l))
        .collect::<Result<_>>()?;
    // The local frame from what is placed in the file (see
    // `super::frame`); what OBJ vertices add is caught after placing.
    let mut placed: Vec<Vec3> = Vec::new();
    for (i, o) in file.object.iter().enumerate() {
        placed.push(match &o.get_ref().translate {
            Some(t) => ctx.vec3(t, &format!("object[{i}].translate"))?,
            None => Vec3::ZERO,
        });
    }
    let origin = super::frame::local_origin(&camera, &lights, &placed);
    super::frame::shift_camera_and_lights(&mut camera, &mut lights, origin);
    let mut objects: Vec<Object> = Vec::with_capacity(file.object.len());
    let mut triangles = 0u64;
    for (i, o) in file.object.iter().enumerate() {
        let (object, emissive) = object(&ctx, &mut assets, i, o, triangles, origin)?;
        triangles += object.mesh.triangle_count() as u64;
        objects.push(object);
        lights.extend(emissive);
    }
    let mut scene = Scene {
        name,
        path: path.to_path_buf(),
        ambient,
        background,
        camera,
        lights,
        objects,
        materials: assets.materials,
        textures: assets.textures,
        origin,
    };
    super::frame::recentre(&mut scene);
    Ok(scene)
}
