//! One error type for everything a user can get wrong: scene files, models,
//! textures, parameters and output paths. Every variant names the file (and
//! line, where there is one) or the parameter, so a message is actionable.

use std::fmt;
use std::path::PathBuf;

/// An error a user can act on. Never a panic: bad input always ends here.
/// Non-exhaustive: a program matches the kinds it handles and keeps a
/// catch-all, so a new kind is not a breaking change.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// A problem inside an input file (scene TOML, OBJ, MTL, texture).
    File {
        /// The file at fault.
        path: PathBuf,
        /// 1-based line number, where the problem has one.
        line: Option<usize>,
        /// What is wrong, in words.
        message: String,
    },
    /// A command-line or scene parameter out of its allowed range.
    Parameter {
        /// The parameter's name as the user wrote it (`--width`, `camera.fov_y`).
        name: String,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// An I/O failure on a path (reading input or writing output).
    Io {
        /// The path being read or written.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The render was cancelled through its observer before it finished
    /// ([`crate::observe::Observer::cancelled`]); nothing was produced.
    Cancelled,
}

impl Error {
    /// An error at a file, optionally at a line.
    pub fn file(path: impl Into<PathBuf>, line: Option<usize>, message: impl Into<String>) -> Self {
        Error::File {
            path: path.into(),
            line,
            message: message.into(),
        }
    }

    /// An error about a named parameter.
    pub fn param(name: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Parameter {
            name: name.into(),
            message: message.into(),
        }
    }

    /// An I/O error at a path.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::File {
                path,
                line: Some(line),
                message,
            } => write!(f, "{}:{}: {}", path.display(), line, message),
            Error::File {
                path,
                line: None,
                message,
            } => write!(f, "{}: {}", path.display(), message),
            Error::Parameter { name, message } => write!(f, "parameter `{}`: {}", name, message),
            Error::Io { path, source } => write!(f, "{}: {}", path.display(), source),
            Error::Cancelled => write!(f, "cancelled"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// Result with the crate's error.
pub type Result<T> = std::result::Result<T, Error>;
