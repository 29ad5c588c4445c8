//! Shading.
