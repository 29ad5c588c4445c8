//! Built-in shapes.
