//! Bounding volume hierarchy for shadow rays (placeholder).
