//! Scenes: the TOML contract (`shared/spec/scene-format.md`), OBJ/MTL, PLY
//! and glTF models,
//! built-in shapes, materials, textures, lights and the camera; from a file,
//! from TOML text or built in code ([`SceneBuilder`]).
//!
//! Everything here is validated on load: a `Scene` that exists is finite,
//! in range and consistent (indices in bounds, lights with area, ...), so
//! later stages never re-check user input.

mod assets;
mod builder;
pub mod frame;
mod gltf;
pub mod input;
pub mod lint;
mod load;
mod obj;
mod ply;
mod shapes;
pub mod starter;
mod texture;

pub use builder::{CameraDesc, Geometry, LightDesc, MaterialDesc, ObjectDesc, SceneBuilder};
pub use load::{load_scene, scene_from_toml, BUILT_SCENE, TOML_TEXT};
pub use texture::{Texture, TextureData};

use crate::geom::Mesh;
use glam::Vec3;
use std::path::PathBuf;

/// Largest magnitude of any number in a scene file (coordinates, lengths,
/// radiance, colours, angles, ...) and of any vertex after its object's
/// transform. Within it, products of up to four coordinates (squared
/// lengths, cross products, plane offsets) stay finite in `f32`; beyond it
/// a scene is refused at load with a message that says so.
pub const MAX_MAGNITUDE: f64 = 1e9;

/// Smallest magnitude of a nonzero length (sphere and light radius, box and
/// quad size, `|u|` and `|v|` of a rect light) or scale factor: products of
/// up to four of them stay normal `f32` numbers.
pub const MIN_MAGNITUDE: f64 = 1e-9;

/// A loaded, validated scene.
#[derive(Debug, Clone)]
pub struct Scene {
    /// `[scene] name`, or the file stem.
    pub name: String,
    /// The scene file it came from.
    pub path: PathBuf,
    /// Constant ambient radiance (stand-in for indirect light), linear RGB.
    pub ambient: Vec3,
    /// Background radiance for pixels with no surface, linear RGB.
    pub background: Vec3,
    /// The pinhole camera.
    pub camera: Camera,
    /// Area lights, in file order (light index k = position here).
    pub lights: Vec<Light>,
    /// Objects in file order, meshes in world space.
    pub objects: Vec<Object>,
    /// All materials; meshes refer to them by index.
    pub materials: Vec<Material>,
    /// All textures; materials and lights refer to them by index.
    pub textures: Vec<Texture>,
    /// World position of this scene's local origin: every position here
    /// (vertices, lights, camera) is relative to it. Zero unless the scene
    /// sits far from the world origin ([`frame`]).
    pub origin: glam::DVec3,
}

impl Scene {
    /// Total triangle count over all objects.
    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| o.mesh.triangle_count()).sum()
    }

    /// Axis-aligned bounds of all geometry (min, max); `None` if empty.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.objects.iter().flat_map(|o| o.mesh.positions.iter());
        let first = *it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))))
    }
}

/// The contract's pinhole camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Up hint.
    pub up: Vec3,
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_y_degrees: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// The geometric shape of an area light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LightShape {
    /// Parallelogram with corners `center ± u ± v`; emits along
    /// `normalize(cross(u, v))` (both ways if `two_sided`).
    Rect {
        /// Centre.
        center: Vec3,
        /// Half-edge vector (texture column direction).
        u: Vec3,
        /// Half-edge vector (texture row direction, row 0 at `center + v`).
        v: Vec3,
        /// Emits on both sides.
        two_sided: bool,
    },
    /// Sphere emitting from its whole surface.
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius (> 0).
        radius: f32,
    },
}

/// An area light.
#[derive(Debug, Clone, PartialEq)]
pub struct Light {
    /// Shape and placement.
    pub shape: LightShape,
    /// Emitted radiance `Le`, linear RGB.
    pub radiance: Vec3,
    /// Optional texture index (rect lights only): `Le = radiance * texel`.
    pub texture: Option<usize>,
}

/// A surface material (contract table "Materials").
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Name (from the MTL, or `inline`/`default`).
    pub name: String,
    /// Lambertian albedo, linear RGB.
    pub albedo: Vec3,
    /// Albedo texture index (multiplies `albedo`).
    pub albedo_texture: Option<usize>,
    /// Specular colour `Ks` of the normalised Blinn-Phong lobe.
    pub specular: Vec3,
    /// Blinn-Phong exponent `Ns`.
    pub shininess: f32,
    /// Constant opacity `d` in [0, 1].
    pub opacity: f32,
    /// Opacity texture index (`map_d`), multiplies `opacity`.
    pub opacity_texture: Option<usize>,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            name: "default".into(),
            albedo: Vec3::splat(0.8),
            albedo_texture: None,
            specular: Vec3::ZERO,
            shininess: 0.0,
            opacity: 1.0,
            opacity_texture: None,
        }
    }
}

impl Material {
    /// True when light passes through nowhere on this material.
    pub fn is_opaque(&self) -> bool {
        self.opacity >= 1.0 && self.opacity_texture.is_none()
    }
}

/// One `[[object]]` of the scene, its mesh in world space.
#[derive(Debug, Clone)]
pub struct Object {
    /// A readable name (OBJ file stem or shape name, with its index).
    pub name: String,
    /// Geometry in world space.
    pub mesh: Mesh,
    /// Occludes light.
    pub cast_shadows: bool,
    /// Receives shadows (false: Vcoef = 1 on it).
    pub receive_shadows: bool,
}

/// A triangle mesh given in memory, in object space.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshData {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Triangles as indices into `positions` (from 0), counter-clockwise =
    /// front.
    pub triangles: Vec<[u32; 3]>,
    /// One shading normal per position; absent: the geometric normal.
    pub normals: Option<Vec<[f32; 3]>>,
    /// One texture coordinate per position.
    pub uvs: Option<Vec<[f32; 2]>>,
}

impl MeshData {
    /// A mesh of `positions` and `triangles`, without normals or uvs.
    pub fn new(positions: Vec<[f32; 3]>, triangles: Vec<[u32; 3]>) -> Self {
        MeshData {
            positions,
            triangles,
            normals: None,
            uvs: None,
        }
    }
}
