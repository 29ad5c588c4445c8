//! Output images.
