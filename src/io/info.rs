//! `kinescan info`: recognise an input file and summarise it (counts, time span, rate, gaps,
//! ranges), streaming so multi-GB files cost one or two passes and bounded memory.
//!
//! Recognition: the `LASF` signature means a LAS, LAZ or COPC file (its header and VLRs are
//! read by `io::las::read`, not its points); the `KSPROF01` magic means binary profiles; a text file whose first line is
//! a kinescan CSV header means CSV profiles, control points or patches; otherwise the file is
//! taken as SBET (136-byte records) or SMRMSG (80-byte records) from its name (`.sbet`,
//! `sbet*`, `.smrmsg`, `smrmsg*`) or, failing that, from its size and the plausibility of its
//! first records. When both readings remain possible the file is refused as ambiguous. Raw
//! IMU and GNSS records (docs/formats.md: 56-byte records, no header) are recognised by name
//! only (`imu*`, `*.imu`; `gnss*`, `*.gnss`, as the simulator writes `imu.bin`, `gnss.bin`).

use super::gnss::GnssFile;
use super::imu::ImuFile;
use super::las::inspect::{is_las, read_header, LasHeaderInfo};
use super::mapped::f64_le;
use super::patches::{read_patches, PATCHES_HEADER};
use super::points::read_control_points;
use super::profiles::{ProfileColumns, ProfileFile, RawReturn, PROFILE_MAGIC};
use super::profiles_csv::{yes_no, ProfileCsvReader, ProfileTally};
use super::sbet::{SbetFile, SBET_RECORD_BYTES};
use super::smrmsg::{SmrmsgFile, SMRMSG_RECORD_BYTES};
use crate::{Error, Result};
use std::fmt;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

/// A gap counts when an interval exceeds this multiple of the median interval.
pub const GAP_FACTOR: f64 = 1.5;
/// How many of the largest gaps are listed.
pub const LISTED_GAPS: usize = 5;
/// The median interval is taken over at most this many evenly spread intervals.
const MEDIAN_SAMPLE: usize = 200_000;

/// What kind of file was recognised.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FileKind {
    /// Applanix SBET trajectory.
    Sbet,
    /// Applanix SMRMSG accuracy.
    Smrmsg,
    /// kinescan binary profiles.
    ProfilesBinary,
    /// CSV profiles.
    ProfilesCsv,
    /// Control / sync points CSV.
    ControlPoints,
    /// Reference planar patches CSV.
    Patches,
    /// LAS, LAZ or COPC point cloud.
    Las,
    /// Raw IMU records.
    Imu,
    /// Raw GNSS position fixes.
    Gnss,
}

/// Ranges over raw IMU records (min, max per body axis x, y, z).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ImuRanges {
    /// Specific force (m/s^2).
    pub specific_force_mps2: [(f64, f64); 3],
    /// Angular rate (deg/s).
    pub rate_dps: [(f64, f64); 3],
}

/// Ranges over raw GNSS fixes.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GnssRanges {
    /// Latitude min, max (deg).
    pub lat_deg: (f64, f64),
    /// Longitude min, max (deg).
    pub lon_deg: (f64, f64),
    /// Ellipsoidal height min, max (m).
    pub h_m: (f64, f64),
    /// North, east, down 1-sigma min, max (m).
    pub sigma_m: [(f64, f64); 3],
}

/// One time gap: an interval longer than [`GAP_FACTOR`] times the median.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Gap {
    /// Time of the record before the gap (s).
    pub after_s: f64,
    /// Length of the interval (s).
    pub interval_s: f64,
}

/// Time coverage of a time-series file (times in the file's own time scale, s).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TimeInfo {
    /// First time (s).
    pub start_s: f64,
    /// Last time (s).
    pub end_s: f64,
    /// end - start (s).
    pub span_s: f64,
    /// Median record interval (s); 0 for a single record.
    pub median_interval_s: f64,
    /// 1 / median interval (Hz); 0 for a single record.
    pub median_rate_hz: f64,
    /// Intervals longer than 1.5 x the median.
    pub gap_count: u64,
    /// The largest gaps, longest first.
    pub largest_gaps: Vec<Gap>,
}

/// Ranges over an SBET trajectory.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SbetRanges {
    /// Latitude min, max (deg).
    pub lat_deg: (f64, f64),
    /// Longitude min, max (deg).
    pub lon_deg: (f64, f64),
    /// Ellipsoidal height min, max (m).
    pub h_m: (f64, f64),
    /// 3D speed |v| min, max (m/s).
    pub speed_mps: (f64, f64),
    /// Roll min, max (deg).
    pub roll_deg: (f64, f64),
    /// Pitch min, max (deg).
    pub pitch_deg: (f64, f64),
    /// True heading (platform heading minus wander angle, wrapped to -180..180) min, max (deg).
    pub heading_deg: (f64, f64),
    /// Largest body angular rate magnitude per axis x, y, z (deg/s).
    pub max_abs_rate_dps: [f64; 3],
}

/// Ranges of the RMS values of an SMRMSG file (min, max each).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SmrmsgRanges {
    /// North, east, down position RMS (m).
    pub position_m: [(f64, f64); 3],
    /// North, east, down velocity RMS (m/s).
    pub velocity_mps: [(f64, f64); 3],
    /// Roll, pitch, heading RMS (arc-minutes).
    pub attitude_arcmin: [(f64, f64); 3],
}

/// Summary of a profile source.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ProfileInfo {
    /// Optional columns present.
    pub columns: ProfileColumns,
    /// Counts, counter range, jumps and wraps, beta range.
    pub tally: ProfileTally,
    /// Hardware time tag range (s), when the time column is present.
    pub time_range_s: Option<(f64, f64)>,
    /// Returns a run rejects for their values (a non-finite field or a negative range; binary
    /// files only: the CSV reader refuses them), counted like `run` counts them.
    pub invalid_returns: u64,
    /// The first of them: "record N: what is wrong".
    pub first_invalid: Option<String>,
}

/// What `kinescan info` reports about one file.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FileInfo {
    /// The file.
    pub path: String,
    /// Recognised kind.
    pub kind: FileKind,
    /// Size (bytes).
    pub size_bytes: u64,
    /// Records (binary), returns (profiles) or data lines (points, patches).
    pub records: u64,
    /// Time coverage (SBET, SMRMSG).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<TimeInfo>,
    /// Position, speed, attitude and rate ranges (SBET).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sbet: Option<SbetRanges>,
    /// RMS ranges (SMRMSG).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smrmsg: Option<SmrmsgRanges>,
    /// Header, CRS and extra dimensions (LAS, LAZ, COPC).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub las: Option<LasHeaderInfo>,
    /// Profile summary (binary or CSV profiles).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub profiles: Option<ProfileInfo>,
    /// Specific force and rate ranges (raw IMU).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub imu: Option<ImuRanges>,
    /// Position and sigma ranges (raw GNSS).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gnss: Option<GnssRanges>,
}

/// Recognises `path` and summarises it; the file is fully validated by its reader first.
pub fn describe(path: &Path) -> Result<FileInfo> {
    let size_bytes = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    let kind = detect(path, size_bytes)?;
    let mut info = FileInfo {
        path: path.display().to_string(),
        kind,
        size_bytes,
        records: 0,
        time: None,
        sbet: None,
        smrmsg: None,
        las: None,
        profiles: None,
        imu: None,
        gnss: None,
    };
    match kind {
        FileKind::Sbet => {
            let f = SbetFile::open(path)?;
            info.records = f.len() as u64;
            info.time = Some(time_info(f.len(), |i| f.time_s(i)));
            info.sbet = Some(sbet_ranges(&f));
        }
        FileKind::Smrmsg => {
            let f = SmrmsgFile::open(path)?;
            info.records = f.len() as u64;
            info.time = Some(time_info(f.len(), |i| f.time_s(i)));
            info.smrmsg = Some(smrmsg_ranges(&f));
        }
        FileKind::Las => {
            let h = read_header(path)?;
            info.records = h.points;
            info.las = Some(h);
        }
        FileKind::ProfilesBinary => {
            let f = ProfileFile::open(path)?;
            let mut invalid = (0u64, None);
            let valid = (0..f.len()).filter_map(|i| match f.get_checked(i) {
                Ok(r) => Some(Ok((r, i as u64))),
                Err(e) => {
                    invalid.0 += 1;
                    if let Error::BadRecord { at, problem, .. } = e {
                        invalid.1.get_or_insert(format!("{at}: {problem}"));
                    }
                    None
                }
            });
            let mut p = profile_info(f.columns(), valid)?;
            (p.invalid_returns, p.first_invalid) = invalid;
            info.records = f.len() as u64;
            info.profiles = Some(p);
        }
        FileKind::ProfilesCsv => {
            let mut r = ProfileCsvReader::open(path)?;
            let columns = r.columns();
            let items = std::iter::from_fn(|| {
                let item = r.next()?;
                Some(item.map(|ret| (ret, r.line_no())))
            });
            let p = profile_info(columns, items)?;
            info.records = p.tally.returns;
            info.profiles = Some(p);
        }
        FileKind::Imu => {
            let f = ImuFile::open(path)?;
            info.records = f.len() as u64;
            info.time = Some(time_info(f.len(), |i| f.time_s(i)));
            let (mut lo, mut hi) = ([f64::INFINITY; 6], [f64::NEG_INFINITY; 6]);
            for i in 0..f.len() {
                let r = f.record(i);
                let v = [r.f_b, r.w_b.map(f64::to_degrees)].concat();
                for k in 0..6 {
                    (lo[k], hi[k]) = (lo[k].min(v[k]), hi[k].max(v[k]));
                }
            }
            info.imu = Some(ImuRanges {
                specific_force_mps2: [0, 1, 2].map(|k| (lo[k], hi[k])),
                rate_dps: [3, 4, 5].map(|k| (lo[k], hi[k])),
            });
        }
        FileKind::Gnss => {
            let f = GnssFile::open(path)?;
            info.records = f.len() as u64;
            info.time = Some(time_info(f.len(), |i| f.time_s(i)));
            let (mut lo, mut hi) = ([f64::INFINITY; 6], [f64::NEG_INFINITY; 6]);
            for i in 0..f.len() {
                let r = f.record(i);
                let v = [
                    r.lat_rad.to_degrees(),
                    r.lon_rad.to_degrees(),
                    r.h_m,
                    r.sigma_ned_m[0],
                    r.sigma_ned_m[1],
                    r.sigma_ned_m[2],
                ];
                for k in 0..6 {
                    (lo[k], hi[k]) = (lo[k].min(v[k]), hi[k].max(v[k]));
                }
            }
            info.gnss = Some(GnssRanges {
                lat_deg: (lo[0], hi[0]),
                lon_deg: (lo[1], hi[1]),
                h_m: (lo[2], hi[2]),
                sigma_m: [3, 4, 5].map(|k| (lo[k], hi[k])),
            });
        }
        FileKind::ControlPoints => info.records = read_control_points(path)?.len() as u64,
        FileKind::Patches => info.records = read_patches(path)?.len() as u64,
    }
    Ok(info)
}

fn detect(path: &Path, size: u64) -> Result<FileKind> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut first = Vec::new();
    BufReader::new(file)
        .take(4096)
        .read_until(b'\n', &mut first)
        .map_err(|e| Error::io(path, e))?;
    if first.starts_with(PROFILE_MAGIC) {
        return Ok(FileKind::ProfilesBinary);
    }
    if is_las(&first) {
        return Ok(FileKind::Las);
    }
    if let Some(kind) = text_kind(&first) {
        return Ok(kind);
    }
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    if name.ends_with(".sbet") || name.starts_with("sbet") {
        return Ok(FileKind::Sbet);
    }
    if name.ends_with(".smrmsg") || name.starts_with("smrmsg") {
        return Ok(FileKind::Smrmsg);
    }
    if name.ends_with(".imu") || name.starts_with("imu") {
        return Ok(FileKind::Imu);
    }
    if name.ends_with(".gnss") || name.starts_with("gnss") {
        return Ok(FileKind::Gnss);
    }
    let sbet =
        size.is_multiple_of(SBET_RECORD_BYTES as u64) && plausible(path, SBET_RECORD_BYTES, true)?;
    let smrmsg = size.is_multiple_of(SMRMSG_RECORD_BYTES as u64)
        && plausible(path, SMRMSG_RECORD_BYTES, false)?;
    match (sbet, smrmsg) {
        (true, false) => Ok(FileKind::Sbet),
        (false, true) => Ok(FileKind::Smrmsg),
        (true, true) => Err(Error::bad_file(
            path,
            "ambiguous: reads as both SBET (136-byte records) and SMRMSG (80-byte records); \
             rename it with a .sbet or .smrmsg extension",
        )),
        (false, false) => Err(Error::bad_file(
            path,
            format!(
                "not recognised: no kinescan profile magic, no known CSV header, and {size} B \
                 is not a plausible SBET (136-byte records) or SMRMSG (80-byte records)"
            ),
        )),
    }
}

/// Kind of a text file from its first line, if it is a known kinescan CSV header.
fn text_kind(first: &[u8]) -> Option<FileKind> {
    let line = std::str::from_utf8(first).ok()?;
    let line = line.trim_start_matches('\u{feff}').trim_end();
    let cols: Vec<&str> = super::csv_text::fields(line).collect();
    let starts = |h: &[&str]| cols.len() >= h.len() && cols[..h.len()] == *h;
    if starts(&super::profiles_csv::PROFILE_CSV_REQUIRED) {
        Some(FileKind::ProfilesCsv)
    } else if starts(&PATCHES_HEADER) {
        Some(FileKind::Patches)
    } else if starts(&super::points::CONTROL_POINTS_HEADER) {
        Some(FileKind::ControlPoints)
    } else {
        None
    }
}

/// Whether the first two records look like SBET (GPS week seconds, latitude and longitude in
/// range, time increasing by < 10 s) or SMRMSG (week seconds, RMS values >= 0, time increasing).
fn plausible(path: &Path, record_bytes: usize, sbet: bool) -> Result<bool> {
    let mut buf = vec![0u8; 2 * record_bytes];
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let n = f.read(&mut buf).map_err(|e| Error::io(path, e))?;
    if n < record_bytes {
        return Ok(false);
    }
    let week_s = |t: f64| (0.0..=604_800.0).contains(&t);
    let rec_ok = |r: &[u8]| {
        let v: Vec<f64> = (0..record_bytes / 8).map(|k| f64_le(r, 8 * k)).collect();
        let finite = v.iter().all(|x| x.is_finite());
        finite
            && week_s(v[0])
            && if sbet {
                v[1].abs() <= std::f64::consts::FRAC_PI_2
                    && v[2].abs() <= 2.0 * std::f64::consts::PI
            } else {
                v[1..].iter().all(|x| *x >= 0.0)
            }
    };
    let first_ok = rec_ok(&buf[..record_bytes]);
    if n < 2 * record_bytes {
        return Ok(first_ok);
    }
    let (t0, t1) = (f64_le(&buf, 0), f64_le(&buf, record_bytes));
    Ok(first_ok && rec_ok(&buf[record_bytes..]) && t1 > t0 && t1 - t0 < 10.0)
}

/// Span, median rate and gaps of `n` increasing times (two passes, bounded memory).
fn time_info(n: usize, time_s: impl Fn(usize) -> f64) -> TimeInfo {
    let (start_s, end_s) = (time_s(0), time_s(n - 1));
    let intervals = n - 1;
    let stride = intervals.div_ceil(MEDIAN_SAMPLE).max(1);
    let mut sample: Vec<f64> = (0..intervals)
        .step_by(stride)
        .map(|i| time_s(i + 1) - time_s(i))
        .collect();
    let median_interval_s = if sample.is_empty() {
        0.0
    } else {
        let mid = sample.len() / 2;
        *sample.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    let mut gap_count = 0;
    let mut largest_gaps: Vec<Gap> = Vec::with_capacity(LISTED_GAPS + 1);
    for i in 0..intervals {
        let dt = time_s(i + 1) - time_s(i);
        if dt > GAP_FACTOR * median_interval_s {
            gap_count += 1;
            if largest_gaps.len() < LISTED_GAPS || dt > largest_gaps[LISTED_GAPS - 1].interval_s {
                largest_gaps.push(Gap {
                    after_s: time_s(i),
                    interval_s: dt,
                });
                largest_gaps.sort_by(|a, b| b.interval_s.total_cmp(&a.interval_s));
                largest_gaps.truncate(LISTED_GAPS);
            }
        }
    }
    TimeInfo {
        start_s,
        end_s,
        span_s: end_s - start_s,
        median_interval_s,
        median_rate_hz: if median_interval_s > 0.0 {
            1.0 / median_interval_s
        } else {
            0.0
        },
        gap_count,
        largest_gaps,
    }
}

fn sbet_ranges(f: &SbetFile) -> SbetRanges {
    let widen = |r: &mut (f64, f64), v: f64| *r = (r.0.min(v), r.1.max(v));
    let r0 = f.record(0);
    let speed = |r: &super::sbet::SbetRecord| {
        (r.vel_x_mps.powi(2) + r.vel_y_mps.powi(2) + r.vel_z_mps.powi(2)).sqrt()
    };
    let heading = |r: &super::sbet::SbetRecord| {
        crate::geo::rotations::wrap_pi(r.platform_heading_rad - r.wander_rad).to_degrees()
    };
    let both = |v: f64| (v, v);
    let mut out = SbetRanges {
        lat_deg: both(r0.lat_rad.to_degrees()),
        lon_deg: both(r0.lon_rad.to_degrees()),
        h_m: both(r0.alt_m),
        speed_mps: both(speed(&r0)),
        roll_deg: both(r0.roll_rad.to_degrees()),
        pitch_deg: both(r0.pitch_rad.to_degrees()),
        heading_deg: both(heading(&r0)),
        max_abs_rate_dps: [0.0; 3],
    };
    for i in 0..f.len() {
        let r = f.record(i);
        widen(&mut out.lat_deg, r.lat_rad.to_degrees());
        widen(&mut out.lon_deg, r.lon_rad.to_degrees());
        widen(&mut out.h_m, r.alt_m);
        widen(&mut out.speed_mps, speed(&r));
        widen(&mut out.roll_deg, r.roll_rad.to_degrees());
        widen(&mut out.pitch_deg, r.pitch_rad.to_degrees());
        widen(&mut out.heading_deg, heading(&r));
        let rates = [r.rate_x_radps, r.rate_y_radps, r.rate_z_radps];
        for (m, v) in out.max_abs_rate_dps.iter_mut().zip(rates) {
            *m = m.max(v.to_degrees().abs());
        }
    }
    out
}

fn smrmsg_ranges(f: &SmrmsgFile) -> SmrmsgRanges {
    let mut lo = [f64::INFINITY; 9];
    let mut hi = [f64::NEG_INFINITY; 9];
    for i in 0..f.len() {
        let a = f.record(i).to_array();
        for k in 0..9 {
            lo[k] = lo[k].min(a[k + 1]);
            hi[k] = hi[k].max(a[k + 1]);
        }
    }
    let three = |first: usize| [0, 1, 2].map(|k| (lo[first + k], hi[first + k]));
    SmrmsgRanges {
        position_m: three(0),
        velocity_mps: three(3),
        attitude_arcmin: three(6),
    }
}

fn profile_info(
    columns: ProfileColumns,
    items: impl Iterator<Item = Result<(RawReturn, u64)>>,
) -> Result<ProfileInfo> {
    let mut tally = ProfileTally::default();
    let mut time_range_s: Option<(f64, f64)> = None;
    for item in items {
        let (r, at) = item?;
        tally.add(&r, at);
        if columns.time {
            let (lo, hi) = time_range_s.unwrap_or((r.time_s, r.time_s));
            time_range_s = Some((lo.min(r.time_s), hi.max(r.time_s)));
        }
    }
    Ok(ProfileInfo {
        columns,
        tally,
        time_range_s,
        invalid_returns: 0,
        first_invalid: None,
    })
}

impl fmt::Display for FileInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match self.kind {
            FileKind::Sbet => "Applanix SBET trajectory",
            FileKind::Smrmsg => "Applanix SMRMSG accuracy",
            FileKind::ProfilesBinary => "kinescan binary profiles",
            FileKind::ProfilesCsv => "CSV profiles",
            FileKind::ControlPoints => "control points (CSV)",
            FileKind::Patches => "reference planar patches (CSV)",
            FileKind::Imu => "raw IMU records",
            FileKind::Gnss => "raw GNSS positions",
            FileKind::Las => match &self.las {
                Some(h) if h.copc => "COPC point cloud",
                Some(h) if h.compressed => "LAZ point cloud",
                _ => "LAS point cloud",
            },
        };
        writeln!(f, "{}: {kind}, {} B", self.path, self.size_bytes)?;
        write!(f, "  records: {}", self.records)?;
        if let Some(t) = &self.time {
            write!(f, "\n{t}")?;
        }
        if let Some(s) = &self.sbet {
            write!(
                f,
                "\n  lat {:.7} .. {:.7} deg, lon {:.7} .. {:.7} deg\n  height {:.3} .. {:.3} m, \
                 speed {:.2} .. {:.2} m/s",
                s.lat_deg.0,
                s.lat_deg.1,
                s.lon_deg.0,
                s.lon_deg.1,
                s.h_m.0,
                s.h_m.1,
                s.speed_mps.0,
                s.speed_mps.1
            )?;
            write!(
                f,
                "\n  roll {:.3} .. {:.3} deg, pitch {:.3} .. {:.3} deg, heading {:.3} .. {:.3} \
                 deg\n  largest angular rate x {:.2}, y {:.2}, z {:.2} deg/s",
                s.roll_deg.0,
                s.roll_deg.1,
                s.pitch_deg.0,
                s.pitch_deg.1,
                s.heading_deg.0,
                s.heading_deg.1,
                s.max_abs_rate_dps[0],
                s.max_abs_rate_dps[1],
                s.max_abs_rate_dps[2]
            )?;
        }
        if let Some(s) = &self.smrmsg {
            let r = |v: (f64, f64), scale: f64, digits: usize| {
                format!("{:.digits$} .. {:.digits$}", v.0 * scale, v.1 * scale)
            };
            let [n, e, d] = s.position_m;
            let [vn, ve, vd] = s.velocity_mps;
            let [ro, pi, he] = s.attitude_arcmin;
            write!(
                f,
                "\n  position RMS north {} mm, east {} mm, down {} mm\n  velocity RMS north {}, \
                 east {}, down {} mm/s\n  attitude RMS roll {}, pitch {}, heading {} arcmin",
                r(n, 1e3, 1),
                r(e, 1e3, 1),
                r(d, 1e3, 1),
                r(vn, 1e3, 1),
                r(ve, 1e3, 1),
                r(vd, 1e3, 1),
                r(ro, 1.0, 3),
                r(pi, 1.0, 3),
                r(he, 1.0, 3)
            )?;
        }
        if let Some(m) = &self.imu {
            let r = |v: [(f64, f64); 3], digits: usize| {
                v.map(|(a, b)| format!("{a:.digits$} .. {b:.digits$}"))
                    .join(", ")
            };
            write!(
                f,
                "\n  specific force x, y, z: {} m/s^2\n  angular rate x, y, z: {} deg/s",
                r(m.specific_force_mps2, 3),
                r(m.rate_dps, 3)
            )?;
        }
        if let Some(g) = &self.gnss {
            let [n, e, d] = g
                .sigma_m
                .map(|(a, b)| format!("{:.1} .. {:.1}", a * 1e3, b * 1e3));
            write!(
                f,
                "\n  lat {:.7} .. {:.7} deg, lon {:.7} .. {:.7} deg\n  height {:.3} .. {:.3} m\n  \
                 sigma north {n} mm, east {e} mm, down {d} mm",
                g.lat_deg.0, g.lat_deg.1, g.lon_deg.0, g.lon_deg.1, g.h_m.0, g.h_m.1
            )?;
        }
        if let Some(h) = &self.las {
            write!(f, "\n{}", las_text(h))?;
        }
        if let Some(p) = &self.profiles {
            write!(f, "\n{p}")?;
        }
        Ok(())
    }
}

/// The text of a LAS/LAZ/COPC header for `kinescan info`.
fn las_text(h: &LasHeaderInfo) -> String {
    let mut s = format!(
        "  LAS {}.{}, point format {} ({} B a record){}, software {}, system {}",
        h.version.0,
        h.version.1,
        h.point_format,
        h.record_length,
        if h.compressed {
            ", LASzip compressed"
        } else {
            ""
        },
        if h.software.is_empty() {
            "-"
        } else {
            &h.software
        },
        if h.system.is_empty() { "-" } else { &h.system }
    );
    let returns: Vec<String> = h
        .points_by_return
        .iter()
        .enumerate()
        .filter(|(_, n)| **n > 0)
        .map(|(k, n)| format!("{}: {n}", k + 1))
        .collect();
    s += &format!(
        "\n  points {} (by return {})",
        h.points,
        if returns.is_empty() {
            "-".to_string()
        } else {
            returns.join(", ")
        }
    );
    s += &format!(
        "\n  X {:.3} .. {:.3}, Y {:.3} .. {:.3}, Z {:.3} .. {:.3} (scale {} {} {}, offset {} {} {})",
        h.min[0], h.max[0], h.min[1], h.max[1], h.min[2], h.max[2], h.scale[0], h.scale[1],
        h.scale[2], h.offset[0], h.offset[1], h.offset[2]
    );
    s += &match &h.crs {
        None => "\n  CRS: none stated".to_string(),
        Some(c) => format!(
            "\n  CRS: {}{}{}",
            c.name,
            c.epsg.map_or(String::new(), |e| format!(" (EPSG:{e})")),
            c.vertical_epsg
                .map_or(String::new(), |e| format!(", vertical EPSG:{e}"))
        ),
    };
    s += &format!(
        "\n  GPS time: {}, created day {} of {}",
        if h.adjusted_gps_time {
            "adjusted standard"
        } else {
            "week seconds"
        },
        h.created.0,
        h.created.1
    );
    let dims: Vec<&str> = h.extra_dims.iter().map(|d| d.name.as_str()).collect();
    s += &format!(
        "\n  extra dimensions ({}): {}",
        dims.len(),
        if dims.is_empty() {
            "-".to_string()
        } else {
            dims.join(", ")
        }
    );
    s
}

impl fmt::Display for TimeInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "  time {:.6} .. {:.6} s (span {:.3} s), median rate {:.3} Hz\n  gaps (> {GAP_FACTOR} x \
             median interval): {}",
            self.start_s, self.end_s, self.span_s, self.median_rate_hz, self.gap_count
        )?;
        for g in &self.largest_gaps {
            write!(
                f,
                "\n    {:.3} s after t = {:.6} s",
                g.interval_s, g.after_s
            )?;
        }
        Ok(())
    }
}

impl fmt::Display for ProfileInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (t, c) = (&self.tally, &self.tally.counters);
        let opt = |v: Option<(u32, u32)>| v.map_or("-".into(), |(a, b)| format!("{a} .. {b}"));
        write!(
            f,
            "  returns {} (missing {}), profiles {}, counter {}\n  counter jumps (> 1 profile) {}, \
             wraps/backward steps {}",
            t.returns,
            t.missing_returns,
            c.profiles,
            opt(t.profile_range),
            c.jump_count,
            c.wrap_count
        )?;
        for j in &c.jumps {
            write!(f, "\n    at {}: {} -> {}", j.at, j.from, j.to)?;
        }
        if let Some((lo, hi)) = t.beta_range_rad {
            write!(f, "\n  beta {lo:.6} .. {hi:.6} rad")?;
        }
        write!(
            f,
            "\n  columns: alpha_rad {}, time_s {}",
            yes_no(self.columns.alpha),
            yes_no(self.columns.time)
        )?;
        if let Some((lo, hi)) = self.time_range_s {
            write!(f, "\n  time tags {lo:.6} .. {hi:.6} s")?;
        }
        if self.invalid_returns > 0 {
            write!(
                f,
                "\n  invalid returns (rejected by run) {}, first at {}",
                self.invalid_returns,
                self.first_invalid.as_deref().unwrap_or("-")
            )?;
        }
        Ok(())
    }
}
