//! LAS 1.4 writer (conventions §7): point data record format 6 plus float Extra Bytes, a WKT CRS VLR,
//! GPS time per conventions §2.
//!
//! Two halves so the pipeline can encode in parallel and write in order with memory independent
//! of file size:
//! - [`encode_points`] turns a chunk of [`LasPoint`]s into raw record bytes and [`ChunkStats`]
//!   (pure, allocation-free per point, safe to run on many threads at once);
//! - [`LasWriter`] appends encoded chunks in order to a temporary file in the destination
//!   directory (with direct I/O where the filesystem allows: `io::direct`), merges their
//!   stats, writes the header last, fsyncs and renames atomically. A file can also be written
//!   in parts ([`LasWriter::part`], one after another, possibly by several processes), its
//!   header written once every part is in ([`finish_parts`]).
//!
//! The header and VLR framing is serialised with the `las` crate's raw types; point records use
//! our own encoder for speed. Output bytes depend only on the points and the configuration (no
//! clock, no randomness), so the same points give the same file however they are chunked.
//!
//! Modules: `layout` (extra dimensions, time convention, scale/offset), `encode` (records and
//! their stats), `header` (header block and VLRs); the writer is here.

mod encode;
mod header;
pub mod inspect;
mod layout;
mod public_header;
pub mod read;

pub use encode::{encode_extra, encode_points, stats_of_records, ChunkStats, LasPoint};
pub(crate) use header::extra_bytes_descriptor;
pub use layout::{ExtraDim, ExtraType, GpsTimeConvention, PointLayout, FRACTION_SCALE};

use crate::io::atomic::{open_in_place, AtomicFile};
use crate::io::direct::{DirectWriter, PartWriter};
use crate::{Error, Result};
use header::{header_bytes, vlr_bytes, HEADER_SIZE};
use layout::check_ascii_field;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// Most extra dimensions a [`PointLayout`] can carry (the size of [`LasPoint::extra`]).
pub const MAX_EXTRA_DIMS: usize = 16;
/// Point data record format written (LAS 1.4 format 6: core fields and GPS time).
pub const POINT_FORMAT: u8 = 6;
/// Bytes of a format 6 record before the extra bytes.
pub const CORE_RECORD_LEN: usize = 30;
/// Default coordinate scale (m): quantisation error at most 0.05 mm.
pub const DEFAULT_SCALE_M: f64 = 1e-4;
/// Seconds in a GPS week.
pub const SECONDS_PER_GPS_WEEK: f64 = 604_800.0;
/// Offset of adjusted standard GPS time: adjusted = standard GPS time - 1e9 s.
pub const ADJUSTED_GPS_TIME_OFFSET_S: f64 = 1e9;
/// Format 6 scan angle unit (deg per count).
pub const SCAN_ANGLE_UNIT_DEG: f64 = 0.006;

const WRITE_BUFFER_BYTES: usize = 1 << 20;

/// File-level settings of a [`LasWriter`].
#[derive(Clone, Debug, PartialEq)]
pub struct LasWriterConfig {
    /// Record layout (scale, offset, time convention, extra dimensions).
    pub layout: PointLayout,
    /// CRS of X, Y, Z as OGC WKT (non-empty, no NUL), written null-terminated to the
    /// `LASF_Projection` record 2112 VLR.
    pub wkt: String,
    /// Header system identifier (ASCII, at most 32 bytes), e.g. the scanner model.
    pub system_identifier: String,
    /// Header file source ID (e.g. run number; 0 = unassigned).
    pub file_source_id: u16,
    /// File creation day of year (1..=366, GMT), from the caller so output is reproducible.
    pub creation_day_of_year: u16,
    /// File creation year (four digits), from the caller.
    pub creation_year: u16,
}

/// What a finished file holds.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LasSummary {
    /// Destination written.
    pub path: PathBuf,
    /// Points in the file.
    pub point_count: u64,
    /// Points per return number 1..=15.
    pub points_by_return: [u64; 15],
    /// Header minimum X, Y, Z (m) of the stored (quantised) coordinates; zeros when empty.
    pub min_m: [f64; 3],
    /// Header maximum X, Y, Z (m); zeros when empty.
    pub max_m: [f64; 3],
    /// Smallest and largest stored GPS time (file convention, s); None when empty.
    pub gps_time_range: Option<(f64, f64)>,
    /// File size (bytes).
    pub file_bytes: u64,
}

/// Streaming LAS writer: append encoded chunks in order, then [`finish`](LasWriter::finish).
///
/// Writes to a temporary file beside the destination; dropping the writer before `finish`
/// deletes it, so the destination only ever holds a complete file. A writer of one part of a
/// file written in parts ([`LasWriter::part`]) writes its records in place instead.
pub struct LasWriter {
    path: PathBuf,
    config: LasWriterConfig,
    file: Target,
    stats: ChunkStats,
    /// Byte offset of the first record written by this writer.
    offset_to_points: u64,
    scratch: Vec<u8>,
}

/// Where a [`LasWriter`]'s bytes go.
enum Target {
    /// A whole file: header, VLRs and records, published atomically.
    Whole(AtomicFile<DirectWriter>),
    /// The records of one part of a file written in parts.
    Part(PartWriter),
}

impl LasWriter {
    /// Starts a LAS file at `path` (created or replaced on [`finish`](LasWriter::finish)).
    pub fn create(path: impl AsRef<Path>, config: LasWriterConfig) -> Result<LasWriter> {
        let path = path.as_ref().to_path_buf();
        check_ascii_field("system identifier", &config.system_identifier, 0)?;
        let vlrs = vlr_bytes(&config)?;
        let mut file = AtomicFile::<DirectWriter>::with_capacity(&path, WRITE_BUFFER_BYTES)?;
        file.write_all(&[0u8; HEADER_SIZE])?;
        file.write_all(&vlrs)?;
        let offset_to_points = offset_of_points(&vlrs)?;
        Ok(Self::with_target(
            path,
            config,
            Target::Whole(file),
            offset_to_points,
        ))
    }

    /// Starts one part of the LAS file `path` written in parts, one after another, each by a
    /// writer of its own (possibly in another process): its records go in place right after
    /// those of the previous part, which ended at byte `previous_end`, or, for the first part
    /// (`None`), after the header and VLRs of `config` (the file is then created anew, the
    /// header left as zeros). [`finish`](LasWriter::finish) makes the part durable and gives
    /// its summary (`file_bytes`: the byte where the part ends). Once every part is in,
    /// [`finish_parts`] writes the header.
    pub fn part(
        path: impl AsRef<Path>,
        config: LasWriterConfig,
        previous_end: Option<u64>,
    ) -> Result<LasWriter> {
        let path = path.as_ref().to_path_buf();
        check_ascii_field("system identifier", &config.system_identifier, 0)?;
        let at = match previous_end {
            Some(end) => end,
            None => offset_of_points(&vlr_bytes(&config)?)?,
        };
        let file = PartWriter::open(&path, at, previous_end.is_none(), WRITE_BUFFER_BYTES)?;
        Ok(Self::with_target(path, config, Target::Part(file), at))
    }

    fn with_target(path: PathBuf, config: LasWriterConfig, file: Target, at: u64) -> LasWriter {
        let record_len = config.layout.record_len;
        LasWriter {
            path,
            config,
            file,
            stats: ChunkStats::empty(record_len),
            offset_to_points: at,
            scratch: Vec::new(),
        }
    }

    /// Appends records made by [`encode_points`] with this writer's layout, and their stats.
    pub fn write_encoded(&mut self, bytes: &[u8], stats: &ChunkStats) -> Result<()> {
        let record_len = self.config.layout.record_len;
        if stats.record_len != record_len || bytes.len() as u64 != stats.count * record_len as u64 {
            return Err(Error::Invalid(format!(
                "{}: encoded chunk of {} bytes / {} points of {} bytes does not match the \
                 writer's {record_len}-byte records",
                self.path.display(),
                bytes.len(),
                stats.count,
                stats.record_len
            )));
        }
        match &mut self.file {
            Target::Whole(file) => file.write_all(bytes)?,
            Target::Part(part) => part.write_all(bytes)?,
        }
        self.stats.merge(stats);
        Ok(())
    }

    /// Encodes and appends `points` (convenience for callers without a parallel encoder).
    pub fn write_points(&mut self, points: &[LasPoint]) -> Result<()> {
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.clear();
        let stats = encode_points(points, &self.config.layout, &mut scratch)
            .map_err(|e| Error::bad_file(&self.path, e.to_string()))?;
        let result = self.write_encoded(&scratch, &stats);
        self.scratch = scratch;
        result
    }

    /// Writes the header, fsyncs, and renames the file into place; for a part, writes its
    /// last records and makes them durable.
    pub fn finish(self) -> Result<LasSummary> {
        let LasWriter {
            path,
            config,
            file,
            stats,
            offset_to_points,
            ..
        } = self;
        let summary = summarise(&path, &config.layout, &stats, offset_to_points);
        match file {
            Target::Whole(mut file) => {
                let header = header_bytes(&config, &summary, offset_to_points as u32)
                    .map_err(|e| Error::bad_file(&path, e))?;
                file.write_at(0, &header)?;
                file.commit()?;
            }
            Target::Part(part) => part.commit()?,
        }
        Ok(summary)
    }
}

/// Completes the LAS file `path` written in parts ([`LasWriter::part`]) with `config`, once
/// every part is in: `parts` are their summaries, in file order. Writes the header made from
/// them (the header [`LasWriter::finish`] writes for the same points) and the VLRs, and fsyncs
/// the file (its parts were made durable by their writers); gives its summary. A header
/// already there is not written again (a file completed before and published stays as it
/// is); the file is refused when its size is not that of its parts.
pub fn finish_parts(
    path: &Path,
    config: &LasWriterConfig,
    parts: &[LasSummary],
) -> Result<LasSummary> {
    check_ascii_field("system identifier", &config.system_identifier, 0)?;
    let vlrs = vlr_bytes(config)?;
    let offset_to_points = offset_of_points(&vlrs)?;
    let summary = summary_of_parts(path, &config.layout, parts, offset_to_points);
    let mut head = header_bytes(config, &summary, offset_to_points as u32)
        .map_err(|e| Error::bad_file(path, e))?;
    head.extend_from_slice(&vlrs);
    let io = |e| Error::io(path, e);
    let file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    if size != summary.file_bytes {
        let problem = format!(
            "{size} bytes, not the {} of its header and the {} points of its parts",
            summary.file_bytes, summary.point_count
        );
        return Err(Error::bad_file(path, problem));
    }
    let mut there = vec![0u8; head.len()];
    file.read_exact_at(&mut there, 0).map_err(io)?;
    if there != head {
        let file = open_in_place(path)?;
        file.write_all_at(&head, 0).map_err(io)?;
        file.sync_all().map_err(io)?;
    }
    Ok(summary)
}

/// The byte offset of the first point record after the header and `vlrs`.
fn offset_of_points(vlrs: &[u8]) -> Result<u64> {
    let offset = HEADER_SIZE + vlrs.len();
    u32::try_from(offset).map_err(|_| Error::Invalid("LAS VLRs too large".into()))?;
    Ok(offset as u64)
}

/// The summary of the LAS file `path` made of `parts` (their summaries, any order), its first
/// record at `offset_to_points`: counts added, bounds of the non-empty parts (each part's are
/// its stored counts scaled, so the extreme of the parts' is that of all the counts scaled).
fn summary_of_parts(
    path: &Path,
    layout: &PointLayout,
    parts: &[LasSummary],
    offset_to_points: u64,
) -> LasSummary {
    let mut all = LasSummary {
        path: path.to_path_buf(),
        point_count: 0,
        points_by_return: [0; 15],
        min_m: [0.0; 3],
        max_m: [0.0; 3],
        gps_time_range: None,
        file_bytes: 0,
    };
    for p in parts.iter().filter(|p| p.point_count > 0) {
        let first = all.point_count == 0;
        all.point_count += p.point_count;
        for (a, b) in all.points_by_return.iter_mut().zip(p.points_by_return) {
            *a += b;
        }
        for k in 0..3 {
            let (min, max) = (p.min_m[k], p.max_m[k]);
            all.min_m[k] = if first { min } else { all.min_m[k].min(min) };
            all.max_m[k] = if first { max } else { all.max_m[k].max(max) };
        }
        all.gps_time_range = match (all.gps_time_range, p.gps_time_range) {
            (Some((a, b)), Some((c, d))) => Some((a.min(c), b.max(d))),
            (a, b) => a.or(b),
        };
    }
    all.file_bytes = offset_to_points + all.point_count * layout.record_len as u64;
    all
}

fn summarise(path: &Path, layout: &PointLayout, stats: &ChunkStats, offset: u64) -> LasSummary {
    let empty = stats.count == 0;
    let to_m = |counts: [i32; 3]| -> [f64; 3] {
        if empty {
            return [0.0; 3];
        }
        std::array::from_fn(|k| layout.coordinate_m(k, counts[k]))
    };
    LasSummary {
        path: path.to_path_buf(),
        point_count: stats.count,
        points_by_return: stats.points_by_return,
        min_m: to_m(stats.min_counts),
        max_m: to_m(stats.max_counts),
        gps_time_range: (!empty).then_some((stats.gps_time_min, stats.gps_time_max)),
        file_bytes: offset + stats.count * stats.record_len as u64,
    }
}
