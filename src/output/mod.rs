//! Output images: PNG (display-referred, sRGB 8-bit) and EXR (linear
//! float radiance plus named AOV layers), both written atomically, and a
//! reader for either format (for `diff` and for tests).
//!
//! Channel names follow the contract's "Output images": `R, G, B` for
//! radiance and `<layer>.<channel>` for layers (`depth.Z`, `position.X`,
//! `normal.X`, `albedo.R`, `mask.Y`, `vcoef.0`, ...).

mod exr;
mod png;

pub use self::exr::write_exr;
pub(crate) use self::png::write_rgb8;
pub use self::png::{srgb_decode, srgb_encode_u8, write_png};

use crate::error::{Error, Result};
use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

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

/// Tells temporary files of one process apart (the pid tells processes
/// apart), so that concurrent writes never share a temporary file.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `path` atomically: `write` is called with a temporary path in the
/// same directory (so the final rename cannot cross file systems), the
/// result is fsynced and renamed over `path`. A reader never sees a
/// half-written image, and a failed write leaves an existing `path` as it
/// was.
///
/// On any error the temporary file is removed and the error names `path`
/// (errors that `write` reports against the temporary path are renamed).
/// A missing or non-directory parent is reported before anything is
/// written.
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let file_name = path.file_name().ok_or_else(|| {
        Error::io(
            path,
            io::Error::new(io::ErrorKind::InvalidInput, "output path has no file name"),
        )
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match fs::metadata(dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => {
            return Err(Error::io(
                path,
                io::Error::new(
                    io::ErrorKind::NotADirectory,
                    format!("{} is not a directory", dir.display()),
                ),
            ))
        }
        Err(e) => {
            let why = if e.kind() == io::ErrorKind::NotFound {
                format!("directory {} does not exist", dir.display())
            } else {
                format!("cannot use directory {}: {e}", dir.display())
            };
            return Err(Error::io(path, io::Error::new(e.kind(), why)));
        }
    }
    let tmp = dir.join(format!(
        ".{}.{}-{}.tmp",
        file_name.to_string_lossy(),
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let result = write(&tmp)
        .map_err(|e| rename_error(e, &tmp, path))
        .and_then(|()| sync_file(&tmp).map_err(|e| Error::io(path, e)))
        .and_then(|()| fs::rename(&tmp, path).map_err(|e| Error::io(path, e)));
    match result {
        Ok(()) => {
            // Make the rename itself durable; a failure here loses nothing
            // that the caller could act on, so it is not an error.
            if let Ok(d) = fs::File::open(dir) {
                let _ = d.sync_all();
            }
            Ok(())
        }
        Err(e) => {
            // The temp file may not exist (write failed to create it).
            let _ = fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// Flushes a written file's data to disk.
fn sync_file(path: &Path) -> io::Result<()> {
    fs::File::open(path)?.sync_all()
}

/// Rewrites an error about the temporary file into one about `path`, the
/// only name the user knows.
fn rename_error(e: Error, tmp: &Path, path: &Path) -> Error {
    let fix = |p: PathBuf| if p == tmp { path.to_path_buf() } else { p };
    match e {
        Error::Io { path: p, source } => Error::Io {
            path: fix(p),
            source,
        },
        Error::File {
            path: p,
            line,
            message,
        } => Error::File {
            path: fix(p),
            line,
            message,
        },
        other => other,
    }
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
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    if bytes.starts_with(&[0x89, b'P', b'N', b'G']) {
        png::read_png(path, &bytes)
    } else if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        exr::read_exr(path, bytes)
    } else {
        Err(Error::file(path, None, "not a PNG or an OpenEXR file"))
    }
}
