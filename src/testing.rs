//! Support for the tests, shared by the unit tests beside the code and the integration suite
//! (`tests/suite`); not part of the library's interface. Two rules it keeps:
//!
//! - **A skip can be forced.** A test that cannot run on this machine (no tmpfs mount, a
//!   filesystem that refuses `O_DIRECT`, a CPU without AVX2, no real data) calls [`skip`] with
//!   a switch; where CI can run it, `.ci/run` sets the switch to `1` and the skip is a failure.
//!   Every skip prints `SKIPPED <test>: <reason>` and appends that line to the file
//!   `$KINESCAN_SKIP_LOG` (the test harness hides a passing test's output, so CI counts skips
//!   from that file).
//! - **A maximum fails on NaN.** `f64::max`, `f64::min` and nalgebra's `max`/`amax` drop a NaN,
//!   so an error that came out NaN would pass a bound checked against them: tests take their
//!   maxima with [`max_of`], [`max_abs`] or [`raise_max`] (clippy's `disallowed-methods` in
//!   `clippy.toml` refuses the others in `tests/`).

use std::io::Write;

/// The switch `name` is set to `1`: a skip under it fails the test.
pub fn forced(name: &str) -> bool {
    std::env::var(name).is_ok_and(|v| v == "1")
}

/// Test `test` cannot run here because of `reason`: a failure when the switch `switch` is
/// forced (see [`forced`]), else a logged skip (see the module's documentation).
pub fn skip(switch: &str, test: &str, reason: &str) {
    skip_unless(forced(switch), switch, test, reason);
}

/// [`skip`] with the switch's state given.
fn skip_unless(forced: bool, switch: &str, test: &str, reason: &str) {
    assert!(
        !forced,
        "{test}: {reason}, and {switch}=1 requires it to run"
    );
    let line = format!("SKIPPED {test}: {reason} (set {switch}=1 to make this a failure)\n");
    eprint!("{line}");
    if let Some(log) = std::env::var_os("KINESCAN_SKIP_LOG") {
        // One write of one line with O_APPEND: lines of parallel tests do not interleave.
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log);
        let written = file.and_then(|mut f| f.write_all(line.as_bytes()));
        assert!(
            written.is_ok(),
            "{test}: cannot log the skip to {}: {written:?}",
            std::path::Path::new(&log).display()
        );
    }
}

/// The largest of `values` (0 for none), failing on NaN.
#[allow(clippy::disallowed_methods)]
pub fn max_of(values: impl IntoIterator<Item = f64>) -> f64 {
    values.into_iter().fold(0.0, |acc, v| {
        assert!(!v.is_nan(), "NaN among the values of a maximum");
        acc.max(v)
    })
}

/// The largest absolute value of `values` (0 for none), failing on NaN: for the entries of a
/// matrix difference, `max_abs((a - b).iter().copied())`.
pub fn max_abs(values: impl IntoIterator<Item = f64>) -> f64 {
    max_of(values.into_iter().map(f64::abs))
}

/// `*acc = max(*acc, v)`, failing on NaN (see [`max_of`]).
#[allow(clippy::disallowed_methods)]
pub fn raise_max(acc: &mut f64, v: f64) {
    assert!(!v.is_nan(), "NaN among the values of a maximum");
    *acc = acc.max(v);
}

/// The smallest of `values` (+inf for none), failing on NaN.
#[allow(clippy::disallowed_methods)]
pub fn min_of(values: impl IntoIterator<Item = f64>) -> f64 {
    values.into_iter().fold(f64::INFINITY, |acc, v| {
        assert!(!v.is_nan(), "NaN among the values of a minimum");
        acc.min(v)
    })
}

/// `x` is NaN or below `bound`: a rate or size that must reach `bound` failed (`x < bound`
/// alone lets a NaN pass).
#[allow(clippy::neg_cmp_op_on_partial_ord)]
pub fn short_of(x: f64, bound: f64) -> bool {
    !(x >= bound)
}

/// `x` is NaN or above `bound`: an error that must stay within `bound` failed (`x > bound`
/// alone lets a NaN pass).
#[allow(clippy::neg_cmp_op_on_partial_ord)]
pub fn beyond(x: f64, bound: f64) -> bool {
    !(x <= bound)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[should_panic(expected = "NaN among the values of a maximum")]
    fn max_of_fails_on_nan() {
        max_of([1.0, f64::NAN, 0.5]);
    }

    #[test]
    #[should_panic(expected = "NaN among the values of a minimum")]
    fn min_of_fails_on_nan() {
        min_of([f64::NAN, 0.5]);
    }

    #[test]
    fn maxima_and_minima() {
        assert_eq!(max_abs([1.0, -3.0, 2.0]), 3.0);
        assert_eq!(min_of([1.0, -3.0, 2.0]), -3.0);
        assert_eq!(max_of([]), 0.0);
        assert!(short_of(f64::NAN, 0.5) && short_of(0.4, 0.5) && !short_of(0.5, 0.5));
        assert!(beyond(f64::NAN, 0.5) && beyond(0.6, 0.5) && !beyond(0.5, 0.5));
    }

    #[test]
    #[should_panic(expected = "KINESCAN_TEST_FORCED_SWITCH=1 requires it to run")]
    fn a_forced_skip_fails() {
        skip_unless(
            true,
            "KINESCAN_TEST_FORCED_SWITCH",
            "a_forced_skip_fails",
            "no reason",
        );
    }
}
