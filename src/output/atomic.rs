//! Writing outputs safely: every output of a run is first written to a
//! temporary file, and only when all of them were written are they moved
//! into place ([`OutputSet`]). What an output path names decides how it
//! is moved there:
//!
//! | the path names | what happens |
//! |---|---|
//! | nothing | the file is created (temporary file beside it, renamed) |
//! | a regular file | replaced atomically, keeping its permissions |
//! | a symlink | followed (through any chain of links, dangling ones too): its final target is created or replaced as above, by a rename in the target's own directory, so the target changes only when every output of the run was written; the link itself stays |
//! | a FIFO or a character device (`/dev/null`, `/dev/stdout`, a tty) | written in place, never replaced: opened without creating, the bytes copied in (a FIFO waits for its reader, as any writer does) |
//! | a directory, a block device, a socket | refused with an error naming the kind |
//! | a file in a directory that accepts no new files (`/proc`, `/sys`) | refused with an error saying so |
//! | a path ending in `/` (or `/.`, `/..`) | refused: it can only name a directory |
//!
//! A write that fails leaves every output path as it was. Every path is
//! resolved (and refused) before anything is written, and commit keeps a
//! hard link to each file it replaces until all renames succeeded, so a
//! late failure (the directory changed meanwhile) restores the old
//! contents too.

use crate::error::{Error, Result};
use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Tells temporary files of one process apart (the pid tells processes
/// apart), so that concurrent writes never share a temporary file.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Symlinks followed before giving up (Linux's own limit is 40).
const MAX_LINKS: usize = 40;

/// Where an output goes, once the path is resolved.
#[derive(Debug, Clone, PartialEq)]
enum Target {
    /// Created or replaced by renaming a temporary file in `dir` over
    /// `file` (the symlink-free final path).
    Replace {
        file: PathBuf,
        dir: PathBuf,
        /// Permissions of the file being replaced, if one exists.
        permissions: Option<fs::Permissions>,
    },
    /// Written in place (FIFO, character device) through the path as
    /// given, which the kernel resolves (also `/proc/self/fd` links).
    InPlace,
}

/// An `Error::Io` at `path` with `message`.
fn refuse(path: &Path, kind: io::ErrorKind, message: impl Into<String>) -> Error {
    Error::io(path, io::Error::new(kind, message.into()))
}

/// The directory a file path lives in (`.` for a bare file name).
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Checks that `dir` exists and is a directory; errors name `path`.
fn check_dir(path: &Path, dir: &Path) -> Result<()> {
    match fs::metadata(dir) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => Err(refuse(
            path,
            io::ErrorKind::NotADirectory,
            format!("{} is not a directory", dir.display()),
        )),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Err(refuse(
            path,
            e.kind(),
            format!("directory {} does not exist", dir.display()),
        )),
        Err(e) => Err(refuse(
            path,
            e.kind(),
            format!("cannot use directory {}: {e}", dir.display()),
        )),
    }
}

/// The kind of a file that is neither regular nor a directory, in words,
/// and whether it is written in place (true) or refused (false).
fn special_kind(ft: &fs::FileType) -> (&'static str, bool) {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if ft.is_fifo() {
            return ("a FIFO", true);
        }
        if ft.is_char_device() {
            return ("a character device", true);
        }
        if ft.is_block_device() {
            return ("a block device", false);
        }
        if ft.is_socket() {
            return ("a socket", false);
        }
    }
    let _ = ft;
    ("not a regular file", false)
}

/// Resolves an output path: follows symlinks to the file that will be
/// written and decides how (see the module table).
fn resolve(path: &Path) -> Result<Target> {
    // `Path` drops a trailing `/` (`o.exr/` has the file name `o.exr`),
    // but the system does not: such a path can only be a directory.
    if ends_like_a_directory(path) {
        return Err(refuse(
            path,
            io::ErrorKind::InvalidInput,
            "ends in /: an output must name a file, not a directory",
        ));
    }
    if path.file_name().is_none() {
        return Err(refuse(
            path,
            io::ErrorKind::InvalidInput,
            "output path has no file name",
        ));
    }
    match fs::metadata(path) {
        // Something exists at the end of the links.
        Ok(m) if m.is_file() => {
            let file = fs::canonicalize(path).map_err(|e| Error::io(path, e))?;
            let dir = parent_dir(&file);
            check_dir(path, &dir)?;
            Ok(Target::Replace {
                file,
                dir,
                permissions: Some(m.permissions()),
            })
        }
        Ok(m) if m.is_dir() => Err(refuse(
            path,
            io::ErrorKind::IsADirectory,
            "is a directory, not an image file",
        )),
        Ok(m) => match special_kind(&m.file_type()) {
            (_, true) => Ok(Target::InPlace),
            (kind, false) => Err(refuse(
                path,
                io::ErrorKind::InvalidInput,
                format!(
                    "is {kind}; outputs go only to regular files (replaced), \
                     FIFOs and character devices (written in place)"
                ),
            )),
        },
        // Nothing there, or a dangling link: follow the links by hand to
        // the name that will be created.
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            let mut file = path.to_path_buf();
            for _ in 0..MAX_LINKS {
                match fs::symlink_metadata(&file) {
                    Ok(m) if m.file_type().is_symlink() => {
                        let to = fs::read_link(&file).map_err(|e| Error::io(path, e))?;
                        file = parent_dir(&file).join(to);
                    }
                    Ok(_) => {
                        // Appeared meanwhile: resolve again from the top.
                        return resolve(path);
                    }
                    Err(_) => {
                        if file.file_name().is_none() || ends_like_a_directory(&file) {
                            return Err(refuse(
                                path,
                                io::ErrorKind::InvalidInput,
                                format!("symlink target {} has no file name", file.display()),
                            ));
                        }
                        let dir = parent_dir(&file);
                        check_dir(path, &dir)?;
                        return Ok(Target::Replace {
                            file,
                            dir,
                            permissions: None,
                        });
                    }
                }
            }
            Err(refuse(
                path,
                io::ErrorKind::InvalidInput,
                format!("more than {MAX_LINKS} levels of symbolic links"),
            ))
        }
        Err(e) => {
            // A missing or non-directory parent says so; anything else
            // (permissions, a loop of links) as the system reports it.
            check_dir(path, &parent_dir(path))?;
            Err(Error::io(path, e))
        }
    }
}

/// Whether `path`'s text ends in a separator, `/.` or `/..` (what a
/// directory path looks like, whatever is there).
fn ends_like_a_directory(path: &Path) -> bool {
    let text = path.as_os_str().to_string_lossy();
    let sep = |c: char| std::path::is_separator(c);
    text.ends_with(sep)
        || text
            .strip_suffix('.')
            .is_some_and(|t| t.is_empty() || t.ends_with(sep))
        || text
            .strip_suffix("..")
            .is_some_and(|t| t.is_empty() || t.ends_with(sep))
}

/// Whether `path` is written in place (a FIFO or a character device, see
/// the module table) rather than replaced; an error as [`check_output`].
pub(super) fn is_in_place(path: &Path) -> Result<bool> {
    resolve(path).map(|t| t == Target::InPlace)
}

/// Refuses an output `path` that is the same file as one of `inputs` (the
/// same device and inode, through any links), so that a command never
/// overwrites what it reads: `merge-tiles p1 p2 -o p1`.
pub fn check_not_input(path: &Path, inputs: &[PathBuf]) -> Result<()> {
    let Ok(out) = fs::metadata(path) else {
        return Ok(()); // nothing there yet: cannot be an input
    };
    for input in inputs {
        let Ok(inp) = fs::metadata(input) else {
            continue; // reading it will report the error
        };
        if same_file(&out, &inp)
            || matches!(
                (fs::canonicalize(path), fs::canonicalize(input)),
                (Ok(a), Ok(b)) if a == b
            )
        {
            return Err(refuse(
                path,
                io::ErrorKind::AlreadyExists,
                format!(
                    "is the same file as the input {}: writing it would destroy \
                     the input; give another output path",
                    input.display()
                ),
            ));
        }
    }
    Ok(())
}

/// Same device and inode (Unix); elsewhere the canonical paths decide.
fn same_file(a: &fs::Metadata, b: &fs::Metadata) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        a.dev() == b.dev() && a.ino() == b.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (a, b);
        false
    }
}

/// Checks an output path before a long computation: the same resolution
/// [`OutputSet::stage`] does (missing directory, a directory or block
/// device at the path, ...), without writing anything.
pub fn check_output(path: &Path) -> Result<()> {
    resolve(path).map(|_| ())
}

/// One written, not yet committed output.
#[derive(Debug)]
struct Staged {
    /// The path as the user gave it (what errors name).
    path: PathBuf,
    /// The temporary file holding the content.
    tmp: PathBuf,
    target: Target,
}

/// A set of outputs committed together: each is written to a temporary
/// file by [`stage`](Self::stage), and [`commit`](Self::commit) moves them
/// all into place only when every one was written. Dropping a set without
/// committing removes its temporary files and leaves every output path as
/// it was.
///
/// Commit writes in-place targets (FIFOs, devices) first, since they can
/// fail late (`/dev/full`) and cannot be undone; then it renames. Should a
/// rename fail after others succeeded (the directory changed meanwhile),
/// the outputs it created are removed again; files it already replaced
/// keep their new content.
#[derive(Debug, Default)]
pub struct OutputSet {
    staged: Vec<Staged>,
    /// `(name, text)` attributes every EXR staged after they are set
    /// carries in its header.
    pub(super) exr_metadata: Vec<(String, String)>,
}

impl OutputSet {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Text attributes (`name`, `value`) for the header of every EXR
    /// staged from now on, e.g. how a progressive render stopped.
    pub fn set_exr_metadata(&mut self, metadata: Vec<(String, String)>) {
        self.exr_metadata = metadata;
    }

    /// Writes one output: `write` is called with a temporary path (beside
    /// the final file, so the rename cannot cross file systems; for
    /// in-place targets in the temporary directory) and the result is
    /// flushed to disk. On error the temporary file is removed and the
    /// error names `path` (errors `write` reports against the temporary
    /// path are renamed).
    pub fn stage(&mut self, path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
        let target = resolve(path)?;
        if let Target::Replace { file, .. } = &target {
            let twice = self.staged.iter().any(|s| match &s.target {
                Target::Replace { file: f, .. } => f == file,
                Target::InPlace => false,
            });
            if twice {
                return Err(refuse(
                    path,
                    io::ErrorKind::AlreadyExists,
                    "is the same file as another output of this run",
                ));
            }
        }
        let tmp = match &target {
            Target::Replace { dir, .. } => temp_name(dir, path, "tmp"),
            Target::InPlace => {
                let name = path
                    .file_name()
                    .map_or("out".into(), |n| n.to_string_lossy());
                let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
                let pid = std::process::id();
                std::env::temp_dir().join(format!("penumbra-{pid}-{n}-{name}.tmp"))
            }
        };
        create_temp(path, &tmp, &target)?;
        // Only a file that is renamed into place needs to be on disk first.
        let durable = target != Target::InPlace;
        let result = write(&tmp)
            .map_err(|e| rename_error(e, &tmp, path))
            .and_then(|()| match durable {
                true => sync_file(&tmp).map_err(|e| Error::io(path, e)),
                false => Ok(()),
            });
        match result {
            Ok(()) => {
                self.staged.push(Staged {
                    path: path.to_path_buf(),
                    tmp,
                    target,
                });
                Ok(())
            }
            Err(e) => {
                let _ = fs::remove_file(&tmp);
                Err(e)
            }
        }
    }

    /// Moves every staged output into place (see the type's notes on the
    /// order and on failures).
    pub fn commit(mut self) -> Result<()> {
        let staged = std::mem::take(&mut self.staged);
        let (in_place, renamed): (Vec<_>, Vec<_>) = staged
            .into_iter()
            .partition(|s| s.target == Target::InPlace);
        let cleanup = |list: &[Staged]| {
            for s in list {
                let _ = fs::remove_file(&s.tmp);
            }
        };
        for (k, s) in in_place.iter().enumerate() {
            if let Err(e) = copy_in_place(s) {
                cleanup(&in_place[k..]);
                cleanup(&renamed);
                return Err(e);
            }
            let _ = fs::remove_file(&s.tmp);
        }
        // What the renames did so far, to undo on a failure: files
        // created (removed again) and files replaced, with a hard link to
        // their old content (moved back).
        let mut created: Vec<&Path> = Vec::new();
        let mut replaced: Vec<(&Path, PathBuf)> = Vec::new();
        let undo = |created: &[&Path], replaced: &[(&Path, PathBuf)]| {
            for f in created {
                let _ = fs::remove_file(f);
            }
            for (file, old) in replaced {
                let _ = fs::rename(old, file);
            }
        };
        for (k, s) in renamed.iter().enumerate() {
            let Target::Replace {
                file,
                dir,
                permissions,
            } = &s.target
            else {
                unreachable!("partitioned above")
            };
            if let Some(p) = permissions {
                // Best effort: a file we may replace but not chmod keeps
                // the default permissions.
                let _ = fs::set_permissions(&s.tmp, p.clone());
            }
            let existed = fs::symlink_metadata(file).is_ok();
            // Only needed when a later rename could fail; best effort (a
            // file system without hard links just cannot undo).
            let backup = (existed && k + 1 < renamed.len())
                .then(|| temp_name(dir, file, "old"))
                .filter(|old| fs::hard_link(file, old).is_ok());
            if let Err(e) = fs::rename(&s.tmp, file) {
                cleanup(&renamed[k..]);
                if let Some(old) = backup {
                    let _ = fs::remove_file(old);
                }
                undo(&created, &replaced);
                return Err(Error::io(&s.path, e));
            }
            match backup {
                Some(old) => replaced.push((file, old)),
                None if !existed => created.push(file),
                None => {}
            }
            // Make the rename itself durable; a failure here loses nothing
            // that the caller could act on, so it is not an error.
            if let Ok(d) = fs::File::open(dir) {
                let _ = d.sync_all();
            }
        }
        for (_, old) in replaced {
            let _ = fs::remove_file(old);
        }
        Ok(())
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        for s in &self.staged {
            let _ = fs::remove_file(&s.tmp);
        }
    }
}

/// A hidden name in `dir` for a temporary file beside `path`'s file,
/// unique to this process and call: `.NAME.PID-N.SUFFIX`.
fn temp_name(dir: &Path, path: &Path, suffix: &str) -> PathBuf {
    let name = path
        .file_name()
        .map_or("out".into(), |n| n.to_string_lossy());
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let pid = std::process::id();
    dir.join(format!(".{name}.{pid}-{n}.{suffix}"))
}

/// Creates the temporary file (exclusively, so it is ours), with an error
/// that says why when its directory accepts no new files.
fn create_temp(path: &Path, tmp: &Path, target: &Target) -> Result<()> {
    match fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(tmp)
    {
        Ok(_) => Ok(()),
        Err(e) => {
            let dir = parent_dir(tmp);
            let why = match (target, e.kind()) {
                // The directory exists (checked) yet "has no such file":
                // a virtual file system like /proc or /sys.
                (Target::Replace { .. }, io::ErrorKind::NotFound) => format!(
                    "cannot replace it: directory {} does not accept new files \
                     (a virtual file system such as /proc or /sys?)",
                    dir.display()
                ),
                _ => format!("cannot create a temporary file in {}: {e}", dir.display()),
            };
            Err(refuse(path, e.kind(), why))
        }
    }
}

/// Copies a staged output into its in-place target (FIFO, device).
fn copy_in_place(s: &Staged) -> Result<()> {
    let mut from = fs::File::open(&s.tmp).map_err(|e| Error::io(&s.path, e))?;
    let mut to = fs::OpenOptions::new()
        .write(true)
        .open(&s.path)
        .map_err(|e| Error::io(&s.path, e))?;
    io::copy(&mut from, &mut to)
        .and_then(|_| io::Write::flush(&mut to))
        .map_err(|e| Error::io(&s.path, e))
}

/// Writes `path` atomically: a one-output [`OutputSet`]. `write` is called
/// with a temporary path; a reader never sees a half-written file, and a
/// failed write leaves `path` as it was. Symlinks are followed and special
/// files are written in place or refused, as the module documents.
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let mut set = OutputSet::new();
    set.stage(path, write)?;
    set.commit()
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
