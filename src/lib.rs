//! penumbra: a pure-software renderer for physically based soft shadows.
//!
//! The modules mirror the pipeline: [`scene`] loading → [`geom`]etry →
//! the [`raster`] pipeline → the [`gbuffer`] → [`shadow`] techniques →
//! [`shade`] → [`output`] and [`report`]s; [`render`] runs them in order.
//!
//! Rendering into memory: a scene from a file ([`scene::load_scene`]) or
//! from TOML text ([`scene::scene_from_toml`]), options checked as the
//! command line checks them ([`render::RenderOptions::validate`], which
//! [`render::render`] calls first), and the radiance, AOV layers, per-light
//! terms and pass timings back as data:
//!
//! ```
//! use penumbra::render::{render, RenderOptions};
//! use penumbra::report::Progress;
//! use penumbra::scene::scene_from_toml;
//!
//! let scene = scene_from_toml(
//!     r#"
//!     [camera]
//!     eye = [0.0, 5.0, 6.0]
//!     target = [0.0, 0.0, 0.0]
//!     fov_y = 45
//!     width = 32
//!     height = 24
//!     [[light]]
//!     type = "rect"
//!     center = [0.0, 4.0, 0.0]
//!     u = [0.5, 0.0, 0.0]
//!     v = [0.0, 0.0, 0.5]
//!     radiance = 10
//!     [[object]]
//!     name = "ground"
//!     shape = "quad"
//!     size = [6.0, 6.0]
//!     [[object]]
//!     name = "occluder"
//!     shape = "quad"
//!     size = [1.0, 1.0]
//!     translate = [0.0, 1.0, 0.0]
//!     "#,
//!     std::path::Path::new("."),
//! )?;
//! let options = RenderOptions {
//!     samples: 16,
//!     ..RenderOptions::default() // dcs: the exact image
//! };
//! let out = render(&scene, &options, &Progress::new(1, false))?;
//! assert_eq!(out.radiance.len(), 32 * 24);
//! assert_eq!(out.lights.len(), 1);
//! // The occluder's shadow: some pixels see less of the light.
//! let vcoef = out.lights[0].vcoef();
//! assert!(vcoef.iter().any(|&v| v < 1.0) && vcoef.iter().any(|&v| v == 1.0));
//! # Ok::<(), penumbra::error::Error>(())
//! ```

// `!(x > 0.0)` is how this crate rejects NaN together with the failing
// range: the negation is the point, not an accident.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod allocator;
#[forbid(unsafe_code)]
pub mod cli;
#[forbid(unsafe_code)]
pub mod cluster;
#[forbid(unsafe_code)]
pub mod compare;
#[forbid(unsafe_code)]
pub mod error;
#[forbid(unsafe_code)]
pub mod gbuffer;
pub mod geom;
#[forbid(unsafe_code)]
pub mod output;
pub mod raster;
#[forbid(unsafe_code)]
pub mod render;
#[forbid(unsafe_code)]
pub mod report;
#[forbid(unsafe_code)]
pub mod sampling;
#[forbid(unsafe_code)]
pub mod scene;
pub mod shade;
pub mod shadow;
pub mod simd;
#[forbid(unsafe_code)]
pub mod view;

pub use error::{Error, Result};
