//! Raster pipeline.
