//! Raw scanner profiles: the binary fixed-record form (memory-mapped, chunkable).
//!
//! Layout (little-endian; full description in docs/formats.md):
//! header 64 bytes: magic `KSPROF01`, u32 version (1), u32 record bytes (40), u32 flags
//! (bit 0: alpha column present, bit 1: time column present), u32 reserved (0), u64 record
//! count, 32 reserved bytes (0). Then records of 40 bytes: u32 profile counter, u16 intensity,
//! u16 reserved (0), f64 mirror angle beta (rad), f64 range (m, 0 = missing return),
//! f64 out-of-plane angle alpha (rad, 0 when absent), f64 hardware time tag (s, 0 when absent).

use super::atomic::AtomicFile;
use super::mapped::{f64_le, MappedRecords};
use crate::{Error, Result};
use std::path::Path;

/// Magic bytes at the start of a binary profile file.
pub const PROFILE_MAGIC: &[u8; 8] = b"KSPROF01";
/// Header size (bytes).
pub const PROFILE_HEADER_BYTES: usize = 64;
/// Record size (bytes).
pub const PROFILE_RECORD_BYTES: usize = 40;
const FLAG_ALPHA: u32 = 1;
const FLAG_TIME: u32 = 2;

/// One raw scanner return as recorded (not time-stamped unless `time_s` is present).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RawReturn {
    /// Profile counter `n` (increments when the mirror passes `beta_start`).
    pub profile: u32,
    /// Raw intensity.
    pub intensity: u16,
    /// Mirror angle beta (rad), conventions §3.
    pub beta_rad: f64,
    /// Measured range rho (m); 0 marks a missing return.
    pub range_m: f64,
    /// Out-of-plane angle alpha (rad); meaningful only when the file has the alpha column.
    pub alpha_rad: f64,
    /// Hardware time tag (s); meaningful only when the file has the time column.
    pub time_s: f64,
}

/// Which optional columns a profile source carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct ProfileColumns {
    /// Per-return alpha (rad) present.
    pub alpha: bool,
    /// Per-return hardware time tag (s) present.
    pub time: bool,
}

impl ProfileColumns {
    fn flags(self) -> u32 {
        ((self.alpha as u32) * FLAG_ALPHA) | ((self.time as u32) * FLAG_TIME)
    }
}

/// A memory-mapped binary profile file. Records are decoded on demand; per-record checks
/// (finite values, counter order) are the reader's caller's job, chunk by chunk.
#[derive(Debug)]
pub struct ProfileFile {
    records: MappedRecords,
    columns: ProfileColumns,
}

impl ProfileFile {
    /// Maps `path` and checks its header against its size.
    pub fn open(path: &Path) -> Result<Self> {
        let records = MappedRecords::open(
            path,
            PROFILE_HEADER_BYTES,
            PROFILE_RECORD_BYTES,
            "kinescan profile",
        )?;
        let h = records.header();
        if &h[0..8] != PROFILE_MAGIC {
            return Err(Error::bad_file(
                path,
                "not a kinescan binary profile file (bad magic); CSV profiles must end in .csv",
            ));
        }
        let u32_at = |at: usize| u32::from_le_bytes(h[at..at + 4].try_into().expect("4 bytes"));
        let (version, record_bytes, flags) = (u32_at(8), u32_at(12), u32_at(16));
        if version != 1 || record_bytes as usize != PROFILE_RECORD_BYTES {
            let msg = format!(
                "unsupported version {version} / record size {record_bytes} (expected 1 / 40)"
            );
            return Err(Error::bad_file(path, msg));
        }
        if flags & !(FLAG_ALPHA | FLAG_TIME) != 0 {
            return Err(Error::bad_file(
                path,
                format!("unknown header flags {flags:#x}"),
            ));
        }
        let count = u64::from_le_bytes(h[24..32].try_into().expect("8 bytes"));
        if count != records.len() as u64 {
            let msg = format!(
                "header says {count} records but the file holds {} (truncated or unfinished)",
                records.len()
            );
            return Err(Error::bad_file(path, msg));
        }
        let columns = ProfileColumns {
            alpha: flags & FLAG_ALPHA != 0,
            time: flags & FLAG_TIME != 0,
        };
        Ok(ProfileFile { records, columns })
    }

    /// File path.
    pub fn path(&self) -> &Path {
        self.records.path()
    }

    /// Number of returns.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// True when the file has no returns.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Optional columns present.
    pub fn columns(&self) -> ProfileColumns {
        self.columns
    }

    /// The raw header bytes (for hashing the file as it is read).
    pub fn header_bytes(&self) -> &[u8] {
        self.records.header()
    }

    /// The raw bytes of records `range` (for hashing the file as it is read).
    pub fn record_bytes(&self, range: std::ops::Range<usize>) -> &[u8] {
        self.records.records(range)
    }

    /// Releases the resident pages of records `range` (and some before it, `io::mapped`): memory
    /// stays flat over a large file; the records are read again if touched.
    pub fn release(&self, range: std::ops::Range<usize>) {
        self.records.release(range)
    }

    /// [`ProfileFile::release`] for a read that jumps about the file: the neighbours a fault
    /// mapped after the range are released too.
    pub fn release_around(&self, range: std::ops::Range<usize>) {
        self.records.release_around(range)
    }

    /// Return `i`.
    #[inline]
    pub fn get(&self, i: usize) -> RawReturn {
        decode(self.records.record(i))
    }

    /// Return `i`, refused (naming the file and the 0-based record) when a value is not finite
    /// or the range is negative.
    pub fn get_checked(&self, i: usize) -> Result<RawReturn> {
        let r = self.get(i);
        let fields = [
            ("beta_rad", r.beta_rad),
            ("range_m", r.range_m),
            ("alpha_rad", r.alpha_rad),
            ("time_s", r.time_s),
        ];
        let problem = if let Some((name, v)) = fields.iter().find(|(_, v)| !v.is_finite()) {
            format!("{name} is {v} (not finite)")
        } else if let Some(problem) = beta_in_degrees(r.beta_rad) {
            problem
        } else if r.range_m < 0.0 {
            format!("range_m {} is negative", r.range_m)
        } else {
            return Ok(r);
        };
        Err(Error::bad_record(
            self.path(),
            format!("record {i}"),
            problem,
        ))
    }
}

/// Records [`ProfileFile::check_angles`] reads at most: evenly spread, they find a mirror
/// angle column in degrees (beyond 2 pi over nearly all of a turn) without reading a large
/// file twice.
pub const ANGLE_SAMPLE_RECORDS: usize = 1 << 16;

impl ProfileFile {
    /// Refuses a file whose mirror angles look like degrees: a finite `beta_rad` beyond 2 pi
    /// among up to [`ANGLE_SAMPLE_RECORDS`] records evenly spread over the file (every record
    /// of a smaller file), naming the file and the first such record. Non-finite values are
    /// left to the run's counts (rejected as non-finite). Each sampled record's pages are
    /// released once read: a sample faults in its neighbours too (fault-around, large folios),
    /// and the samples of a large file would otherwise leave nearly all of it resident
    /// (1.15 GB of a 1.2 GB file at 3e7 returns).
    pub fn check_angles(&self) -> Result<()> {
        let step = self.len().div_ceil(ANGLE_SAMPLE_RECORDS).max(1);
        for i in (0..self.len()).step_by(step) {
            let beta = self.get(i).beta_rad;
            if step > 1 {
                self.release(i..i + 1);
            }
            if let Some(problem) = beta.is_finite().then(|| beta_in_degrees(beta)).flatten() {
                return Err(Error::bad_record(
                    self.path(),
                    format!("record {i}"),
                    problem,
                ));
            }
        }
        Ok(())
    }
}

/// The refusal of a mirror angle beyond 2 pi (with a margin of 1e-9 of a turn for rounding):
/// radians are expected, degrees are the likely cause. One rule for CSV and binary profiles.
pub fn beta_in_degrees(beta_rad: f64) -> Option<String> {
    (beta_rad.abs() > std::f64::consts::TAU * (1.0 + 1e-9)).then(|| {
        format!(
            "beta_rad {beta_rad} is beyond 2 pi: mirror angles are radians (degrees given? \
             multiply by pi/180)"
        )
    })
}

#[inline]
fn decode(b: &[u8]) -> RawReturn {
    RawReturn {
        profile: u32::from_le_bytes(b[0..4].try_into().expect("4 bytes")),
        intensity: u16::from_le_bytes(b[4..6].try_into().expect("2 bytes")),
        beta_rad: f64_le(b, 8),
        range_m: f64_le(b, 16),
        alpha_rad: f64_le(b, 24),
        time_s: f64_le(b, 32),
    }
}

/// Encodes one return into its 40-byte record.
#[inline]
pub fn encode(r: &RawReturn) -> [u8; PROFILE_RECORD_BYTES] {
    let mut b = [0u8; PROFILE_RECORD_BYTES];
    b[0..4].copy_from_slice(&r.profile.to_le_bytes());
    b[4..6].copy_from_slice(&r.intensity.to_le_bytes());
    b[8..16].copy_from_slice(&r.beta_rad.to_le_bytes());
    b[16..24].copy_from_slice(&r.range_m.to_le_bytes());
    b[24..32].copy_from_slice(&r.alpha_rad.to_le_bytes());
    b[32..40].copy_from_slice(&r.time_s.to_le_bytes());
    b
}

fn header(columns: ProfileColumns, count: u64) -> [u8; PROFILE_HEADER_BYTES] {
    let mut h = [0u8; PROFILE_HEADER_BYTES];
    h[0..8].copy_from_slice(PROFILE_MAGIC);
    h[8..12].copy_from_slice(&1u32.to_le_bytes());
    h[12..16].copy_from_slice(&(PROFILE_RECORD_BYTES as u32).to_le_bytes());
    h[16..20].copy_from_slice(&columns.flags().to_le_bytes());
    h[24..32].copy_from_slice(&count.to_le_bytes());
    h
}

/// Streaming, atomic binary profile writer. The header's count is written by `finish`, so an
/// unfinished file never exists at the destination and a truncated one is detected on open.
pub struct ProfileWriter {
    out: AtomicFile,
    columns: ProfileColumns,
    count: u64,
}

impl ProfileWriter {
    /// Starts writing `path` with the given optional columns.
    pub fn create(path: &Path, columns: ProfileColumns) -> Result<Self> {
        let mut out = AtomicFile::create(path)?;
        out.write_all(&header(columns, 0))?;
        Ok(ProfileWriter {
            out,
            columns,
            count: 0,
        })
    }

    /// Appends one return.
    #[inline]
    pub fn push(&mut self, r: &RawReturn) -> Result<()> {
        self.count += 1;
        self.out.write_all(&encode(r))
    }

    /// Appends already-encoded records (a multiple of 40 bytes).
    pub fn push_encoded(&mut self, bytes: &[u8]) -> Result<()> {
        assert_eq!(bytes.len() % PROFILE_RECORD_BYTES, 0);
        self.count += (bytes.len() / PROFILE_RECORD_BYTES) as u64;
        self.out.write_all(bytes)
    }

    /// Completes the header and renames the file into place; returns the record count.
    pub fn finish(mut self) -> Result<u64> {
        let h = header(self.columns, self.count);
        self.out.write_at(0, &h)?;
        self.out.commit()?;
        Ok(self.count)
    }
}
