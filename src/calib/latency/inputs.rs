//! The lab's CSV files: scanner returns with time tags, table passes, the IMU attitude stream.

use super::estimate::{AttitudeSample, TablePass, TimedReturn};
use crate::io::csv_text::CsvTable;
use crate::io::profiles_csv::ProfileCsvReader;
use crate::{Error, Result};
use std::path::Path;

/// Reads scanner returns (conventions §6 profile CSV, through the shared
/// [`ProfileCsvReader`]: exact header, per-line checks naming the line); `time_s` is required.
/// Missing returns (range 0 or empty) are skipped. `alpha0_rad` is used where there is no
/// `alpha_rad` column.
pub fn read_returns(path: &Path, alpha0_rad: f64) -> Result<Vec<TimedReturn>> {
    let reader = ProfileCsvReader::open(path)?;
    let columns = reader.columns();
    if !columns.time {
        return Err(Error::bad_file(
            path,
            "no `time_s` column: the latency calibration needs the GPS time of each return",
        ));
    }
    let mut out = Vec::new();
    for r in reader {
        let r = r?;
        if r.range_m == 0.0 {
            continue;
        }
        out.push(TimedReturn {
            profile: r.profile.into(),
            time_s: r.time_s,
            alpha_rad: if columns.alpha {
                r.alpha_rad
            } else {
                alpha0_rad
            },
            beta_rad: r.beta_rad,
            range_m: r.range_m,
        });
    }
    Ok(out)
}

/// Reads the table log `pass,t_start_s,t_end_s,table_rate_deg_s`. A zero rate, an empty or
/// reversed interval, or passes out of order are errors naming the line.
pub fn read_passes(path: &Path) -> Result<Vec<TablePass>> {
    let t = CsvTable::read(path)?;
    let (c0, c1, cr) = (
        t.column("t_start_s")?,
        t.column("t_end_s")?,
        t.column("table_rate_deg_s")?,
    );
    t.column("pass")?;
    let mut out: Vec<TablePass> = Vec::new();
    for (line, f) in t.rows() {
        let p = TablePass {
            t_start_s: t.f64(line, f, c0)?,
            t_end_s: t.f64(line, f, c1)?,
            rate_rad_s: t.f64(line, f, cr)?.to_radians(),
        };
        if p.rate_rad_s == 0.0 {
            return Err(t.bad(line, "zero table speed: latency needs the table turning"));
        }
        if p.t_end_s <= p.t_start_s {
            return Err(t.bad(line, "t_end_s must be after t_start_s"));
        }
        if out.last().is_some_and(|q| p.t_start_s < q.t_end_s) {
            return Err(t.bad(line, "pass starts before the previous one ends"));
        }
        out.push(p);
    }
    if out.is_empty() {
        return Err(Error::bad_file(path, "no table passes"));
    }
    Ok(out)
}

/// Reads the IMU attitude stream `time_s,roll_deg,pitch_deg,heading_deg`.
pub fn read_attitude(path: &Path) -> Result<Vec<AttitudeSample>> {
    let t = CsvTable::read(path)?;
    let cols = [
        t.column("time_s")?,
        t.column("roll_deg")?,
        t.column("pitch_deg")?,
        t.column("heading_deg")?,
    ];
    let mut out: Vec<AttitudeSample> = Vec::new();
    for (line, f) in t.rows() {
        let mut v = [0.0; 4];
        for (k, &c) in cols.iter().enumerate() {
            v[k] = t.f64(line, f, c)?;
        }
        let s = AttitudeSample {
            time_s: v[0],
            roll_rad: v[1].to_radians(),
            pitch_rad: v[2].to_radians(),
            heading_rad: v[3].to_radians(),
        };
        if out.last().is_some_and(|q| s.time_s <= q.time_s) {
            return Err(t.bad(line, "time_s not strictly increasing"));
        }
        out.push(s);
    }
    if out.len() < 2 {
        return Err(Error::bad_file(path, "fewer than 2 attitude records"));
    }
    Ok(out)
}
