//! Design rows of the GLS products `X^T C^-1 X`: what the fit and the continuous-time model
//! accumulate per return.

use super::{Observation, N_EFFECTS};

/// One design row, sparse: `(column, value)` entries, each column at most once.
pub(crate) type RowFn<'a> = dyn Fn(&Observation, &mut Vec<(usize, f64)>) + Sync + 'a;

/// The catalogue's design row: every signature, then the residual (column [`N_EFFECTS`]).
pub(crate) fn catalogue_row(o: &Observation, out: &mut Vec<(usize, f64)>) {
    out.extend(o.signature.iter().copied().enumerate());
    out.push((N_EFFECTS, o.residual_m));
}
