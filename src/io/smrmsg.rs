//! Applanix SMRMSG accuracy files (conventions §6): 10 little-endian f64 per 80-byte record.

use super::timed::{TimedFile, TimedRecord, TimedWriter};

/// Bytes per SMRMSG record.
pub const SMRMSG_RECORD_BYTES: usize = 80;

/// Radians per arc-minute (SMRMSG attitude RMS unit).
pub const RAD_PER_ARCMIN: f64 = std::f64::consts::PI / (180.0 * 60.0);

/// One SMRMSG record (1 sigma RMS values, file order and units).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct SmrmsgRecord {
    /// GPS seconds of the week (s).
    pub time_s: f64,
    /// North position RMS (m).
    pub north_m: f64,
    /// East position RMS (m).
    pub east_m: f64,
    /// Down position RMS (m).
    pub down_m: f64,
    /// North velocity RMS (m/s).
    pub vel_north_mps: f64,
    /// East velocity RMS (m/s).
    pub vel_east_mps: f64,
    /// Down velocity RMS (m/s).
    pub vel_down_mps: f64,
    /// Roll RMS (arc-minutes).
    pub roll_arcmin: f64,
    /// Pitch RMS (arc-minutes).
    pub pitch_arcmin: f64,
    /// Heading RMS (arc-minutes).
    pub heading_arcmin: f64,
}

impl SmrmsgRecord {
    /// All 10 fields in file order.
    pub fn to_array(&self) -> [f64; 10] {
        [
            self.time_s,
            self.north_m,
            self.east_m,
            self.down_m,
            self.vel_north_mps,
            self.vel_east_mps,
            self.vel_down_mps,
            self.roll_arcmin,
            self.pitch_arcmin,
            self.heading_arcmin,
        ]
    }

    /// Record from 10 fields in file order.
    pub fn from_array(a: [f64; 10]) -> Self {
        SmrmsgRecord {
            time_s: a[0],
            north_m: a[1],
            east_m: a[2],
            down_m: a[3],
            vel_north_mps: a[4],
            vel_east_mps: a[5],
            vel_down_mps: a[6],
            roll_arcmin: a[7],
            pitch_arcmin: a[8],
            heading_arcmin: a[9],
        }
    }
}

const FIELD_NAMES: [&str; 10] = [
    "time",
    "north RMS",
    "east RMS",
    "down RMS",
    "north velocity RMS",
    "east velocity RMS",
    "down velocity RMS",
    "roll RMS",
    "pitch RMS",
    "heading RMS",
];

impl TimedRecord for SmrmsgRecord {
    const FIELDS: usize = 10;
    const KIND: &'static str = "SMRMSG";

    fn field_names() -> &'static [&'static str] {
        &FIELD_NAMES
    }

    fn from_fields(fields: &[f64]) -> Self {
        Self::from_array(fields.try_into().expect("10 fields"))
    }

    fn to_fields(&self, out: &mut [f64]) {
        out.copy_from_slice(&self.to_array());
    }

    fn problem(fields: &[f64]) -> Option<String> {
        let names = Self::field_names();
        let k = fields[1..].iter().position(|v| *v < 0.0)? + 1;
        Some(format!("{} is negative ({})", names[k], fields[k]))
    }
}

/// A validated, memory-mapped SMRMSG file.
pub type SmrmsgFile = TimedFile<SmrmsgRecord>;

/// Streaming, atomic SMRMSG writer.
pub type SmrmsgWriter = TimedWriter<SmrmsgRecord>;
