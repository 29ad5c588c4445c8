//! Textures (placeholder; the scene loader fills this in).
use glam::{Vec2, Vec3};
use std::path::PathBuf;

/// Texel storage: colour textures are linear RGB, opacity textures scalar.
#[derive(Debug, Clone)]
pub enum TextureData {
    /// Linear RGB texels, row-major, row 0 at the top.
    Rgb(Vec<Vec3>),
    /// Scalar texels (opacity), row-major, row 0 at the top.
    Scalar(Vec<f32>),
}

/// A decoded texture.
#[derive(Debug, Clone)]
pub struct Texture {
    /// The file it was read from.
    pub path: PathBuf,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Texels.
    pub data: TextureData,
}

impl Texture {
    /// Nearest-texel RGB lookup with the OBJ uv convention.
    pub fn lookup_rgb(&self, _uv: Vec2) -> Vec3 {
        Vec3::ONE
    }
}
