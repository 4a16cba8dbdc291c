//! GNSS position files (docs/formats.md): 7 little-endian f64 per 56-byte record, no header:
//! time, latitude, longitude (rad, WGS84), ellipsoidal height (m) of the antenna phase
//! centre, and its 1-sigma north, east, down errors (m). An epoch without a fix (an outage) is
//! simply absent.

use super::timed::{TimedFile, TimedRecord, TimedWriter};

/// Bytes per GNSS record.
pub const GNSS_RECORD_BYTES: usize = 56;

/// One GNSS position fix.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct GnssRecord {
    /// GPS seconds of the week (s).
    pub time_s: f64,
    /// Geodetic latitude of the antenna, WGS84 (rad).
    pub lat_rad: f64,
    /// Longitude (rad).
    pub lon_rad: f64,
    /// Ellipsoidal height (m).
    pub h_m: f64,
    /// 1-sigma north, east, down position errors (m), > 0.
    pub sigma_ned_m: [f64; 3],
}

const FIELD_NAMES: [&str; 7] = [
    "time",
    "latitude",
    "longitude",
    "height",
    "north sigma",
    "east sigma",
    "down sigma",
];

impl TimedRecord for GnssRecord {
    const FIELDS: usize = 7;
    const KIND: &'static str = "GNSS";

    fn field_names() -> &'static [&'static str] {
        &FIELD_NAMES
    }

    fn from_fields(f: &[f64]) -> Self {
        GnssRecord {
            time_s: f[0],
            lat_rad: f[1],
            lon_rad: f[2],
            h_m: f[3],
            sigma_ned_m: [f[4], f[5], f[6]],
        }
    }

    fn to_fields(&self, out: &mut [f64]) {
        out[..4].copy_from_slice(&[self.time_s, self.lat_rad, self.lon_rad, self.h_m]);
        out[4..7].copy_from_slice(&self.sigma_ned_m);
    }

    fn problem(f: &[f64]) -> Option<String> {
        if f[1].abs() > std::f64::consts::FRAC_PI_2 {
            return Some(format!("latitude {} rad is outside [-pi/2, pi/2]", f[1]));
        }
        if f[2].abs() > 2.0 * std::f64::consts::PI {
            return Some(format!("longitude {} rad is outside [-2 pi, 2 pi]", f[2]));
        }
        if f[3].abs() > 1.0e5 {
            return Some(format!("height {} m is beyond +-100 km", f[3]));
        }
        (4..7)
            .find(|&k| f[k] <= 0.0 || f[k] > 1.0e3)
            .map(|k| format!("{} {} m must be in (0, 1000]", FIELD_NAMES[k], f[k]))
    }
}

/// A validated, memory-mapped GNSS file.
pub type GnssFile = TimedFile<GnssRecord>;

/// Streaming, atomic GNSS writer.
pub type GnssWriter = TimedWriter<GnssRecord>;
