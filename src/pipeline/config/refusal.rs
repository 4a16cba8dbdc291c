//! How a table's check refuses a value: its full dotted key (`sensor.boresight_deg[2]`) and
//! what is wrong.

/// A refused value: its full dotted key and what is wrong.
pub type Refusal = (String, String);

/// A [`Refusal`] of `key`.
pub(super) fn refuse(key: impl Into<String>, problem: impl Into<String>) -> Refusal {
    (key.into(), problem.into())
}

/// The elements of the array key `key`, each named `key[i]`.
pub(super) fn elements<'a>(
    key: &'a str,
    values: &'a [f64],
) -> impl Iterator<Item = (String, f64)> + 'a {
    values
        .iter()
        .enumerate()
        .map(move |(i, v)| (format!("{key}[{i}]"), *v))
}

/// Refuses the first of `values` (dotted key, value) that `ok` rejects: it "must be `what`".
fn require<K: Into<String>>(
    values: impl IntoIterator<Item = (K, f64)>,
    ok: impl Fn(f64) -> bool,
    what: &str,
) -> Result<(), Refusal> {
    for (key, v) in values {
        if !ok(v) {
            return Err(refuse(key, format!("must be {what}, got {v}")));
        }
    }
    Ok(())
}

/// Refuses the first of `values` that is not a finite number > 0.
pub(super) fn require_positive<K: Into<String>>(
    values: impl IntoIterator<Item = (K, f64)>,
) -> Result<(), Refusal> {
    require(values, |v| v.is_finite() && v > 0.0, "a finite number > 0")
}

/// Refuses the first of `values` that is not a finite number >= 0.
pub(super) fn require_non_negative<K: Into<String>>(
    values: impl IntoIterator<Item = (K, f64)>,
) -> Result<(), Refusal> {
    require(
        values,
        |v| v.is_finite() && v >= 0.0,
        "a finite number >= 0",
    )
}

/// Refuses the first of `values` that is not a finite number.
pub(super) fn require_finite<K: Into<String>>(
    values: impl IntoIterator<Item = (K, f64)>,
) -> Result<(), Refusal> {
    require(values, f64::is_finite, "a finite number")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_bad_value_is_refused_by_its_full_key() {
        let arm = [0.1, f64::NAN, 0.2];
        let e = require_finite(elements("sensor.lever_arm_b_m", &arm)).unwrap_err();
        assert_eq!(e.0, "sensor.lever_arm_b_m[1]");
        assert_eq!(e.1, "must be a finite number, got NaN");
        assert!(require_positive([("a", 1.0), ("b", 2.0)]).is_ok());
        assert_eq!(
            require_positive([("a", 1.0), ("b", 0.0)]).unwrap_err().0,
            "b"
        );
        assert_eq!(require_non_negative([("c", -1e-9)]).unwrap_err().0, "c");
        assert!(require_non_negative([("c", 0.0)]).is_ok());
    }
}
