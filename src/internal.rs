//! The pipeline's modules, for the command line, the benches and the
//! tests: not the library's interface, and not stable. Programs use the
//! items at the crate root. The modules stay in their folders under
//! `src/` (the tree mirrors the pipeline); this file only gathers them.

#[path = "allocator.rs"]
pub mod allocator;
#[forbid(unsafe_code)]
#[path = "cli.rs"]
pub mod cli;
#[forbid(unsafe_code)]
#[path = "cluster/mod.rs"]
pub mod cluster;
#[forbid(unsafe_code)]
#[path = "compare/mod.rs"]
pub mod compare;
#[forbid(unsafe_code)]
#[path = "error.rs"]
pub mod error;
#[forbid(unsafe_code)]
#[path = "gbuffer/mod.rs"]
pub mod gbuffer;
#[path = "geom/mod.rs"]
pub mod geom;
#[forbid(unsafe_code)]
#[path = "observe.rs"]
pub mod observe;
#[forbid(unsafe_code)]
#[path = "output/mod.rs"]
pub mod output;
#[path = "raster/mod.rs"]
pub mod raster;
#[forbid(unsafe_code)]
#[path = "render/mod.rs"]
pub mod render;
#[forbid(unsafe_code)]
#[path = "report/mod.rs"]
pub mod report;
#[forbid(unsafe_code)]
#[path = "sampling/mod.rs"]
pub mod sampling;
#[forbid(unsafe_code)]
#[path = "scene/mod.rs"]
pub mod scene;
#[path = "shade/mod.rs"]
pub mod shade;
#[path = "shadow/mod.rs"]
pub mod shadow;
#[path = "simd/mod.rs"]
pub mod simd;
#[forbid(unsafe_code)]
#[path = "view.rs"]
pub mod view;
