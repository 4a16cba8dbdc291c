//! Validation of loaded simulator files: the first failure, named by its dotted key.

use crate::{Error, Result};

/// Collects the first validation failure, naming the key.
pub(crate) struct Checker<'a> {
    src: &'a str,
    err: Option<Error>,
}

impl<'a> Checker<'a> {
    /// A checker for the file named `src`.
    pub(crate) fn new(src: &'a str) -> Self {
        Checker { src, err: None }
    }

    /// Records `problem()` against `key` unless `ok`.
    pub(crate) fn test(&mut self, key: &str, ok: bool, problem: impl FnOnce() -> String) {
        if !ok && self.err.is_none() {
            self.err = Some(Error::config(self.src, key, problem()));
        }
    }
    /// Requires a finite value > 0.
    pub(crate) fn pos(&mut self, key: &str, v: f64) {
        self.test(key, v.is_finite() && v > 0.0, || {
            format!("must be a finite number > 0, got {v}")
        });
    }
    /// Requires a finite value >= 0.
    pub(crate) fn nonneg(&mut self, key: &str, v: f64) {
        self.test(key, v.is_finite() && v >= 0.0, || {
            format!("must be a finite number >= 0, got {v}")
        });
    }
    /// Requires lo <= v <= hi.
    pub(crate) fn range(&mut self, key: &str, v: f64, lo: f64, hi: f64) {
        self.test(key, v.is_finite() && (lo..=hi).contains(&v), || {
            format!("must be within [{lo}, {hi}], got {v}")
        });
    }
    /// Requires every element finite.
    pub(crate) fn finite(&mut self, key: &str, v: &[f64]) {
        self.test(key, v.iter().all(|x| x.is_finite()), || {
            format!("must be finite numbers, got {v:?}")
        });
    }
    /// Requires a non-empty interval lo < hi, both > 0.
    pub(crate) fn interval(&mut self, key: &str, v: [f64; 2]) {
        self.test(key, v[0] > 0.0 && v[1] >= v[0] && v[1].is_finite(), || {
            format!("must be [min, max] with 0 < min <= max, got {v:?}")
        });
    }
    pub(crate) fn done(self) -> Result<()> {
        self.err.map_or(Ok(()), Err)
    }
}
