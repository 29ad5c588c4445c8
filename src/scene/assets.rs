//! What the scene file and its OBJ/MTL files share while loading: the
//! material and texture tables (`Assets`) and the default material.

use super::{Material, Texture};
use crate::error::{Error, Result};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Index of the default material (albedo 0.8, opaque) in `Scene::materials`.
pub(super) const DEFAULT_MATERIAL: u32 = 0;

/// How a texture's texels are decoded; part of the texture cache key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) enum TextureKind {
    /// sRGB colour (albedo, light).
    Color,
    /// Linear opacity (alpha or luminance).
    Opacity,
}

/// Materials and textures shared by all objects and lights of a scene.
pub(super) struct Assets {
    pub(super) materials: Vec<Material>,
    pub(super) textures: Vec<Texture>,
    texture_ids: HashMap<(PathBuf, TextureKind), usize>,
}

impl Assets {
    pub(super) fn new() -> Self {
        Assets {
            materials: vec![Material::default()],
            textures: Vec::new(),
            texture_ids: HashMap::new(),
        }
    }

    /// The index of a texture, loaded once per file and kind. `from:line`
    /// is the statement referencing it, where errors point.
    pub(super) fn texture(
        &mut self,
        path: &Path,
        kind: TextureKind,
        from: &Path,
        line: Option<usize>,
    ) -> Result<usize> {
        // Canonical paths make `a/../t.png` and `t.png` one texture; a path
        // that does not resolve fails in the loader with a proper message.
        let key = (
            std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()),
            kind,
        );
        if let Some(&i) = self.texture_ids.get(&key) {
            return Ok(i);
        }
        let texture = match kind {
            TextureKind::Color => Texture::load_color(path, from, line)?,
            TextureKind::Opacity => Texture::load_opacity(path, from, line)?,
        };
        self.textures.push(texture);
        self.texture_ids.insert(key, self.textures.len() - 1);
        Ok(self.textures.len() - 1)
    }

    /// The index of a material; identical materials (the default, repeated
    /// inline ones) share one.
    pub(super) fn material(&mut self, m: Material) -> Result<u32> {
        let i = self
            .materials
            .iter()
            .position(|x| *x == m)
            .unwrap_or_else(|| {
                self.materials.push(m);
                self.materials.len() - 1
            });
        u32::try_from(i).map_err(|_| Error::param("materials", "more than 2^32 materials"))
    }
}
