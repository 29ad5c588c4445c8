//! Light samples, in one place for every technique (placeholder).
