//! The shared shadow kit: building blocks several techniques use, so that
//! no technique imports from a sibling technique.
//!
//! - [`cache`]: per-render caches filled on first use (caster adjacency,
//!   S-triangles, semi-opaque caster groups, the shadow-ray tracer).
//! - [`timing`]: pass timing.
//! - [`tiles`]: tile-local to image pixel mapping.

pub mod cache;
pub mod tiles;
pub mod timing;

pub use cache::ShadowCache;
pub use tiles::TilePixels;
pub use timing::PassTimer;
