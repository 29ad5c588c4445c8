//! Geometry: meshes (and, as techniques need them, edge adjacency,
//! silhouettes and the BVH).

mod mesh;

pub use mesh::Mesh;
