//! Files of the calibration commands: the CSV tables a lab records (configs are read by
//! `io::config_file`).
//!
//! Scanner returns are read by the shared conventions §6 reader (`io::profiles_csv`) and outputs are
//! written through `io::atomic`. The calibration-only tables below use the small [`CsvTable`]:
//! the shared line reader and field parsers (`io::csv_text`) are private to `io`, and those
//! tables are a few hundred lines read whole, with optional columns looked up by name.
//!
//! Formats (documented for users in `docs/calibration.md`):
//! - scanner returns: conventions §6 profile CSV `profile,beta_rad,range_m,intensity[,alpha_rad][,time_s]`;
//!   the latency calibration needs `time_s` (GPS time of the return, s).
//! - table passes: `pass,t_start_s,t_end_s,table_rate_deg_s` (signed rate about the table axis).
//! - IMU attitude stream: `time_s,roll_deg,pitch_deg,heading_deg` (convention attitude angles).
//! - tripod ellipse centres: `site,leg,y_s_m,z_s_m,sigma_m` (scan-plane coordinates, s frame).
//! - tripod sites: `site,roll_deg,pitch_deg,heading_deg,sigma_roll_deg,sigma_pitch_deg,
//!   sigma_heading_deg` (IMU attitude averaged over the static scan).

use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// A CSV table read whole: column names and rows of fields with their 1-based line numbers.
pub struct CsvTable {
    path: PathBuf,
    columns: Vec<String>,
    rows: Vec<(usize, Vec<String>)>,
}

impl CsvTable {
    /// Reads `path`; the first line is the header. Blank lines are skipped.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let (_, header) = lines
            .next()
            .ok_or_else(|| Error::bad_file(path, "empty file"))?;
        let columns: Vec<String> = header.split(',').map(|s| s.trim().to_string()).collect();
        let mut rows = Vec::new();
        for (i, line) in lines {
            let fields: Vec<String> = line.split(',').map(|s| s.trim().to_string()).collect();
            if fields.len() != columns.len() {
                return Err(Error::bad_record(
                    path,
                    format!("line {}", i + 1),
                    format!("{} fields, header has {}", fields.len(), columns.len()),
                ));
            }
            rows.push((i + 1, fields));
        }
        Ok(Self {
            path: path.to_path_buf(),
            columns,
            rows,
        })
    }

    /// Index of column `name`, or an error naming the file and the missing column.
    pub fn column(&self, name: &str) -> Result<usize> {
        self.columns.iter().position(|c| c == name).ok_or_else(|| {
            Error::bad_file(
                &self.path,
                format!(
                    "missing column `{name}` (header: {})",
                    self.columns.join(",")
                ),
            )
        })
    }

    /// Index of column `name` if present.
    pub fn optional_column(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|c| c == name)
    }

    /// Rows with their 1-based line numbers.
    pub fn rows(&self) -> impl Iterator<Item = (usize, &[String])> {
        self.rows.iter().map(|(l, f)| (*l, f.as_slice()))
    }

    /// Parses field `col` of a row as a finite f64; empty gives `None`.
    pub fn opt_f64(&self, line: usize, fields: &[String], col: usize) -> Result<Option<f64>> {
        let s = &fields[col];
        if s.is_empty() {
            return Ok(None);
        }
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            _ => Err(self.bad(
                line,
                format!("`{}` = `{s}` is not a finite number", self.columns[col]),
            )),
        }
    }

    /// Parses field `col` as a required finite f64.
    pub fn f64(&self, line: usize, fields: &[String], col: usize) -> Result<f64> {
        self.opt_f64(line, fields, col)?
            .ok_or_else(|| self.bad(line, format!("`{}` is empty", self.columns[col])))
    }

    /// Parses field `col` as an unsigned integer.
    pub fn u64(&self, line: usize, fields: &[String], col: usize) -> Result<u64> {
        fields[col].parse::<u64>().map_err(|_| {
            self.bad(
                line,
                format!(
                    "`{}` = `{}` is not an integer",
                    self.columns[col], fields[col]
                ),
            )
        })
    }

    /// A [`Error::BadRecord`] for `line` of this file.
    pub fn bad(&self, line: usize, problem: impl Into<String>) -> Error {
        Error::bad_record(&self.path, format!("line {line}"), problem)
    }

    /// The file read.
    pub fn path(&self) -> &Path {
        &self.path
    }
}
