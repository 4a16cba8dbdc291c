//! The data the diagnosis statistics work on: one [`Observation`] per return on a reference
//! patch, grouped into [`Visit`]s (docs/diagnosis.md).

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
    /// Measured range (m).
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
}

/// One time-contiguous run of returns over one patch in one pass: its navigation error is one
/// draw `z_v ~ N(0, nav_cov)` shared by all its returns.
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
}
