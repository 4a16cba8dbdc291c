//! Headerless files of fixed records of little-endian f64 whose first field is a strictly
//! increasing GPS time: the shape shared by SBET and SMRMSG. One reader (memory-mapped,
//! validated on open) and one atomic streaming writer serve both.

use super::atomic::AtomicFile;
use super::mapped::{f64_le, MappedRecords};
use crate::{Error, Result};
use std::marker::PhantomData;
use std::path::Path;

/// A record type stored as `FIELDS` little-endian f64, time first.
pub trait TimedRecord: Sized {
    /// Number of f64 fields.
    const FIELDS: usize;
    /// File kind for messages ("SBET").
    const KIND: &'static str;
    /// Field names in file order, for messages.
    fn field_names() -> &'static [&'static str];
    /// Record from fields in file order (`fields.len() == FIELDS`).
    fn from_fields(fields: &[f64]) -> Self;
    /// Fields in file order into `out` (`out.len() == FIELDS`).
    fn to_fields(&self, out: &mut [f64]);
    /// A format-specific problem with finite fields (range of a latitude, sign of an RMS...).
    fn problem(fields: &[f64]) -> Option<String>;
    /// A problem between two consecutive valid records `prev` and `next` (a jump no vehicle
    /// can make...); none by default.
    fn step_problem(_prev: &[f64], _next: &[f64]) -> Option<String> {
        None
    }
}

/// Records validated between two releases of their mapped pages.
const VALIDATE_RELEASE: usize = 1 << 16;

/// Maximum number of fields of a [`TimedRecord`].
const MAX_FIELDS: usize = 17;

/// A validated, memory-mapped file of [`TimedRecord`]s.
#[derive(Debug)]
pub struct TimedFile<R> {
    records: MappedRecords,
    kind: PhantomData<R>,
}

impl<R: TimedRecord> TimedFile<R> {
    /// Maps and validates `path`: whole records, at least one, every field finite, the
    /// record's own checks, time strictly increasing. The first problem is reported with its
    /// 0-based record index.
    pub fn open(path: &Path) -> Result<Self> {
        let records = MappedRecords::open(path, 0, 8 * R::FIELDS, R::KIND)?;
        if records.is_empty() {
            return Err(Error::bad_file(
                path,
                format!("{} file has no records", R::KIND),
            ));
        }
        let file = TimedFile {
            records,
            kind: PhantomData,
        };
        file.validate()?;
        Ok(file)
    }

    fn validate(&self) -> Result<()> {
        let mut prev_t = f64::NEG_INFINITY;
        let mut f = [0.0; MAX_FIELDS];
        let mut prev = [0.0; MAX_FIELDS];
        for i in 0..self.len() {
            let f = self.fields(i, &mut f);
            let names = R::field_names();
            let problem = if let Some(k) = f.iter().position(|v| !v.is_finite()) {
                Some(format!("{} is {} (not finite)", names[k], f[k]))
            } else if let Some(p) = R::problem(f) {
                Some(p)
            } else if f[0] <= prev_t {
                Some(format!(
                    "time {} s does not increase (previous record {prev_t} s): \
                     time going backwards or repeating",
                    f[0]
                ))
            } else if i > 0 {
                R::step_problem(&prev[..R::FIELDS], f)
            } else {
                None
            };
            if let Some(p) = problem {
                return Err(Error::bad_record(self.path(), format!("record {i}"), p));
            }
            prev_t = f[0];
            prev[..R::FIELDS].copy_from_slice(f);
            // Validated pages are dropped as the pass goes: opening a file of hours of IMU
            // records does not make it all resident (re-read from the page cache if touched).
            if i % VALIDATE_RELEASE == 0 && i > 0 {
                self.records.release(i - VALIDATE_RELEASE..i);
            }
        }
        Ok(())
    }

    fn fields<'b>(&self, i: usize, buf: &'b mut [f64; MAX_FIELDS]) -> &'b [f64] {
        let bytes = self.records.record(i);
        for (k, v) in buf[..R::FIELDS].iter_mut().enumerate() {
            *v = f64_le(bytes, 8 * k);
        }
        &buf[..R::FIELDS]
    }

    /// File path.
    pub fn path(&self) -> &Path {
        self.records.path()
    }

    /// Number of records (>= 1).
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// Always false: an open file has at least one record.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Record `i`.
    #[inline]
    pub fn record(&self, i: usize) -> R {
        let mut buf = [0.0; MAX_FIELDS];
        R::from_fields(self.fields(i, &mut buf))
    }

    /// Time of record `i` (s).
    #[inline]
    pub fn time_s(&self, i: usize) -> f64 {
        f64_le(self.records.record(i), 0)
    }

    /// Lets the kernel drop the mapped pages of records `range` (they are re-read if touched
    /// again): resident memory stays flat over a long pass through the file.
    pub fn release(&self, range: std::ops::Range<usize>) {
        self.records.release(range);
    }

    /// Lets the kernel drop every mapped page of the file (see [`TimedFile::release`]).
    pub fn release_all(&self) {
        self.records.release_around(0..self.len());
    }

    /// Lets the kernel drop the mapped pages of the records from `t0_s` to `t1_s` (s), with
    /// one record either side and the neighbours a fault maps with them.
    pub fn release_times(&self, t0_s: f64, t1_s: f64) {
        let first_after = |t: f64| {
            let (mut lo, mut hi) = (0, self.len());
            while lo < hi {
                let mid = (lo + hi) / 2;
                if self.time_s(mid) <= t {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            lo
        };
        let start = first_after(t0_s).saturating_sub(1);
        let end = (first_after(t1_s) + 1).min(self.len());
        self.records.release_around(start..end);
    }
}

/// Streaming, atomic writer of [`TimedRecord`]s.
pub struct TimedWriter<R> {
    out: AtomicFile,
    last_t: f64,
    count: u64,
    kind: PhantomData<R>,
}

impl<R: TimedRecord> TimedWriter<R> {
    /// Starts writing `path`.
    pub fn create(path: &Path) -> Result<Self> {
        let out = AtomicFile::create(path)?;
        Ok(TimedWriter {
            out,
            last_t: f64::NEG_INFINITY,
            count: 0,
            kind: PhantomData,
        })
    }

    /// Appends a record; refuses what [`TimedFile::open`] would refuse.
    pub fn push(&mut self, r: &R) -> Result<()> {
        let mut f = [0.0; MAX_FIELDS];
        let f = &mut f[..R::FIELDS];
        r.to_fields(f);
        let bad =
            f.iter().any(|v| !v.is_finite()) || R::problem(f).is_some() || f[0] <= self.last_t;
        if bad {
            let msg = format!(
                "refusing to write an invalid {} record (see docs/formats.md)",
                R::KIND
            );
            return Err(Error::bad_record(
                self.out.path(),
                format!("record {}", self.count),
                msg,
            ));
        }
        let mut buf = [0u8; 8 * MAX_FIELDS];
        for (k, v) in f.iter().enumerate() {
            buf[8 * k..8 * k + 8].copy_from_slice(&v.to_le_bytes());
        }
        self.last_t = f[0];
        self.count += 1;
        self.out.write_all(&buf[..8 * R::FIELDS])
    }

    /// Finishes the file atomically; returns the record count.
    pub fn finish(self) -> Result<u64> {
        self.out.commit()?;
        Ok(self.count)
    }
}
