//! kinescan's one CSV reader, shared by every CSV format: a streaming line reader with 1-based
//! line numbers, exact header checking, field parsers whose errors name the file, the line and
//! the column, and [`CsvTable`] for the small tables read whole with columns looked up by name.

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
    let cols: Vec<&str> = fields(&header).collect();
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

/// The trimmed, comma-separated fields of a line (kinescan's CSV has no quoting).
pub(crate) fn fields(line: &str) -> impl Iterator<Item = &str> {
    line.split(',').map(str::trim)
}

/// Splits the current line into exactly `out.len()` trimmed fields.
pub(crate) fn split_fields<'a, R: BufRead>(lines: &'a Lines<R>, out: &mut [&'a str]) -> Result<()> {
    let mut count = 0;
    for f in fields(lines.line()) {
        if let Some(slot) = out.get_mut(count) {
            *slot = f;
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

/// A small CSV table read whole (a few hundred lines): columns looked up by name (optional
/// ones allowed), rows with their 1-based line numbers for messages.
pub(crate) struct CsvTable {
    path: PathBuf,
    columns: Vec<String>,
    rows: Vec<(usize, Vec<String>)>,
}

impl CsvTable {
    /// Reads `path` through [`Lines`]: the first non-blank line is the header, blank lines are
    /// skipped, every row has the header's number of fields.
    pub(crate) fn read(path: &Path) -> Result<Self> {
        let mut lines = Lines::open(path)?;
        let header = lines
            .header()?
            .ok_or_else(|| Error::bad_file(path, "empty file"))?;
        let columns: Vec<String> = fields(&header).map(str::to_string).collect();
        let mut rows = Vec::new();
        while lines.advance()? {
            let row: Vec<String> = fields(lines.line()).map(str::to_string).collect();
            if row.len() != columns.len() {
                let msg = format!(
                    "{} fields where the header has {}",
                    row.len(),
                    columns.len()
                );
                return Err(Error::bad_record(path, lines.at(), msg));
            }
            rows.push((lines.line_no() as usize, row));
        }
        Ok(Self {
            path: path.to_path_buf(),
            columns,
            rows,
        })
    }

    /// Index of column `name`, or an error naming the file and the missing column.
    pub(crate) fn column(&self, name: &str) -> Result<usize> {
        self.optional_column(name).ok_or_else(|| {
            let msg = format!(
                "missing column `{name}` (header: {})",
                self.columns.join(",")
            );
            Error::bad_file(&self.path, msg)
        })
    }

    /// Index of column `name` if present.
    pub(crate) fn optional_column(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|c| c == name)
    }

    /// Rows with their 1-based line numbers.
    pub(crate) fn rows(&self) -> impl Iterator<Item = (usize, &[String])> {
        self.rows.iter().map(|(l, f)| (*l, f.as_slice()))
    }

    /// Parses field `col` of a row as a finite f64; empty gives `None`.
    pub(crate) fn opt_f64(&self, line: usize, row: &[String], col: usize) -> Result<Option<f64>> {
        let s = &row[col];
        if s.is_empty() {
            return Ok(None);
        }
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            _ => {
                let msg = format!("`{}` = `{s}` is not a finite number", self.columns[col]);
                Err(self.bad(line, msg))
            }
        }
    }

    /// Parses field `col` as a required finite f64.
    pub(crate) fn f64(&self, line: usize, row: &[String], col: usize) -> Result<f64> {
        self.opt_f64(line, row, col)?
            .ok_or_else(|| self.bad(line, format!("`{}` is empty", self.columns[col])))
    }

    /// Parses field `col` as an unsigned integer.
    pub(crate) fn u64(&self, line: usize, row: &[String], col: usize) -> Result<u64> {
        row[col].parse::<u64>().map_err(|_| {
            let msg = format!("`{}` = `{}` is not an integer", self.columns[col], row[col]);
            self.bad(line, msg)
        })
    }

    /// A [`Error::BadRecord`] for `line` of this file.
    pub(crate) fn bad(&self, line: usize, problem: impl Into<String>) -> Error {
        Error::bad_record(&self.path, format!("line {line}"), problem)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> Result<CsvTable> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        std::fs::write(&path, text).unwrap();
        CsvTable::read(&path)
    }

    #[test]
    fn tables_follow_the_shared_line_rules() {
        let t = table("\u{feff}site, x_m ,note\r\n\n1,2.5,\r\n2,-1,a\n").unwrap();
        let (site, x, note) = (t.column("site").unwrap(), t.column("x_m").unwrap(), 2);
        let rows: Vec<_> = t.rows().collect();
        assert_eq!(rows.len(), 2);
        let (line, row) = rows[0];
        assert_eq!(line, 3, "blank line 2 skipped, line numbers kept");
        assert_eq!(t.u64(line, row, site).unwrap(), 1);
        assert_eq!(t.f64(line, row, x).unwrap(), 2.5);
        assert_eq!(t.opt_f64(line, row, note).unwrap(), None);
        assert!(t.optional_column("sigma_m").is_none());
        let e = t.column("sigma_m").unwrap_err().to_string();
        assert!(
            e.contains("t.csv") && e.contains("missing column `sigma_m`"),
            "{e}"
        );
        let e = t.f64(4, rows[1].1, note).unwrap_err().to_string();
        assert!(
            e.contains("line 4: `note` = `a` is not a finite number"),
            "{e}"
        );
    }

    #[test]
    fn table_errors_name_the_line() {
        let e = |text: &str| table(text).err().unwrap().to_string();
        assert!(e("a,b\n1\n").contains("line 2: 1 fields where the header has 2"));
        assert!(e("a,b\n1,2").contains("line 2: the last line has no newline"));
        assert!(e("\n\n").contains("empty file"));
    }
}
