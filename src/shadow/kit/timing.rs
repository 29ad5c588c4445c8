//! Pass timing: one [`PassTimer`] per pass (or [`timed`] around it)
//! instead of hand-written `PassTiming` literals.

use crate::shadow::PassTiming;
use std::time::{Duration, Instant};

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

    /// Records the pass's wall-clock time into `passes` and returns it.
    pub fn finish(self, passes: &mut Vec<PassTiming>) -> Duration {
        let time = self.start.elapsed();
        passes.push(PassTiming {
            name: self.name,
            time,
        });
        time
    }

    /// Records the pass as `name (detail)`, for a detail known only once
    /// the pass has run (a count of receivers, rays, ...), and returns its
    /// time.
    pub fn finish_with(
        self,
        passes: &mut Vec<PassTiming>,
        detail: impl std::fmt::Display,
    ) -> Duration {
        let time = self.start.elapsed();
        passes.push(PassTiming {
            name: format!("{} ({detail})", self.name),
            time,
        });
        time
    }
}

/// Runs `f` as the pass `name`, recording its time into `passes`.
pub fn timed<R>(passes: &mut Vec<PassTiming>, name: impl Into<String>, f: impl FnOnce() -> R) -> R {
    let t = PassTimer::start(name);
    let r = f();
    t.finish(passes);
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_are_recorded_in_order_with_their_detail() {
        let mut passes = Vec::new();
        let x = timed(&mut passes, "first", || 7);
        let t = PassTimer::start("second");
        let d = t.finish_with(&mut passes, "3 rays");
        let names: Vec<&str> = passes.iter().map(|p| p.name.as_str()).collect();
        assert_eq!((x, names), (7, vec!["first", "second (3 rays)"]));
        assert_eq!(passes[1].time, d);
    }
}
