//! LAS 1.4 writer (conventions §7): point data record format 6 plus float Extra Bytes, a WKT CRS VLR,
//! GPS time per conventions §2.
//!
//! Two halves so the pipeline can encode in parallel and write in order with memory independent
//! of file size:
//! - [`encode_points`] turns a chunk of [`LasPoint`]s into raw record bytes and [`ChunkStats`]
//!   (pure, allocation-free per point, safe to run on many threads at once);
//! - [`LasWriter`] appends encoded chunks in order to a temporary file in the destination
//!   directory, merges their stats, writes the header last, fsyncs and renames atomically.
//!
//! The header and VLR framing is serialised with the `las` crate's raw types; point records use
//! our own encoder for speed. Output bytes depend only on the points and the configuration (no
//! clock, no randomness), so the same points give the same file however they are chunked.

use std::path::{Path, PathBuf};

use las::raw::vlr::RecordLength;
use las::Version;

use crate::io::atomic::AtomicFile;
use crate::{Error, Result};

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

const HEADER_SIZE: usize = 375;
const VLR_HEADER_SIZE: usize = 54;
const EXTRA_BYTES_DESCRIPTOR_LEN: usize = 192;
const NUMBER_OF_RETURNS_MAX: u8 = 15;
const SCAN_ANGLE_MAX_COUNTS: f64 = 30_000.0;
const GLOBAL_ENCODING_GPS_ADJUSTED: u16 = 1 << 0;
const GLOBAL_ENCODING_WKT: u16 = 1 << 4;
const WRITE_BUFFER_BYTES: usize = 1 << 20;

/// Storage type of one extra dimension (LAS 1.4 Extra Bytes `data_type`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExtraType {
    /// IEEE 754 single (data_type 9, 4 bytes).
    F32,
    /// IEEE 754 double (data_type 10, 8 bytes).
    F64,
    /// A fraction 0..=1 as an unsigned char (data_type 1, 1 byte) with scale
    /// [`FRACTION_SCALE`] in the descriptor: stored `round(v / scale)`, resolution 0.4%.
    /// Readers that apply the scale (laspy, PDAL, LAStools) show the fraction.
    FractionU8,
}

/// Scale of [`ExtraType::FractionU8`]: 250 steps for 0..=1.
pub const FRACTION_SCALE: f64 = 0.004;

impl ExtraType {
    /// Bytes per value in a record.
    pub fn size(self) -> usize {
        match self {
            ExtraType::F32 => 4,
            ExtraType::F64 => 8,
            ExtraType::FractionU8 => 1,
        }
    }

    /// LAS 1.4 Extra Bytes `data_type` code.
    pub fn data_type_code(self) -> u8 {
        match self {
            ExtraType::F32 => 9,
            ExtraType::F64 => 10,
            ExtraType::FractionU8 => 1,
        }
    }

    /// The descriptor's scale, if the type has one.
    pub fn scale(self) -> Option<f64> {
        match self {
            ExtraType::FractionU8 => Some(FRACTION_SCALE),
            ExtraType::F32 | ExtraType::F64 => None,
        }
    }
}

/// One named, typed extra dimension, described in the Extra Bytes VLR.
#[derive(Clone, Debug, PartialEq)]
pub struct ExtraDim {
    /// Name readers show (ASCII, 1..=32 bytes, unique in the layout), e.g. `sigma_x`.
    pub name: String,
    /// Storage type.
    pub data_type: ExtraType,
    /// Free text, ASCII, at most 32 bytes, e.g. `1-sigma along X (m)`.
    pub description: String,
}

impl ExtraDim {
    /// A float32 dimension.
    pub fn f32(name: &str, description: &str) -> Self {
        ExtraDim {
            name: name.into(),
            data_type: ExtraType::F32,
            description: description.into(),
        }
    }

    /// A float64 dimension.
    pub fn f64(name: &str, description: &str) -> Self {
        ExtraDim {
            name: name.into(),
            data_type: ExtraType::F64,
            description: description.into(),
        }
    }

    /// A fraction (0..=1) stored in one byte ([`ExtraType::FractionU8`]).
    pub fn fraction(name: &str, description: &str) -> Self {
        ExtraDim {
            name: name.into(),
            data_type: ExtraType::FractionU8,
            description: description.into(),
        }
    }
}

/// Which GPS time the file carries (conventions §2). Never mixed within one file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GpsTimeConvention {
    /// GPS seconds of the week, as in the trajectory (global encoding bit 0 clear).
    WeekSeconds,
    /// Adjusted standard GPS time = week * 604800 + seconds of week - 1e9 (bit 0 set).
    AdjustedStandard {
        /// GPS week number (continuous, not modulo 1024) of the seconds-of-week times.
        gps_week: u32,
    },
}

impl GpsTimeConvention {
    /// Seconds added to GPS seconds of the week to get the stored time (exact in f64).
    pub fn shift_s(self) -> f64 {
        match self {
            GpsTimeConvention::WeekSeconds => 0.0,
            GpsTimeConvention::AdjustedStandard { gps_week } => {
                f64::from(gps_week) * SECONDS_PER_GPS_WEEK - ADJUSTED_GPS_TIME_OFFSET_S
            }
        }
    }
}

/// Everything that fixes the bytes of a point record: coordinate scale/offset, time convention
/// and extra dimensions. Validated on construction.
#[derive(Clone, Debug, PartialEq)]
pub struct PointLayout {
    scale_m: [f64; 3],
    offset_m: [f64; 3],
    time: GpsTimeConvention,
    extra_dims: Vec<ExtraDim>,
    extra_offsets: Vec<usize>,
    record_len: usize,
}

impl PointLayout {
    /// Layout with the default scale (0.0001 m on X, Y, Z).
    ///
    /// `offset_m`: map-frame offset (m) subtracted before scaling, e.g. the first point rounded
    /// to a metre; a stored coordinate must stay within +-2^31 scale steps (+-214 km at the
    /// default scale) of it.
    pub fn new(
        offset_m: [f64; 3],
        time: GpsTimeConvention,
        extra_dims: Vec<ExtraDim>,
    ) -> Result<Self> {
        Self::with_scale([DEFAULT_SCALE_M; 3], offset_m, time, extra_dims)
    }

    /// Layout with an explicit coordinate scale (m per count, positive and finite).
    pub fn with_scale(
        scale_m: [f64; 3],
        offset_m: [f64; 3],
        time: GpsTimeConvention,
        extra_dims: Vec<ExtraDim>,
    ) -> Result<Self> {
        if scale_m.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(Error::Invalid(format!(
                "LAS scale {scale_m:?} m must be positive"
            )));
        }
        if offset_m.iter().any(|o| !o.is_finite()) {
            return Err(Error::Invalid(format!(
                "LAS offset {offset_m:?} m must be finite"
            )));
        }
        validate_extra_dims(&extra_dims)?;
        let mut extra_offsets = Vec::with_capacity(extra_dims.len());
        let mut record_len = CORE_RECORD_LEN;
        for dim in &extra_dims {
            extra_offsets.push(record_len);
            record_len += dim.data_type.size();
        }
        Ok(PointLayout {
            scale_m,
            offset_m,
            time,
            extra_dims,
            extra_offsets,
            record_len,
        })
    }

    /// Coordinate scale (m per count) on X, Y, Z.
    pub fn scale_m(&self) -> [f64; 3] {
        self.scale_m
    }
    /// Coordinate offset (m) on X, Y, Z.
    pub fn offset_m(&self) -> [f64; 3] {
        self.offset_m
    }
    /// GPS time convention of the file.
    pub fn time(&self) -> GpsTimeConvention {
        self.time
    }
    /// Extra dimensions in record order.
    pub fn extra_dims(&self) -> &[ExtraDim] {
        &self.extra_dims
    }
    /// Bytes per point record (30 + extra bytes).
    pub fn record_len(&self) -> usize {
        self.record_len
    }
}

fn validate_extra_dims(dims: &[ExtraDim]) -> Result<()> {
    if dims.len() > MAX_EXTRA_DIMS {
        return Err(Error::Invalid(format!(
            "{} LAS extra dimensions requested, at most {MAX_EXTRA_DIMS} supported",
            dims.len()
        )));
    }
    for (i, dim) in dims.iter().enumerate() {
        check_ascii_field("extra dimension name", &dim.name, 1)?;
        check_ascii_field("extra dimension description", &dim.description, 0)?;
        if dims[..i].iter().any(|d| d.name == dim.name) {
            return Err(Error::Invalid(format!(
                "LAS extra dimension `{}` given twice",
                dim.name
            )));
        }
    }
    Ok(())
}

/// A 32-byte LAS text field: ASCII without NUL, `min_len..=32` bytes.
fn check_ascii_field(what: &str, text: &str, min_len: usize) -> Result<()> {
    if text.len() < min_len || text.len() > 32 || !text.is_ascii() || text.contains('\0') {
        return Err(Error::Invalid(format!(
            "LAS {what} `{text}` must be {min_len} to 32 ASCII characters without NUL"
        )));
    }
    Ok(())
}

fn fixed_32(text: &str) -> [u8; 32] {
    let mut out = [0u8; 32];
    out[..text.len()].copy_from_slice(text.as_bytes());
    out
}

fn fixed_16(text: &str) -> [u8; 16] {
    let mut out = [0u8; 16];
    out[..text.len()].copy_from_slice(text.as_bytes());
    out
}

/// One output point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LasPoint {
    /// Map-frame X (m), the file's X axis (e.g. UTM easting).
    pub x: f64,
    /// Map-frame Y (m), the file's Y axis (e.g. UTM northing).
    pub y: f64,
    /// Map-frame Z (m), the file's Z axis (e.g. ellipsoidal height).
    pub z: f64,
    /// Return intensity, scanner units.
    pub intensity: u16,
    /// Return number, 1..=15.
    pub return_number: u8,
    /// Number of returns of the pulse, 1..=15.
    pub number_of_returns: u8,
    /// Scan angle (deg), -180..=180; stored as i16 in 0.006 deg counts.
    pub scan_angle_deg: f64,
    /// GPS seconds of the week (conventions §2 trajectory time). The encoder converts to the file's
    /// convention ([`PointLayout::time`]); never pass adjusted standard time here.
    pub gps_time: f64,
    /// Point source ID (e.g. run or scanner number).
    pub point_source_id: u16,
    /// ASPRS classification (0 = never classified).
    pub classification: u8,
    /// User data byte.
    pub user_data: u8,
    /// Values of the layout's extra dimensions, in its order (index i = dimension i), converted
    /// to the dimension's type; entries past the layout's count are ignored.
    pub extra: [f64; MAX_EXTRA_DIMS],
}

impl Default for LasPoint {
    fn default() -> Self {
        LasPoint {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            intensity: 0,
            return_number: 1,
            number_of_returns: 1,
            scan_angle_deg: 0.0,
            gps_time: 0.0,
            point_source_id: 0,
            classification: 0,
            user_data: 0,
            extra: [0.0; MAX_EXTRA_DIMS],
        }
    }
}

/// What the header needs from a run of encoded records. Mergeable in any grouping: merging the
/// stats of consecutive chunks equals the stats of their concatenation.
#[derive(Clone, Debug, PartialEq)]
pub struct ChunkStats {
    /// Points encoded.
    pub count: u64,
    /// Points per return number 1..=15 (index 0 = first return).
    pub points_by_return: [u64; 15],
    /// Smallest stored X, Y, Z integer counts (i32::MAX when empty).
    pub min_counts: [i32; 3],
    /// Largest stored X, Y, Z integer counts (i32::MIN when empty).
    pub max_counts: [i32; 3],
    /// Smallest stored GPS time, file convention (s); +inf when empty.
    pub gps_time_min: f64,
    /// Largest stored GPS time, file convention (s); -inf when empty.
    pub gps_time_max: f64,
    /// Record length the bytes were encoded with.
    pub record_len: usize,
}

impl ChunkStats {
    /// Stats of no points with records of `record_len` bytes.
    pub fn empty(record_len: usize) -> Self {
        ChunkStats {
            count: 0,
            points_by_return: [0; 15],
            min_counts: [i32::MAX; 3],
            max_counts: [i32::MIN; 3],
            gps_time_min: f64::INFINITY,
            gps_time_max: f64::NEG_INFINITY,
            record_len,
        }
    }

    /// Adds `other` (encoded with the same record length) into `self`.
    pub fn merge(&mut self, other: &ChunkStats) {
        self.count += other.count;
        for (a, b) in self.points_by_return.iter_mut().zip(other.points_by_return) {
            *a += b;
        }
        for k in 0..3 {
            self.min_counts[k] = self.min_counts[k].min(other.min_counts[k]);
            self.max_counts[k] = self.max_counts[k].max(other.max_counts[k]);
        }
        self.gps_time_min = self.gps_time_min.min(other.gps_time_min);
        self.gps_time_max = self.gps_time_max.max(other.gps_time_max);
    }

    fn add(&mut self, counts: [i32; 3], return_number: u8, gps_time: f64) {
        self.count += 1;
        self.points_by_return[usize::from(return_number) - 1] += 1;
        for (k, c) in counts.into_iter().enumerate() {
            self.min_counts[k] = self.min_counts[k].min(c);
            self.max_counts[k] = self.max_counts[k].max(c);
        }
        self.gps_time_min = self.gps_time_min.min(gps_time);
        self.gps_time_max = self.gps_time_max.max(gps_time);
    }
}

/// Stats of records already encoded with `layout` (e.g. part of an encoded chunk split across
/// two files), read back from the bytes: equal to what [`encode_points`] returned for them.
pub fn stats_of_records(bytes: &[u8], layout: &PointLayout) -> ChunkStats {
    let mut stats = ChunkStats::empty(layout.record_len);
    for rec in bytes.chunks_exact(layout.record_len) {
        let i32_at = |at: usize| i32::from_le_bytes(rec[at..at + 4].try_into().expect("4 bytes"));
        let gps_time = f64::from_le_bytes(rec[22..30].try_into().expect("8 bytes"));
        stats.add([i32_at(0), i32_at(4), i32_at(8)], rec[14] & 0x0f, gps_time);
    }
    stats
}

/// Serialises `points` into format 6 records with the layout's extra bytes.
///
/// Appends `points.len() * layout.record_len()` bytes to `out` (what it appended is
/// unspecified after an error). Coordinates are stored as `round((v - offset) / scale)`;
/// GPS time as `gps_time + layout.time().shift_s()`; extra values cast to their type.
/// Pure and allocation-free per point: call it from many threads on separate chunks.
///
/// Errors (index = position in `points`): a coordinate that is not finite or whose count does
/// not fit i32 (says by how much, suggests offset/scale), a return number or number of returns
/// outside 1..=15, a scan angle outside +-180 deg.
pub fn encode_points(
    points: &[LasPoint],
    layout: &PointLayout,
    out: &mut Vec<u8>,
) -> Result<ChunkStats> {
    let record_len = layout.record_len;
    let shift_s = layout.time.shift_s();
    let mut stats = ChunkStats::empty(record_len);
    let start = out.len();
    out.resize(start + points.len() * record_len, 0);
    for (i, (p, rec)) in points
        .iter()
        .zip(out[start..].chunks_exact_mut(record_len))
        .enumerate()
    {
        let counts = [
            quantise(p.x, 0, layout, i)?,
            quantise(p.y, 1, layout, i)?,
            quantise(p.z, 2, layout, i)?,
        ];
        check_returns(p, i)?;
        let scan_angle = scan_angle_counts(p.scan_angle_deg, i)?;
        let gps_time = p.gps_time + shift_s;
        rec[0..4].copy_from_slice(&counts[0].to_le_bytes());
        rec[4..8].copy_from_slice(&counts[1].to_le_bytes());
        rec[8..12].copy_from_slice(&counts[2].to_le_bytes());
        rec[12..14].copy_from_slice(&p.intensity.to_le_bytes());
        rec[14] = p.return_number | (p.number_of_returns << 4);
        rec[15] = 0; // classification flags, scanner channel, scan direction, edge of line
        rec[16] = p.classification;
        rec[17] = p.user_data;
        rec[18..20].copy_from_slice(&scan_angle.to_le_bytes());
        rec[20..22].copy_from_slice(&p.point_source_id.to_le_bytes());
        rec[22..30].copy_from_slice(&gps_time.to_le_bytes());
        for ((dim, &at), &v) in layout
            .extra_dims
            .iter()
            .zip(&layout.extra_offsets)
            .zip(&p.extra)
        {
            match dim.data_type {
                ExtraType::F32 => rec[at..at + 4].copy_from_slice(&(v as f32).to_le_bytes()),
                ExtraType::F64 => rec[at..at + 8].copy_from_slice(&v.to_le_bytes()),
                // Clamped to 0..=1 (NaN is stored as 0).
                ExtraType::FractionU8 => {
                    rec[at] = (v.clamp(0.0, 1.0) / FRACTION_SCALE).round() as u8;
                }
            }
        }
        stats.add(counts, p.return_number, gps_time);
    }
    Ok(stats)
}

fn quantise(v: f64, axis: usize, layout: &PointLayout, index: usize) -> Result<i32> {
    let (scale, offset) = (layout.scale_m[axis], layout.offset_m[axis]);
    let counts = ((v - offset) / scale).round();
    if counts >= f64::from(i32::MIN) && counts <= f64::from(i32::MAX) {
        return Ok(counts as i32);
    }
    let name = ["X", "Y", "Z"][axis];
    if !v.is_finite() {
        return Err(Error::Invalid(format!(
            "LAS point {index} of the chunk: {name} is {v}"
        )));
    }
    let reach_m = f64::from(i32::MAX) * scale;
    Err(Error::Invalid(format!(
        "LAS point {index} of the chunk: {name} = {v} m is {:.3} m beyond what LAS can store with \
         scale {scale} m and offset {offset} m (offset +- {reach_m:.3} m); set the offset near \
         the data (e.g. the first point rounded) or use a coarser scale",
        (v - offset).abs() - reach_m
    )))
}

fn check_returns(p: &LasPoint, index: usize) -> Result<()> {
    let ok = |n: u8| (1..=NUMBER_OF_RETURNS_MAX).contains(&n);
    if ok(p.return_number) && ok(p.number_of_returns) {
        return Ok(());
    }
    Err(Error::Invalid(format!(
        "LAS point {index} of the chunk: return {} of {} (both must be 1..=15)",
        p.return_number, p.number_of_returns
    )))
}

fn scan_angle_counts(deg: f64, index: usize) -> Result<i16> {
    let counts = (deg / SCAN_ANGLE_UNIT_DEG).round();
    if counts.abs() <= SCAN_ANGLE_MAX_COUNTS {
        return Ok(counts as i16);
    }
    Err(Error::Invalid(format!(
        "LAS point {index} of the chunk: scan angle {deg} deg outside -180..=180 deg"
    )))
}

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
#[derive(Clone, Debug, PartialEq)]
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
/// deletes it, so the destination only ever holds a complete file.
pub struct LasWriter {
    path: PathBuf,
    config: LasWriterConfig,
    file: AtomicFile,
    stats: ChunkStats,
    offset_to_points: u32,
    scratch: Vec<u8>,
}

impl LasWriter {
    /// Starts a LAS file at `path` (created or replaced on [`finish`](LasWriter::finish)).
    pub fn create(path: impl AsRef<Path>, config: LasWriterConfig) -> Result<LasWriter> {
        let path = path.as_ref().to_path_buf();
        check_ascii_field("system identifier", &config.system_identifier, 0)?;
        let vlrs = vlr_bytes(&config)?;
        let mut file = AtomicFile::with_capacity(&path, WRITE_BUFFER_BYTES)?;
        file.write_all(&[0u8; HEADER_SIZE])?;
        file.write_all(&vlrs)?;
        let offset_to_points = u32::try_from(HEADER_SIZE + vlrs.len())
            .map_err(|_| Error::Invalid("LAS VLRs too large".into()))?;
        let record_len = config.layout.record_len;
        Ok(LasWriter {
            path,
            config,
            file,
            stats: ChunkStats::empty(record_len),
            offset_to_points,
            scratch: Vec::new(),
        })
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
        self.file.write_all(bytes)?;
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

    /// Writes the header, fsyncs, and renames the file into place.
    pub fn finish(self) -> Result<LasSummary> {
        let LasWriter {
            path,
            config,
            mut file,
            stats,
            offset_to_points,
            ..
        } = self;
        let summary = summarise(&path, &config.layout, &stats, offset_to_points);
        let header = header_bytes(&config, &stats, &summary, offset_to_points)
            .map_err(|e| Error::bad_file(&path, e))?;
        file.write_at(0, &header)?;
        file.commit()?;
        Ok(summary)
    }
}

fn summarise(path: &Path, layout: &PointLayout, stats: &ChunkStats, offset: u32) -> LasSummary {
    let empty = stats.count == 0;
    let to_m = |counts: [i32; 3]| -> [f64; 3] {
        if empty {
            return [0.0; 3];
        }
        std::array::from_fn(|k| f64::from(counts[k]) * layout.scale_m[k] + layout.offset_m[k])
    };
    LasSummary {
        path: path.to_path_buf(),
        point_count: stats.count,
        points_by_return: stats.points_by_return,
        min_m: to_m(stats.min_counts),
        max_m: to_m(stats.max_counts),
        gps_time_range: (!empty).then_some((stats.gps_time_min, stats.gps_time_max)),
        file_bytes: u64::from(offset) + stats.count * stats.record_len as u64,
    }
}

/// The 375-byte LAS 1.4 public header block (legacy counts zero: format 6).
fn header_bytes(
    config: &LasWriterConfig,
    stats: &ChunkStats,
    summary: &LasSummary,
    offset_to_points: u32,
) -> std::result::Result<Vec<u8>, String> {
    let layout = &config.layout;
    let mut global_encoding = GLOBAL_ENCODING_WKT;
    if matches!(layout.time, GpsTimeConvention::AdjustedStandard { .. }) {
        global_encoding |= GLOBAL_ENCODING_GPS_ADJUSTED;
    }
    let raw = las::raw::Header {
        file_source_id: config.file_source_id,
        global_encoding,
        version: Version::new(1, 4),
        system_identifier: fixed_32(&config.system_identifier),
        generating_software: fixed_32(concat!("kinescan ", env!("CARGO_PKG_VERSION"))),
        file_creation_day_of_year: config.creation_day_of_year,
        file_creation_year: config.creation_year,
        header_size: HEADER_SIZE as u16,
        offset_to_point_data: offset_to_points,
        number_of_variable_length_records: 1 + u32::from(!layout.extra_dims.is_empty()),
        point_data_record_format: POINT_FORMAT,
        point_data_record_length: layout.record_len as u16,
        number_of_point_records: 0,
        number_of_points_by_return: [0; 5],
        x_scale_factor: layout.scale_m[0],
        y_scale_factor: layout.scale_m[1],
        z_scale_factor: layout.scale_m[2],
        x_offset: layout.offset_m[0],
        y_offset: layout.offset_m[1],
        z_offset: layout.offset_m[2],
        max_x: summary.max_m[0],
        min_x: summary.min_m[0],
        max_y: summary.max_m[1],
        min_y: summary.min_m[1],
        max_z: summary.max_m[2],
        min_z: summary.min_m[2],
        start_of_waveform_data_packet_record: Some(0),
        evlr: None,
        large_file: Some(las::raw::header::LargeFile {
            number_of_point_records: stats.count,
            number_of_points_by_return: stats.points_by_return,
        }),
        ..Default::default()
    };
    let mut out = Vec::with_capacity(HEADER_SIZE);
    raw.write_to(&mut out)
        .map_err(|e| format!("LAS header: {e}"))?;
    if out.len() != HEADER_SIZE {
        return Err(format!(
            "LAS header is {} bytes, expected {HEADER_SIZE}",
            out.len()
        ));
    }
    Ok(out)
}

/// The WKT CRS VLR then (with extra dimensions) the Extra Bytes VLR, framed.
fn vlr_bytes(config: &LasWriterConfig) -> Result<Vec<u8>> {
    if config.wkt.is_empty() || config.wkt.contains('\0') {
        return Err(Error::Invalid(
            "LAS WKT CRS must be non-empty and contain no NUL".into(),
        ));
    }
    let mut wkt = config.wkt.as_bytes().to_vec();
    wkt.push(0);
    let mut out = Vec::new();
    push_vlr(
        &mut out,
        "LASF_Projection",
        2112,
        "OGC COORDINATE SYSTEM WKT",
        wkt,
    )?;
    let dims = &config.layout.extra_dims;
    if dims.is_empty() {
        return Ok(out);
    }
    let mut descriptors = Vec::with_capacity(dims.len() * EXTRA_BYTES_DESCRIPTOR_LEN);
    for dim in dims {
        descriptors.extend_from_slice(&extra_bytes_descriptor(dim));
    }
    push_vlr(&mut out, "LASF_Spec", 4, "Extra Bytes", descriptors)?;
    Ok(out)
}

fn push_vlr(
    out: &mut Vec<u8>,
    user_id: &str,
    record_id: u16,
    description: &str,
    data: Vec<u8>,
) -> Result<()> {
    let len = u16::try_from(data.len()).map_err(|_| {
        Error::Invalid(format!(
            "LAS {description} VLR of {} bytes exceeds 65535",
            data.len()
        ))
    })?;
    let vlr = las::raw::Vlr {
        reserved: 0,
        user_id: fixed_16(user_id),
        record_id,
        record_length_after_header: RecordLength::Vlr(len),
        description: fixed_32(description),
        data,
    };
    let start = out.len();
    vlr.write_to(&mut *out)
        .map_err(|e| Error::Invalid(format!("LAS VLR: {e}")))?;
    debug_assert_eq!(out.len() - start, VLR_HEADER_SIZE + usize::from(len));
    Ok(())
}

/// LAS 1.4 R15 EXTRA_BYTES struct (192 bytes): reserved[2], data_type, options (bit 3: scale
/// given; no no_data, min, max or offset), name[32], unused[4], no_data[3], min[3], max[3],
/// scale[3] (f64 at 112, only the first used), offset[3], description[32]; unused fields zero.
fn extra_bytes_descriptor(dim: &ExtraDim) -> [u8; EXTRA_BYTES_DESCRIPTOR_LEN] {
    let mut d = [0u8; EXTRA_BYTES_DESCRIPTOR_LEN];
    d[2] = dim.data_type.data_type_code();
    if let Some(scale) = dim.data_type.scale() {
        d[3] = 1 << 3;
        d[112..120].copy_from_slice(&scale.to_le_bytes());
    }
    d[4..36].copy_from_slice(&fixed_32(&dim.name));
    d[160..192].copy_from_slice(&fixed_32(&dim.description));
    d
}
