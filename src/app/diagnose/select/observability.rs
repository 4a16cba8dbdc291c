//! Observability of the catalogue before solving: condition number, variance inflation,
//! pairwise correlations and the inseparable groups with a hint of what would separate them
//! (docs/conventions.md §8; method: docs/diagnosis.md, "Statistics").

use crate::app::diagnose::model::fit::Normals;
use crate::app::diagnose::model::{Effect, ObservationSet, N_EFFECTS};
use crate::Result;
use nalgebra::{DMatrix, SymmetricEigen};

/// Effects whose estimates correlate beyond this (in absolute value) when fitted together are
/// one inseparable group.
pub const GROUP_CORRELATION: f64 = 0.9;
/// Condition numbers and variance inflations above this are reported as infinite.
const SINGULAR: f64 = 1e12;

/// Which member of an inseparable group is named first: the more common cause in practice
/// first. Mounting angles move whenever a scanner is re-mounted; instrument zeros (encoder,
/// range) are calibration constants that age; a timing latency is often never measured; a
/// lever arm is taped to a centimetre; a heading offset needs a mis-aligned INS; a range
/// scale, a clock offset or drift, and a cone error are factory quantities that rarely change.
pub const PREFERENCE: [Effect; N_EFFECTS] = [
    Effect::BoresightX,
    Effect::BoresightY,
    Effect::BoresightZ,
    Effect::EncoderOffset,
    Effect::RangeZero,
    Effect::AttitudeLatency,
    Effect::LeverArmX,
    Effect::LeverArmY,
    Effect::LeverArmZ,
    Effect::HeadingOffset,
    Effect::RangeScale,
    Effect::PositionLatency,
    Effect::ClockOffset,
    Effect::ClockDrift,
    Effect::Cone,
];

/// Where `e` stands in [`PREFERENCE`] (0: the most common cause).
pub(crate) fn preference_rank(e: Effect) -> usize {
    PREFERENCE
        .iter()
        .position(|&p| p == e)
        .expect("PREFERENCE lists every effect")
}

/// How an effect moves a point, for the hint of what would separate two of them.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    /// Grows with the platform's motion (speed, rotation rates) or with time.
    Timing,
    /// An angle: grows with range.
    Angle,
    /// A fixed offset: independent of range.
    Offset,
    /// Proportional to range.
    Scale,
}

fn kind(e: Effect) -> Kind {
    match e {
        Effect::AttitudeLatency
        | Effect::PositionLatency
        | Effect::ClockOffset
        | Effect::ClockDrift => Kind::Timing,
        Effect::BoresightX
        | Effect::BoresightY
        | Effect::BoresightZ
        | Effect::EncoderOffset
        | Effect::Cone
        | Effect::HeadingOffset => Kind::Angle,
        Effect::LeverArmX | Effect::LeverArmY | Effect::LeverArmZ | Effect::RangeZero => {
            Kind::Offset
        }
        Effect::RangeScale => Kind::Scale,
    }
}

/// The data that would separate two effects of the given kinds.
fn separating_data(a: Kind, b: Kind) -> &'static str {
    use Kind::*;
    match (a, b) {
        (Timing, Timing) => "a turn at another speed and a longer survey (attitude latency follows the rotation rate, position latency and clock offset the speed, clock drift grows with time)",
        (Timing, _) | (_, Timing) => "a turn and a change of speed (timing errors grow with the motion, mounting errors do not)",
        (Angle, Angle) => "a pass in the opposite direction and returns on both scan sides",
        (Offset, Offset) => "a pass in the opposite direction and patches of other orientations and heights (walls and ground)",
        (Scale, Scale) => "targets at other ranges",
        (Angle, _) | (_, Angle) => "targets at other ranges (angular errors grow with range) and a pass in the opposite direction",
        (Offset, Scale) | (Scale, Offset) => "targets at other ranges (a scale error grows with range, an offset does not)",
    }
}

/// Effects the data cannot tell apart.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// Members, the preferred ([`PREFERENCE`]) first; one member when the effect is separable.
    pub members: Vec<Effect>,
    /// Largest pairwise |correlation| inside the group (0 for one member).
    pub max_abs_correlation: f64,
    /// What data would separate the members (empty for one member).
    pub separating_data: Vec<&'static str>,
    /// Members joined by the residuals, not by the geometry: groups the survey's residuals
    /// cannot reject in place of the chosen one (`select`'s rivals; empty here).
    pub rivals: Vec<Effect>,
}

impl Group {
    /// `self` with the members of `rival` joined (a group the residuals cannot reject in its
    /// place), `correlation` the largest |correlation| between the two groups' members.
    pub(crate) fn join_rival(&mut self, rival: &Group, correlation: f64) {
        let hint = separating_data(kind(self.members[0]), kind(rival.members[0]));
        for h in std::iter::once(hint).chain(rival.separating_data.iter().copied()) {
            if !self.separating_data.contains(&h) {
                self.separating_data.push(h);
            }
        }
        self.members.extend(&rival.members);
        self.rivals.extend(&rival.members);
        self.max_abs_correlation = self
            .max_abs_correlation
            .max(rival.max_abs_correlation)
            .max(correlation);
    }
}

/// How well the effects can be estimated on a set of references, before any solving.
#[derive(Debug, Clone, PartialEq)]
pub struct Observability {
    /// The observable effects the other fields describe, in the order asked.
    pub effects: Vec<Effect>,
    /// Effects without any signature on these references.
    pub unobservable: Vec<Effect>,
    /// Condition number of the Jacobi-scaled normal matrix of all `effects` together
    /// (infinite above 1e12).
    pub condition_number: f64,
    /// Variance inflation of each effect in the joint fit of all `effects`:
    /// `(N^-1)_jj N_jj = 1 / (1 - R_j^2)` (infinite above 1e12).
    pub vif: Vec<f64>,
    /// Correlation of the estimates of each pair when the two are fitted together (diagonal 1).
    pub correlation: DMatrix<f64>,
    /// Inseparable groups (|correlation| > [`GROUP_CORRELATION`], linked transitively),
    /// ordered by their preferred member.
    pub groups: Vec<Group>,
}

/// The observability of `effects` on `refs`.
pub fn observability(
    set: &ObservationSet,
    refs: &[usize],
    effects: &[Effect],
) -> Result<Observability> {
    Ok(observability_of(&Normals::of(set, refs)?, effects))
}

pub(crate) fn observability_of(normals: &Normals, effects: &[Effect]) -> Observability {
    let col = |e: Effect| crate::app::diagnose::model::signature_index(e);
    let (observable, unobservable): (Vec<Effect>, Vec<Effect>) = effects
        .iter()
        .partition(|&&e| normals.m[(col(e), col(e))] > 0.0);
    let k = observable.len();
    let scaled = DMatrix::from_fn(k, k, |i, j| {
        let (a, b) = (col(observable[i]), col(observable[j]));
        normals.m[(a, b)] / (normals.m[(a, a)] * normals.m[(b, b)]).sqrt()
    });
    let correlation = DMatrix::from_fn(k, k, |i, j| if i == j { 1.0 } else { -scaled[(i, j)] });
    let (condition_number, vif) = inflation(&scaled);
    let groups = group(&observable, &correlation);
    Observability {
        effects: observable,
        unobservable,
        condition_number,
        vif,
        correlation,
        groups,
    }
}

/// Condition number and variance inflations of a correlation-scaled normal matrix.
fn inflation(scaled: &DMatrix<f64>) -> (f64, Vec<f64>) {
    let k = scaled.nrows();
    if k == 0 {
        return (1.0, Vec::new());
    }
    let eig = SymmetricEigen::new(scaled.clone());
    let max = eig.eigenvalues.max();
    let min = eig.eigenvalues.min();
    let capped = |x: f64| {
        if x.is_finite() && x < SINGULAR {
            x
        } else {
            f64::INFINITY
        }
    };
    let condition = if min > 0.0 {
        capped(max / min)
    } else {
        f64::INFINITY
    };
    let floor = max / SINGULAR;
    let vif = (0..k)
        .map(|j| {
            capped(
                (0..k)
                    .map(|m| {
                        eig.eigenvectors[(j, m)].powi(2) / eig.eigenvalues[m].max(floor * 1e-3)
                    })
                    .sum(),
            )
        })
        .collect();
    (condition, vif)
}

/// Single-linkage groups of |correlation| > [`GROUP_CORRELATION`].
fn group(effects: &[Effect], correlation: &DMatrix<f64>) -> Vec<Group> {
    let k = effects.len();
    let mut label: Vec<usize> = (0..k).collect();
    for i in 0..k {
        for j in i + 1..k {
            if correlation[(i, j)].abs() > GROUP_CORRELATION {
                let (from, to) = (label[j], label[i]);
                label
                    .iter_mut()
                    .filter(|l| **l == from)
                    .for_each(|l| *l = to);
            }
        }
    }
    let mut groups: Vec<Group> = Vec::new();
    for l in 0..k {
        let mut idx: Vec<usize> = (0..k).filter(|&i| label[i] == l).collect();
        if idx.is_empty() {
            continue;
        }
        idx.sort_by_key(|&i| preference_rank(effects[i]));
        let mut max_abs_correlation: f64 = 0.0;
        let mut separating: Vec<&'static str> = Vec::new();
        for (a, &i) in idx.iter().enumerate() {
            for &j in &idx[a + 1..] {
                max_abs_correlation = max_abs_correlation.max(correlation[(i, j)].abs());
                let hint = separating_data(kind(effects[i]), kind(effects[j]));
                if correlation[(i, j)].abs() > GROUP_CORRELATION && !separating.contains(&hint) {
                    separating.push(hint);
                }
            }
        }
        groups.push(Group {
            members: idx.iter().map(|&i| effects[i]).collect(),
            max_abs_correlation,
            separating_data: separating,
            rivals: Vec::new(),
        });
    }
    groups.sort_by_key(|g| preference_rank(g.members[0]));
    groups
}
