//! Stage 5, **write**: where georeferenced points go. One or more LAS files, split per input or
//! by point count, named predictably, each written atomically; records arrive encoded, in
//! input order.

use super::config::{OutputFormat, PipelineConfig, SplitMode};
use super::files::{numbered_part, per_input_part};
use super::schema::OutputSchema;
use crate::geo::ellipsoid::{geodetic_to_ecef, Geodetic};
use crate::geo::geoid::GeoidGrid;
use crate::geo::projection::MapFrame;
use crate::io::las::{
    encode_points, finish_parts, stats_of_records, ChunkStats, GpsTimeConvention, LasPoint,
    LasSummary, LasWriter, LasWriterConfig, PointLayout, SECONDS_PER_GPS_WEEK,
};
use crate::io::profiles::ProfileFile;
use crate::trajectory::Trajectory;
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// File-level settings shared by every output file of a run.
pub struct SinkSettings {
    config: LasWriterConfig,
    las: PathBuf,
    stem: String,
    split: SplitMode,
    max_points: u64,
}

impl SinkSettings {
    /// Settings from the pipeline: scale, offset (map coordinates of the first trajectory
    /// record, rounded to 1 km), GPS time convention, the schema's extra dimensions, CRS
    /// (compound with the geoid's heights when given).
    pub fn new(
        c: &PipelineConfig,
        schema: &OutputSchema,
        frame: &MapFrame,
        geoid: Option<&GeoidGrid>,
        traj: &Trajectory,
    ) -> Result<Self> {
        let first = traj.sbet().record(0);
        let g = Geodetic {
            lat_rad: first.lat_rad,
            lon_rad: first.lon_rad,
            h_m: first.alt_m,
        };
        let mut origin = frame.ecef_to_map(&geodetic_to_ecef(g));
        origin.z -= geoid
            .and_then(|grid| grid.undulation_m(g.lat_rad, g.lon_rad))
            .unwrap_or(0.0);
        // Z in the file is in the CRS's unit (feet for a foot CRS), as X and Y.
        origin.z /= frame.metres_per_unit();
        // A geographic frame's X and Y are degrees: offset to 0.01 deg (about 1 km), the rest
        // to 1 km.
        let round_xy = if frame.is_geographic() { 0.01 } else { 1000.0 };
        let round = [round_xy, round_xy, 1000.0];
        let offset = c.output.offset_m.unwrap_or(
            [origin.x, origin.y, origin.z]
                .iter()
                .zip(round)
                .map(|(v, r)| (v / r).round() * r)
                .collect::<Vec<f64>>()
                .try_into()
                .expect("three axes"),
        );
        let time = match c.inputs.gps_week {
            Some(gps_week) => GpsTimeConvention::AdjustedStandard { gps_week },
            None => GpsTimeConvention::WeekSeconds,
        };
        let layout =
            PointLayout::with_scale(axis_scales(c, frame), offset, time, schema.dims().to_vec())?;
        let (day, year) = creation_date(c.inputs.gps_week, first.time_s);
        let config = LasWriterConfig {
            layout,
            wkt: match geoid {
                Some(grid) => {
                    grid.compound_wkt(&frame.to_string(), &frame.wkt(), frame.metres_per_unit())
                }
                None => frame.wkt(),
            },
            system_identifier: "kinescan mobile laser scanning".into(),
            file_source_id: 0,
            creation_day_of_year: day,
            creation_year: year,
        };
        Ok(SinkSettings {
            config,
            las: c.output.las.to_path_buf(),
            stem: c.output.stem(),
            split: c.output.split,
            max_points: c.output.max_points_per_file.unwrap_or(u64::MAX),
        })
    }

    /// The record layout of the files of these settings.
    pub fn layout(&self) -> &PointLayout {
        &self.config.layout
    }

    /// Completes the output file (`output.las`) written in parts by sinks of these settings
    /// ([`LasSink::part`]) once every part is in, from the parts' summaries in file order:
    /// its header (`io::las::finish_parts`). Gives the file's summary.
    pub fn finish_parts(&self, parts: &[LasSummary]) -> Result<LasSummary> {
        finish_parts(&self.las, &self.config, parts)
    }
}

/// Metres per degree of latitude, rounded up (111,132.954 m at the equator to 111,694.2 m at
/// the poles on WGS84): a degree of longitude is at most this long too.
const MAX_METRES_PER_DEGREE: f64 = 111_700.0;

/// The LAS scale of X, Y and Z: `output.scale_m` on every axis; for a geographic frame, X and
/// Y (degrees) at the power of ten of a degree that is no coarser than `output.scale_m` along
/// any meridian or parallel (1 mm: 1e-9 deg, 0.11 mm north, at most 0.11 mm east), Z in metres.
/// 1e-9 deg leaves +-2.1 deg about the offset (the first trajectory record's, to 0.01 deg) for
/// the i32 coordinates, more than a survey spans (`output.scale_m = 1e-4`: 1e-10 deg, +-0.21
/// deg).
pub fn axis_scales(c: &PipelineConfig, frame: &MapFrame) -> [f64; 3] {
    let s = c.output.scale_m;
    if !frame.is_geographic() {
        return [s; 3];
    }
    let deg = 10f64.powf((s / MAX_METRES_PER_DEGREE).log10().floor());
    [deg, deg, s]
}

/// Survey date `YYYY-MM-DD` (UTC day of the GPS time, leap seconds aside) from the GPS week
/// and seconds of week; None without a week.
pub fn survey_date(gps_week: Option<u32>, sow: f64) -> Option<String> {
    gps_week?;
    let (day_of_year, year) = creation_date(gps_week, sow);
    let leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
    let months = [
        31,
        if leap { 29 } else { 28 },
        31,
        30,
        31,
        30,
        31,
        31,
        30,
        31,
        30,
        31,
    ];
    let mut day = day_of_year;
    for (m, len) in months.iter().enumerate() {
        if day <= *len {
            return Some(format!("{year:04}-{:02}-{day:02}", m + 1));
        }
        day -= len;
    }
    None
}

/// Survey day (day of year, year) from the GPS week and seconds of week; (0, 0) ("unknown",
/// as the LAS specification allows) without a week, so output never depends on the clock.
fn creation_date(gps_week: Option<u32>, sow: f64) -> (u16, u16) {
    let Some(week) = gps_week else { return (0, 0) };
    // GPS epoch 1980-01-06 is day 5 (0-based) of 1980; count whole days forward.
    let mut days = (f64::from(week) * SECONDS_PER_GPS_WEEK + sow).div_euclid(86_400.0) as i64 + 5;
    let mut year = 1980i64;
    loop {
        let len = if (year % 4 == 0 && year % 100 != 0) || year % 400 == 0 {
            366
        } else {
            365
        };
        if days < len {
            return ((days + 1) as u16, year as u16);
        }
        days -= len;
        year += 1;
    }
}

/// The open output file(s).
pub struct LasSink {
    settings: SinkSettings,
    /// `Some` for a sink writing one part of a file written in parts: where the previous
    /// part ended (`None` for the first part).
    part_after: Option<Option<u64>>,
    current: Option<LasWriter>,
    in_current: u64,
    parts: u32,
    input: PathBuf,
    done: Vec<LasSummary>,
}

impl LasSink {
    /// A sink with no file open yet.
    pub fn new(settings: SinkSettings) -> Self {
        LasSink {
            settings,
            part_after: None,
            current: None,
            in_current: 0,
            parts: 0,
            input: PathBuf::new(),
            done: Vec::new(),
        }
    }

    /// A sink writing one part of the file `settings` names (`output.las`, not split), written
    /// in parts (`io::las::LasWriter::part`): its records in place after those of the previous
    /// part, which ended at byte `previous_end` (`None`: the first part). Its summary's
    /// `file_bytes` is the byte where the part ends; [`SinkSettings::finish_parts`] completes
    /// the file.
    pub fn part(settings: SinkSettings, previous_end: Option<u64>) -> Self {
        LasSink {
            part_after: Some(previous_end),
            ..LasSink::new(settings)
        }
    }

    /// Called before each profile file's points: starts a new file when splitting per input.
    pub fn start_input(&mut self, profile_path: &Path) -> Result<()> {
        self.input = profile_path.to_path_buf();
        if self.settings.split == SplitMode::PerInput {
            self.close()?;
            self.open()?;
        }
        Ok(())
    }

    fn path_for_next(&self) -> PathBuf {
        let las = &self.settings.las;
        match self.settings.split {
            SplitMode::None => las.clone(),
            SplitMode::PerInput => per_input_part(las, &self.settings.stem, &self.input, "las"),
            SplitMode::MaxPoints => numbered_part(las, &self.settings.stem, self.parts + 1, "las"),
        }
    }

    fn open(&mut self) -> Result<()> {
        let path = self.path_for_next();
        if self.done.iter().any(|s| s.path == path) {
            let msg = "two profile files share a file stem, so per-input outputs would collide";
            return Err(Error::bad_file(path, msg));
        }
        let config = self.settings.config.clone();
        self.current = Some(match self.part_after {
            Some(previous_end) if self.parts == 0 => LasWriter::part(&path, config, previous_end)?,
            Some(_) => {
                let msg = "a part of a file written in parts is not split into files";
                return Err(Error::bad_file(path, msg));
            }
            None => LasWriter::create(&path, config)?,
        });
        self.parts += 1;
        self.in_current = 0;
        Ok(())
    }

    fn close(&mut self) -> Result<()> {
        if let Some(w) = self.current.take() {
            self.done.push(w.finish()?);
        }
        Ok(())
    }

    /// The record layout every file of this sink uses.
    pub fn layout(&self) -> &PointLayout {
        self.settings.layout()
    }

    /// Writes encoded records in order, rolling to a new file at the point limit.
    pub fn write(&mut self, mut records: &[u8], stats: &ChunkStats) -> Result<()> {
        crate::interrupt::check()?;
        let layout = self.settings.config.layout.clone();
        let len = layout.record_len();
        let mut whole = Some(stats.clone());
        while !records.is_empty() || self.current.is_none() {
            if self.current.is_none() || self.in_current == self.settings.max_points {
                self.close()?;
                self.open()?;
            }
            let n = (records.len() / len) as u64;
            let room = (self.settings.max_points - self.in_current).min(n);
            let (now, rest) = records.split_at(room as usize * len);
            // Stats of a split chunk are recomputed from its records.
            let part = match whole.take() {
                Some(s) if room == n => s,
                _ => stats_of_records(now, &layout),
            };
            self.current
                .as_mut()
                .expect("opened above")
                .write_encoded(now, &part)?;
            self.in_current += room;
            records = rest;
        }
        Ok(())
    }

    /// Finishes every file (an empty run still writes one valid, empty LAS file).
    pub fn finish(mut self) -> Result<Vec<LasSummary>> {
        if self.current.is_none() && self.done.is_empty() {
            self.open()?;
        }
        self.close()?;
        Ok(self.done)
    }
}

/// Names a chunk's encoding error `e` by the record of `file` that fails (`records[k]` is the
/// record of `batch[k]`); a coordinate beyond the LAS range by the keys that fix it.
pub(super) fn encode_error(
    e: Error,
    batch: &[LasPoint],
    records: &[usize],
    layout: &PointLayout,
    file: &ProfileFile,
) -> Error {
    let failing = (0..batch.len())
        .find(|&k| encode_points(&batch[k..=k], layout, &mut Vec::new()).is_err())
        .unwrap_or(0);
    let mut problem = e.to_string();
    if let Some((_, what)) = problem.split_once(" of the chunk: ") {
        problem = what.to_string();
    }
    if problem.contains("beyond what LAS can store") {
        let p = &batch[failing];
        let near = [p.x, p.y, p.z].map(|v| (v / 1000.0).round() * 1000.0);
        problem += &format!(
            ": set output.offset_m near the data (e.g. [{}, {}, {}]) or a coarser output.scale_m",
            near[0], near[1], near[2]
        );
    }
    Error::bad_record(file.path(), format!("record {}", records[failing]), problem)
}

/// The finished LAS files in the configured format, each beside its LAS: LAZ compressed in
/// parallel chunks on the current thread pool (`io::laz`), the LAS removed.
pub fn into_format(format: OutputFormat, files: Vec<LasSummary>) -> Result<Vec<LasSummary>> {
    if format == OutputFormat::Las {
        return Ok(files);
    }
    files
        .into_iter()
        .map(|mut s| {
            let laz = s.path.with_extension(format.extension());
            if laz == s.path {
                // `output.las` already has the format's extension: the uncompressed file
                // moves aside, else it would be removed under the compressed one's name.
                let aside = s.path.with_extension("uncompressed.las");
                std::fs::rename(&s.path, &aside).map_err(|e| Error::io(&s.path, e))?;
                s.path = aside;
            }
            let sizes = match format {
                OutputFormat::Copc => {
                    crate::io::copc::write_copc(&s.path, &laz, crate::io::copc::LEAF_POINTS)?
                }
                _ => crate::io::laz::compress_las(&s.path, &laz)?,
            };
            std::fs::remove_file(&s.path).map_err(|e| Error::io(&s.path, e))?;
            s.path = laz;
            s.file_bytes = sizes.laz_bytes;
            Ok(s)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{creation_date, survey_date};

    #[test]
    fn survey_date_from_gps_week() {
        // GPS week 2390, Wednesday 12:00: 2025-10-29 (week 2390 starts Sunday 2025-10-26).
        assert_eq!(
            survey_date(Some(2390), 3.5 * 86_400.0).as_deref(),
            Some("2025-10-29")
        );
        // Week 0, second 0: the GPS epoch.
        assert_eq!(survey_date(Some(0), 0.0).as_deref(), Some("1980-01-06"));
        assert_eq!(survey_date(None, 0.0), None);
    }

    #[test]
    fn creation_date_from_gps_week() {
        // GPS week 0 starts 1980-01-06 (day 6); week 2346 starts 2024-12-22 (day 357 of a
        // leap year), and ten days later is 2025-01-01.
        assert_eq!(creation_date(Some(0), 0.0), (6, 1980));
        assert_eq!(creation_date(Some(2346), 0.0), (357, 2024));
        assert_eq!(creation_date(Some(2346), 10.0 * 86_400.0 + 5.0), (1, 2025));
        assert_eq!(creation_date(None, 0.0), (0, 0));
    }
}
