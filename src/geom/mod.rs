//! Geometry: meshes, the scene's concatenated triangle list (and, as
//! techniques need them, edge adjacency, silhouettes and the BVH).

#[forbid(unsafe_code)]
pub mod adjacency;
pub mod bvh;
#[forbid(unsafe_code)]
mod mesh;
#[forbid(unsafe_code)]
mod scene_geometry;
#[forbid(unsafe_code)]
pub mod silhouette;

pub use adjacency::{Edge, EdgeAdjacency, EdgeUse};

pub use mesh::Mesh;
pub use scene_geometry::{SceneGeometry, TriangleFrame};
