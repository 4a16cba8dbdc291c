//! Raw scanner profiles, CSV form (conventions §6): header `profile,beta_rad,range_m,intensity`,
//! optionally followed by `,alpha_rad` and/or `,time_s` (in that order). One return per line,
//! ordered by profile counter. An empty or zero range is a missing return (range 0).
//!
//! Units: beta and alpha in radians (conventions §3 scanner frame), range in metres, time in seconds
//! (hardware time tag), intensity a raw unsigned 16-bit count, profile an unsigned 32-bit
//! counter. Everything streams: one line in memory at a time.

use super::atomic::AtomicFile;
pub use super::counters::CounterJump;
use super::counters::CounterTracker;
use super::csv_text::{self, Lines};
use super::profiles::{ProfileColumns, ProfileFile, ProfileWriter, RawReturn};
use crate::{Error, Result};
use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;

/// Required columns of a CSV profile file, in order.
pub const PROFILE_CSV_REQUIRED: [&str; 4] = ["profile", "beta_rad", "range_m", "intensity"];
/// Optional columns, allowed only in this order after the required ones.
pub const PROFILE_CSV_OPTIONAL: [&str; 2] = ["alpha_rad", "time_s"];

/// Streaming CSV profile reader: an iterator of validated returns. The first bad line ends
/// the iteration with an error naming the file and the 1-based line.
pub struct ProfileCsvReader<R> {
    lines: Lines<R>,
    columns: ProfileColumns,
    last_profile: Option<u32>,
    failed: bool,
}

impl ProfileCsvReader<BufReader<File>> {
    /// Opens `path` and checks its header.
    pub fn open(path: &Path) -> Result<Self> {
        Self::from_lines(Lines::open(path)?)
    }
}

impl<R: BufRead> ProfileCsvReader<R> {
    /// Reads CSV from `reader`; `path` names the source in messages.
    pub fn from_reader(path: &Path, reader: R) -> Result<Self> {
        Self::from_lines(Lines::new(path, reader))
    }

    fn from_lines(mut lines: Lines<R>) -> Result<Self> {
        let header = lines.header()?;
        let present = csv_text::check_header(
            lines.path(),
            header,
            &PROFILE_CSV_REQUIRED,
            &PROFILE_CSV_OPTIONAL,
        )?;
        Ok(ProfileCsvReader {
            lines,
            columns: ProfileColumns {
                alpha: present[0],
                time: present[1],
            },
            last_profile: None,
            failed: false,
        })
    }

    /// Optional columns present in the header.
    pub fn columns(&self) -> ProfileColumns {
        self.columns
    }

    /// 1-based line number of the return last yielded.
    pub fn line_no(&self) -> u64 {
        self.lines.line_no()
    }

    fn parse_line(&mut self) -> Result<RawReturn> {
        let lines = &self.lines;
        let n = 4 + self.columns.alpha as usize + self.columns.time as usize;
        let mut f = [""; 6];
        csv_text::split_fields(lines, &mut f[..n])?;
        let bad = |what: String| Error::bad_record(lines.path(), lines.at(), what);
        let profile: u32 = f[0].parse().map_err(|_| {
            bad(format!(
                "profile counter `{}` is not an unsigned integer (0..={})",
                f[0],
                u32::MAX
            ))
        })?;
        let beta_rad = csv_text::finite_f64(lines, "beta_rad", f[1])?;
        if let Some(problem) = super::profiles::beta_in_degrees(beta_rad) {
            return Err(bad(problem));
        }
        let range_m = match f[2] {
            "" => 0.0,
            s => csv_text::finite_f64(lines, "range_m", s)?,
        };
        if range_m < 0.0 {
            return Err(bad(format!("range_m {range_m} is negative")));
        }
        let intensity = match f[3] {
            "" if range_m == 0.0 => 0,
            s => s.parse::<u16>().map_err(|_| {
                bad(format!(
                    "intensity `{s}` is not an integer in 0..=65535 (u16)"
                ))
            })?,
        };
        let mut next = 4;
        let mut optional = |on: bool, name: &str| -> Result<f64> {
            if !on {
                return Ok(0.0);
            }
            next += 1;
            csv_text::finite_f64(lines, name, f[next - 1])
        };
        let alpha_rad = optional(self.columns.alpha, "alpha_rad")?;
        let time_s = optional(self.columns.time, "time_s")?;
        if let Some(prev) = self.last_profile.filter(|p| profile < *p) {
            return Err(bad(format!(
                "profile counter decreases from {prev} to {profile}: wrap or reordered file"
            )));
        }
        self.last_profile = Some(profile);
        Ok(RawReturn {
            profile,
            intensity,
            beta_rad,
            range_m,
            alpha_rad,
            time_s,
        })
    }
}

impl<R: BufRead> Iterator for ProfileCsvReader<R> {
    type Item = Result<RawReturn>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        let item = match self.lines.advance() {
            Ok(false) => return None,
            Ok(true) => self.parse_line(),
            Err(e) => Err(e),
        };
        self.failed = item.is_err();
        Some(item)
    }
}

/// Running summary of a stream of returns.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct ProfileTally {
    /// Returns seen (missing ones included).
    pub returns: u64,
    /// Missing returns (range 0).
    pub missing_returns: u64,
    /// Profile counter: first and last, distinct profiles, jumps and backward steps (the first
    /// [`super::counters::MAX_LISTED_JUMPS`] listed, all counted).
    #[serde(flatten)]
    pub counters: CounterTracker,
    /// Smallest and largest counter.
    pub profile_range: Option<(u32, u32)>,
    /// Smallest and largest mirror angle beta (rad) over all returns.
    pub beta_range_rad: Option<(f64, f64)>,
}

impl ProfileTally {
    /// Adds one return found at `at` (1-based line or 0-based record).
    pub fn add(&mut self, r: &RawReturn, at: u64) {
        self.returns += 1;
        self.missing_returns += (r.range_m == 0.0) as u64;
        self.counters.add(at, r.profile);
        let (lo, hi) = self.profile_range.unwrap_or((r.profile, r.profile));
        self.profile_range = Some((lo.min(r.profile), hi.max(r.profile)));
        let (blo, bhi) = self.beta_range_rad.unwrap_or((r.beta_rad, r.beta_rad));
        self.beta_range_rad = Some((blo.min(r.beta_rad), bhi.max(r.beta_rad)));
    }
}

/// What [`import_csv`] converted.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ImportSummary {
    /// Optional columns carried over.
    pub columns: ProfileColumns,
    /// Counts, counter range and jumps (jump positions are 1-based CSV lines).
    pub tally: ProfileTally,
    /// The CSV line of each record of the binary file.
    #[serde(skip)]
    pub lines: RecordLines,
}

/// The 1-based CSV line of each 0-based record of an imported file, so messages about a record
/// name the user's line. Stored sparsely: `(record, line - record)` wherever the difference
/// changes (at the first record and after blank lines).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RecordLines {
    steps: Vec<(u64, u64)>,
}

impl RecordLines {
    fn push(&mut self, record: u64, line: u64) {
        let offset = line - record;
        if self.steps.last().is_none_or(|&(_, o)| o != offset) {
            self.steps.push((record, offset));
        }
    }

    /// The line of `record` (records after the last one continue its numbering).
    pub fn line_of(&self, record: u64) -> u64 {
        let k = self.steps.partition_point(|&(r, _)| r <= record);
        record + k.checked_sub(1).map_or(0, |k| self.steps[k].1)
    }
}

impl std::fmt::Display for ImportSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (t, c) = (&self.tally, &self.tally.counters);
        writeln!(
            f,
            "{} returns ({} missing) in {} profiles, counter {} .. {}",
            t.returns,
            t.missing_returns,
            c.profiles,
            c.first_profile.map_or("-".into(), |p| p.to_string()),
            c.last_profile.map_or("-".into(), |p| p.to_string()),
        )?;
        writeln!(
            f,
            "optional columns: alpha_rad {}, time_s {}",
            yes_no(self.columns.alpha),
            yes_no(self.columns.time)
        )?;
        write!(f, "counter jumps (> 1 profile): {}", c.jump_count)?;
        for j in &c.jumps {
            write!(f, "\n  line {}: {} -> {}", j.at, j.from, j.to)?;
        }
        Ok(())
    }
}

pub(crate) fn yes_no(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

/// Converts CSV profiles at `csv` to the binary form at `bin` (written atomically: nothing
/// appears at `bin` unless every line is valid). Streams both files.
pub fn import_csv(csv: &Path, bin: &Path) -> Result<ImportSummary> {
    let mut reader = ProfileCsvReader::open(csv)?;
    let columns = reader.columns();
    let mut writer = ProfileWriter::create(bin, columns)?;
    let mut tally = ProfileTally::default();
    let mut lines = RecordLines::default();
    while let Some(r) = reader.next() {
        let r = r?;
        lines.push(tally.returns, reader.line_no());
        tally.add(&r, reader.line_no());
        writer.push(&r)?;
    }
    if tally.returns == 0 {
        return Err(Error::bad_file(csv, "no returns after the header"));
    }
    writer.finish()?;
    Ok(ImportSummary {
        columns,
        tally,
        lines,
    })
}

/// Converts a binary profile file to CSV (columns as in the binary header); returns the
/// number of returns written.
pub fn export_csv(bin: &Path, csv: &Path) -> Result<u64> {
    let file = ProfileFile::open(bin)?;
    let mut w = ProfileCsvWriter::create(csv, file.columns())?;
    for i in 0..file.len() {
        w.push(&file.get(i)).map_err(|e| match e {
            Error::BadRecord { problem, .. } => {
                Error::bad_record(bin, format!("record {i}"), problem)
            }
            e => e,
        })?;
    }
    w.finish()
}

/// Streaming, atomic CSV profile writer. Every f64 uses Rust's shortest round-trip
/// formatting, so reading the file back gives bit-identical values.
pub struct ProfileCsvWriter {
    out: AtomicFile,
    columns: ProfileColumns,
    last_profile: Option<u32>,
    count: u64,
    line: String,
}

impl ProfileCsvWriter {
    /// Starts writing `path` with the given optional columns.
    pub fn create(path: &Path, columns: ProfileColumns) -> Result<Self> {
        let mut out = AtomicFile::create(path)?;
        let mut header = PROFILE_CSV_REQUIRED.join(",");
        for (on, name) in [(columns.alpha, "alpha_rad"), (columns.time, "time_s")] {
            if on {
                header.push(',');
                header.push_str(name);
            }
        }
        header.push('\n');
        out.write_all(header.as_bytes())?;
        Ok(ProfileCsvWriter {
            out,
            columns,
            last_profile: None,
            count: 0,
            line: String::with_capacity(128),
        })
    }

    /// Appends one return; refuses what the reader would refuse (non-finite values, negative
    /// range, decreasing counter), naming the 0-based return.
    pub fn push(&mut self, r: &RawReturn) -> Result<()> {
        use std::fmt::Write as _;
        let finite = [r.beta_rad, r.range_m, r.alpha_rad, r.time_s]
            .iter()
            .all(|v| v.is_finite());
        if !finite || r.range_m < 0.0 || self.last_profile.is_some_and(|p| r.profile < p) {
            let msg = format!(
                "refusing to write a non-finite, negative-range or counter-decreasing return: {r:?}"
            );
            return Err(Error::bad_record(
                self.out.path(),
                format!("return {}", self.count),
                msg,
            ));
        }
        self.line.clear();
        let l = &mut self.line;
        let _ = write!(
            l,
            "{},{},{},{}",
            r.profile, r.beta_rad, r.range_m, r.intensity
        );
        if self.columns.alpha {
            let _ = write!(l, ",{}", r.alpha_rad);
        }
        if self.columns.time {
            let _ = write!(l, ",{}", r.time_s);
        }
        l.push('\n');
        self.last_profile = Some(r.profile);
        self.count += 1;
        self.out
            .writer()
            .write_all(self.line.as_bytes())
            .map_err(|e| Error::io(self.out.path(), e))
    }

    /// Finishes the file atomically; returns the number of returns written.
    pub fn finish(self) -> Result<u64> {
        self.out.commit()?;
        Ok(self.count)
    }
}

#[cfg(test)]
mod record_lines_tests {
    use super::RecordLines;

    #[test]
    fn lines_of_records_across_blank_lines() {
        // Header on line 1, records 0..3 on lines 2..4, a blank line, records 3.. from line 6.
        let mut m = RecordLines::default();
        for (record, line) in [(0, 2), (1, 3), (2, 4), (3, 6), (4, 7)] {
            m.push(record, line);
        }
        let lines: Vec<u64> = (0..6).map(|r| m.line_of(r)).collect();
        assert_eq!(lines, [2, 3, 4, 6, 7, 8]);
        assert_eq!(m.steps.len(), 2);
    }
}
