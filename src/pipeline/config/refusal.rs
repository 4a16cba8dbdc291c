//! How a table's check refuses a value: its dotted key and what is wrong.

/// A refused value: its dotted key and what is wrong.
pub type Refusal = (&'static str, String);

/// Refuses the first of `values` (dotted key, value) that is not a finite number > 0.
pub(super) fn require_positive(values: &[(&'static str, f64)]) -> Result<(), Refusal> {
    match values.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
        Some(&(key, v)) => Err((key, format!("must be a finite number > 0, got {v}"))),
        None => Ok(()),
    }
}
