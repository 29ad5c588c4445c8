//! Watching a render from outside: its stages as they start and end, and a
//! request to stop. The render polls [`Observer::cancelled`] between passes
//! and the long passes poll it between tiles; a cancelled render returns
//! [`crate::Error::Cancelled`], never a partial image.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Hears a render's progress and may ask it to stop. Every method has a
/// default that does nothing, so an observer implements only what it needs.
/// Called from the render's worker threads, hence `Sync`.
pub trait Observer: Sync {
    /// A stage starts: `geometry`, `g-buffer`, `shadows`, `shading`.
    fn stage(&self, _name: &str) {}
    /// A stage has finished.
    fn step(&self) {}
    /// True once the render should stop. Polled often: keep it cheap.
    fn cancelled(&self) -> bool {
        false
    }
    /// A progressive render finished a sample set: its running error
    /// estimate, time left and (on request) its mean image.
    fn set_done(&self, _status: &crate::render::SetStatus<'_>) {}
}

/// The observer that hears nothing and never cancels.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Observer for Silent {}

/// A flag that cancels the renders it observes: clone it, hand one copy
/// to the render and call [`Cancel::cancel`] on another (from any thread).
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// A flag not yet raised.
    pub fn new() -> Self {
        Cancel::default()
    }

    /// Asks every render observing this flag (or a clone of it) to stop.
    pub fn cancel(&self) {
        // Relaxed is enough: the flag carries no data with it, and a
        // render that sees it a few tiles late only stops a little later.
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether [`Cancel::cancel`] was called.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

impl Observer for Cancel {
    fn cancelled(&self) -> bool {
        self.is_cancelled()
    }
}
