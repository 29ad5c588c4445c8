//! Geometry: meshes, the scene's concatenated triangle list (and, as
//! techniques need them, edge adjacency, silhouettes and the BVH).

pub mod adjacency;
pub mod bvh;
mod mesh;
mod scene_geometry;
pub mod silhouette;

pub use adjacency::{Edge, EdgeAdjacency, EdgeUse};

pub use mesh::Mesh;
pub use scene_geometry::{SceneGeometry, TriangleFrame};
