//! The one way penumbra reads an input file: scene TOML, OBJ and MTL
//! files, textures, `diff` images and tile parts all come through [`read`].
//!
//! Only regular files are read (symbolic links to them included): opening
//! a FIFO blocks until a writer appears, and a device such as `/dev/zero`
//! never ends. Files are read up to [`MAX_INPUT_BYTES`], a limit far above
//! any input penumbra can render, so that a mistaken path fails at once
//! with a message instead of filling memory.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

/// Largest input file read, in bytes (4 GiB). A larger file is refused
/// before it is read.
pub const MAX_INPUT_BYTES: u64 = 4 << 30;

/// What kind of file system object `meta` is, in words, for messages.
fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        } else if t.is_char_device() {
            return "a character device";
        } else if t.is_block_device() {
            return "a block device";
        } else if t.is_socket() {
            return "a socket";
        }
    }
    "a special file"
}

/// The error for a file over the limit.
fn too_large(size: u64) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!(
            "{size} bytes is more than the input limit of {} bytes (4 GiB)",
            MAX_INPUT_BYTES
        ),
    )
}

/// Reads a whole input file, refusing what is not a regular file and
/// files over [`MAX_INPUT_BYTES`]. Errors are `io::Error`s whose message
/// says why, so that each caller names the file (and the line that
/// referenced it) as it does for any I/O error.
pub fn read(path: &Path) -> io::Result<Vec<u8>> {
    read_limited(path, MAX_INPUT_BYTES)
}

/// [`read`] with another size limit (for tests).
pub fn read_limited(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    // Checked before opening: `open` on a FIFO blocks until a writer
    // opens it, which may be never.
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{}; penumbra reads only regular files", kind_of(&meta)),
        ));
    }
    if meta.len() > limit {
        return Err(too_large(meta.len()));
    }
    let file = File::open(path)?;
    // The file may have been swapped between the check and the open.
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{}; penumbra reads only regular files", kind_of(&meta)),
        ));
    }
    // A file that grows while it is read (or a `/proc` file reporting size
    // 0) still stops at the limit: one byte more says it is over.
    let mut bytes = Vec::with_capacity(meta.len().min(limit) as usize);
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}
