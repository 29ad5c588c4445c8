//! glTF materials as penumbra's: `baseColorFactor` × `baseColorTexture`
//! (sRGB) as albedo, `alphaMode` as opacity; what the renderer does not
//! model is counted for the file's one warning.

use super::data::{data_uri, err, read_uri, Buffers};
use crate::error::{Error, Result};
use crate::scene::assets::{Assets, DEFAULT_MATERIAL};
use crate::scene::{Material, Texture, TextureData};
use gltf_json as json;
use image::DynamicImage;
use json::material::AlphaMode;
use json::texture::{MagFilter, MinFilter, WrappingMode};
use json::validation::Checked;
use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};

/// What a texture is made of an image for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Use {
    /// sRGB albedo.
    Color,
    /// The alpha channel as opacity (`BLEND`).
    Alpha,
    /// Alpha × factor ≥ cutoff as a binary opacity (`MASK`), both as bits.
    Mask(u32, u32),
}

/// What the file's used materials ask for that penumbra does not model.
#[derive(Debug, Default)]
pub(super) struct Ignored {
    metallic_roughness: usize,
    normal_maps: usize,
    occlusion_maps: usize,
    emission: usize,
    single_sided: usize,
    samplers: usize,
    other_uv_sets: usize,
    /// Extension names found on materials and textures.
    pub extensions: BTreeSet<String>,
}

impl Ignored {
    /// The items in words ("normal maps (2 materials)").
    pub fn items(&self) -> Vec<String> {
        let count = |n: usize, what: &str| match n {
            1 => format!("1 {what}"),
            n => format!("{n} {what}s"),
        };
        let mut out = Vec::new();
        let mut add = |n: usize, item: &str, what: &str| {
            if n > 0 {
                out.push(format!("{item} ({})", count(n, what)));
            }
        };
        add(self.metallic_roughness, "metallic-roughness", "material");
        add(self.normal_maps, "normal maps", "material");
        add(self.occlusion_maps, "occlusion maps", "material");
        add(self.emission, "emission", "material");
        add(
            self.single_sided,
            "doubleSided: false (every surface is two-sided in penumbra)",
            "material",
        );
        add(
            self.samplers,
            "texture filtering and wrapping other than nearest/repeat",
            "texture",
        );
        add(
            self.other_uv_sets,
            "texture coordinate sets other than TEXCOORD_0",
            "texture",
        );
        out
    }
}

/// glTF material index → scene material index, converted on first use
/// (so that unused materials cannot fail on their textures).
pub(super) struct Materials {
    /// An inline material every triangle gets; the file's are not read.
    material_override: Option<u32>,
    /// Materials converted so far.
    ids: HashMap<usize, u32>,
    /// Textures made so far, by image and use (`None`: the image has no
    /// alpha channel, so no opacity texture).
    textures: HashMap<(usize, Use), Option<usize>>,
    /// What the converted materials ask for that is not modelled.
    pub ignored: Ignored,
}

impl Materials {
    /// No material converted yet.
    pub fn new(material_override: Option<u32>) -> Self {
        Materials {
            material_override,
            ids: HashMap::new(),
            textures: HashMap::new(),
            ignored: Ignored::default(),
        }
    }

    /// The scene material of a primitive's `material` (at `used_at`).
    pub fn id(
        &mut self,
        bufs: &mut Buffers,
        material: Option<usize>,
        used_at: &str,
        assets: &mut Assets,
    ) -> Result<u32> {
        if let Some(id) = self.material_override {
            return Ok(id);
        }
        let Some(m) = material else {
            return Ok(DEFAULT_MATERIAL);
        };
        if let Some(&id) = self.ids.get(&m) {
            return Ok(id);
        }
        let root = bufs.root;
        let Some(source) = root.materials.get(m) else {
            return Err(err(
                bufs.path,
                used_at,
                format!(
                    "material {m} does not exist (the file has {})",
                    root.materials.len()
                ),
            ));
        };
        let converted = self.convert(bufs, m, source, assets)?;
        let id = assets.material(converted)?;
        self.ids.insert(m, id);
        Ok(id)
    }

    /// Converts material `m`.
    fn convert(
        &mut self,
        bufs: &mut Buffers,
        m: usize,
        source: &json::Material,
        assets: &mut Assets,
    ) -> Result<Material> {
        let path = bufs.path;
        let at = format!("/materials/{m}");
        let pbr = &source.pbr_metallic_roughness;
        let factor = pbr.base_color_factor.0;
        if !factor.iter().all(|x| (0.0..=1.0).contains(x)) {
            return Err(err(
                path,
                &format!("{at}/pbrMetallicRoughness/baseColorFactor"),
                format!("{factor:?}: each must be in [0, 1]"),
            ));
        }
        let Checked::Valid(mode) = source.alpha_mode else {
            return Err(err(path, &format!("{at}/alphaMode"), "invalid alpha mode"));
        };
        let cutoff = source.alpha_cutoff.map_or(0.5, |c| c.0);
        if !(cutoff >= 0.0 && cutoff.is_finite()) {
            return Err(err(
                path,
                &format!("{at}/alphaCutoff"),
                format!("{cutoff}: must be a number ≥ 0"),
            ));
        }
        self.note_ignored(bufs.root, source);
        let base = pbr.base_color_texture.as_ref();
        let base_at = format!("{at}/pbrMetallicRoughness/baseColorTexture");
        let albedo_texture = match base {
            Some(info) => self.texture(bufs, info, &base_at, Use::Color, assets)?,
            None => None,
        };
        let alpha = factor[3];
        let constant_mask = if alpha >= cutoff { 1.0 } else { 0.0 };
        let (opacity, opacity_texture) = match (mode, base) {
            (AlphaMode::Opaque, _) => (1.0, None),
            (AlphaMode::Mask, None) => (constant_mask, None),
            (AlphaMode::Mask, Some(info)) => {
                let mask = Use::Mask(alpha.to_bits(), cutoff.to_bits());
                match self.texture(bufs, info, &base_at, mask, assets)? {
                    Some(t) => (1.0, Some(t)),
                    None => (constant_mask, None),
                }
            }
            (AlphaMode::Blend, None) => (alpha, None),
            (AlphaMode::Blend, Some(info)) => (
                alpha,
                self.texture(bufs, info, &base_at, Use::Alpha, assets)?,
            ),
        };
        Ok(Material {
            name: source
                .name
                .clone()
                .unwrap_or_else(|| format!("material {m}")),
            albedo: glam::Vec3::new(factor[0], factor[1], factor[2]),
            albedo_texture,
            opacity,
            opacity_texture,
            ..Material::default()
        })
    }

    /// Counts what `source` asks for that penumbra does not model.
    fn note_ignored(&mut self, root: &json::Root, source: &json::Material) {
        let pbr = &source.pbr_metallic_roughness;
        let ig = &mut self.ignored;
        if pbr.metallic_factor.0 != 0.0
            || pbr.roughness_factor.0 != 1.0
            || pbr.metallic_roughness_texture.is_some()
        {
            ig.metallic_roughness += 1;
        }
        ig.normal_maps += usize::from(source.normal_texture.is_some());
        ig.occlusion_maps += usize::from(source.occlusion_texture.is_some());
        ig.emission +=
            usize::from(source.emissive_texture.is_some() || source.emissive_factor.0 != [0.0; 3]);
        ig.single_sided += usize::from(!source.double_sided);
        let extension_names = |e: Option<&serde_json::Map<String, serde_json::Value>>| {
            e.into_iter()
                .flat_map(|m| m.keys().cloned())
                .collect::<Vec<_>>()
        };
        ig.extensions.extend(extension_names(
            source.extensions.as_ref().map(|e| &e.others),
        ));
        ig.extensions
            .extend(extension_names(pbr.extensions.as_ref().map(|e| &e.others)));
        if let Some(info) = &pbr.base_color_texture {
            ig.extensions
                .extend(extension_names(info.extensions.as_ref().map(|e| &e.others)));
            ig.other_uv_sets += usize::from(info.tex_coord != 0);
            let sampler = root
                .textures
                .get(info.index.value())
                .and_then(|t| t.sampler)
                .and_then(|s| root.samplers.get(s.value()));
            if let Some(s) = sampler {
                let nearest_repeat = matches!(
                    s.mag_filter,
                    None | Some(Checked::Valid(MagFilter::Nearest))
                ) && matches!(
                    s.min_filter,
                    None | Some(Checked::Valid(MinFilter::Nearest))
                ) && s.wrap_s == Checked::Valid(WrappingMode::Repeat)
                    && s.wrap_t == Checked::Valid(WrappingMode::Repeat);
                ig.samplers += usize::from(!nearest_repeat);
            }
        }
    }

    /// The texture of `info` (at `used_at`) for `usage`, made once per
    /// image and use; `None` for an opacity use of an image without alpha.
    fn texture(
        &mut self,
        bufs: &mut Buffers,
        info: &json::texture::Info,
        used_at: &str,
        usage: Use,
        assets: &mut Assets,
    ) -> Result<Option<usize>> {
        let (path, root) = (bufs.path, bufs.root);
        let t = info.index.value();
        let Some(texture) = root.textures.get(t) else {
            return Err(err(
                path,
                &format!("{used_at}/index"),
                format!(
                    "texture {t} does not exist (the file has {})",
                    root.textures.len()
                ),
            ));
        };
        let image = texture.source.value();
        if let Some(&made) = self.textures.get(&(image, usage)) {
            return Ok(made);
        }
        let (name, img) = decode_image(bufs, image, &format!("/textures/{t}/source"))?;
        let made = match usage {
            Use::Color => Some(Texture::color_from_image(&name, &img)),
            _ if !img.color().has_alpha() => None,
            Use::Alpha => Some(opacity_texture(name, &img, |a| a)),
            Use::Mask(factor, cutoff) => {
                let (factor, cutoff) = (f32::from_bits(factor), f32::from_bits(cutoff));
                Some(opacity_texture(name, &img, |a| {
                    if a * factor >= cutoff {
                        1.0
                    } else {
                        0.0
                    }
                }))
            }
        };
        let made = made.map(|texture| {
            assets.textures.push(texture);
            assets.textures.len() - 1
        });
        self.textures.insert((image, usage), made);
        Ok(made)
    }
}

/// A scalar opacity texture of `f(alpha)` for each texel of `img`.
fn opacity_texture(path: PathBuf, img: &DynamicImage, f: impl Fn(f32) -> f32) -> Texture {
    let texels = img.to_rgba32f().pixels().map(|p| f(p.0[3])).collect();
    Texture {
        path,
        width: img.width(),
        height: img.height(),
        data: TextureData::Scalar(texels),
    }
}

/// Decodes image `i` (referred to at `used_at`): a file beside the glTF
/// file, a `data:` URI or a buffer view. Returns the name it goes by (the
/// file, or `model.glb#/images/2` for an embedded image) and the image.
fn decode_image(bufs: &mut Buffers, i: usize, used_at: &str) -> Result<(PathBuf, DynamicImage)> {
    let (path, dir, root) = (bufs.path, bufs.dir, bufs.root);
    let Some(image) = root.images.get(i) else {
        return Err(err(
            path,
            used_at,
            format!(
                "image {i} does not exist (the file has {})",
                root.images.len()
            ),
        ));
    };
    let at = format!("/images/{i}");
    let embedded = PathBuf::from(format!("{}#{at}", path.display()));
    let decode = |bytes: &[u8], name: &Path| {
        super::super::texture::decode_bytes(bytes, name, path, None).map_err(|e| match e {
            Error::File {
                path,
                line,
                message,
            } => Error::File {
                path,
                line,
                message: format!("{at}: {message}"),
            },
            e => e,
        })
    };
    match (&image.uri, image.buffer_view) {
        (Some(uri), _) if uri.starts_with("data:") => {
            let bytes = data_uri(path, &format!("{at}/uri"), uri)?;
            Ok((embedded.clone(), decode(&bytes, &embedded)?))
        }
        (Some(uri), _) => {
            let (file, bytes) = read_uri(path, dir, &format!("{at}/uri"), uri, "texture")?;
            let img = decode(&bytes, &file)?;
            Ok((file, img))
        }
        (None, Some(v)) => {
            let (bytes, _) = bufs.view(v.value(), &format!("{at}/bufferView"))?;
            Ok((embedded.clone(), decode(bytes, &embedded)?))
        }
        (None, None) => Err(err(path, &at, "neither `uri` nor `bufferView`")),
    }
}
