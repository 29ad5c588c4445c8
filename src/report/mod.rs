//! Reporting: progress, timings (and, later, error metrics and plots).

mod progress;

pub use progress::Progress;
