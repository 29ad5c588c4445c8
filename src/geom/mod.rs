//! Geometry: meshes, the scene's concatenated triangle list (and, as
//! techniques need them, edge adjacency, silhouettes and the BVH).

mod mesh;
mod scene_geometry;

pub use mesh::Mesh;
pub use scene_geometry::SceneGeometry;
