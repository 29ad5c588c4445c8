//! penumbra: a pure-software renderer for physically based soft shadows.
//!
//! The modules mirror the pipeline: [`scene`] loading → [`geom`]etry →
//! the [`raster`] pipeline → the [`gbuffer`] → [`shadow`] techniques →
//! [`shade`] → [`output`] and [`report`]s; [`render`] runs them in order.

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
