//! Output images: PNG (display-referred, sRGB 8-bit) and EXR (linear
//! float radiance plus named AOV layers), both written atomically and,
//! for a run with several outputs, all or none ([`OutputSet`]); a reader
//! for either format (for `diff` and for tests); printing to stdout and
//! stderr that survives a closed pipe.
//!
//! Channel names follow the contract's "Output images": `R, G, B` for
//! radiance and `<layer>.<channel>` for layers (`depth.Z`, `position.X`,
//! `normal.X`, `albedo.R`, `mask.Y`, `vcoef.0`, ...).

mod atomic;
mod exr;
mod png;
mod stdio;

pub use self::atomic::{check_not_input, check_output, write_atomically, OutputSet};
pub use self::exr::write_exr;
pub(crate) use self::png::write_rgb8;
pub use self::png::{srgb8, srgb_decode, srgb_encode_u8, write_png};
pub use self::stdio::{write_stderr, write_stdout};

use crate::error::{Error, Result};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// A named multi-channel float image layer written to EXR as channels
/// `<name>.<channel>`, e.g. name `"depth"` with channels `["Z"]`,
/// `"position"` with `["X", "Y", "Z"]`, `"vcoef"` with `["0", "1"]`.
/// Each channel holds `width × height` values, row-major, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    /// Layer name (the part before the dot).
    pub name: String,
    /// `(channel name, values)` pairs.
    pub channels: Vec<(String, Vec<f32>)>,
}

/// An image read back by [`read_image`].
#[derive(Debug, Clone, PartialEq)]
pub struct LoadedImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `(full channel name, values)`: row-major, row 0 at the top, linear.
    /// PNG: `R, G, B` (sRGB-decoded) and `A` if it has alpha (as stored).
    /// EXR: every channel by its full name (`R`, `depth.Z`, ...), with a
    /// part's layer name prefixed if the file names its parts.
    pub channels: Vec<(String, Vec<f32>)>,
}

impl LoadedImage {
    /// The values of the channel named `name`, if present.
    pub fn channel(&self, name: &str) -> Option<&[f32]> {
        self.channels
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }
}

impl OutputSet {
    /// Stages `radiance` as a PNG at `path` (see [`write_png`]).
    pub fn png(&mut self, path: &Path, width: u32, height: u32, radiance: &[Vec3]) -> Result<()> {
        png::stage_png(self, path, width, height, radiance)
    }

    /// Stages `radiance` and `layers` as an EXR at `path` (see
    /// [`write_exr`]).
    pub fn exr(
        &mut self,
        path: &Path,
        width: u32,
        height: u32,
        radiance: &[Vec3],
        layers: &[Layer],
    ) -> Result<()> {
        exr::stage_exr(self, path, width, height, radiance, layers)
    }
}

/// An image file format, chosen by the output path's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// 8-bit sRGB radiance (`.png`).
    Png,
    /// Linear float radiance plus the AOV layers (`.exr`).
    Exr,
}

/// The format an image output at `path` is written in, from its extension
/// (`.png`, `.exr`, any case); `param` names the option in the error for
/// any other extension. A path without an extension that names a FIFO or
/// a character device (`/dev/stdout`, `/dev/null`) gets PNG, as it always
/// did: such names have no extension to choose by. Checks the path as
/// [`check_output`] does first, so its errors come before this one's.
pub fn image_format(param: &str, path: &Path) -> Result<Format> {
    let special = atomic::is_in_place(path)?;
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("png") => Ok(Format::Png),
        Some("exr") => Ok(Format::Exr),
        None if special => Ok(Format::Png),
        _ => Err(Error::param(
            param,
            format!(
                "{}: the extension decides the image format; accepted: .png (8-bit sRGB), \
                 .exr (linear float with the AOV layers)",
                path.display()
            ),
        )),
    }
}

impl OutputSet {
    /// Stages an image at `path` in `format`: a PNG of `radiance`, or an
    /// EXR of `radiance` and `layers`.
    pub fn image(
        &mut self,
        path: &Path,
        format: Format,
        width: u32,
        height: u32,
        radiance: &[Vec3],
        layers: &[Layer],
    ) -> Result<()> {
        match format {
            Format::Png => self.png(path, width, height, radiance),
            Format::Exr => self.exr(path, width, height, radiance, layers),
        }
    }
}

/// The image outputs of `render` or `merge-tiles`: `-o` in the format of
/// its extension and, if given, `--exr` (always EXR, any name), each
/// checked before any work (see [`check_output`]), with the outputs that
/// must not be overwritten (`inputs`, e.g. the parts being merged).
pub fn image_outputs(
    output: &Path,
    exr: Option<&Path>,
    inputs: &[PathBuf],
) -> Result<Vec<(PathBuf, Format)>> {
    let mut list = vec![(output.to_path_buf(), image_format("--output", output)?)];
    if let Some(exr) = exr {
        check_output(exr)?;
        list.push((exr.to_path_buf(), Format::Exr));
    }
    for (path, _) in &list {
        check_not_input(path, inputs)?;
    }
    Ok(list)
}

/// Checks that `len` values make a `width × height` image with at least
/// one pixel; the error names the output `path`.
pub(crate) fn check_size(
    path: &Path,
    width: u32,
    height: u32,
    len: usize,
    what: &str,
) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::file(
            path,
            None,
            format!("cannot write an empty {width}×{height} image"),
        ));
    }
    let expected = u64::from(width) * u64::from(height);
    if len as u64 != expected {
        return Err(Error::file(
            path,
            None,
            format!("{what} has {len} values, a {width}×{height} image needs {expected}"),
        ));
    }
    Ok(())
}

/// Reads a PNG (decoded from sRGB to linear) or an EXR (all channels, by
/// full name), recognised by their magic bytes rather than the extension.
pub fn read_image(path: &Path) -> Result<LoadedImage> {
    let bytes = crate::scene::input::read(path).map_err(|e| Error::io(path, e))?;
    if bytes.starts_with(&[0x89, b'P', b'N', b'G']) {
        png::read_png(path, &bytes)
    } else if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        exr::read_exr(path, bytes)
    } else {
        Err(Error::file(path, None, "not a PNG or an OpenEXR file"))
    }
}
