//! penumbra: a pure-software renderer for physically based soft shadows.
//!
//! The modules mirror the pipeline: [`scene`] loading → [`geom`]etry →
//! the [`raster`] pipeline → the [`gbuffer`] → [`shadow`] techniques →
//! [`shade`] → [`output`] and [`report`]s; [`render`] runs them in order.

pub mod cli;
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
pub mod view;

pub use error::{Error, Result};
