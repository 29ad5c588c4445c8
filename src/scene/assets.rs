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
    /// The index of each distinct material: a mesh with a material per
    /// face colour (PLY) adds many, and a linear search would be quadratic.
    material_ids: HashMap<MaterialKey, u32>,
}

/// A material's identity: its fields, floats by their bits (`-0.0` as
/// `0.0`, so that keys agree with `==` on the finite values materials hold).
#[derive(PartialEq, Eq, Hash)]
struct MaterialKey {
    name: String,
    floats: [u32; 8],
    textures: [Option<usize>; 2],
}

impl MaterialKey {
    fn of(m: &Material) -> Self {
        // Destructured, so that a field added to `Material` cannot be left
        // out of its identity.
        let Material {
            name,
            albedo,
            albedo_texture,
            specular,
            shininess,
            opacity,
            opacity_texture,
        } = m;
        let [a, b, c] = albedo.to_array();
        let [d, e, f] = specular.to_array();
        MaterialKey {
            name: name.clone(),
            floats: [a, b, c, d, e, f, *shininess, *opacity].map(|x| (x + 0.0).to_bits()),
            textures: [*albedo_texture, *opacity_texture],
        }
    }
}

impl Assets {
    pub(super) fn new() -> Self {
        let default = Material::default();
        Assets {
            material_ids: HashMap::from([(MaterialKey::of(&default), DEFAULT_MATERIAL)]),
            materials: vec![default],
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
        let key = MaterialKey::of(&m);
        if let Some(&i) = self.material_ids.get(&key) {
            return Ok(i);
        }
        let i = u32::try_from(self.materials.len())
            .map_err(|_| Error::param("materials", "more than 2^32 materials"))?;
        self.materials.push(m);
        self.material_ids.insert(key, i);
        Ok(i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn equal_materials_share_an_index() {
        let mut assets = Assets::new();
        let red = |albedo| Material {
            name: "red".into(),
            albedo,
            ..Material::default()
        };
        assert_eq!(
            assets.material(Material::default()).unwrap(),
            DEFAULT_MATERIAL
        );
        let a = assets.material(red(Vec3::X)).unwrap();
        assert_eq!(a, 1);
        // -0.0 == 0.0, as the linear search compared them.
        assert_eq!(assets.material(red(Vec3::new(1.0, -0.0, 0.0))).unwrap(), a);
        assert_eq!(assets.material(red(Vec3::Y)).unwrap(), 2);
        assert_eq!(assets.materials.len(), 3);
    }
}
