//! LAZ 1.4 output: a finished LAS file of this project (docs/conventions.md §7) compressed
//! with LASzip's layered chunked coding (the `laz` crate, pure Rust), chunks of
//! [`CHUNK_POINTS`] points compressed in parallel on the current rayon pool.
//!
//! The LAZ holds the LAS's header and VLRs unchanged (WKT, Extra Bytes descriptors) except for
//! what LASzip requires: the point format's compression bit (0x80), one more VLR (the
//! `laszip encoded` record 22204 describing the items: point 14, RGB/NIR none, the extra bytes
//! as one "byte 14" item) and the moved offset to the point data. The point data is the
//! offset of the chunk table (i64), the chunks, then the chunk table. Points, extra bytes and
//! their order are identical to the LAS's; readers (laspy with lazrs, LASzip, PDAL) restore
//! the LAS records byte for byte.

use std::path::Path;

use laz::laszip::{LazItemRecordBuilder, LazVlr, LazVlrBuilder};
use laz::ParLasZipCompressor;

use super::atomic::AtomicFile;
use crate::{Error, Result};

/// Points per LASzip chunk (LASzip's default): the unit of parallel compression and of random
/// access in readers.
pub const CHUNK_POINTS: u32 = 50_000;
/// Chunks handed to the parallel compressor at once (bounds memory to the mapped input).
const CHUNKS_PER_BATCH: usize = 16;

pub(super) const OFFSET_TO_POINTS_AT: usize = 96;
pub(super) const NUMBER_OF_VLRS_AT: usize = 100;
pub(super) const POINT_FORMAT_AT: usize = 104;
const RECORD_LEN_AT: usize = 105;
const POINT_COUNT_14_AT: usize = 247;
pub(super) const START_OF_EVLRS_AT: usize = 235;
const HEADER_SIZE_AT: usize = 94;
pub(super) const LAS14_HEADER_SIZE: usize = 375;
pub(super) const VLR_HEADER_SIZE: usize = 54;
pub(super) const COMPRESSED_BIT: u8 = 0x80;

/// Sizes of a compression.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LazSummary {
    /// Points compressed.
    pub point_count: u64,
    /// Size of the LAS read (bytes).
    pub las_bytes: u64,
    /// Size of the LAZ written (bytes).
    pub laz_bytes: u64,
}

/// Compresses the LAS 1.4 file `las` (as written by [`super::las::LasWriter`]: no EVLRs) into
/// `laz`, written atomically. Errors name the file.
pub fn compress_las(las: &Path, laz: &Path) -> Result<LazSummary> {
    let (map, layout) = map_las(las)?;
    let vlr = laszip_vlr(&layout).map_err(|p| Error::bad_file(las, p))?;
    let mut vlr_data = Vec::new();
    vlr.write_to(&mut vlr_data).map_err(|e| Error::io(laz, e))?;
    let mut out = AtomicFile::create(laz)?;
    out.write_all(&header_for_laz(&map, &layout, vlr_data.len()))?;
    out.write_all(&map[LAS14_HEADER_SIZE..layout.offset_to_points])?;
    out.write_all(&laszip_vlr_header(vlr_data.len()))?;
    out.write_all(&vlr_data)?;
    let points = &map[layout.offset_to_points..];
    let io = |e: std::io::Error| Error::io(laz, e);
    let mut compressor = ParLasZipCompressor::new(out.writer(), vlr)
        .map_err(|e| Error::bad_file(laz, format!("LAZ compressor: {e}")))?;
    let batch = CHUNK_POINTS as usize * CHUNKS_PER_BATCH * layout.record_len;
    for part in points.chunks(batch) {
        compressor.compress_many(part).map_err(io)?;
    }
    compressor
        .done()
        .map_err(|e| Error::bad_file(laz, format!("LAZ compressor: {e}")))?;
    out.commit()?;
    let laz_bytes = std::fs::metadata(laz).map_err(|e| Error::io(laz, e))?.len();
    Ok(LazSummary {
        point_count: layout.point_count,
        las_bytes: map.len() as u64,
        laz_bytes,
    })
}

/// The LAS 1.4 file `las` (one of this project's outputs) memory-mapped, with where its records
/// are; errors name the file. An empty file is refused as not a LAS file.
pub fn map_las(las: &Path) -> Result<(memmap2::Mmap, LasLayout)> {
    let file = std::fs::File::open(las).map_err(|e| Error::io(las, e))?;
    // SAFETY: the file is our own finished output (written atomically), not modified while
    // mapped; a later run replaces it by rename, leaving this mapping's inode intact.
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(las, e))?;
    let layout = LasLayout::of(&map).map_err(|p| Error::bad_file(las, p))?;
    Ok((map, layout))
}

/// Where the records of a LAS 1.4 file written by [`super::las::LasWriter`] are (what the
/// compression and the day's merge of unit outputs read).
pub struct LasLayout {
    /// Byte offset of the first point record.
    pub offset_to_points: usize,
    /// Point data record format.
    pub point_format: u8,
    /// Bytes per point record.
    pub record_len: usize,
    /// Point records in the file.
    pub point_count: u64,
}

impl LasLayout {
    /// Reads the header of `b` (a whole file); the problem when it is not an uncompressed LAS
    /// 1.4 file without EVLRs whose size matches its point count.
    pub fn of(b: &[u8]) -> std::result::Result<Self, String> {
        if b.len() < LAS14_HEADER_SIZE || &b[..4] != b"LASF" || b[24] != 1 || b[25] != 4 {
            return Err("not a LAS 1.4 file".into());
        }
        let u16_at = |i: usize| u16::from_le_bytes([b[i], b[i + 1]]);
        let u32_at = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().expect("4 bytes"));
        let u64_at = |i: usize| u64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
        if usize::from(u16_at(HEADER_SIZE_AT)) != LAS14_HEADER_SIZE
            || u64_at(START_OF_EVLRS_AT) != 0
        {
            return Err("LAS with a non-standard header or EVLRs: not supported for LAZ".into());
        }
        let layout = LasLayout {
            offset_to_points: u32_at(OFFSET_TO_POINTS_AT) as usize,
            point_format: b[POINT_FORMAT_AT],
            record_len: usize::from(u16_at(RECORD_LEN_AT)),
            point_count: u64_at(POINT_COUNT_14_AT),
        };
        let expected =
            layout.offset_to_points as u64 + layout.point_count * layout.record_len as u64;
        if b[POINT_FORMAT_AT] & COMPRESSED_BIT != 0 || expected != b.len() as u64 {
            return Err(format!(
                "LAS of {} bytes does not hold {} records of {} bytes after byte {}",
                b.len(),
                layout.point_count,
                layout.record_len,
                layout.offset_to_points
            ));
        }
        Ok(layout)
    }

    /// The bytes of record `i` of the whole file `b`.
    pub fn record<'a>(&self, b: &'a [u8], i: usize) -> &'a [u8] {
        let at = self.offset_to_points + i * self.record_len;
        &b[at..at + self.record_len]
    }
}

/// LASzip items for the point format with its extra bytes, fixed chunks of [`CHUNK_POINTS`].
fn laszip_vlr(layout: &LasLayout) -> std::result::Result<LazVlr, String> {
    Ok(LazVlrBuilder::new(laszip_items(layout)?)
        .with_fixed_chunk_size(CHUNK_POINTS)
        .build())
}

/// LASzip items for the point format (6 to 8) with its extra bytes.
pub(super) fn laszip_items(
    layout: &LasLayout,
) -> std::result::Result<Vec<laz::laszip::LazItem>, String> {
    let core = match layout.point_format {
        6 => 30,
        7 => 36,
        8 => 38,
        f => {
            return Err(format!(
                "point format {f}: LAZ output supports formats 6 to 8"
            ))
        }
    };
    let extra = layout
        .record_len
        .checked_sub(core)
        .and_then(|e| u16::try_from(e).ok())
        .ok_or_else(|| format!("record length {} below the format's", layout.record_len))?;
    LazItemRecordBuilder::default_for_point_format_id(layout.point_format, extra)
        .map_err(|e| e.to_string())
}

/// The LAS header with the compression bit, one more VLR and the moved point offset.
fn header_for_laz(b: &[u8], layout: &LasLayout, vlr_data_len: usize) -> Vec<u8> {
    let mut h = b[..LAS14_HEADER_SIZE].to_vec();
    let offset = (layout.offset_to_points + VLR_HEADER_SIZE + vlr_data_len) as u32;
    h[OFFSET_TO_POINTS_AT..OFFSET_TO_POINTS_AT + 4].copy_from_slice(&offset.to_le_bytes());
    let vlrs = u32::from_le_bytes(
        h[NUMBER_OF_VLRS_AT..NUMBER_OF_VLRS_AT + 4]
            .try_into()
            .expect("4"),
    );
    h[NUMBER_OF_VLRS_AT..NUMBER_OF_VLRS_AT + 4].copy_from_slice(&(vlrs + 1).to_le_bytes());
    h[POINT_FORMAT_AT] |= COMPRESSED_BIT;
    h
}

/// The 54-byte VLR header of the `laszip encoded` record.
fn laszip_vlr_header(data_len: usize) -> Vec<u8> {
    vlr_header(
        LazVlr::USER_ID,
        LazVlr::RECORD_ID,
        data_len as u16,
        LazVlr::DESCRIPTION,
    )
}

/// A 54-byte VLR header: reserved, user id, record id, length after the header, description.
pub(super) fn vlr_header(
    user_id: &str,
    record_id: u16,
    data_len: u16,
    description: &str,
) -> Vec<u8> {
    let mut v = vec![0u8; VLR_HEADER_SIZE];
    v[2..2 + user_id.len()].copy_from_slice(user_id.as_bytes());
    v[18..20].copy_from_slice(&record_id.to_le_bytes());
    v[20..22].copy_from_slice(&data_len.to_le_bytes());
    v[22..22 + description.len()].copy_from_slice(description.as_bytes());
    v
}
