//! penumbra: a pure-software renderer for physically based soft shadows.
//!
//! The modules mirror the pipeline: [`scene`] loading → [`geom`]etry →
//! the [`raster`] pipeline → the [`gbuffer`] → [`shadow`] techniques →
//! [`shade`] → [`output`] and [`report`]s; [`render`] runs them in order.

// `!(x > 0.0)` is how this crate rejects NaN together with the failing
// range: the negation is the point, not an accident.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod allocator;
pub mod cli;
pub mod cluster;
pub mod compare;
pub mod error;
pub mod gbuffer;
pub mod geom;
pub mod output;
pub mod raster;
pub mod render;
pub mod report;
pub mod sampling;
pub mod scene;
pub mod shade;
pub mod shadow;
pub mod simd;
pub mod view;

pub use error::{Error, Result};
