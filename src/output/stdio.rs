//! Printing that survives a closed pipe: `penumbra diff ... | head -1`
//! must end quietly, not panic the way `println!` does on `EPIPE`.

use crate::error::{Error, Result};
use std::io::{self, Write};

/// Writes `text` to stdout and flushes it. A reader that went away (a
/// closed pipe) is not an error: the rest of the text is dropped and the
/// command ends with the exit code it would have had anyway. Other
/// failures (a full disk behind `> file`) are errors naming stdout.
pub fn write_stdout(text: &str) -> Result<()> {
    let mut out = io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(Error::io("<stdout>", e)),
    }
}

/// Writes `text` to stderr, ignoring failures: stderr is where failures
/// would be reported, so there is nowhere left to report its own.
pub fn write_stderr(text: &str) {
    let mut err = io::stderr().lock();
    let _ = err.write_all(text.as_bytes()).and_then(|()| err.flush());
}
