//! Geometry: meshes, the scene's concatenated triangle list (and, as
//! techniques need them, edge adjacency, silhouettes and the BVH).

pub mod bvh;
mod mesh;
mod scene_geometry;

pub use mesh::Mesh;
pub use scene_geometry::SceneGeometry;
