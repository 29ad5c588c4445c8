//! All objects' triangles in one indexed list: what a draw call, a BVH or a
//! silhouette pass iterates over.

use super::adjacency::split_sizes;
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::sync::{Arc, OnceLock};

/// Every object's mesh concatenated, with a map back to objects.
#[derive(Debug, Clone, Default)]
pub struct SceneGeometry {
    /// World positions of all vertices.
    pub positions: Vec<Vec3>,
    /// Triangles indexing `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// For each triangle, its object's index in [`Scene::objects`]
    /// (shared: every G-buffer of the scene refers to it).
    pub triangle_object: Arc<[u32]>,
    /// For each triangle, its index in [`Scene::materials`] (shared, as
    /// `triangle_object`).
    pub triangle_material: Arc<[u32]>,
    /// For each object, the index of its first triangle here.
    pub object_first_triangle: Vec<u32>,
    /// For each object, the index of its first vertex here.
    pub object_first_vertex: Vec<u32>,
    /// For each object: is its surface closed (every welded edge used as
    /// often in one direction as in the other)? A closed surface hides
    /// its back faces from any eye outside it.
    pub object_closed: Vec<bool>,
    /// Welded edge adjacency of all triangles, built on first use
    /// ([`Self::adjacency`]): only edge-walking techniques need it, and at
    /// millions of triangles it is the largest structure after the meshes.
    adjacency: OnceLock<super::EdgeAdjacency>,
    /// Per triangle, its unit geometric normal from the winding (the f64
    /// frame normal normalised, then rounded to f32; [`Self::frame`]); zero
    /// for a sliver.
    /// Shared like `triangle_object`: G-buffers store only whether it is
    /// flipped.
    pub unit_normals: Arc<[Vec3]>,
}

/// A triangle's plane and the dual vectors that turn a point of the plane
/// into barycentrics with two dot products (f64).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleFrame {
    /// First corner.
    pub a: DVec3,
    /// Unnormalised normal `(b - a) × (c - a)` (winding order).
    pub normal: DVec3,
    /// `b1 = (p - a) · dual1`.
    pub dual1: DVec3,
    /// `b2 = (p - a) · dual2`.
    pub dual2: DVec3,
    /// Centroid, for rays grazing the plane.
    pub centroid: DVec3,
}

impl TriangleFrame {
    /// All zero (an empty cache slot).
    pub const ZERO: TriangleFrame = TriangleFrame {
        a: DVec3::ZERO,
        normal: DVec3::ZERO,
        dual1: DVec3::ZERO,
        dual2: DVec3::ZERO,
        centroid: DVec3::ZERO,
    };

    /// The frame of triangle `(a, b, c)`.
    pub fn new([a, b, c]: [DVec3; 3]) -> Self {
        let (e1, e2) = (b - a, c - a);
        let normal = e1.cross(e2);
        let n2 = normal.length_squared();
        // Degenerate triangles were dropped at load; a zero here can only
        // come from a sliver and gives zero duals (users fall back to the
        // centroid).
        let inv = if n2 > 0.0 { 1.0 / n2 } else { 0.0 };
        TriangleFrame {
            a,
            normal,
            dual1: e2.cross(normal) * inv,
            dual2: normal.cross(e1) * inv,
            centroid: (a + b + c) / 3.0,
        }
    }

    /// Where the ray `origin + t dir` meets the triangle's plane: `(t, b1,
    /// b2)` with unclamped barycentrics, or `None` for a ray (numerically)
    /// in the plane or a hit behind the origin.
    #[inline]
    pub fn hit(&self, origin: DVec3, dir: DVec3) -> Option<(f64, f64, f64)> {
        let t = self.normal.dot(self.a - origin) / self.normal.dot(dir);
        if !(t.is_finite() && t > 0.0) {
            return None;
        }
        let d = origin + dir * t - self.a;
        Some((t, d.dot(self.dual1), d.dot(self.dual2)))
    }
}

impl SceneGeometry {
    /// Concatenates the scene's meshes in object order.
    ///
    /// Object by object in parallel, each into its own slice of arrays
    /// sized up front, and the shared per-triangle arrays written in place
    /// (`Arc<[T]>` from a `Vec` is a copy): at millions of triangles the
    /// serial copies and their page faults were a third of this step.
    pub fn new(scene: &Scene) -> Self {
        let objects = &scene.objects;
        let n_triangles: usize = objects.iter().map(|o| o.mesh.triangles.len()).sum();
        let n_vertices: usize = objects.iter().map(|o| o.mesh.positions.len()).sum();
        let mut g = SceneGeometry::default();
        let (mut first_vertex, mut first_triangle) = (0u32, 0u32);
        for obj in objects {
            g.object_first_vertex.push(first_vertex);
            g.object_first_triangle.push(first_triangle);
            first_vertex += obj.mesh.positions.len() as u32;
            first_triangle += obj.mesh.triangles.len() as u32;
        }
        g.positions = vec![Vec3::ZERO; n_vertices];
        g.triangles = vec![[0; 3]; n_triangles];
        let mut triangle_material = shared_slice(n_triangles);
        let mut triangle_object = shared_slice(n_triangles);
        {
            let vertex_sizes = objects.iter().map(|o| o.mesh.positions.len());
            let triangle_sizes = || objects.iter().map(|o| o.mesh.triangles.len());
            let pieces = split_sizes(&mut g.positions, vertex_sizes)
                .into_iter()
                .zip(split_sizes(&mut g.triangles, triangle_sizes()))
                .zip(split_sizes(
                    mut_slice(&mut triangle_material),
                    triangle_sizes(),
                ))
                .zip(split_sizes(
                    mut_slice(&mut triangle_object),
                    triangle_sizes(),
                ));
            let firsts = &g.object_first_vertex;
            pieces
                .collect::<Vec<_>>()
                .into_par_iter()
                .enumerate()
                .for_each(|(oi, (((positions, triangles), materials), object))| {
                    let mesh = &objects[oi].mesh;
                    let base = firsts[oi];
                    positions.copy_from_slice(&mesh.positions);
                    for (out, t) in triangles.iter_mut().zip(&mesh.triangles) {
                        *out = t.map(|i| i + base);
                    }
                    materials.copy_from_slice(&mesh.material_ids);
                    object.fill(oi as u32);
                });
        }
        g.triangle_material = triangle_material;
        g.triangle_object = triangle_object;
        g.object_closed = super::adjacency::closed_objects(&g, objects.len());
        let mut unit_normals = shared_slice(n_triangles);
        mut_slice(&mut unit_normals)
            .par_iter_mut()
            .zip(g.triangles.par_iter())
            .with_min_len(4096)
            .for_each(|(n, t)| {
                let [a, b, c] = t.map(|i| g.positions[i as usize].as_dvec3());
                // TriangleFrame::new's normal, operation for operation.
                *n = (b - a).cross(c - a).normalize_or_zero().as_vec3();
            });
        g.unit_normals = unit_normals;
        g
    }

    /// The welded edge adjacency of all triangles, built on the first call
    /// (the same for any caller and thread count).
    pub fn adjacency(&self) -> &super::EdgeAdjacency {
        self.adjacency
            .get_or_init(|| super::EdgeAdjacency::build(self, |_| true))
    }

    /// Whether [`Self::adjacency`] has been built (`--explain` reports
    /// it left out when no technique asked for it).
    pub fn adjacency_built(&self) -> bool {
        self.adjacency.get().is_some()
    }

    /// Triangle `triangle`'s plane and barycentric frame in f64, from its
    /// corners (a few dozen flops: computed where needed rather than
    /// stored for every triangle).
    #[inline]
    pub fn frame(&self, triangle: u32) -> TriangleFrame {
        let t = self.triangles[triangle as usize];
        TriangleFrame::new(t.map(|i| self.positions[i as usize].as_dvec3()))
    }

    /// Object `o`'s triangles, as indices into `triangles`.
    #[inline]
    pub fn object_triangle_range(&self, o: usize) -> std::ops::Range<usize> {
        let end =
            (self.object_first_triangle.get(o + 1)).map_or(self.triangles.len(), |&t| t as usize);
        self.object_first_triangle[o] as usize..end
    }

    /// Object `o`'s vertices, as indices into `positions`.
    #[inline]
    pub fn object_vertex_range(&self, o: usize) -> std::ops::Range<usize> {
        let end =
            (self.object_first_vertex.get(o + 1)).map_or(self.positions.len(), |&v| v as usize);
        self.object_first_vertex[o] as usize..end
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

/// A shared slice of `n` default values, allocated once in place (`Arc<[T]>`
/// from a `Vec` would copy it), to be filled through [`mut_slice`].
fn shared_slice<T: Default + Clone>(n: usize) -> Arc<[T]> {
    std::iter::repeat_n(T::default(), n).collect()
}

/// The contents of a shared slice this thread has just made (no other
/// handle exists yet).
fn mut_slice<T>(shared: &mut Arc<[T]>) -> &mut [T] {
    Arc::get_mut(shared).expect("a slice made by shared_slice has no other handle")
}
