//! Triangle meshes in world space, as every later stage sees them.

use glam::{Vec2, Vec3};

/// A triangle mesh in world space (transforms already applied).
///
/// Positions are f32: scenes are authored in f32 (OBJ, TOML) and every
/// consumer (rasterizer, BVH) works in f32; where more precision matters
/// (camera-ray hit points) the consumer promotes to f64 locally.
#[derive(Debug, Clone, Default)]
pub struct Mesh {
    /// Vertex positions, world space.
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals (unit length, world space), when every
    /// vertex has one. Absent: the geometric normal is used.
    pub normals: Option<Vec<Vec3>>,
    /// Per-vertex texture coordinates, when the mesh has them.
    pub uvs: Option<Vec<Vec2>>,
    /// Triangles as vertex indices, counter-clockwise = front.
    pub triangles: Vec<[u32; 3]>,
    /// Per-triangle index into [`crate::scene::Scene::materials`].
    pub material_ids: Vec<u32>,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The three corner positions of triangle `t`.
    #[inline]
    pub fn corners(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Unnormalised geometric normal of triangle `t` (from the winding).
    #[inline]
    pub fn face_normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.corners(t);
        (b - a).cross(c - a)
    }
}
