//! `[inputs]` (what is read) and `[trajectory]` (how the trajectory is interpolated).

use super::refusal::{refuse, require_finite, require_positive, Refusal};
use crate::io::config_file::ConfigPath;
use serde::{Deserialize, Serialize};

/// `[inputs]`: what is read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputsConfig {
    /// Applanix SBET trajectory.
    pub sbet: ConfigPath,
    /// Applanix SMRMSG accuracy file (needed for uncertainty).
    #[serde(default)]
    pub smrmsg: Option<ConfigPath>,
    /// Scanner profile files, one per pass (binary `.ksprof` or CSV `.csv`). Pass `k` (from 0)
    /// gets point source id `first_point_source_id + k`.
    pub profiles: Vec<ConfigPath>,
    /// Point source id of the first profile file.
    #[serde(default = "one_u16")]
    pub first_point_source_id: u16,
    /// GPS week of the trajectory's seconds-of-week times. When given, LAS GPS time is
    /// adjusted standard GPS time; when absent, GPS week seconds (conventions §2).
    #[serde(default)]
    pub gps_week: Option<u32>,
}

/// `[trajectory]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryConfig {
    /// Longest interval between trajectory records that may be interpolated across (s).
    #[serde(default = "default_max_gap_s")]
    pub max_gap_s: f64,
    /// Added to the SBET true heading (deg, clockwise from north; docs/conventions.md §3).
    #[serde(default)]
    pub heading_offset_deg: f64,
}

impl Default for TrajectoryConfig {
    fn default() -> Self {
        TrajectoryConfig {
            max_gap_s: default_max_gap_s(),
            heading_offset_deg: 0.0,
        }
    }
}

impl TrajectoryConfig {
    /// The trajectory options (angles converted to radians).
    pub fn options(&self) -> crate::trajectory::TrajectoryOptions {
        crate::trajectory::TrajectoryOptions {
            max_gap_s: self.max_gap_s,
            heading_offset_rad: self.heading_offset_deg.to_radians(),
        }
    }
}

impl InputsConfig {
    /// Checks that there is a profile file.
    pub(super) fn check(&self) -> Result<(), Refusal> {
        if self.profiles.is_empty() {
            let problem = "at least one profile file is required";
            return Err(refuse("inputs.profiles", problem));
        }
        if let Some(week) = self.gps_week.filter(|w| *w > MAX_GPS_WEEK) {
            let problem = format!(
                "GPS week {week} is outside the GPS era (week 0 began on 1980-01-06; week \
                 {MAX_GPS_WEEK} ends in 2099, and weeks in 2026 are about 2400): a week number \
                 counts weeks, not seconds or days (the LAS creation date and adjusted GPS times \
                 come from it)"
            );
            return Err(refuse("inputs.gps_week", problem));
        }
        Ok(())
    }
}

/// The last GPS week before 2100 (weeks of 7 days from 1980-01-06).
pub const MAX_GPS_WEEK: u32 = 6260;

impl TrajectoryConfig {
    /// Checks the gap limit and the heading offset.
    pub(super) fn check(&self) -> Result<(), Refusal> {
        require_positive([("trajectory.max_gap_s", self.max_gap_s)])?;
        require_finite([("trajectory.heading_offset_deg", self.heading_offset_deg)])
    }
}

fn one_u16() -> u16 {
    1
}
fn default_max_gap_s() -> f64 {
    crate::trajectory::TrajectoryOptions::default().max_gap_s
}
