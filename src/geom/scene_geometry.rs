//! All objects' triangles in one indexed list: what a draw call, a BVH or a
//! silhouette pass iterates over.

use crate::scene::Scene;
use glam::Vec3;

/// Every object's mesh concatenated, with a map back to objects.
#[derive(Debug, Clone, Default)]
pub struct SceneGeometry {
    /// World positions of all vertices.
    pub positions: Vec<Vec3>,
    /// Triangles indexing `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// For each triangle, its object's index in [`Scene::objects`].
    pub triangle_object: Vec<u32>,
    /// For each triangle, its index in [`Scene::materials`].
    pub triangle_material: Vec<u32>,
    /// For each object, the index of its first triangle here.
    pub object_first_triangle: Vec<u32>,
}

impl SceneGeometry {
    /// Concatenates the scene's meshes in object order.
    pub fn new(scene: &Scene) -> Self {
        let mut g = SceneGeometry::default();
        for (oi, obj) in scene.objects.iter().enumerate() {
            let base = g.positions.len() as u32;
            g.object_first_triangle.push(g.triangles.len() as u32);
            g.positions.extend_from_slice(&obj.mesh.positions);
            g.triangles
                .extend(obj.mesh.triangles.iter().map(|t| t.map(|i| i + base)));
            g.triangle_material
                .extend_from_slice(&obj.mesh.material_ids);
            g.triangle_object
                .extend(std::iter::repeat_n(oi as u32, obj.mesh.triangles.len()));
        }
        g
    }

    /// (object index, triangle index inside that object's mesh).
    #[inline]
    pub fn locate(&self, triangle: u32) -> (usize, usize) {
        let o = self.triangle_object[triangle as usize];
        (
            o as usize,
            (triangle - self.object_first_triangle[o as usize]) as usize,
        )
    }
}
