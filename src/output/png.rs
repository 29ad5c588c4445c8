//! PNG: radiance clamped to [0, 1], sRGB-encoded with the exact IEC
//! 61966-2-1 curve, 8-bit RGB.

use super::{check_size, LoadedImage, OutputSet};
use crate::error::{Error, Result};
use glam::Vec3;
use image::codecs::png::{PngDecoder, PngEncoder};
use image::{DynamicImage, ExtendedColorType, ImageEncoder};
use std::fs::File;
use std::io::{BufWriter, Cursor, Write};
use std::path::Path;

/// Encodes a linear value to an 8-bit sRGB code: clamped to [0, 1] (NaN
/// counts as 0), the exact piecewise sRGB curve in `f64`, rounded to the
/// nearest code. `0.5` encodes to 188.
pub fn srgb_encode_u8(linear: f32) -> u8 {
    let c = if linear.is_nan() {
        0.0
    } else {
        f64::from(linear).clamp(0.0, 1.0)
    };
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    // s ∈ [0, 1], so the rounded code is in [0, 255].
    (s * 255.0).round() as u8
}

/// Decodes an sRGB-encoded value in [0, 1] to linear (exact curve).
pub fn srgb_decode(encoded: f64) -> f64 {
    if encoded <= 0.040_45 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    }
}

/// Writes `radiance` (`width × height` linear RGB, row 0 at the top) as an
/// 8-bit sRGB PNG at `path`, atomically (see
/// [`write_atomically`](super::write_atomically)). Values are clamped to
/// [0, 1] and NaN becomes 0.
pub fn write_png(path: &Path, width: u32, height: u32, radiance: &[Vec3]) -> Result<()> {
    let mut set = OutputSet::new();
    stage_png(&mut set, path, width, height, radiance)?;
    set.commit()
}

/// [`write_png`] into `set`.
pub(super) fn stage_png(
    set: &mut OutputSet,
    path: &Path,
    width: u32,
    height: u32,
    radiance: &[Vec3],
) -> Result<()> {
    check_size(path, width, height, radiance.len(), "radiance")?;
    stage_rgb8(set, path, width, height, &srgb8(radiance))
}

/// The 8-bit sRGB codes of linear `radiance` (R, G, B per pixel), as the
/// PNG output stores them: each value through [`srgb_encode_u8`]. The one
/// tone mapping of every display-referred image here (the PNG output,
/// FLIP's inputs).
pub fn srgb8(radiance: &[Vec3]) -> Vec<u8> {
    radiance
        .iter()
        .flat_map(|c| [c.x, c.y, c.z])
        .map(srgb_encode_u8)
        .collect()
}

/// Writes 8-bit RGB `bytes` (`width × height × 3`, row 0 at the top) as a
/// PNG at `path`, atomically. Shared by the image output and the report's
/// charts and heat maps, so every PNG is encoded the same way.
pub(crate) fn write_rgb8(path: &Path, width: u32, height: u32, bytes: &[u8]) -> Result<()> {
    let mut set = OutputSet::new();
    stage_rgb8(&mut set, path, width, height, bytes)?;
    set.commit()
}

/// [`write_rgb8`] into `set`.
fn stage_rgb8(
    set: &mut OutputSet,
    path: &Path,
    width: u32,
    height: u32,
    bytes: &[u8],
) -> Result<()> {
    if !bytes.len().is_multiple_of(3) {
        return Err(Error::file(
            path,
            None,
            format!("RGB data has {} bytes, not a multiple of 3", bytes.len()),
        ));
    }
    check_size(path, width, height, bytes.len() / 3, "RGB data")?;
    set.stage(path, |tmp| {
        let file = File::create(tmp).map_err(|e| Error::io(tmp, e))?;
        let mut out = BufWriter::new(file);
        PngEncoder::new(&mut out)
            .write_image(bytes, width, height, ExtendedColorType::Rgb8)
            .map_err(|e| image_error(tmp, e))?;
        out.flush().map_err(|e| Error::io(tmp, e))
    })
}

/// An `image` crate error as ours, at `path`.
fn image_error(path: &Path, e: image::ImageError) -> Error {
    match e {
        image::ImageError::IoError(io) => Error::io(path, io),
        other => Error::file(path, None, other.to_string()),
    }
}

/// Decodes PNG `bytes` read from `path`: `R, G, B` sRGB-decoded to linear
/// and `A` (if present) as stored, all in [0, 1]. 16-bit files keep their
/// precision.
pub(super) fn read_png(path: &Path, bytes: &[u8]) -> Result<LoadedImage> {
    let decoder = PngDecoder::new(Cursor::new(bytes)).map_err(|e| image_error(path, e))?;
    let img = DynamicImage::from_decoder(decoder).map_err(|e| image_error(path, e))?;
    let (width, height) = (img.width(), img.height());
    let color = img.color();
    let has_alpha = color.has_alpha();
    let wide = color.bytes_per_pixel() > color.channel_count();
    let rgba: Vec<f64> = if wide {
        img.to_rgba16()
            .into_raw()
            .into_iter()
            .map(|v| f64::from(v) / 65535.0)
            .collect()
    } else {
        img.to_rgba8()
            .into_raw()
            .into_iter()
            .map(|v| f64::from(v) / 255.0)
            .collect()
    };
    let names: &[&str] = if has_alpha {
        &["R", "G", "B", "A"]
    } else {
        &["R", "G", "B"]
    };
    let channels = names
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let values = rgba
                .chunks_exact(4)
                .map(|px| {
                    if k == 3 {
                        px[3] as f32
                    } else {
                        srgb_decode(px[k]) as f32
                    }
                })
                .collect();
            (name.to_string(), values)
        })
        .collect();
    Ok(LoadedImage {
        width,
        height,
        channels,
    })
}
