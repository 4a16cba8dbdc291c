//! Applanix SMRMSG accuracy files (SPEC 6): 10 little-endian f64 per 80-byte record.

use super::atomic::AtomicFile;
use super::mapped::{f64_le, MappedRecords};
use crate::{Error, Result};
use std::path::Path;

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

    fn decode(bytes: &[u8]) -> Self {
        let mut a = [0.0; 10];
        for (k, v) in a.iter_mut().enumerate() {
            *v = f64_le(bytes, 8 * k);
        }
        Self::from_array(a)
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

/// A validated, memory-mapped SMRMSG file.
#[derive(Debug)]
pub struct SmrmsgFile {
    records: MappedRecords,
}

impl SmrmsgFile {
    /// Maps and validates `path`: whole records, at least one, finite fields, RMS values >= 0,
    /// time strictly increasing (first problem reported with its 0-based record index).
    pub fn open(path: &Path) -> Result<Self> {
        let records = MappedRecords::open(path, 0, SMRMSG_RECORD_BYTES, "SMRMSG")?;
        if records.is_empty() {
            return Err(Error::bad_file(path, "SMRMSG file has no records"));
        }
        let file = SmrmsgFile { records };
        file.validate()?;
        Ok(file)
    }

    fn validate(&self) -> Result<()> {
        let mut prev_t = f64::NEG_INFINITY;
        for i in 0..self.len() {
            let r = self.record(i).to_array();
            let problem = if let Some(k) = r.iter().position(|v| !v.is_finite()) {
                Some(format!("{} is {} (not finite)", FIELD_NAMES[k], r[k]))
            } else if let Some(k) = r[1..].iter().position(|v| *v < 0.0) {
                Some(format!("{} is negative ({})", FIELD_NAMES[k + 1], r[k + 1]))
            } else if r[0] <= prev_t {
                Some(format!(
                    "time {} s does not increase (previous {prev_t} s)",
                    r[0]
                ))
            } else {
                None
            };
            if let Some(p) = problem {
                return Err(Error::bad_record(self.path(), format!("record {i}"), p));
            }
            prev_t = r[0];
        }
        Ok(())
    }

    /// File path.
    pub fn path(&self) -> &Path {
        self.records.path()
    }

    /// Number of records (>= 1).
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// Always false: an open SMRMSG has at least one record.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Record `i`.
    #[inline]
    pub fn record(&self, i: usize) -> SmrmsgRecord {
        SmrmsgRecord::decode(self.records.record(i))
    }

    /// Time of record `i` (s).
    #[inline]
    pub fn time_s(&self, i: usize) -> f64 {
        f64_le(self.records.record(i), 0)
    }
}

/// Streaming, atomic SMRMSG writer.
pub struct SmrmsgWriter {
    out: AtomicFile,
    last_t: f64,
    count: u64,
}

impl SmrmsgWriter {
    /// Starts writing `path`.
    pub fn create(path: &Path) -> Result<Self> {
        Ok(SmrmsgWriter {
            out: AtomicFile::create(path)?,
            last_t: f64::NEG_INFINITY,
            count: 0,
        })
    }

    /// Appends a record; refuses non-increasing time, negative or non-finite fields.
    pub fn push(&mut self, r: &SmrmsgRecord) -> Result<()> {
        let a = r.to_array();
        if a.iter().any(|v| !v.is_finite())
            || a[1..].iter().any(|v| *v < 0.0)
            || r.time_s <= self.last_t
        {
            let msg = "refusing to write a non-finite, negative or non-increasing-time record";
            return Err(Error::bad_record(
                self.out.path(),
                format!("record {}", self.count),
                msg,
            ));
        }
        let mut buf = [0u8; SMRMSG_RECORD_BYTES];
        for (k, v) in a.iter().enumerate() {
            buf[8 * k..8 * k + 8].copy_from_slice(&v.to_le_bytes());
        }
        self.last_t = r.time_s;
        self.count += 1;
        self.out.write_all(&buf)
    }

    /// Finishes the file atomically; returns the record count.
    pub fn finish(self) -> Result<u64> {
        self.out.commit()?;
        Ok(self.count)
    }
}
