//! Scene loading (placeholder).
use super::Scene;
use crate::error::{Error, Result};
use std::path::Path;

/// Load and validate a scene file.
pub fn load_scene(path: &Path) -> Result<Scene> {
    Err(Error::file(path, None, "not yet"))
}
