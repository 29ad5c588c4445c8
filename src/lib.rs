//! penumbra: a pure-software renderer for physically based soft shadows.
//!
//! The modules mirror the pipeline: [`scene`] loading → [`geom`]etry →
//! the [`raster`] pipeline → [`shadow`] techniques → [`shade`] → [`output`].

pub mod error;
pub mod geom;
pub mod output;
pub mod raster;
pub mod scene;
pub mod shade;

pub use error::{Error, Result};
