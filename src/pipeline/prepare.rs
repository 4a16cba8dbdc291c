//! Stage 2, **prepare**: the inputs opened and checked before any computation. The trajectory
//! (SBET, SMRMSG) is opened and validated, the output frame fixed, binary profile files are
//! memory-mapped and CSV profile files imported into a temporary binary file beside the output
//! (removed when the [`Prepared`] value is dropped).

use super::config::{FrameConfig, LoadedPipeline, PipelineConfig};
use crate::geo::geoid::GeoidGrid;
use crate::geo::projection::MapFrame;
use crate::io::digest::FileRecord;
use crate::io::profiles::ProfileFile;
use crate::io::profiles_csv::RecordLines;
use crate::trajectory::Trajectory;
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// One profile file ready to be read.
#[derive(Debug)]
pub struct PreparedInput {
    /// The file named in the pipeline (a CSV file when imported).
    pub original: PathBuf,
    /// The binary file read (the import of a CSV file).
    pub file: ProfileFile,
    /// Point source id of its points.
    pub point_source_id: u16,
    /// The CSV line of every record of an imported CSV file (`None` for a binary file), to
    /// name the user's line in messages ([`on_user_line`]).
    pub record_lines: Option<RecordLines>,
}

/// Everything opened for a run.
#[derive(Debug)]
pub struct Prepared {
    /// The trajectory (and accuracy file).
    pub traj: Trajectory,
    /// The output mapping frame.
    pub frame: MapFrame,
    /// The geoid grid of `output.geoid` (orthometric heights), checked to cover the survey.
    pub geoid: Option<GeoidGrid>,
    /// The profile files, in pipeline order.
    pub inputs: Vec<PreparedInput>,
    /// The pipeline, trajectory and accuracy files, hashed for the report.
    pub files: Vec<FileRecord>,
    /// Folder of the LAS output (created).
    pub out_dir: PathBuf,
    /// Holds the imports of CSV files until the run ends.
    _staging: tempfile::TempDir,
}

/// Opens every input of a run and hashes the pipeline, trajectory and geoid files for its
/// report; imports CSV profile files beside the output.
pub fn run(p: &LoadedPipeline) -> Result<Prepared> {
    let prepared = open(p)?;
    let c = &p.config;
    let mut files = vec![
        FileRecord::of("pipeline", &p.path)?,
        FileRecord::of("sbet", &c.inputs.sbet)?,
    ];
    if let Some(s) = &c.inputs.smrmsg {
        files.push(FileRecord::of("smrmsg", s)?);
    }
    if let Some(g) = &c.output.geoid {
        files.push(FileRecord::of("geoid", g)?);
    }
    Ok(Prepared { files, ..prepared })
}

/// [`run`] without hashing any file (`files` empty): a day's passes, whose report lists none.
pub fn open(p: &LoadedPipeline) -> Result<Prepared> {
    let c = &p.config;
    let traj = open_trajectory(c)?;
    let frame = map_frame(&c.output.frame, &traj)?;
    check_frame_near_data(p, &frame, &traj)?;
    let geoid = open_geoid(p, &traj)?;
    let out_dir = c
        .output
        .las
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    std::fs::create_dir_all(&out_dir).map_err(|e| Error::io(&out_dir, e))?;
    let staging = crate::io::atomic::create_temp_dir(&out_dir, "import")?;
    let inputs = open_profiles(c, staging.path())?;
    Ok(Prepared {
        traj,
        frame,
        geoid,
        inputs,
        files: Vec::new(),
        out_dir,
        _staging: staging,
    })
}

/// Opens and checks the trajectory, the frame and every profile file without writing beside
/// the output (CSV files are imported into a temporary folder and so parsed completely).
pub fn check_inputs(p: &LoadedPipeline) -> Result<()> {
    let c = &p.config;
    let traj = open_trajectory(c)?;
    let frame = map_frame(&c.output.frame, &traj)?;
    check_frame_near_data(p, &frame, &traj)?;
    open_geoid(p, &traj)?;
    let staging = tempfile::tempdir().map_err(|e| Error::io(std::env::temp_dir(), e))?;
    open_profiles(c, staging.path())?;
    Ok(())
}

/// Opens and validates the trajectory with the pipeline's options.
pub fn open_trajectory(c: &PipelineConfig) -> Result<Trajectory> {
    let opts = c.trajectory.options();
    Trajectory::open(&c.inputs.sbet, c.inputs.smrmsg.as_deref(), opts)
}

/// The output mapping frame: UTM zone and hemisphere from the first trajectory record unless
/// configured.
pub fn map_frame(f: &FrameConfig, traj: &Trajectory) -> Result<MapFrame> {
    let first = traj.sbet().record(0);
    match *f {
        FrameConfig::Utm { zone, north } => {
            let auto = MapFrame::utm_for(first.lon_rad, first.lat_rad)?;
            let MapFrame::Utm {
                zone: z0,
                north: n0,
            } = auto
            else {
                unreachable!("utm_for gives UTM")
            };
            MapFrame::utm(zone.unwrap_or(z0), north.unwrap_or(n0))
        }
        FrameConfig::Ecef => Ok(MapFrame::Ecef),
        FrameConfig::Enu { .. } => MapFrame::local_enu(f.enu_origin().expect("enu")),
        FrameConfig::Epsg { code } => MapFrame::from_epsg(code),
    }
}

/// Opens the grid of `output.geoid` and checks that it has nodes under every point the
/// scanner can reach from every trajectory record (the range limit plus the range offset and
/// the lever arm), so no point falls outside it; errors name the key and the file.
pub fn open_geoid(p: &LoadedPipeline, traj: &Trajectory) -> Result<Option<GeoidGrid>> {
    let Some(path) = &p.config.output.geoid else {
        return Ok(None);
    };
    let source = p.path.display().to_string();
    let refuse = |problem: String| Error::config(&source, "output.geoid", problem);
    let grid = GeoidGrid::open(path).map_err(|e| refuse(e.to_string()))?;
    let s = &p.config.sensor;
    let reach_m = s.max_range_m * (1.0 + s.range_scale_ppm.abs() * 1e-6)
        + s.range_zero_m.abs()
        + nalgebra::Vector3::from(s.lever_arm_b_m).norm();
    let sbet = traj.sbet();
    let outside = (0..sbet.len())
        .map(|i| sbet.record(i))
        .find(|r| !grid.covers_around(r.lat_rad, r.lon_rad, reach_m));
    if let Some(r) = outside {
        let e = grid.extent();
        return Err(refuse(format!(
            "{}: the grid's nodes cover latitudes {} .. {} deg, longitudes {} .. {} deg, but \
             points up to {reach_m:.0} m (sensor.max_range_m + range offset + lever arm) from \
             the trajectory at t = {:.3} s (lat {:.6}, lon {:.6} deg) would fall outside it; \
             use a grid that covers the survey",
            path.display(),
            e.south_deg,
            e.north_deg,
            e.west_deg,
            e.east_deg,
            r.time_s,
            r.lat_rad.to_degrees(),
            r.lon_rad.to_degrees()
        )));
    }
    Ok(Some(grid))
}

/// Maps binary profile files; CSV files are first imported into `staging`. A file that lacks
/// a column the time model needs is refused here, naming it.
pub fn open_profiles(c: &PipelineConfig, staging: &Path) -> Result<Vec<PreparedInput>> {
    let first_id = c.inputs.first_point_source_id;
    c.inputs
        .profiles
        .iter()
        .enumerate()
        .map(|(k, path)| {
            let is_csv = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
            let (file, record_lines) = if is_csv {
                let bin = staging.join(format!("input{k}.ksprof"));
                let summary = crate::io::profiles_csv::import_csv(path, &bin)?;
                (ProfileFile::open(&bin)?, Some(summary.lines))
            } else {
                let file = ProfileFile::open(path)?;
                file.check_angles()?;
                (file, None)
            };
            if c.time.model.needs_time_tags() && !file.columns().time {
                let msg = format!(
                    "time.model = \"{}\" needs a time_s column, which this file lacks",
                    c.time.model.name()
                );
                return Err(Error::bad_file(path, msg));
            }
            Ok(PreparedInput {
                original: path.to_path_buf(),
                file,
                point_source_id: first_id.saturating_add(k as u16),
                record_lines,
            })
        })
        .collect()
}
/// Farthest a trajectory position may lie from a UTM zone's central meridian (deg): the
/// zone's own 3 deg plus a 1 deg margin (scale error there about 1e-3; beyond it coordinates
/// lose meaning fast: zone 60 at 11.6 E is 180 deg away).
pub const UTM_MAX_OFFSET_DEG: f64 = 4.0;
/// Latitude (deg) beyond which data on the other side of the equator than the configured
/// hemisphere is refused.
const HEMISPHERE_MARGIN_DEG: f64 = 1.0;

/// Refuses a UTM frame far from the trajectory (every record checked), naming the key to
/// change.
fn check_frame_near_data(p: &LoadedPipeline, frame: &MapFrame, traj: &Trajectory) -> Result<()> {
    let sbet = traj.sbet();
    let (mut worst, mut lat_min, mut lat_max) = (0.0f64, f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..sbet.len() {
        let r = sbet.record(i);
        if let Some(d) = frame.utm_offset_deg(r.lon_rad) {
            worst = if d.abs() > worst.abs() { d } else { worst };
        }
        lat_min = lat_min.min(r.lat_rad.to_degrees());
        lat_max = lat_max.max(r.lat_rad.to_degrees());
    }
    let source = p.path.display().to_string();
    if worst.abs() > UTM_MAX_OFFSET_DEG {
        return Err(Error::config(
            source,
            "output.frame.zone",
            format!(
                "{frame}: the trajectory reaches {worst:.1} deg from the zone's central meridian \
                 (at most +-{UTM_MAX_OFFSET_DEG} deg: the zone's 3 deg plus a margin); give the \
                 zone that contains the data, or leave it out to take it from the trajectory"
            ),
        ));
    }
    if let MapFrame::Utm { north, .. } = *frame {
        let wrong = if north {
            lat_min < -HEMISPHERE_MARGIN_DEG
        } else {
            lat_max > HEMISPHERE_MARGIN_DEG
        };
        if wrong {
            return Err(Error::config(
                source,
                "output.frame.north",
                format!(
                    "{frame}: the trajectory's latitudes {lat_min:.2} .. {lat_max:.2} deg are in \
                     the other hemisphere; set north = {} or leave it out",
                    !north
                ),
            ));
        }
    }
    Ok(())
}

/// An error about the binary import of the user's CSV file told in the user's terms: the CSV
/// file and its line instead of the import and its record.
pub fn on_user_line(e: Error, input: &PreparedInput) -> Error {
    let Some(lines) = &input.record_lines else {
        return e;
    };
    let (file, original) = (input.file.path(), &input.original);
    match e {
        Error::BadRecord { path, at, problem } if path == file => {
            let at = match at.strip_prefix("record ").map(str::parse::<u64>) {
                Some(Ok(record)) => format!("line {}", lines.line_of(record)),
                _ => at,
            };
            Error::bad_record(original, at, problem)
        }
        Error::BadFile { path, problem } if path == file => Error::bad_file(original, problem),
        other => other,
    }
}
