//! The raster pipeline, Larrabee style, on the CPU: a programmable vertex
//! stage, homogeneous clipping (vertices at infinity welcome), fixed-point
//! setup with exact edge functions and the top-left rule, binning into
//! 64×64 tiles rasterized in parallel, 8×8 block descent, and 8-lane SIMD
//! coverage, depth, stencil and fragment batches.

#[forbid(unsafe_code)]
mod bin;
#[forbid(unsafe_code)]
mod clip;
#[forbid(unsafe_code)]
mod fragment;
#[forbid(unsafe_code)]
mod framebuffer;
mod pipeline;
#[forbid(unsafe_code)]
mod setup;
#[forbid(unsafe_code)]
mod simd;
#[forbid(unsafe_code)]
mod state;
#[forbid(unsafe_code)]
mod tile;
#[forbid(unsafe_code)]
mod vertex;

pub use bin::TileBins;
pub use clip::{clip_triangle, ClippedPolygon};
pub use fragment::{FragmentBatch, FragmentStage, NoFragmentStage};
pub use framebuffer::{
    DepthStencilTile, Framebuffer, TileGrid, TiledTarget, FAR_DEPTH, TILE_PIXELS, TILE_SIZE,
};
pub use pipeline::{draw, draw_depth_shift_counts, draw_numbered, DrawStats};
pub use setup::{
    EdgeFunction, Plane, QuadExtra, SetupTriangle, Viewport, GUARD_BAND, MAX_SIDE, NO_QUAD,
    SUBPIXEL_BITS,
};
pub use simd::LANES;
pub use state::{CompareFunc, CullMode, RasterState, StencilFace, StencilOp, StencilState};
pub use vertex::{run_vertex_stage, run_vertex_stage_into, ClipVertex};
