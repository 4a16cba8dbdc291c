//! Small shared pieces of kinescan's CSV readers and writers: a streaming line reader with
//! 1-based line numbers, exact header checking, and field parsers whose errors name the file,
//! the line and the column.

use crate::{Error, Result};
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

/// Streams the lines of a text file, one reused buffer, never the whole file in memory.
pub(crate) struct Lines<R> {
    path: PathBuf,
    reader: R,
    buf: String,
    line_no: u64,
}

impl Lines<BufReader<File>> {
    /// Opens `path` for line-by-line reading.
    pub(crate) fn open(path: &Path) -> Result<Self> {
        let f = File::open(path).map_err(|e| Error::io(path, e))?;
        Ok(Lines::new(path, BufReader::with_capacity(1 << 20, f)))
    }
}

impl<R: BufRead> Lines<R> {
    /// Reads from `reader`; `path` is only used in messages.
    pub(crate) fn new(path: &Path, reader: R) -> Self {
        Lines {
            path: path.to_path_buf(),
            reader,
            buf: String::new(),
            line_no: 0,
        }
    }

    /// File path (for messages).
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    /// 1-based number of the line last returned.
    pub(crate) fn line_no(&self) -> u64 {
        self.line_no
    }

    /// `"line N"` for the line last returned.
    pub(crate) fn at(&self) -> String {
        format!("line {}", self.line_no)
    }

    /// Advances to the next non-blank line; false at the end of the file. The line is then
    /// available from [`Lines::line`].
    pub(crate) fn advance(&mut self) -> Result<bool> {
        loop {
            self.buf.clear();
            let n = self.reader.read_line(&mut self.buf).map_err(|e| {
                let msg = format!("line {}: {e}", self.line_no + 1);
                Error::bad_file(&self.path, msg)
            })?;
            if n == 0 {
                return Ok(false);
            }
            self.line_no += 1;
            if self.buf.trim().is_empty() {
                continue;
            }
            if !self.buf.ends_with('\n') {
                let msg = "the last line has no newline: the file may be cut short inside it \
                           (if the line is complete, end it with a newline)";
                return Err(Error::bad_record(&self.path, self.at(), msg));
            }
            return Ok(true);
        }
    }

    /// The current line without its terminator (and without a UTF-8 BOM on line 1).
    pub(crate) fn line(&self) -> &str {
        let s = self.buf.trim_end_matches(['\n', '\r']);
        if self.line_no == 1 {
            s.trim_start_matches('\u{feff}')
        } else {
            s
        }
    }

    /// The header line (the first non-blank line), or `None` for an empty file.
    pub(crate) fn header(&mut self) -> Result<Option<String>> {
        Ok(self.advance()?.then(|| self.line().to_string()))
    }
}

/// Checks a header line: exactly `required` in order, then any subset of `optional` in the
/// order given. Returns which optional columns are present. Any other column is refused by
/// name.
pub(crate) fn check_header(
    path: &Path,
    header: Option<String>,
    required: &[&str],
    optional: &[&str],
) -> Result<Vec<bool>> {
    let expected = || {
        let opt: String = optional.iter().map(|o| format!("[,{o}]")).collect();
        format!("{}{opt}", required.join(","))
    };
    let Some(header) = header else {
        return Err(Error::bad_file(
            path,
            format!("empty file: expected the header `{}`", expected()),
        ));
    };
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    for (k, want) in required.iter().enumerate() {
        match cols.get(k) {
            Some(c) if c == want => {}
            Some(c) => {
                let msg = format!(
                    "line 1: header column {} is `{c}` where `{want}` is expected \
                     (header must be `{}`)",
                    k + 1,
                    expected()
                );
                return Err(Error::bad_file(path, msg));
            }
            None => {
                let msg = format!(
                    "line 1: header lacks column `{want}` (header must be `{}`)",
                    expected()
                );
                return Err(Error::bad_file(path, msg));
            }
        }
    }
    let mut present = vec![false; optional.len()];
    let mut next_opt = 0;
    for c in &cols[required.len()..] {
        match optional[next_opt..].iter().position(|o| o == c) {
            Some(p) => {
                present[next_opt + p] = true;
                next_opt += p + 1;
            }
            None => {
                let msg = format!(
                    "line 1: unknown or misplaced column `{c}` (header must be `{}`)",
                    expected()
                );
                return Err(Error::bad_file(path, msg));
            }
        }
    }
    Ok(present)
}

/// Splits the current line into exactly `out.len()` trimmed fields.
pub(crate) fn split_fields<'a, R: BufRead>(lines: &'a Lines<R>, out: &mut [&'a str]) -> Result<()> {
    let mut count = 0;
    for f in lines.line().split(',') {
        if let Some(slot) = out.get_mut(count) {
            *slot = f.trim();
        }
        count += 1;
    }
    if count != out.len() {
        let msg = format!("{count} fields where the header has {}", out.len());
        return Err(Error::bad_record(lines.path(), lines.at(), msg));
    }
    Ok(())
}

/// Parses a finite f64 from column `name`.
pub(crate) fn finite_f64<R: BufRead>(lines: &Lines<R>, name: &str, field: &str) -> Result<f64> {
    let bad = |what: String| Error::bad_record(lines.path(), lines.at(), what);
    let v: f64 = field
        .parse()
        .map_err(|_| bad(format!("{name} `{field}` is not a number")))?;
    if !v.is_finite() {
        return Err(bad(format!("{name} is {field} (not finite)")));
    }
    Ok(v)
}

/// Parses an identifier: non-empty, without quotes.
pub(crate) fn identifier<R: BufRead>(lines: &Lines<R>, field: &str) -> Result<String> {
    if field.is_empty() || field.contains('"') {
        let msg = format!("id `{field}` must be non-empty and unquoted");
        return Err(Error::bad_record(lines.path(), lines.at(), msg));
    }
    Ok(field.to_string())
}

/// Refuses an id a CSV writer could not write unambiguously.
pub(crate) fn check_writable_id(path: &Path, index: usize, id: &str) -> Result<()> {
    let bad = id.is_empty()
        || id != id.trim()
        || id.contains([',', '"', '\n', '\r'])
        || id.starts_with('\u{feff}');
    if bad {
        let msg = format!("id {id:?} is empty or holds a comma, quote, newline or edge space");
        return Err(Error::bad_record(path, format!("item {index}"), msg));
    }
    Ok(())
}

/// Checks a geodetic position given in degrees and returns it in radians.
pub(crate) fn lat_lon_rad<R: BufRead>(
    lines: &Lines<R>,
    lat_deg: f64,
    lon_deg: f64,
) -> Result<(f64, f64)> {
    let bad = |what: String| Error::bad_record(lines.path(), lines.at(), what);
    if lat_deg.abs() > 90.0 {
        return Err(bad(format!("lat_deg {lat_deg} is outside [-90, 90]")));
    }
    if lon_deg.abs() > 180.0 {
        return Err(bad(format!("lon_deg {lon_deg} is outside [-180, 180]")));
    }
    Ok((lat_deg.to_radians(), lon_deg.to_radians()))
}

/// Tracks ids already seen, for duplicate detection with the first line of each id.
#[derive(Default)]
pub(crate) struct SeenIds(std::collections::HashMap<String, u64>);

impl SeenIds {
    /// Refuses an id seen before, naming both lines.
    pub(crate) fn insert<R: BufRead>(&mut self, lines: &Lines<R>, id: &str) -> Result<()> {
        if let Some(first) = self.0.insert(id.to_string(), lines.line_no()) {
            let msg = format!("duplicate id `{id}` (first on line {first})");
            return Err(Error::bad_record(lines.path(), lines.at(), msg));
        }
        Ok(())
    }
}
