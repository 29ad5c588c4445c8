//! The shared shadow kit: building blocks several techniques use, so that
//! no technique imports from a sibling technique.
//!
//! - [`cache`]: per-render caches filled on first use (caster adjacency,
//!   S-triangles, semi-opaque caster groups, the shadow-ray tracer).
//! - [`rays`]: shadow rays, the shadow-ray origin rule and its epsilons.
//! - [`volumes`]: hard shadow volumes and exact stencil counts.
//! - [`wedge_geometry`]: the light's bound, penumbra wedges and their halves.
//! - [`membership`]: half-wedge membership and the per-light start.
//! - [`light_view`]: views from a point on a light and caster depth maps.
//! - [`shadow_maps`]: what the shadow-map techniques share: receiver
//!   projection with depth bias, the hard test, PCF.
//! - [`many_maps`]: what the many-map techniques share: points on the
//!   light, receivers facing it, one map consumed by every receiver, exact
//!   integer accumulation.
//! - [`light_frame`]: the rect light's frame, projections into it,
//!   clipping to it and region integrals.
//! - [`enclosure`]: lights inside closed casters.
//! - [`groups`]: semi-opaque caster groups and transmittance.
//! - [`timing`]: pass timing.
//! - [`tiles`]: tile-local to image pixel mapping.
//! - [`verify`]: `--verify`, re-casting relations with shadow rays.

#[forbid(unsafe_code)]
pub mod cache;
#[forbid(unsafe_code)]
pub mod enclosure;
#[forbid(unsafe_code)]
pub mod groups;
#[forbid(unsafe_code)]
pub mod light_frame;
#[forbid(unsafe_code)]
pub mod light_view;
#[forbid(unsafe_code)]
pub mod many_maps;
#[forbid(unsafe_code)]
pub mod map_fit;
#[forbid(unsafe_code)]
pub mod map_options;
#[forbid(unsafe_code)]
pub mod membership;
pub mod rays;
#[forbid(unsafe_code)]
pub mod shadow_maps;
#[forbid(unsafe_code)]
pub mod stsv;
#[forbid(unsafe_code)]
pub mod tiles;
#[forbid(unsafe_code)]
pub mod timing;
#[forbid(unsafe_code)]
pub mod verify;
#[forbid(unsafe_code)]
pub mod volumes;
#[forbid(unsafe_code)]
pub mod wedge_geometry;

pub use cache::ShadowCache;
pub use tiles::TilePixels;
pub use timing::PassTimer;
