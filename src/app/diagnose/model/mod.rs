//! The data the diagnosis statistics work on: one [`Observation`] per return on a reference
//! patch, grouped into [`Visit`]s (docs/diagnosis.md), and the residual model the statistics rest
//! on (docs/diagnosis.md, "Statistics"):
//!
//! `r_v = S_v theta + G_v z_v + e_v`, `e_v ~ N(0, diag(var_white))`, `z_v ~ N(0, P_v)`,
//!
//! for the returns of visit `v`: `S_v` rows are the effect signatures, `G_v` rows the
//! navigation gradients, `z_v` the navigation error shared by the visit, `P_v` its covariance,
//! visits independent. With correlation times ([`ObservationSet::nav_tau_s`]) the navigation
//! error is instead a Gauss-Markov process in time, continuous within and between visits
//! (docs/diagnosis.md, "The residual model").

use crate::{Error, Result};

pub mod continuous;
pub(super) mod design;
pub mod fit;
mod join;
pub mod metrics;

/// Number of catalogue effects (docs/conventions.md §8).
pub const N_EFFECTS: usize = Effect::ALL.len();

/// A catalogue effect (docs/conventions.md §8): a correction to one pipeline value, in the
/// unit of its name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Effect {
    /// `latency.attitude_s` (s).
    AttitudeLatency,
    /// `latency.position_s` (s).
    PositionLatency,
    /// `time.t0_s` (s).
    ClockOffset,
    /// `time.period_s`, relative (ppm).
    ClockDrift,
    /// `sensor.boresight_deg[0]` (deg).
    BoresightX,
    /// `sensor.boresight_deg[1]` (deg).
    BoresightY,
    /// `sensor.boresight_deg[2]` (deg).
    BoresightZ,
    /// `sensor.lever_arm_b_m[0]` (m).
    LeverArmX,
    /// `sensor.lever_arm_b_m[1]` (m).
    LeverArmY,
    /// `sensor.lever_arm_b_m[2]` (m).
    LeverArmZ,
    /// `sensor.range_zero_m` (m).
    RangeZero,
    /// `sensor.range_scale_ppm` (ppm).
    RangeScale,
    /// `sensor.encoder_offset_deg` (deg).
    EncoderOffset,
    /// `sensor.alpha0_deg` (deg).
    Cone,
    /// `trajectory.heading_offset_deg` (deg).
    HeadingOffset,
}

impl Effect {
    /// Every effect, in catalogue order.
    pub const ALL: [Effect; 15] = [
        Effect::AttitudeLatency,
        Effect::PositionLatency,
        Effect::ClockOffset,
        Effect::ClockDrift,
        Effect::BoresightX,
        Effect::BoresightY,
        Effect::BoresightZ,
        Effect::LeverArmX,
        Effect::LeverArmY,
        Effect::LeverArmZ,
        Effect::RangeZero,
        Effect::RangeScale,
        Effect::EncoderOffset,
        Effect::Cone,
        Effect::HeadingOffset,
    ];

    /// The catalogue name (docs/conventions.md §8).
    pub fn name(self) -> &'static str {
        [
            "attitude_latency_s",
            "position_latency_s",
            "clock_offset_s",
            "clock_drift_ppm",
            "boresight_x_deg",
            "boresight_y_deg",
            "boresight_z_deg",
            "lever_arm_x_m",
            "lever_arm_y_m",
            "lever_arm_z_m",
            "range_zero_m",
            "range_scale_ppm",
            "encoder_offset_deg",
            "cone_deg",
            "heading_offset_deg",
        ][self as usize]
    }
}

/// Which side of the vehicle a beam points to (body y: right positive).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// Body y < 0.
    Left,
    /// Body y >= 0.
    Right,
}

/// Where and how a return was measured (docs/conventions.md §8 covariate names).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covariates {
    /// GPS time of the return (s).
    pub time_s: f64,
    /// Range (m) without the return's own range noise: the measured range less the residual's
    /// departure from its visit's mean along the beam (`observe`'s `denoised_ranges_m`). Binned
    /// at the measured range, the bins would select on the noise that is also in the residual
    /// (a return measured long sits in a longer bin and off its plane the same way): on 15 laps
    /// without any effect that alone gave chi2 50-59 on 16 dof along the range
    /// (docs/diagnosis.md, "The range covariate").
    pub range_m: f64,
    /// Mirror angle, wrapped to (-180, 180] (deg).
    pub beta_deg: f64,
    /// Angle between the beam and the patch normal (deg, 0 = head-on).
    pub incidence_deg: f64,
    /// Vehicle speed (m/s).
    pub speed_mps: f64,
    /// Body rate about z (deg/s).
    pub yaw_rate_dps: f64,
    /// Body rate about x (deg/s).
    pub roll_rate_dps: f64,
    /// Body rate about y (deg/s).
    pub pitch_rate_dps: f64,
    /// True heading, [0, 360) (deg).
    pub heading_deg: f64,
    /// Side of the beam.
    pub side: Side,
    /// Pass: index of the profile file in `inputs.profiles`.
    pub pass: usize,
    /// Index of the reference patch (as [`Observation::reference`]).
    pub reference_id: usize,
}

/// One return on a reference patch.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Index of the reference patch in [`ObservationSet::reference_ids`].
    pub reference: usize,
    /// Index of its visit in [`ObservationSet::visits`].
    pub visit: usize,
    /// Record index of its return in its pass's profile file (a control point's
    /// observations: their visit's first return): with the pass, which return it is, so two
    /// observations of one survey can be compared return by return.
    pub record: usize,
    /// `n . (x_e - c_e)` (m): signed distance of the point georeferenced with the configured
    /// values from the patch plane (`n` unit normal, `c_e` centre, ECEF).
    pub residual_m: f64,
    /// Independent part of Var(residual) (m^2): scanner range, beta and alpha noise along `n`.
    pub var_white_m2: f64,
    /// d residual / d (INS position error north, east, down (m); roll, pitch, heading (rad)).
    pub nav_gradient: [f64; 6],
    /// d residual / d effect size, in [`Effect::ALL`] order and each effect's unit: how far the
    /// point moves along `n` per unit of the effect present in the data but not configured.
    pub signature: [f64; N_EFFECTS],
    /// Where and how it was measured.
    pub covariates: Covariates,
    /// The two SBET records its navigation state is interpolated between (`None`: a control
    /// point's mean over returns of many records): white navigation noise, one draw per
    /// record, is shared by the returns between the same two records.
    pub nav_record: Option<NavRecord>,
    /// Where the return lies on its patch (m): its point's offsets from the patch centre along
    /// the patch's in-plane axes (NaN for a control point's observations). Single precision:
    /// a few patches' metres to a tenth of a millimetre.
    pub plane_uv_m: [f32; 2],
}

/// Where a return sits between two trajectory records (docs/diagnosis.md, "White navigation
/// noise").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavRecord {
    /// Index of the first record in the trajectory file (the second is the next one).
    pub index: usize,
    /// Interpolation weight of the second record, 0..1.
    pub w: f64,
}

/// One time-contiguous run of returns over one patch in one pass. Without correlation times
/// its navigation error is one draw `z_v ~ N(0, nav_cov)` shared by all its returns; with them
/// `nav_cov` gives the sigmas of the continuous-time errors at its returns.
#[derive(Debug, Clone, PartialEq)]
pub struct Visit {
    /// Index of the reference patch.
    pub reference: usize,
    /// Pass (profile file index).
    pub pass: usize,
    /// `P_v` (m^2, rad^2): SMRMSG position and attitude variances at the visit's mid time,
    /// plus the patch survey variance along its normal in the position block.
    pub nav_cov: [[f64; 6]; 6],
}

/// All observations of one diagnosis.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ObservationSet {
    /// The observations, grouped by visit.
    pub observations: Vec<Observation>,
    /// The visits.
    pub visits: Vec<Visit>,
    /// Patch id of each reference index (only patches with observations).
    pub reference_ids: Vec<String>,
    /// Number of passes (profile files).
    pub passes: usize,
    /// Correlation times (s) of the navigation position and attitude errors (first-order
    /// Gauss-Markov processes in time, within and between visits). `None`: one error per
    /// visit, visits independent.
    pub nav_tau_s: Option<[f64; 2]>,
    /// Variance of white navigation noise (one draw per trajectory record, shared by the
    /// returns interpolated between the same records) per component, as a share of the
    /// component's variance in `nav_cov` (position, attitude block; docs/diagnosis.md, "White
    /// navigation noise"). 0: none; more needs `nav_tau_s`.
    pub nav_white_share: [f64; 2],
    /// A second, slow Gauss-Markov process per block beside the one of `nav_tau_s`
    /// (docs/diagnosis.md, "Two time scales"). `None`: one process; `Some` needs `nav_tau_s`.
    pub nav_slow: Option<SlowNav>,
}

/// The second, slow navigation error process of each block (position, attitude): component
/// `k` gains `sqrt(share) s_k(t) xi_k(t)`, `s_k` its sigma in `nav_cov`, `xi_k` a unit
/// first-order Gauss-Markov process of correlation time `tau_s`, independent of the first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlowNav {
    /// Variance as a share of each component's variance in `nav_cov` (position, attitude).
    pub share: [f64; 2],
    /// Correlation times (s; position, attitude).
    pub tau_s: [f64; 2],
}

/// Column of `effect` in [`Observation::signature`].
pub fn signature_index(effect: Effect) -> usize {
    Effect::ALL
        .iter()
        .position(|&e| e == effect)
        .expect("Effect::ALL lists every effect")
}

/// A covariate, by its docs/conventions.md §8 name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Covariate {
    /// `time_s`
    TimeS,
    /// `range_m`
    RangeM,
    /// `beta_deg`
    BetaDeg,
    /// `incidence_deg`
    IncidenceDeg,
    /// `speed_mps`
    SpeedMps,
    /// `yaw_rate_dps`
    YawRateDps,
    /// `roll_rate_dps`
    RollRateDps,
    /// `pitch_rate_dps`
    PitchRateDps,
    /// `heading_deg`
    HeadingDeg,
    /// `side`
    Side,
    /// `pass`
    Pass,
    /// `reference_id`
    ReferenceId,
}

impl Covariate {
    /// Every covariate.
    pub const ALL: [Covariate; 12] = [
        Covariate::TimeS,
        Covariate::RangeM,
        Covariate::BetaDeg,
        Covariate::IncidenceDeg,
        Covariate::SpeedMps,
        Covariate::YawRateDps,
        Covariate::RollRateDps,
        Covariate::PitchRateDps,
        Covariate::HeadingDeg,
        Covariate::Side,
        Covariate::Pass,
        Covariate::ReferenceId,
    ];

    /// The name of docs/conventions.md §8.
    pub fn name(self) -> &'static str {
        match self {
            Covariate::TimeS => "time_s",
            Covariate::RangeM => "range_m",
            Covariate::BetaDeg => "beta_deg",
            Covariate::IncidenceDeg => "incidence_deg",
            Covariate::SpeedMps => "speed_mps",
            Covariate::YawRateDps => "yaw_rate_dps",
            Covariate::RollRateDps => "roll_rate_dps",
            Covariate::PitchRateDps => "pitch_rate_dps",
            Covariate::HeadingDeg => "heading_deg",
            Covariate::Side => "side",
            Covariate::Pass => "pass",
            Covariate::ReferenceId => "reference_id",
        }
    }

    /// Whether the covariate takes categories (one bin per value) rather than a continuum.
    pub fn is_categorical(self) -> bool {
        matches!(
            self,
            Covariate::Side | Covariate::Pass | Covariate::ReferenceId
        )
    }

    /// The covariate's value for one return (side: left 0, right 1).
    pub fn value(self, c: &Covariates) -> f64 {
        match self {
            Covariate::TimeS => c.time_s,
            Covariate::RangeM => c.range_m,
            Covariate::BetaDeg => c.beta_deg,
            Covariate::IncidenceDeg => c.incidence_deg,
            Covariate::SpeedMps => c.speed_mps,
            Covariate::YawRateDps => c.yaw_rate_dps,
            Covariate::RollRateDps => c.roll_rate_dps,
            Covariate::PitchRateDps => c.pitch_rate_dps,
            Covariate::HeadingDeg => c.heading_deg,
            Covariate::Side => match c.side {
                Side::Left => 0.0,
                Side::Right => 1.0,
            },
            Covariate::Pass => c.pass as f64,
            Covariate::ReferenceId => c.reference_id as f64,
        }
    }
}

/// Covariance (m^2) of the white navigation noise of returns `a` and `b`: per component `k`
/// one draw per trajectory record of variance `white_var[k]` (m^2, rad^2), interpolated as
/// the navigation state is. Zero unless both lie between the same two records of one pass
/// (returns between neighbouring records also share one; that covariance is left out,
/// docs/diagnosis.md, "White navigation noise"); `a`'s own white navigation variance when `b`
/// is `a`.
pub(crate) fn white_nav_cov_m2(a: &Observation, b: &Observation, white_var: &[f64; 6]) -> f64 {
    let (Some(ra), Some(rb)) = (a.nav_record, b.nav_record) else {
        return 0.0;
    };
    if ra.index != rb.index || a.covariates.pass != b.covariates.pass {
        return 0.0;
    }
    let shared = (1.0 - ra.w) * (1.0 - rb.w) + ra.w * rb.w;
    let per_component: f64 = (0..6)
        .map(|k| a.nav_gradient[k] * b.nav_gradient[k] * white_var[k])
        .sum();
    shared * per_component
}

impl ObservationSet {
    /// Checks every index and number the statistics rely on; the error names the observation
    /// or visit and the field. Called once, where a set is made from a survey
    /// (`observe::observe`); the stages after it take the set as valid (screening and
    /// the navigation model keep it so) and do not check it again.
    pub fn validate(&self) -> Result<()> {
        if self
            .nav_white_share
            .iter()
            .any(|w| !w.is_finite() || *w < 0.0)
        {
            return Err(invalid(format!(
                "nav_white_share = {:?} (must be finite and >= 0)",
                self.nav_white_share
            )));
        }
        if self.nav_white_share != [0.0; 2] && self.nav_tau_s.is_none() {
            return Err(invalid(format!(
                "nav_white_share = {:?} without nav_tau_s (white navigation noise is part of \
                 the continuous-time model)",
                self.nav_white_share
            )));
        }
        if let Some(slow) = self.nav_slow {
            let bad = |v: &[f64; 2], min_exclusive: bool| {
                v.iter()
                    .any(|x| !x.is_finite() || *x < 0.0 || (min_exclusive && *x == 0.0))
            };
            if bad(&slow.share, false) || bad(&slow.tau_s, true) || self.nav_tau_s.is_none() {
                return Err(invalid(format!(
                    "nav_slow = {slow:?} (shares finite and >= 0, correlation times finite and \
                     > 0, and nav_tau_s set)"
                )));
            }
        }
        if let Some(tau) = self.nav_tau_s {
            if tau.iter().any(|t| !t.is_finite() || *t <= 0.0) {
                return Err(invalid(format!(
                    "nav_tau_s = {tau:?} (must be finite and > 0)"
                )));
            }
        }
        for (v, visit) in self.visits.iter().enumerate() {
            if visit.reference >= self.reference_ids.len() {
                return Err(invalid(format!(
                    "visit {v}: reference {} but only {} reference ids",
                    visit.reference,
                    self.reference_ids.len()
                )));
            }
            if visit.nav_cov.iter().flatten().any(|x| !x.is_finite()) {
                return Err(invalid(format!("visit {v}: nav_cov is not finite")));
            }
        }
        for (i, o) in self.observations.iter().enumerate() {
            let Some(visit) = self.visits.get(o.visit) else {
                return Err(invalid(format!(
                    "observation {i}: visit {} but only {} visits",
                    o.visit,
                    self.visits.len()
                )));
            };
            if visit.reference != o.reference {
                return Err(invalid(format!(
                    "observation {i}: reference {} but its visit {} is on reference {}",
                    o.reference, o.visit, visit.reference
                )));
            }
            if !(o.var_white_m2.is_finite() && o.var_white_m2 > 0.0) {
                return Err(invalid(format!(
                    "observation {i}: var_white_m2 = {} (must be finite and > 0)",
                    o.var_white_m2
                )));
            }
            let finite = o.residual_m.is_finite()
                && o.nav_gradient.iter().all(|x| x.is_finite())
                && o.signature.iter().all(|x| x.is_finite());
            if !finite {
                return Err(invalid(format!(
                    "observation {i}: residual_m, nav_gradient or signature is not finite"
                )));
            }
            if let Some(r) = o.nav_record.filter(|r| !(0.0..=1.0).contains(&r.w)) {
                return Err(invalid(format!(
                    "observation {i}: nav_record.w = {} (must be within 0..1)",
                    r.w
                )));
            }
        }
        Ok(())
    }

    /// The observations of each visit (indices into [`Self::observations`]).
    pub(crate) fn visit_members(&self) -> Vec<Vec<usize>> {
        let mut members = vec![Vec::new(); self.visits.len()];
        for (i, o) in self.observations.iter().enumerate() {
            members[o.visit].push(i);
        }
        members
    }

    /// The same set without any observation (visits, references, passes and correlation
    /// times kept).
    pub(crate) fn clone_without_observations(&self) -> ObservationSet {
        ObservationSet {
            observations: Vec::new(),
            visits: self.visits.clone(),
            reference_ids: self.reference_ids.clone(),
            passes: self.passes,
            nav_tau_s: self.nav_tau_s,
            nav_white_share: self.nav_white_share,
            nav_slow: self.nav_slow,
        }
    }

    /// The variance of `o` (m^2) that no other return's navigation error explains: the
    /// scanner's, plus the white navigation noise ([`Self::nav_white_share`]) along its
    /// navigation gradient (which returns between the same records share).
    /// The white navigation variances are taken once, when the function is made.
    pub fn independent_var_m2(&self) -> impl Fn(&Observation) -> f64 + Sync + '_ {
        let white_var = self.white_nav_var(self.nav_white_share);
        move |o| o.var_white_m2 + white_nav_cov_m2(o, o, &white_var)
    }

    /// Variance of the white navigation noise per component (m^2, rad^2) at shares `white`
    /// (position, attitude block) of the median over the visits of each component's variance:
    /// an SBET's record-to-record jitter does not follow its stated sigma, which grows in an
    /// outage and with a random walk.
    pub fn white_nav_var(&self, white: [f64; 2]) -> [f64; 6] {
        if white == [0.0; 2] || self.visits.is_empty() {
            return [0.0; 6];
        }
        std::array::from_fn(|k| {
            let mut v: Vec<f64> = self
                .visits
                .iter()
                .map(|v| v.nav_cov[k][k].max(0.0))
                .collect();
            let mid = v.len() / 2;
            white[k / 3] * *v.select_nth_unstable_by(mid, f64::total_cmp).1
        })
    }

    /// Reference indices that have at least one observation, ascending.
    pub fn observed_references(&self) -> Vec<usize> {
        let mut seen = vec![false; self.reference_ids.len()];
        for o in &self.observations {
            if let Some(s) = seen.get_mut(o.reference) {
                *s = true;
            }
        }
        (0..seen.len()).filter(|&r| seen[r]).collect()
    }
}

fn invalid(problem: String) -> Error {
    Error::Invalid(format!("diagnosis observations: {problem}"))
}

/// A correction of the residuals by catalogue effects: `r - S theta`.
#[derive(Debug, Clone, Copy)]
pub struct Theta<'a> {
    /// The effects.
    pub effects: &'a [Effect],
    /// Their values, in the unit of each name.
    pub values: &'a [f64],
}

impl Theta<'_> {
    /// The residual of `o` after the correction (m).
    pub fn corrected(&self, o: &Observation) -> f64 {
        o.residual_m
            - self
                .effects
                .iter()
                .zip(self.values)
                .map(|(&e, &x)| o.signature[signature_index(e)] * x)
                .sum::<f64>()
    }
}

/// Synthetic observation sets drawn from the model itself, for the statistics' unit tests.
#[cfg(test)]
pub(crate) mod synthetic;

#[cfg(test)]
mod tests {
    use super::synthetic::{draw, Scenario};
    use super::*;

    #[test]
    fn validate_names_the_observation_and_field() {
        let mut set = draw(&Scenario::default(), 1);
        set.validate().unwrap();
        set.observations[7].var_white_m2 = 0.0;
        let e = set.validate().unwrap_err().to_string();
        assert!(
            e.contains("observation 7") && e.contains("var_white_m2"),
            "{e}"
        );
    }

    #[test]
    fn effect_names_are_the_catalogue_in_order() {
        let names: Vec<_> = Effect::ALL.iter().map(|e| e.name()).collect();
        assert_eq!(names[0], "attitude_latency_s");
        assert_eq!(names[14], "heading_offset_deg");
        for (i, e) in Effect::ALL.iter().enumerate() {
            assert_eq!(signature_index(*e), i);
        }
    }
}
