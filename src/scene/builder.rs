//! Scenes built in code: [`SceneBuilder`] describes what a scene file
//! describes (camera, lights, objects from built-in shapes, mesh files
//! (OBJ, PLY, glTF) or in-memory meshes, materials), and [`SceneBuilder::build`] validates it.
//!
//! There is one validator, the scene file's: the builder writes the scene
//! file it describes and loads it through the loader's own code, so every
//! check and every message is the file path's. Its errors name no file or
//! line (the user never saw the text): each becomes a parameter error
//! naming the item and key at fault (`light[0].radius`,
//! `object "ground".size`), with the loader's message. An in-memory mesh
//! has no TOML form; its object is written as an `obj` entry that the
//! loader, told which objects are in memory, builds from the mesh instead
//! of a file, through the checks and the placement every object gets.

use super::load::{parse_scene, MemoryMeshes, BUILT_SCENE};
use super::{MeshData, Scene};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};
use toml::Value;

/// A scene described in code, validated by [`SceneBuilder::build`] exactly
/// as a scene file is loaded (same checks, same messages).
///
/// The smallest scene: a camera, a light and one object.
///
/// ```
/// use penumbra::{CameraDesc, LightDesc, ObjectDesc, SceneBuilder};
///
/// let scene = SceneBuilder::new()
///     .camera(CameraDesc::new([0.0, 2.0, 5.0], [0.0, 0.0, 0.0], 45.0).size(32, 24))
///     .light(LightDesc::sphere([0.0, 4.0, 0.0], 0.5, [10.0; 3]))
///     .object(ObjectDesc::quad([6.0, 6.0]).named("ground"))
///     .build()?;
/// assert_eq!(scene.objects[0].name, "ground");
/// assert_eq!((scene.camera.width, scene.camera.height), (32, 24));
///
/// // Bad input is an error naming the item and key, never a panic.
/// let err = SceneBuilder::new()
///     .camera(CameraDesc::new([0.0, 2.0, 5.0], [0.0, 0.0, 0.0], 45.0))
///     .object(ObjectDesc::sphere(-1.0))
///     .build()
///     .unwrap_err();
/// assert!(err.to_string().contains("`object[0].radius` must be positive"));
/// # Ok::<(), penumbra::Error>(())
/// ```
#[derive(Debug, Clone, Default)]
pub struct SceneBuilder {
    name: Option<String>,
    ambient: Option<[f64; 3]>,
    background: Option<[f64; 3]>,
    camera: Option<CameraDesc>,
    lights: Vec<LightDesc>,
    objects: Vec<ObjectDesc>,
    base_dir: PathBuf,
}

/// The pinhole camera of a built scene (the scene file's `[camera]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraDesc {
    /// Eye position.
    pub eye: [f64; 3],
    /// Point looked at.
    pub target: [f64; 3],
    /// Up hint.
    pub up: [f64; 3],
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_y: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// An area light of a built scene (a scene file's `[[light]]`).
#[derive(Debug, Clone, PartialEq)]
pub enum LightDesc {
    /// A parallelogram with corners `center ± u ± v`, emitting along
    /// `normalize(cross(u, v))`.
    Rect {
        /// Centre.
        center: [f64; 3],
        /// Half-edge vector (texture column direction).
        u: [f64; 3],
        /// Half-edge vector (texture row direction).
        v: [f64; 3],
        /// Emitted radiance, linear RGB.
        radiance: [f64; 3],
        /// Optional texture, `Le = radiance * texel`; relative paths are
        /// relative to [`SceneBuilder::base_dir`].
        texture: Option<PathBuf>,
        /// Emits on both sides.
        two_sided: bool,
    },
    /// A sphere emitting from its whole surface.
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius.
        radius: f64,
        /// Emitted radiance, linear RGB.
        radiance: [f64; 3],
    },
}

/// The geometry of an object of a built scene.
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// The contract's UV sphere, pole axis +Y.
    Sphere {
        /// Radius.
        radius: f64,
        /// Segments around the pole axis.
        segments: u32,
        /// Rings from pole to pole.
        rings: u32,
    },
    /// A box of `size`, centred on the origin.
    Box {
        /// Extent along x, y and z.
        size: [f64; 3],
    },
    /// A quad of `size[0] × size[1]` in the plane y = 0, centred, facing +Y.
    Quad {
        /// Extent along x and z.
        size: [f64; 2],
    },
    /// A mesh file, read as a scene's `obj = ...` is (by extension: OBJ
    /// with its MTL files, PLY, glTF or GLB); relative paths are relative
    /// to [`SceneBuilder::base_dir`].
    Obj(PathBuf),
    /// A mesh given in memory.
    Mesh(MeshData),
}

/// An inline material (a scene file's `material = { ... }`).
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialDesc {
    /// Lambertian albedo, linear RGB.
    pub albedo: [f64; 3],
    /// Albedo texture (multiplies `albedo`).
    pub albedo_texture: Option<PathBuf>,
    /// Specular colour of the normalised Blinn-Phong lobe.
    pub specular: [f64; 3],
    /// Blinn-Phong exponent.
    pub shininess: f64,
    /// Constant opacity in [0, 1].
    pub opacity: f64,
    /// Opacity texture (multiplies `opacity`).
    pub opacity_texture: Option<PathBuf>,
}

/// An object of a built scene (a scene file's `[[object]]`): geometry,
/// then scale, rotation and translation, a material and shadow flags.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectDesc {
    /// A name for messages and reports (default: the shape or file stem
    /// with the object's index).
    pub name: Option<String>,
    /// What the object is.
    pub geometry: Geometry,
    /// Translation, applied last.
    pub translate: [f64; 3],
    /// Euler angles in degrees, applied X then Y then Z.
    pub rotate: [f64; 3],
    /// Scale factors, applied first.
    pub scale: [f64; 3],
    /// Inline material; on an OBJ it replaces the MTL materials. Absent:
    /// the MTL's, else the default (albedo 0.8, opaque).
    pub material: Option<MaterialDesc>,
    /// Occludes light.
    pub cast_shadows: bool,
    /// Receives shadows (false: Vcoef = 1 on it).
    pub receive_shadows: bool,
}

impl CameraDesc {
    /// A camera at `eye` looking at `target` with vertical field of view
    /// `fov_y` degrees; up +Y and 1024 × 1024 pixels, as a scene file's
    /// defaults.
    pub fn new(eye: [f64; 3], target: [f64; 3], fov_y: f64) -> Self {
        CameraDesc {
            eye,
            target,
            up: [0.0, 1.0, 0.0],
            fov_y,
            width: 1024,
            height: 1024,
        }
    }

    /// With image size `width × height` pixels.
    pub fn size(self, width: u32, height: u32) -> Self {
        CameraDesc {
            width,
            height,
            ..self
        }
    }

    /// With up hint `up`.
    pub fn up(self, up: [f64; 3]) -> Self {
        CameraDesc { up, ..self }
    }
}

impl LightDesc {
    /// A one-sided rect light without texture.
    pub fn rect(center: [f64; 3], u: [f64; 3], v: [f64; 3], radiance: [f64; 3]) -> Self {
        LightDesc::Rect {
            center,
            u,
            v,
            radiance,
            texture: None,
            two_sided: false,
        }
    }

    /// A sphere light.
    pub fn sphere(center: [f64; 3], radius: f64, radiance: [f64; 3]) -> Self {
        LightDesc::Sphere {
            center,
            radius,
            radiance,
        }
    }
}

impl Default for MaterialDesc {
    /// The contract's defaults: albedo 0.8 grey, no specular lobe, opaque.
    fn default() -> Self {
        MaterialDesc {
            albedo: [0.8; 3],
            albedo_texture: None,
            specular: [0.0; 3],
            shininess: 0.0,
            opacity: 1.0,
            opacity_texture: None,
        }
    }
}

impl ObjectDesc {
    /// An object of `geometry` with no transform, no material of its own,
    /// casting and receiving shadows.
    pub fn new(geometry: Geometry) -> Self {
        ObjectDesc {
            name: None,
            geometry,
            translate: [0.0; 3],
            rotate: [0.0; 3],
            scale: [1.0; 3],
            material: None,
            cast_shadows: true,
            receive_shadows: true,
        }
    }

    /// A sphere of `radius` with the default 20 segments and 20 rings.
    pub fn sphere(radius: f64) -> Self {
        Self::new(Geometry::Sphere {
            radius,
            segments: 20,
            rings: 20,
        })
    }

    /// A box of `size`.
    pub fn cuboid(size: [f64; 3]) -> Self {
        Self::new(Geometry::Box { size })
    }

    /// A quad of `size` (x, z).
    pub fn quad(size: [f64; 2]) -> Self {
        Self::new(Geometry::Quad { size })
    }

    /// A mesh file: OBJ, PLY, glTF or GLB (by extension).
    pub fn obj(path: impl Into<PathBuf>) -> Self {
        Self::new(Geometry::Obj(path.into()))
    }

    /// A mesh given in memory.
    pub fn mesh(mesh: MeshData) -> Self {
        Self::new(Geometry::Mesh(mesh))
    }

    /// Named `name`.
    pub fn named(self, name: impl Into<String>) -> Self {
        ObjectDesc {
            name: Some(name.into()),
            ..self
        }
    }

    /// Translated by `t`.
    pub fn translate(self, t: [f64; 3]) -> Self {
        ObjectDesc {
            translate: t,
            ..self
        }
    }

    /// Rotated by Euler angles `degrees` (X, then Y, then Z).
    pub fn rotate(self, degrees: [f64; 3]) -> Self {
        ObjectDesc {
            rotate: degrees,
            ..self
        }
    }

    /// Scaled by `factors` (x, y, z).
    pub fn scale(self, factors: [f64; 3]) -> Self {
        ObjectDesc {
            scale: factors,
            ..self
        }
    }

    /// With inline material `material`.
    pub fn material(self, material: MaterialDesc) -> Self {
        ObjectDesc {
            material: Some(material),
            ..self
        }
    }

    /// With shadow flags: whether it occludes light and whether it
    /// receives shadows.
    pub fn shadows(self, cast: bool, receive: bool) -> Self {
        ObjectDesc {
            cast_shadows: cast,
            receive_shadows: receive,
            ..self
        }
    }
}

impl SceneBuilder {
    /// An empty scene: no camera yet (required), no lights or objects, zero
    /// ambient and background, relative paths relative to the current
    /// directory.
    pub fn new() -> Self {
        Self::default()
    }

    /// Names the scene (default "scene").
    pub fn name(mut self, name: impl Into<String>) -> Self {
        self.name = Some(name.into());
        self
    }

    /// Constant ambient radiance (stand-in for indirect light), linear RGB.
    pub fn ambient(mut self, rgb: [f64; 3]) -> Self {
        self.ambient = Some(rgb);
        self
    }

    /// Background radiance for pixels with no surface, linear RGB.
    pub fn background(mut self, rgb: [f64; 3]) -> Self {
        self.background = Some(rgb);
        self
    }

    /// The folder that relative paths (OBJ files, textures) are relative to.
    pub fn base_dir(mut self, dir: impl Into<PathBuf>) -> Self {
        self.base_dir = dir.into();
        self
    }

    /// Sets the camera.
    pub fn camera(mut self, camera: CameraDesc) -> Self {
        self.camera = Some(camera);
        self
    }

    /// Adds a light (light index = order of addition).
    pub fn light(mut self, light: LightDesc) -> Self {
        self.lights.push(light);
        self
    }

    /// Adds an object.
    pub fn object(mut self, object: ObjectDesc) -> Self {
        self.objects.push(object);
        self
    }

    /// The validated scene. Errors are those of a scene file with the
    /// same content, as [`Error::Parameter`]s naming the item and key (an
    /// error inside a referenced OBJ, MTL or texture file names that file
    /// and line, as for a scene file).
    pub fn build(&self) -> Result<Scene> {
        let doc = self.document()?;
        let meshes: MemoryMeshes = (self.objects.iter().enumerate())
            .filter_map(|(i, o)| match &o.geometry {
                Geometry::Mesh(m) => Some((i, m)),
                _ => None,
            })
            .collect();
        let path = Path::new(BUILT_SCENE);
        parse_scene(doc.text.as_bytes(), path, &self.base_dir, "scene", &meshes)
            .map_err(|e| doc.locate(e))
    }

    /// The scene file this builder describes.
    fn document(&self) -> Result<Document> {
        let mut doc = Document::default();
        let mut scene = Vec::new();
        if let Some(name) = &self.name {
            scene.push(("name", Value::String(name.clone())));
        }
        if let Some(rgb) = self.ambient {
            scene.push(("ambient", triple(rgb)));
        }
        if let Some(rgb) = self.background {
            scene.push(("background", triple(rgb)));
        }
        doc.section("[scene]", "scene".into(), &scene);
        if let Some(c) = &self.camera {
            let camera = [
                ("eye", triple(c.eye)),
                ("target", triple(c.target)),
                ("up", triple(c.up)),
                ("fov_y", Value::Float(c.fov_y)),
                ("width", Value::Integer(c.width.into())),
                ("height", Value::Integer(c.height.into())),
            ];
            doc.section("[camera]", "camera".into(), &camera);
        }
        for (i, l) in self.lights.iter().enumerate() {
            let label = format!("light[{i}]");
            let entries = light_entries(l, &label)?;
            doc.section("[[light]]", label, &entries);
        }
        for (i, o) in self.objects.iter().enumerate() {
            let label = match &o.name {
                Some(name) => format!("object {name:?}"),
                None => format!("object[{i}]"),
            };
            let entries = object_entries(o, &label)?;
            doc.section("[[object]]", label.clone(), &entries);
            if let Geometry::Mesh(_) = o.geometry {
                // Its `obj` line stands for the mesh: errors there are the mesh's.
                for (_, key) in doc.lines.iter_mut().rev().take(entries.len()) {
                    if *key == format!("{label}.obj") {
                        *key = format!("{label}.mesh");
                    }
                }
            }
        }
        Ok(doc)
    }
}

/// `[x, y, z]` as a TOML array.
fn triple(xs: [f64; 3]) -> Value {
    Value::Array(xs.iter().map(|&x| Value::Float(x)).collect())
}

/// A path as a TOML string; TOML text holds only UTF-8, so another path is
/// an error at `key`.
fn path_value(p: &Path, key: String) -> Result<Value> {
    match p.to_str() {
        Some(s) => Ok(Value::String(s.to_string())),
        None => Err(Error::param(
            key,
            format!("`{}` is not valid UTF-8", p.display()),
        )),
    }
}

/// The keys of light `l` (named `label`).
fn light_entries(l: &LightDesc, label: &str) -> Result<Vec<(&'static str, Value)>> {
    Ok(match l {
        LightDesc::Rect {
            center,
            u,
            v,
            radiance,
            texture,
            two_sided,
        } => {
            let mut entries = vec![
                ("type", Value::String("rect".into())),
                ("center", triple(*center)),
                ("u", triple(*u)),
                ("v", triple(*v)),
                ("radiance", triple(*radiance)),
                ("two_sided", Value::Boolean(*two_sided)),
            ];
            if let Some(t) = texture {
                entries.push(("texture", path_value(t, format!("{label}.texture"))?));
            }
            entries
        }
        LightDesc::Sphere {
            center,
            radius,
            radiance,
        } => vec![
            ("type", Value::String("sphere".into())),
            ("center", triple(*center)),
            ("radius", Value::Float(*radius)),
            ("radiance", triple(*radiance)),
        ],
    })
}

/// The keys of object `o` (named `label`).
fn object_entries(o: &ObjectDesc, label: &str) -> Result<Vec<(&'static str, Value)>> {
    let mut entries = Vec::new();
    if let Some(name) = &o.name {
        entries.push(("name", Value::String(name.clone())));
    }
    let shape = |s: &str| Value::String(s.into());
    match &o.geometry {
        Geometry::Sphere {
            radius,
            segments,
            rings,
        } => entries.extend([
            ("shape", shape("sphere")),
            ("radius", Value::Float(*radius)),
            ("segments", Value::Integer((*segments).into())),
            ("rings", Value::Integer((*rings).into())),
        ]),
        Geometry::Box { size } => {
            entries.extend([("shape", shape("box")), ("size", triple(*size))])
        }
        Geometry::Quad { size } => entries.extend([
            ("shape", shape("quad")),
            (
                "size",
                Value::Array(size.iter().map(|&x| Value::Float(x)).collect()),
            ),
        ]),
        Geometry::Obj(path) => entries.push(("obj", path_value(path, format!("{label}.obj"))?)),
        // The loader builds this object from the mesh (`MemoryMeshes`),
        // not from a file: the string only shows in its default name.
        Geometry::Mesh(_) => entries.push(("obj", Value::String("<in-memory mesh>".into()))),
    }
    entries.extend([
        ("translate", triple(o.translate)),
        ("rotate", triple(o.rotate)),
        ("scale", triple(o.scale)),
        ("cast_shadows", Value::Boolean(o.cast_shadows)),
        ("receive_shadows", Value::Boolean(o.receive_shadows)),
    ]);
    if let Some(m) = &o.material {
        let mut table = toml::Table::new();
        table.insert("albedo".into(), triple(m.albedo));
        table.insert("specular".into(), triple(m.specular));
        table.insert("shininess".into(), Value::Float(m.shininess));
        table.insert("opacity".into(), Value::Float(m.opacity));
        let key = |k: &str| format!("{label}.material.{k}");
        if let Some(t) = &m.albedo_texture {
            let v = path_value(t, key("albedo_texture"))?;
            table.insert("albedo_texture".into(), v);
        }
        if let Some(t) = &m.opacity_texture {
            let v = path_value(t, key("opacity_texture"))?;
            table.insert("opacity_texture".into(), v);
        }
        entries.push(("material", Value::Table(table)));
    }
    Ok(entries)
}

/// The scene file a builder writes, and which item and key each of its
/// lines holds, so that an error at a line can name them instead.
#[derive(Default)]
struct Document {
    text: String,
    /// From the line on (1-based), the item or `item.key` the text is.
    lines: Vec<(usize, String)>,
}

impl Document {
    /// The line the next text starts on (1-based).
    fn next_line(&self) -> usize {
        self.text.matches('\n').count() + 1
    }

    /// Appends a section or array-of-tables entry: `header`, then one
    /// `key = value` line per entry.
    fn section(&mut self, header: &str, label: String, entries: &[(&str, Value)]) {
        if entries.is_empty() && header == "[scene]" {
            // Still owns the first line: an error with no place (a missing
            // section) lands there and is the scene's.
            self.lines.push((1, label));
            self.text.push_str("# built in code\n");
            return;
        }
        self.lines.push((self.next_line(), label.clone()));
        self.text.push_str(header);
        self.text.push('\n');
        for (key, value) in entries {
            self.lines
                .push((self.next_line(), format!("{label}.{key}")));
            self.text.push_str(&format!("{key} = {value}\n"));
        }
    }

    /// `e` with the builder's text located: an error at one of its lines
    /// becomes a parameter error naming the item and key there; errors in
    /// other files (OBJ, MTL, textures) stay as they are.
    fn locate(&self, e: Error) -> Error {
        match e {
            Error::File {
                path,
                line,
                message,
            } if path == Path::new(BUILT_SCENE) => {
                let line = line.unwrap_or(1);
                let at = self.lines.partition_point(|(l, _)| *l <= line);
                let mut name = match at {
                    0 => "scene",
                    _ => self.lines[at - 1].1.as_str(),
                };
                // A missing section has no place in the text; the
                // message names it, and so does the error.
                if let Some(section) = (message.strip_prefix("missing field `"))
                    .and_then(|rest| rest.strip_suffix('`'))
                    .filter(|_| name == "scene")
                {
                    name = section;
                }
                Error::param(name.to_string(), message)
            }
            e => e,
        }
    }
}
