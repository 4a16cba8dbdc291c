//! Stopping cleanly on SIGINT and SIGTERM: the binary's signal handler calls [`request`]; long
//! loops (the run's writer loop, every atomic write) call [`check`], which turns the request
//! into [`Error::Interrupted`]. The error unwinds normally, so every temporary file and staging
//! folder is removed by its owner and nothing is published.

use crate::{Error, Result};
use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Asks the running command to stop; returns whether a stop had already been asked for.
pub fn request() -> bool {
    REQUESTED.swap(true, Ordering::SeqCst)
}

/// Whether a stop has been asked for.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}

/// `Err(Error::Interrupted)` once a stop has been asked for.
#[inline]
pub fn check() -> Result<()> {
    if requested() {
        Err(Error::Interrupted)
    } else {
        Ok(())
    }
}
