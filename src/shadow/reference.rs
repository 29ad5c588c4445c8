//! The ray-traced reference (placeholder).
