//! LAS 1.2-1.4 input (any point format 0-10), memory-mapped: the header, the VLRs and EVLRs
//! as byte ranges (so a copy can keep them byte for byte), the extra-bytes descriptors, the
//! CRS (WKT VLR 2112 or the GeoTIFF key directory 34735), the GPS time convention, and each
//! record's coordinates and time. LAZ input is decompressed (the `laz` crate) to a LAS file
//! first ([`decompress_laz`]). Errors name the file and, for records, the record.

pub use super::public_header::EXTRA_BYTES_DESCRIPTOR_LEN;
use super::public_header::{
    f64_at, record_ids, text, u16_at, u64_at, PublicHeader, EVLR_HEADER_LEN, VLR_HEADER_LEN,
};
use super::{GpsTimeConvention, SECONDS_PER_GPS_WEEK};
use crate::io::atomic::AtomicFile;
use crate::{Error, Result};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Global encoding bit 0: GPS time is adjusted standard GPS time.
const ADJUSTED_TIME_BIT: u16 = 1;

/// The CRS of a cloud as stored.
#[derive(Debug, Clone, PartialEq)]
pub enum LasCrs {
    /// OGC WKT (VLR 2112), NULs trimmed.
    Wkt(String),
    /// GeoTIFF keys (the short values of the key directory; 32767 = user-defined).
    GeoKeys(GeoKeys),
}

/// The GeoTIFF keys that fix a frame (each `None` when absent).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GeoKeys {
    /// `GTModelTypeGeoKey` (1024): 1 projected, 2 geographic, 3 geocentric.
    pub model_type: Option<u16>,
    /// `GeographicTypeGeoKey` (2048).
    pub geographic: Option<u16>,
    /// `ProjectedCSTypeGeoKey` (3072).
    pub projected: Option<u16>,
    /// `ProjectionGeoKey` (3074): e.g. 16011 = UTM zone 11N.
    pub projection: Option<u16>,
}

/// One variable-length record (or extended one): where it is in the file.
#[derive(Debug, Clone, PartialEq)]
pub struct VlrSpan {
    /// User id (NULs trimmed).
    pub user_id: String,
    /// Record id.
    pub record_id: u16,
    /// Whole record (header and payload) in the file.
    pub bytes: Range<usize>,
    /// Payload in the file.
    pub payload: Range<usize>,
}

/// One extra dimension of the input (from its Extra Bytes VLR).
#[derive(Debug, Clone, PartialEq)]
pub struct InputExtraDim {
    /// Name (NULs trimmed).
    pub name: String,
    /// Byte offset within the record's extra bytes.
    pub offset: usize,
    /// Bytes in a record.
    pub size: usize,
    /// The 192-byte descriptor as stored.
    pub descriptor: Vec<u8>,
}

/// A LAS file mapped for reading.
#[derive(Debug)]
pub struct LasInput {
    path: PathBuf,
    map: memmap2::Mmap,
    /// Version (major, minor).
    pub version: (u8, u8),
    /// Header size (bytes).
    pub header_size: usize,
    /// Point data record format (0-10).
    pub point_format: u8,
    /// Bytes per record.
    pub record_len: usize,
    /// Byte offset of the first record.
    pub offset_to_points: usize,
    /// Records.
    pub point_count: u64,
    /// Coordinate scale (m).
    pub scale: [f64; 3],
    /// Coordinate offset (m).
    pub offset: [f64; 3],
    /// Global encoding.
    pub global_encoding: u16,
    /// VLRs in file order.
    pub vlrs: Vec<VlrSpan>,
    /// EVLRs in file order.
    pub evlrs: Vec<VlrSpan>,
    /// Extra dimensions (empty without an Extra Bytes VLR).
    pub extra_dims: Vec<InputExtraDim>,
}

/// Bytes of the core record of a point format (before extra bytes).
pub fn core_record_len(format: u8) -> Option<usize> {
    [20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67]
        .get(usize::from(format))
        .copied()
}

/// Offset of GPS time in a record of `format`, `None` for formats without time (0, 2).
pub fn gps_time_offset(format: u8) -> Option<usize> {
    match format {
        1 | 3 | 4 | 5 => Some(20),
        6..=10 => Some(22),
        _ => None,
    }
}

/// Whether `path` is a LAZ file (LAS signature with a compressed point format).
pub fn is_laz(path: &Path) -> Result<bool> {
    let mut head = [0u8; 105];
    use std::io::Read;
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let n = f.read(&mut head).map_err(|e| Error::io(path, e))?;
    if n < 105 || &head[..4] != b"LASF" {
        return Err(Error::bad_file(
            path,
            "not a LAS/LAZ file (no LASF signature)",
        ));
    }
    Ok(head[104] & 0xC0 != 0)
}

impl LasInput {
    /// Maps and parses `path` (uncompressed LAS).
    pub fn open(path: &Path) -> Result<LasInput> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        // SAFETY: read-only map of an input; kinescan never writes its inputs.
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
        Self::parse(path, map)
    }

    fn parse(path: &Path, map: memmap2::Mmap) -> Result<LasInput> {
        let bad = |p: String| Error::bad_file(path, p);
        let b = &map[..];
        let Some(h) = PublicHeader::parse(b) else {
            return Err(bad(
                "not a LAS file (no LASF signature or header shorter than 227 bytes)".into(),
            ));
        };
        let version = h.version;
        if version.0 != 1 || !(2..=4).contains(&version.1) {
            return Err(bad(format!(
                "LAS {}.{}: LAS 1.2 to 1.4 are read",
                version.0, version.1
            )));
        }
        let header_size = h.header_size;
        let min_header = match version.1 {
            2 => 227,
            3 => 235,
            _ => 375,
        };
        if header_size < min_header || header_size > b.len() {
            return Err(bad(format!(
                "header size {header_size} B invalid for LAS 1.{}",
                version.1
            )));
        }
        if h.compressed() {
            return Err(bad("compressed (LAZ) point data: decompress first".into()));
        }
        let point_format = h.format_byte;
        let core = core_record_len(point_format).ok_or_else(|| {
            bad(format!(
                "point format {point_format}: formats 0 to 10 are read"
            ))
        })?;
        let record_len = usize::from(h.record_len);
        if record_len < core {
            return Err(bad(format!(
                "record length {record_len} B below the {core} B of point format {point_format}"
            )));
        }
        let offset_to_points = h.offset_to_points as usize;
        let point_count = h.point_count();
        let (evlr_start, evlr_count) = h.evlrs();
        let (scale, offset) = (h.scale, h.offset);
        if scale.iter().any(|s| !(s.is_finite() && *s != 0.0))
            || offset.iter().any(|o| !o.is_finite())
        {
            return Err(bad(format!("invalid scale {scale:?} or offset {offset:?}")));
        }
        // VLRs.
        let mut vlrs = Vec::new();
        let mut at = header_size;
        for k in 0..h.vlr_count {
            if at + VLR_HEADER_LEN > offset_to_points {
                return Err(bad(format!(
                    "VLR {k} runs past the point data offset {offset_to_points}"
                )));
            }
            let len = usize::from(u16_at(b, at + 20));
            let end = at + VLR_HEADER_LEN + len;
            if end > offset_to_points {
                return Err(bad(format!(
                    "VLR {k} ({len} B) runs past the point data offset"
                )));
            }
            let (user_id, record_id) = record_ids(&b[at..]);
            vlrs.push(VlrSpan {
                user_id,
                record_id,
                bytes: at..end,
                payload: at + VLR_HEADER_LEN..end,
            });
            at = end;
        }
        let points_end = offset_to_points as u64 + point_count * record_len as u64;
        if points_end > b.len() as u64 {
            let whole = (b.len().saturating_sub(offset_to_points)) / record_len;
            return Err(bad(format!(
                "truncated: the header announces {point_count} records of {record_len} B from byte \
                 {offset_to_points}, the file holds {whole} whole records ({} B)",
                b.len()
            )));
        }
        // EVLRs.
        let mut evlrs = Vec::new();
        let mut at = evlr_start as usize;
        for k in 0..evlr_count {
            if (at as u64) < points_end || at + EVLR_HEADER_LEN > b.len() {
                return Err(bad(format!(
                    "EVLR {k} at byte {at} outside the file or inside the points"
                )));
            }
            let len = u64_at(b, at + 20) as usize;
            let end = at
                .checked_add(EVLR_HEADER_LEN + len)
                .filter(|&e| e <= b.len());
            let end = end
                .ok_or_else(|| bad(format!("EVLR {k} ({len} B) runs past the end of the file")))?;
            let (user_id, record_id) = record_ids(&b[at..]);
            evlrs.push(VlrSpan {
                user_id,
                record_id,
                bytes: at..end,
                payload: at + EVLR_HEADER_LEN..end,
            });
            at = end;
        }
        let mut input = LasInput {
            path: path.to_path_buf(),
            version,
            header_size,
            point_format,
            record_len,
            offset_to_points,
            point_count,
            scale,
            offset,
            global_encoding: h.global_encoding,
            vlrs,
            evlrs,
            extra_dims: Vec::new(),
            map,
        };
        input.extra_dims = input.read_extra_dims(core)?;
        Ok(input)
    }

    fn read_extra_dims(&self, core: usize) -> Result<Vec<InputExtraDim>> {
        let Some(v) = self.find_vlr("LASF_Spec", 4) else {
            return Ok(Vec::new());
        };
        let payload = &self.map[v.payload.clone()];
        let mut dims = Vec::new();
        let mut offset = 0;
        for d in payload.chunks_exact(EXTRA_BYTES_DESCRIPTOR_LEN) {
            let data_type = d[2];
            let size = match data_type {
                // Undocumented bytes: `options` holds their count (LAS 1.4 R15 Table 24).
                0 => usize::from(d[3]).max(1),
                1 | 2 => 1,
                3 | 4 => 2,
                5 | 6 | 9 => 4,
                7 | 8 | 10 => 8,
                t => {
                    return Err(Error::bad_file(
                        &self.path,
                        format!("Extra Bytes descriptor with data type {t}: only 0 to 10 are read"),
                    ))
                }
            };
            dims.push(InputExtraDim {
                name: text(&d[4..36]),
                offset,
                size,
                descriptor: d.to_vec(),
            });
            offset += size;
        }
        if core + offset > self.record_len {
            return Err(Error::bad_file(
                &self.path,
                format!(
                    "Extra Bytes VLR describes {offset} B but records have {} B after the core",
                    self.record_len - core
                ),
            ));
        }
        Ok(dims)
    }

    /// Names the file `path` in errors (a LAZ cloud read from its decompressed copy).
    pub fn set_path(&mut self, path: &Path) {
        self.path = path.to_path_buf();
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The whole file's bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.map
    }

    /// The first VLR with `user_id` and `record_id`.
    pub fn find_vlr(&self, user_id: &str, record_id: u16) -> Option<&VlrSpan> {
        self.vlrs
            .iter()
            .chain(&self.evlrs)
            .find(|v| v.user_id == user_id && v.record_id == record_id)
    }

    /// Bytes of the core record (before extra bytes).
    pub fn core_len(&self) -> usize {
        core_record_len(self.point_format).expect("checked on open")
    }

    /// Record `i`'s bytes.
    #[inline]
    pub fn record(&self, i: usize) -> &[u8] {
        let at = self.offset_to_points + i * self.record_len;
        &self.map[at..at + self.record_len]
    }

    /// Records `range`'s bytes.
    pub fn records(&self, range: Range<usize>) -> &[u8] {
        let at = self.offset_to_points;
        &self.map[at + range.start * self.record_len..at + range.end * self.record_len]
    }

    /// Tells the kernel the pages of records `range` are done with (memory stays flat).
    pub fn release(&self, range: Range<usize>) {
        let page = 4096;
        let start = (self.offset_to_points + range.start * self.record_len).div_ceil(page) * page;
        let end = (self.offset_to_points + range.end * self.record_len) / page * page;
        if end > start {
            // SAFETY: advising about pages of our read-only mapping.
            let _ = unsafe {
                self.map.unchecked_advise_range(
                    memmap2::UncheckedAdvice::DontNeed,
                    start,
                    end - start,
                )
            };
        }
    }

    /// Coordinates (m) of a record.
    #[inline]
    pub fn xyz(&self, rec: &[u8]) -> [f64; 3] {
        let c = |k: usize| {
            let v = i32::from_le_bytes(rec[4 * k..4 * k + 4].try_into().expect("4 bytes"));
            f64::from(v) * self.scale[k] + self.offset[k]
        };
        [c(0), c(1), c(2)]
    }

    /// The stored GPS time of a record (needs a format with time).
    #[inline]
    pub fn stored_time(&self, rec: &[u8], time_at: usize) -> f64 {
        f64_at(rec, time_at)
    }

    /// Where GPS time is in a record, or an error naming the file when the format has none.
    pub fn time_offset(&self) -> Result<usize> {
        gps_time_offset(self.point_format).ok_or_else(|| {
            Error::bad_file(
                &self.path,
                format!(
                    "point format {} has no GPS time: per-point poses need the time of every \
                     point (formats 1, 3-10 carry it)",
                    self.point_format
                ),
            )
        })
    }

    /// How the stored time relates to the trajectory's seconds of week: adjusted standard GPS
    /// time (global encoding bit 0) needs the GPS week (`gps_week`, from the pipeline).
    pub fn time_convention(&self, gps_week: Option<u32>) -> Result<GpsTimeConvention> {
        if self.global_encoding & ADJUSTED_TIME_BIT == 0 {
            return Ok(GpsTimeConvention::WeekSeconds);
        }
        match gps_week {
            Some(gps_week) => Ok(GpsTimeConvention::AdjustedStandard { gps_week }),
            None => Err(Error::bad_file(
                &self.path,
                "GPS time is adjusted standard time (global encoding bit 0): set inputs.gps_week \
                 to the trajectory's GPS week to relate it to the SBET's seconds of week",
            )),
        }
    }

    /// The CRS: the WKT VLR/EVLR, else the GeoTIFF keys; an error naming the file when it has
    /// neither.
    pub fn crs(&self) -> Result<LasCrs> {
        if let Some(v) = self.find_vlr("LASF_Projection", 2112) {
            let wkt = text(&self.map[v.payload.clone()]);
            if !wkt.is_empty() {
                return Ok(LasCrs::Wkt(wkt));
            }
        }
        if let Some(v) = self.find_vlr("LASF_Projection", 34735) {
            let p = &self.map[v.payload.clone()];
            let shorts = p.len() / 2;
            let n = if shorts >= 4 {
                usize::from(u16_at(p, 6))
            } else {
                0
            };
            let mut keys = GeoKeys::default();
            for k in 0..n.min(shorts.saturating_sub(4) / 4) {
                let e = 8 + 8 * k;
                let (id, loc, value) = (u16_at(p, e), u16_at(p, e + 2), u16_at(p, e + 6));
                if loc != 0 {
                    continue;
                }
                match id {
                    1024 => keys.model_type = Some(value),
                    2048 => keys.geographic = Some(value),
                    3072 => keys.projected = Some(value),
                    3074 => keys.projection = Some(value),
                    _ => {}
                }
            }
            if keys != GeoKeys::default() {
                return Ok(LasCrs::GeoKeys(keys));
            }
        }
        Err(Error::bad_file(
            &self.path,
            "no CRS: neither a WKT VLR (LASF_Projection 2112) nor GeoTIFF keys (34735) with an \
             EPSG code; the frame of X, Y, Z must be known to recover each point's geometry",
        ))
    }
}

/// Time of week (s) of a stored time under `convention`.
#[inline]
pub fn seconds_of_week(stored: f64, convention: GpsTimeConvention) -> f64 {
    stored - convention.shift_s()
}

/// Whether a seconds-of-week time is plausible (within one week).
pub fn plausible_week_seconds(t: f64) -> bool {
    (-1.0..SECONDS_PER_GPS_WEEK + 1.0).contains(&t)
}

/// Decompresses the LAZ `laz` into the LAS file `las` (written atomically): the same header
/// (compression bit cleared, the `laszip encoded` VLR removed, offsets moved), VLRs, records
/// and EVLRs. Errors name the LAZ file; a truncated LAZ is refused.
pub fn decompress_laz(laz: &Path, las: &Path) -> Result<()> {
    use laz::LasZipDecompressor;
    let file = std::fs::File::open(laz).map_err(|e| Error::io(laz, e))?;
    // SAFETY: read-only map of an input.
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(laz, e))?;
    let b = &map[..];
    let bad = |p: String| Error::bad_file(laz, p);
    let Some(h) = PublicHeader::parse(b) else {
        return Err(bad("not a LAZ file (no LASF signature)".into()));
    };
    let header_size = h.header_size;
    let offset_to_points = h.offset_to_points as usize;
    if header_size > b.len() || offset_to_points > b.len() || offset_to_points < header_size {
        return Err(bad("truncated or corrupt header".into()));
    }
    let record_len = usize::from(h.record_len);
    let count = h.point_count();
    let (evlr_start, evlr_count) = h.evlrs();
    let evlr_start = evlr_start as usize;
    // VLRs: keep all but laszip's.
    let mut kept = Vec::new();
    let mut laz_vlr = None;
    let mut at = header_size;
    for k in 0..h.vlr_count {
        if at + VLR_HEADER_LEN > offset_to_points {
            return Err(bad(format!("VLR {k} runs past the point data offset")));
        }
        let len = usize::from(u16_at(b, at + 20));
        let end = at + VLR_HEADER_LEN + len;
        if end > offset_to_points {
            return Err(bad(format!("VLR {k} runs past the point data offset")));
        }
        if record_ids(&b[at..]) == ("laszip encoded".to_string(), 22204) {
            laz_vlr = Some(
                laz::LazVlr::from_buffer(&b[at + VLR_HEADER_LEN..end])
                    .map_err(|e| bad(format!("laszip VLR: {e}")))?,
            );
        } else {
            kept.push(at..end);
        }
        at = end;
    }
    let vlr = laz_vlr.ok_or_else(|| bad("compressed point format without a laszip VLR".into()))?;
    let points_end = if evlr_count > 0 { evlr_start } else { b.len() };
    if points_end > b.len() || points_end < offset_to_points {
        return Err(bad(format!(
            "EVLR offset {evlr_start} outside the file: truncated"
        )));
    }
    let vlr_bytes: usize = kept.iter().map(|r| r.len()).sum();
    let new_offset = header_size + vlr_bytes;
    let mut header = b[..header_size].to_vec();
    header[96..100].copy_from_slice(&(new_offset as u32).to_le_bytes());
    header[100..104].copy_from_slice(&(kept.len() as u32).to_le_bytes());
    header[104] &= !0xC0;
    let new_points_end = new_offset as u64 + count * record_len as u64;
    if evlr_count > 0 {
        header[235..243].copy_from_slice(&new_points_end.to_le_bytes());
    }
    let mut out = AtomicFile::create(las)?;
    out.write_all(&header)?;
    for r in &kept {
        out.write_all(&b[r.clone()])?;
    }
    // The chunk table offset at the start of the point data is absolute in the file.
    let mut source = std::io::Cursor::new(&b[..points_end]);
    source.set_position(offset_to_points as u64);
    let mut dec = LasZipDecompressor::new(source, vlr).map_err(|e| bad(format!("LAZ: {e}")))?;
    let batch = 50_000usize;
    let mut buf = vec![0u8; batch * record_len];
    let mut left = count as usize;
    let mut done = 0usize;
    while left > 0 {
        let n = left.min(batch);
        let part = &mut buf[..n * record_len];
        dec.decompress_many(part).map_err(|e| {
            bad(format!(
                "LAZ data ends or is corrupt near point {done} of {count}: {e} (truncated file?)"
            ))
        })?;
        out.write_all(part)?;
        left -= n;
        done += n;
        crate::interrupt::check()?;
    }
    if evlr_count > 0 {
        out.write_all(&b[evlr_start..])?;
    }
    out.commit()
}
