//! Pass timing: one [`PassTimer`] per pass instead of hand-written
//! `PassTiming` literals.

use crate::shadow::PassTiming;
use std::time::Instant;

/// A running pass: started on creation, recorded by [`PassTimer::finish`].
#[derive(Debug)]
pub struct PassTimer {
    name: String,
    start: Instant,
}

impl PassTimer {
    /// Starts timing the pass `name`.
    pub fn start(name: impl Into<String>) -> PassTimer {
        PassTimer {
            name: name.into(),
            start: Instant::now(),
        }
    }

    /// Records the pass's wall-clock time into `passes`.
    pub fn finish(self, passes: &mut Vec<PassTiming>) {
        passes.push(PassTiming {
            name: self.name,
            time: self.start.elapsed(),
        });
    }
}

/// Runs `f` as the pass `name`, recording its time into `passes`.
pub fn timed<R>(passes: &mut Vec<PassTiming>, name: impl Into<String>, f: impl FnOnce() -> R) -> R {
    let t = PassTimer::start(name);
    let r = f();
    t.finish(passes);
    r
}
