//! Raw IMU files (docs/formats.md): 7 little-endian f64 per 56-byte record, no header: time,
//! specific force x/y/z (m/s^2), angular rate x/y/z (rad/s), body frame (x forward, y right,
//! z down; conventions §3). Each record holds the mean over the interval that ends at its time
//! (the velocity and angle increments divided by the interval).

use super::timed::{TimedFile, TimedRecord, TimedWriter};

/// Bytes per IMU record.
pub const IMU_RECORD_BYTES: usize = 56;

/// Largest magnitude accepted for a specific force (m/s^2, 100 g) or an angular rate (rad/s):
/// beyond it a record is corrupt, not a vehicle.
const MAX_SPECIFIC_FORCE_MPS2: f64 = 981.0;
const MAX_RATE_RADPS: f64 = 100.0;

/// One IMU record: the mean specific force and angular rate over the interval ending at `time_s`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct ImuRecord {
    /// GPS seconds of the week at the end of the interval (s).
    pub time_s: f64,
    /// Specific force, body frame (m/s^2).
    pub f_b: [f64; 3],
    /// Angular rate of the body against inertial space, body frame (rad/s).
    pub w_b: [f64; 3],
}

const FIELD_NAMES: [&str; 7] = [
    "time",
    "x specific force",
    "y specific force",
    "z specific force",
    "x angular rate",
    "y angular rate",
    "z angular rate",
];

impl TimedRecord for ImuRecord {
    const FIELDS: usize = 7;
    const KIND: &'static str = "IMU";

    fn field_names() -> &'static [&'static str] {
        &FIELD_NAMES
    }

    fn from_fields(f: &[f64]) -> Self {
        ImuRecord {
            time_s: f[0],
            f_b: [f[1], f[2], f[3]],
            w_b: [f[4], f[5], f[6]],
        }
    }

    fn to_fields(&self, out: &mut [f64]) {
        out[0] = self.time_s;
        out[1..4].copy_from_slice(&self.f_b);
        out[4..7].copy_from_slice(&self.w_b);
    }

    fn problem(f: &[f64]) -> Option<String> {
        if let Some(k) = (1..4).find(|&k| f[k].abs() > MAX_SPECIFIC_FORCE_MPS2) {
            return Some(format!("{} {} m/s^2 is beyond 100 g", FIELD_NAMES[k], f[k]));
        }
        (4..7)
            .find(|&k| f[k].abs() > MAX_RATE_RADPS)
            .map(|k| format!("{} {} rad/s is beyond 100 rad/s", FIELD_NAMES[k], f[k]))
    }
}

/// A validated, memory-mapped IMU file.
pub type ImuFile = TimedFile<ImuRecord>;

/// Streaming, atomic IMU writer.
pub type ImuWriter = TimedWriter<ImuRecord>;
