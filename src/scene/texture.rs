//! Textures: decoding (PNG, JPEG, TGA) and nearest-texel lookup.
//!
//! Colour textures are stored linear (sRGB decoded on load), opacity
//! textures as linear scalars, so lookups never convert.

use crate::error::{Error, Result};
use glam::{DVec3, Vec2, Vec3};
use image::{DynamicImage, ImageFormat, ImageReader};
use std::io::Cursor;
use std::path::{Path, PathBuf};

/// Largest texture accepted, in texels; checked from the header, before
/// anything is decoded.
pub const MAX_TEXELS: u64 = 1 << 26;

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

/// Rec. 709 luminance weights, for opacity maps without alpha.
const LUMA: Vec3 = Vec3::new(0.2126, 0.7152, 0.0722);

/// The exact sRGB decoding curve.
pub(super) fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Reads and decodes an image, refusing oversized ones before decoding.
/// Errors name the texture and point at the reference (`referenced_from`,
/// `line`), since that is where a user fixes a bad path.
fn decode(path: &Path, referenced_from: &Path, line: Option<usize>) -> Result<DynamicImage> {
    let fail = |why: String| {
        Error::file(
            referenced_from,
            line,
            format!("texture `{}`: {why}", path.display()),
        )
    };
    let bytes = super::input::read(path).map_err(|e| fail(format!("cannot read: {e}")))?;
    decode_bytes(&bytes, path, referenced_from, line)
}

/// Decodes an image already in memory (a file's bytes, or an image
/// embedded in a glTF file), refusing oversized ones before decoding.
/// `path` names the image in messages and hints its format by extension.
pub(super) fn decode_bytes(
    bytes: &[u8],
    path: &Path,
    referenced_from: &Path,
    line: Option<usize>,
) -> Result<DynamicImage> {
    let fail = |why: String| {
        Error::file(
            referenced_from,
            line,
            format!("texture `{}`: {why}", path.display()),
        )
    };
    // TGA has no magic number: the extension is the hint, and content
    // sniffing overrides it for the formats that have one.
    let reader = || -> Result<ImageReader<Cursor<&[u8]>>> {
        let mut r = ImageReader::new(Cursor::new(bytes));
        if let Ok(format) = ImageFormat::from_path(path) {
            r.set_format(format);
        }
        r.with_guessed_format()
            .map_err(|e| fail(format!("cannot read: {e}")))
    };
    let (w, h) = reader()?
        .into_dimensions()
        .map_err(|e| fail(format!("cannot decode: {e}")))?;
    if w == 0 || h == 0 {
        return Err(fail(format!("empty image ({w}×{h})")));
    }
    if u64::from(w) * u64::from(h) > MAX_TEXELS {
        return Err(fail(format!(
            "{w}×{h} texels is more than the limit of {MAX_TEXELS}"
        )));
    }
    reader()?
        .decode()
        .map_err(|e| fail(format!("cannot decode: {e}")))
}

/// Wraps an image-plane coordinate (in texels) into `0..n`: repeat
/// addressing. Computed in f64 so that huge coordinates stay exact integers;
/// NaN and infinities land on texel 0.
fn wrap(x: f32, n: u32) -> usize {
    let t = f64::from(x).floor();
    if !t.is_finite() || n == 0 {
        return 0;
    }
    (t.rem_euclid(f64::from(n)) as usize).min(n as usize - 1)
}

/// Clamps an image-plane coordinate (in texels) into `0..n`; NaN → 0.
fn clamp(x: f32, n: u32) -> usize {
    // `as` saturates and maps NaN to 0, so no finite check is needed.
    (x.floor().max(0.0) as usize).min((n as usize).saturating_sub(1))
}

impl Texture {
    /// Loads a colour texture (albedo or light texture): sRGB decoded to
    /// linear RGB. 8-bit images go through a 256-entry table; deeper ones
    /// use the exact curve per channel.
    ///
    /// Errors are `Error::File` at `referenced_from:line`, naming `path`.
    pub fn load_color(path: &Path, referenced_from: &Path, line: Option<usize>) -> Result<Texture> {
        let img = decode(path, referenced_from, line)?;
        Ok(Self::color_from_image(path, &img))
    }

    /// A colour texture from a decoded image (see [`Self::load_color`]);
    /// `path` is what the texture is called.
    pub(super) fn color_from_image(path: &Path, img: &DynamicImage) -> Texture {
        let texels: Vec<Vec3> = if img.color().bytes_per_pixel() == img.color().channel_count() {
            let table: [f32; 256] = std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0));
            img.to_rgb8()
                .pixels()
                .map(|p| Vec3::from_array(p.0.map(|c| table[usize::from(c)])))
                .collect()
        } else {
            img.to_rgb32f()
                .pixels()
                .map(|p| Vec3::from_array(p.0.map(srgb_to_linear)))
                .collect()
        };
        Texture {
            path: path.to_path_buf(),
            width: img.width(),
            height: img.height(),
            data: TextureData::Rgb(texels),
        }
    }

    /// Loads an opacity texture (`map_d`): linear, the alpha channel if the
    /// image has one, else its luminance.
    ///
    /// Errors are `Error::File` at `referenced_from:line`, naming `path`.
    pub fn load_opacity(
        path: &Path,
        referenced_from: &Path,
        line: Option<usize>,
    ) -> Result<Texture> {
        let img = decode(path, referenced_from, line)?;
        let has_alpha = img.color().has_alpha();
        let texels = img
            .to_rgba32f()
            .pixels()
            .map(|p| {
                let [r, g, b, a] = p.0;
                if has_alpha {
                    a
                } else {
                    LUMA.dot(Vec3::new(r, g, b))
                }
            })
            .collect();
        Ok(Texture {
            path: path.to_path_buf(),
            width: img.width(),
            height: img.height(),
            data: TextureData::Scalar(texels),
        })
    }

    /// The texel at (column, row) as RGB; black if out of range, which only
    /// a hand-built texture with too little data can cause.
    fn texel(&self, col: usize, row: usize) -> Vec3 {
        let i = row * self.width as usize + col;
        match &self.data {
            TextureData::Rgb(t) => t.get(i).copied().unwrap_or(Vec3::ZERO),
            TextureData::Scalar(t) => Vec3::splat(t.get(i).copied().unwrap_or(0.0)),
        }
    }

    /// The texel seen at `uv`: column `floor(u W)`, row `floor((1 - v) H)`
    /// (v = 0 is the bottom row), repeat outside [0, 1].
    fn at_uv(&self, uv: Vec2) -> Vec3 {
        let col = wrap(uv.x * self.width as f32, self.width);
        let row = wrap((1.0 - uv.y) * self.height as f32, self.height);
        self.texel(col, row)
    }

    /// Nearest-texel RGB lookup with the OBJ uv convention (v = 0 is the
    /// bottom row), repeating outside [0, 1]; NaN/infinite uv give texel 0.
    /// A scalar texture gives its value on all three channels.
    pub fn lookup_rgb(&self, uv: Vec2) -> Vec3 {
        self.at_uv(uv)
    }

    /// Nearest-texel scalar lookup, same convention as [`Self::lookup_rgb`].
    /// An RGB texture gives its luminance.
    pub fn lookup_scalar(&self, uv: Vec2) -> f32 {
        match self.data {
            TextureData::Scalar(_) => self.at_uv(uv).x,
            TextureData::Rgb(_) => LUMA.dot(self.at_uv(uv)),
        }
    }

    /// Light-texture lookup: column `s W`, row `t H` counted from the top,
    /// clamped to the image (the rect light's parametrisation, not the OBJ
    /// one); NaN gives texel 0.
    pub fn texel_st(&self, s: f32, t: f32) -> Vec3 {
        let col = clamp(s * self.width as f32, self.width);
        let row = clamp(t * self.height as f32, self.height);
        self.texel(col, row)
    }

    /// Mean texel value as RGB (a scalar texture's mean on all channels);
    /// zero for an empty texture.
    pub fn mean_rgb(&self) -> Vec3 {
        let (sum, n) = match &self.data {
            TextureData::Rgb(t) => (t.iter().map(|c| c.as_dvec3()).sum::<DVec3>(), t.len()),
            TextureData::Scalar(t) => {
                (DVec3::splat(t.iter().map(|&x| f64::from(x)).sum()), t.len())
            }
        };
        if n == 0 {
            return Vec3::ZERO;
        }
        (sum / n as f64).as_vec3()
    }
}
