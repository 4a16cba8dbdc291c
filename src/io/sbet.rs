//! Applanix SBET trajectory files (SPEC 6): 17 little-endian f64 per 136-byte record, no header.

use super::atomic::AtomicFile;
use super::mapped::{f64_le, MappedRecords};
use crate::{Error, Result};
use std::path::Path;

/// Bytes per SBET record.
pub const SBET_RECORD_BYTES: usize = 136;

/// One SBET record, fields in file order.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct SbetRecord {
    /// GPS seconds of the week (s).
    pub time_s: f64,
    /// Geodetic latitude, WGS84 (rad).
    pub lat_rad: f64,
    /// Longitude (rad).
    pub lon_rad: f64,
    /// Ellipsoidal height (m).
    pub alt_m: f64,
    /// Velocity along wander-frame x (m/s).
    pub vel_x_mps: f64,
    /// Velocity along wander-frame y (m/s).
    pub vel_y_mps: f64,
    /// Velocity along wander-frame z, down (m/s).
    pub vel_z_mps: f64,
    /// Roll (rad).
    pub roll_rad: f64,
    /// Pitch (rad).
    pub pitch_rad: f64,
    /// Platform heading in the wander frame (rad); true heading = this - wander.
    pub platform_heading_rad: f64,
    /// Wander angle (rad).
    pub wander_rad: f64,
    /// Body x acceleration (m/s^2).
    pub acc_x_mps2: f64,
    /// Body y acceleration (m/s^2).
    pub acc_y_mps2: f64,
    /// Body z acceleration (m/s^2).
    pub acc_z_mps2: f64,
    /// Body x angular rate (rad/s).
    pub rate_x_radps: f64,
    /// Body y angular rate (rad/s).
    pub rate_y_radps: f64,
    /// Body z angular rate (rad/s).
    pub rate_z_radps: f64,
}

impl SbetRecord {
    /// True heading (rad), clockwise from north: platform heading minus wander angle.
    #[inline]
    pub fn true_heading_rad(&self) -> f64 {
        self.platform_heading_rad - self.wander_rad
    }

    /// All 17 fields in file order.
    pub fn to_array(&self) -> [f64; 17] {
        [
            self.time_s,
            self.lat_rad,
            self.lon_rad,
            self.alt_m,
            self.vel_x_mps,
            self.vel_y_mps,
            self.vel_z_mps,
            self.roll_rad,
            self.pitch_rad,
            self.platform_heading_rad,
            self.wander_rad,
            self.acc_x_mps2,
            self.acc_y_mps2,
            self.acc_z_mps2,
            self.rate_x_radps,
            self.rate_y_radps,
            self.rate_z_radps,
        ]
    }

    /// Record from 17 fields in file order.
    pub fn from_array(a: [f64; 17]) -> Self {
        SbetRecord {
            time_s: a[0],
            lat_rad: a[1],
            lon_rad: a[2],
            alt_m: a[3],
            vel_x_mps: a[4],
            vel_y_mps: a[5],
            vel_z_mps: a[6],
            roll_rad: a[7],
            pitch_rad: a[8],
            platform_heading_rad: a[9],
            wander_rad: a[10],
            acc_x_mps2: a[11],
            acc_y_mps2: a[12],
            acc_z_mps2: a[13],
            rate_x_radps: a[14],
            rate_y_radps: a[15],
            rate_z_radps: a[16],
        }
    }

    fn decode(bytes: &[u8]) -> Self {
        let mut a = [0.0; 17];
        for (k, v) in a.iter_mut().enumerate() {
            *v = f64_le(bytes, 8 * k);
        }
        Self::from_array(a)
    }
}

const FIELD_NAMES: [&str; 17] = [
    "time",
    "latitude",
    "longitude",
    "altitude",
    "x velocity",
    "y velocity",
    "z velocity",
    "roll",
    "pitch",
    "platform heading",
    "wander angle",
    "x acceleration",
    "y acceleration",
    "z acceleration",
    "x angular rate",
    "y angular rate",
    "z angular rate",
];

/// A validated, memory-mapped SBET file.
#[derive(Debug)]
pub struct SbetFile {
    records: MappedRecords,
}

impl SbetFile {
    /// Maps and validates `path`: whole records, at least one, every field finite, latitude in
    /// [-pi/2, pi/2], time strictly increasing. The first problem found is reported with its
    /// 0-based record index.
    pub fn open(path: &Path) -> Result<Self> {
        let records = MappedRecords::open(path, 0, SBET_RECORD_BYTES, "SBET")?;
        if records.is_empty() {
            return Err(Error::bad_file(path, "SBET file has no records"));
        }
        let file = SbetFile { records };
        file.validate()?;
        Ok(file)
    }

    fn validate(&self) -> Result<()> {
        let mut prev_t = f64::NEG_INFINITY;
        for i in 0..self.len() {
            let r = self.record(i).to_array();
            let at = || format!("record {i}");
            if let Some(k) = r.iter().position(|v| !v.is_finite()) {
                let msg = format!("{} is {} (not finite)", FIELD_NAMES[k], r[k]);
                return Err(Error::bad_record(self.path(), at(), msg));
            }
            if r[1].abs() > std::f64::consts::FRAC_PI_2 {
                let msg = format!("latitude {} rad is outside [-pi/2, pi/2]", r[1]);
                return Err(Error::bad_record(self.path(), at(), msg));
            }
            if r[0] <= prev_t {
                let msg = format!(
                    "time {} s does not increase (previous record {prev_t} s): \
                     time going backwards or repeating",
                    r[0]
                );
                return Err(Error::bad_record(self.path(), at(), msg));
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

    /// Always false: an open SBET has at least one record.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Record `i`.
    #[inline]
    pub fn record(&self, i: usize) -> SbetRecord {
        SbetRecord::decode(self.records.record(i))
    }

    /// Time of record `i` (s).
    #[inline]
    pub fn time_s(&self, i: usize) -> f64 {
        f64_le(self.records.record(i), 0)
    }
}

/// Streaming, atomic SBET writer.
pub struct SbetWriter {
    out: AtomicFile,
    last_t: f64,
    count: u64,
}

impl SbetWriter {
    /// Starts writing `path`.
    pub fn create(path: &Path) -> Result<Self> {
        Ok(SbetWriter {
            out: AtomicFile::create(path)?,
            last_t: f64::NEG_INFINITY,
            count: 0,
        })
    }

    /// Appends a record; refuses non-increasing time or non-finite fields.
    pub fn push(&mut self, r: &SbetRecord) -> Result<()> {
        let a = r.to_array();
        if a.iter().any(|v| !v.is_finite()) || r.time_s <= self.last_t {
            let msg = "refusing to write a non-finite or non-increasing-time record";
            return Err(Error::bad_record(
                self.out.path(),
                format!("record {}", self.count),
                msg,
            ));
        }
        let mut buf = [0u8; SBET_RECORD_BYTES];
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
