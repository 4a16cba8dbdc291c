//! COPC 1.0 output (Cloud Optimized Point Cloud, <https://copc.io>): a finished LAS file of
//! this project (docs/conventions.md §7) reorganised as a clustered octree, one LAZ chunk per
//! octree node, so that viewers and servers read only the nodes a view needs.
//!
//! Written here on the `laz` crate (variable-size chunks) because the georust `copc-rs` writer
//! needs `las` 0.9 and `laz` 0.9 while this project uses `las` 0.11 and `laz` 0.13.
//!
//! Layout: the LAS 1.4 header (compression bit set, point count and bounds unchanged), the
//! `copc` info VLR (record 1, 160 bytes) first, the LAS's own VLRs (WKT, Extra Bytes), the
//! `laszip encoded` VLR (variable chunks), the chunks, LASzip's chunk table, and the `copc`
//! hierarchy EVLR (record 1000: one page, an entry per non-empty node).
//!
//! Octree: a cube about the centre of the LAS bounds, half size the largest half extent. Each
//! node holds a grid of [`GRID`]^3 cells; a node reached by at most [`LEAF_POINTS`] points is a
//! leaf holding them all, otherwise the first point (file order) of each of its cells stays and
//! the others go one level down ([`MAX_LEVEL`] takes what is left). So every point is in
//! exactly one node, every node's points lie inside its cube, every ancestor of a non-empty
//! node is non-empty, and the file does not depend on the thread count.
//! Within a node the points keep their LAS order; nodes are written in key order.

use std::io::Cursor;
use std::path::Path;

use laz::laszip::{ChunkTable, ChunkTableEntry, LazVlr, LazVlrBuilder};
use laz::LasZipCompressor;
use rayon::prelude::*;

use super::atomic::write_atomic;
use super::laz::{
    laszip_items, vlr_header, LasLayout, LazSummary, COMPRESSED_BIT, LAS14_HEADER_SIZE,
    NUMBER_OF_VLRS_AT, OFFSET_TO_POINTS_AT, POINT_FORMAT_AT, START_OF_EVLRS_AT, VLR_HEADER_SIZE,
};
use crate::{Error, Result};

/// Cells per node edge: the root's point spacing is its edge length over this.
pub const GRID: u32 = 128;
/// Deepest level; it holds every point whose cells above were all taken.
pub const MAX_LEVEL: u32 = 16;
/// A node reached by at most this many points keeps them all (LASzip's default chunk size).
pub const LEAF_POINTS: usize = 50_000;

const USER_ID: &str = "copc";
const INFO_RECORD: u16 = 1;
const HIERARCHY_RECORD: u16 = 1000;
const INFO_LEN: usize = 160;
const ENTRY_LEN: usize = 32;
const EVLR_HEADER_SIZE: usize = 60;
const NUMBER_OF_EVLRS_AT: usize = 243;
const SCALE_AT: usize = 131;
const OFFSET_AT: usize = 155;
const MAX_X_AT: usize = 179;
/// Byte of the GPS time in point formats 6 to 8.
const GPS_TIME_IN_RECORD: usize = 22;

/// An octree node: level, then x, y, z indices at that level.
type NodeKey = [u32; 4];

/// Converts the LAS 1.4 file `las` (as written by [`super::las::LasWriter`]) into the COPC file
/// `copc`, written atomically; nodes reached by at most `leaf_points` points are leaves (the
/// pipeline uses [`LEAF_POINTS`]). Errors name the file.
pub fn write_copc(las: &Path, copc: &Path, leaf_points: usize) -> Result<LazSummary> {
    let (map, layout) = super::laz::map_las(las)?;
    let bad = |p: String| Error::bad_file(las, p);
    let cube = Cube::of_header(&map);
    let nodes = nodes(&map, &layout, &cube, leaf_points);
    let items = laszip_items(&layout).map_err(bad)?;
    let vlr = LazVlrBuilder::new(items).with_variable_chunk_size().build();
    let mut laszip = Vec::new();
    vlr.write_to(&mut laszip).map_err(|e| Error::io(copc, e))?;
    let own_vlrs = &map[LAS14_HEADER_SIZE..layout.offset_to_points];
    let points_at = LAS14_HEADER_SIZE
        + VLR_HEADER_SIZE
        + INFO_LEN
        + own_vlrs.len()
        + VLR_HEADER_SIZE
        + laszip.len();
    let io = |e: std::io::Error| Error::io(copc, e);
    let (mut bytes, entries) = point_data(&map, &layout, &vlr, &nodes, points_at).map_err(io)?;
    let evlr_at = bytes.len();
    bytes.extend(evlr_header(entries.len() * ENTRY_LEN));
    entries.iter().for_each(|e| bytes.extend_from_slice(e));
    let hierarchy = ((evlr_at + EVLR_HEADER_SIZE) as u64, entries.len());
    let mut head = header(&map, points_at, evlr_at);
    head.extend(vlr_header(
        USER_ID,
        INFO_RECORD,
        INFO_LEN as u16,
        "copc info",
    ));
    head.extend(info(&cube, hierarchy, gps_time_range(&map, &layout)));
    head.extend_from_slice(own_vlrs);
    let laszip_header = (LazVlr::USER_ID, LazVlr::RECORD_ID, LazVlr::DESCRIPTION);
    head.extend(vlr_header(
        laszip_header.0,
        laszip_header.1,
        laszip.len() as u16,
        laszip_header.2,
    ));
    head.extend(laszip);
    assert_eq!(head.len(), points_at);
    bytes[..points_at].copy_from_slice(&head);
    write_atomic(copc, &bytes)?;
    Ok(LazSummary {
        point_count: layout.point_count,
        las_bytes: map.len() as u64,
        laz_bytes: bytes.len() as u64,
    })
}

/// The octree's root cube, in the LAS's coordinates (m or the frame's unit), and the header's
/// scale and offset to read the records' integer coordinates.
struct Cube {
    min: [f64; 3],
    edge: f64,
    scale: [f64; 3],
    offset: [f64; 3],
}

impl Cube {
    fn of_header(b: &[u8]) -> Cube {
        let f64_at = |i: usize| f64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
        let axis = |k: usize| (f64_at(MAX_X_AT + 16 * k + 8), f64_at(MAX_X_AT + 16 * k));
        let (lo, hi) = ([0, 1, 2].map(|k| axis(k).0), [0, 1, 2].map(|k| axis(k).1));
        // A little over the largest extent so the maximum falls inside the last cell.
        let edge = (0..3).map(|k| hi[k] - lo[k]).fold(1e-3, f64::max) * (1.0 + 1e-9);
        let centre = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
        Cube {
            min: centre.map(|c| c - 0.5 * edge),
            edge,
            scale: [0, 1, 2].map(|k| f64_at(SCALE_AT + 8 * k)),
            offset: [0, 1, 2].map(|k| f64_at(OFFSET_AT + 8 * k)),
        }
    }

    /// The point's cell indices at `level` (GRID << level cells per edge).
    fn cell(&self, record: &[u8], level: u32) -> [u32; 3] {
        let cells = GRID << level;
        [0, 1, 2].map(|k| {
            let raw = i32::from_le_bytes(record[4 * k..4 * k + 4].try_into().expect("4 bytes"));
            let x = f64::from(raw) * self.scale[k] + self.offset[k];
            let i = ((x - self.min[k]) / self.edge * f64::from(cells)).floor();
            i.clamp(0.0, f64::from(cells - 1)) as u32
        })
    }
}

/// Every node's point indices (file order), by node key (level, x, y, z) in key order. Level
/// by level, the points not yet placed are sorted by (node, cell, index): a node reached by
/// at most `leaf_points` points keeps them all (a leaf); otherwise the first point of each
/// cell stays and the others go on to the next level.
fn nodes(
    map: &[u8],
    layout: &LasLayout,
    cube: &Cube,
    leaf_points: usize,
) -> Vec<(NodeKey, Vec<u32>)> {
    let mut pending: Vec<u32> = (0..layout.point_count as u32).collect();
    let mut placed: Vec<(NodeKey, u32)> = Vec::with_capacity(pending.len());
    for level in 0..=MAX_LEVEL {
        let mut keyed: Vec<([u32; 3], [u32; 3], u32)> = pending
            .par_iter()
            .map(|&i| {
                let cell = cube.cell(layout.record(map, i as usize), level);
                (cell.map(|c| c / GRID), cell, i)
            })
            .collect();
        keyed.par_sort_unstable();
        pending.clear();
        for node in keyed.chunk_by(|a, b| a.0 == b.0) {
            let [x, y, z] = node[0].0;
            let key = [level, x, y, z];
            if node.len() <= leaf_points || level == MAX_LEVEL {
                placed.extend(node.iter().map(|&(_, _, i)| (key, i)));
                continue;
            }
            for cell in node.chunk_by(|a, b| a.1 == b.1) {
                placed.push((key, cell[0].2));
                pending.extend(cell[1..].iter().map(|&(_, _, i)| i));
            }
        }
        if pending.is_empty() {
            break;
        }
    }
    placed.par_sort_unstable();
    placed
        .chunk_by(|a, b| a.0 == b.0)
        .map(|node| (node[0].0, node.iter().map(|&(_, i)| i).collect()))
        .collect()
}

/// One node's records compressed as one LASzip chunk (chunks are coded independently, so
/// they compress in parallel and concatenate).
fn chunk(
    map: &[u8],
    layout: &LasLayout,
    vlr: &LazVlr,
    members: &[u32],
) -> std::io::Result<Vec<u8>> {
    let mut records = Vec::with_capacity(members.len() * layout.record_len);
    for &i in members {
        records.extend_from_slice(layout.record(map, i as usize));
    }
    let mut compressor = LasZipCompressor::new(Cursor::new(Vec::new()), vlr.clone())
        .map_err(std::io::Error::other)?;
    compressor.compress_many(&records)?;
    compressor.finish_current_chunk()?;
    let bytes = compressor.into_inner().into_inner();
    // After the 8 bytes the compressor reserves for the chunk table's offset.
    Ok(bytes[ChunkTable::OFFSET_SIZE..].to_vec())
}

/// The file up to the end of the chunk table (`points_at` zero bytes for the header and VLRs,
/// the chunk table's offset, the nodes' chunks, the table) and each node's hierarchy entry.
fn point_data(
    map: &[u8],
    layout: &LasLayout,
    vlr: &LazVlr,
    nodes: &[(NodeKey, Vec<u32>)],
    points_at: usize,
) -> std::io::Result<(Vec<u8>, Vec<[u8; ENTRY_LEN]>)> {
    let chunks: Vec<Vec<u8>> = nodes
        .par_iter()
        .map(|(_, members)| chunk(map, layout, vlr, members))
        .collect::<std::io::Result<_>>()?;
    let mut bytes = vec![0u8; points_at + ChunkTable::OFFSET_SIZE];
    let mut table = ChunkTable::with_capacity(chunks.len());
    let mut entries = Vec::with_capacity(nodes.len());
    for ((key, members), c) in nodes.iter().zip(&chunks) {
        let at = bytes.len() as u64;
        entries.push(entry(*key, at, c.len() as u64, members.len()));
        table.push(ChunkTableEntry {
            point_count: members.len() as u64,
            byte_count: c.len() as u64,
        });
        bytes.extend_from_slice(c);
    }
    let table_at = bytes.len() as u64;
    bytes[points_at..points_at + ChunkTable::OFFSET_SIZE].copy_from_slice(&table_at.to_le_bytes());
    table.write_to(&mut bytes, vlr)?;
    Ok((bytes, entries))
}

/// A hierarchy entry: key (level, x, y, z as i32), chunk offset (u64), byte size and point
/// count (i32).
fn entry(key: NodeKey, offset: u64, size: u64, points: usize) -> [u8; ENTRY_LEN] {
    let mut e = [0u8; ENTRY_LEN];
    for (k, v) in key.iter().enumerate() {
        e[4 * k..4 * k + 4].copy_from_slice(&(*v as i32).to_le_bytes());
    }
    e[16..24].copy_from_slice(&offset.to_le_bytes());
    e[24..28].copy_from_slice(&(size as i32).to_le_bytes());
    e[28..32].copy_from_slice(&(points as i32).to_le_bytes());
    e
}

/// The 160-byte info VLR: centre, half size, root spacing, hierarchy page (offset, entries),
/// GPS time range.
fn info(cube: &Cube, (hierarchy_at, entries): (u64, usize), (t_min, t_max): (f64, f64)) -> Vec<u8> {
    let half = 0.5 * cube.edge;
    let mut v = Vec::with_capacity(INFO_LEN);
    for k in 0..3 {
        v.extend((cube.min[k] + half).to_le_bytes());
    }
    v.extend(half.to_le_bytes());
    v.extend((cube.edge / f64::from(GRID)).to_le_bytes());
    v.extend(hierarchy_at.to_le_bytes());
    v.extend(((entries * ENTRY_LEN) as u64).to_le_bytes());
    v.extend(t_min.to_le_bytes());
    v.extend(t_max.to_le_bytes());
    v.resize(INFO_LEN, 0);
    v
}

/// The 60-byte EVLR header of the hierarchy.
fn evlr_header(data_len: usize) -> Vec<u8> {
    let mut v = vec![0u8; EVLR_HEADER_SIZE];
    v[2..2 + USER_ID.len()].copy_from_slice(USER_ID.as_bytes());
    v[18..20].copy_from_slice(&HIERARCHY_RECORD.to_le_bytes());
    v[20..28].copy_from_slice(&(data_len as u64).to_le_bytes());
    let description = "EPT hierarchy";
    v[28..28 + description.len()].copy_from_slice(description.as_bytes());
    v
}

/// The LAS header with the compression bit, two more VLRs, the new point offset and one EVLR.
fn header(b: &[u8], points_at: usize, evlr_at: usize) -> Vec<u8> {
    let mut h = b[..LAS14_HEADER_SIZE].to_vec();
    let u32_at = |h: &[u8], i: usize| u32::from_le_bytes(h[i..i + 4].try_into().expect("4"));
    h[OFFSET_TO_POINTS_AT..OFFSET_TO_POINTS_AT + 4]
        .copy_from_slice(&(points_at as u32).to_le_bytes());
    let vlrs = u32_at(&h, NUMBER_OF_VLRS_AT) + 2;
    h[NUMBER_OF_VLRS_AT..NUMBER_OF_VLRS_AT + 4].copy_from_slice(&vlrs.to_le_bytes());
    h[POINT_FORMAT_AT] |= COMPRESSED_BIT;
    h[START_OF_EVLRS_AT..START_OF_EVLRS_AT + 8].copy_from_slice(&(evlr_at as u64).to_le_bytes());
    h[NUMBER_OF_EVLRS_AT..NUMBER_OF_EVLRS_AT + 4].copy_from_slice(&1u32.to_le_bytes());
    h
}

/// Smallest and largest GPS time of the records (0, 0 without points).
fn gps_time_range(map: &[u8], layout: &LasLayout) -> (f64, f64) {
    (0..layout.point_count as usize)
        .map(|i| {
            let r = layout.record(map, i);
            let at = GPS_TIME_IN_RECORD;
            f64::from_le_bytes(r[at..at + 8].try_into().expect("8 bytes"))
        })
        .fold(None, |acc: Option<(f64, f64)>, t| {
            Some(acc.map_or((t, t), |(lo, hi)| (lo.min(t), hi.max(t))))
        })
        .unwrap_or((0.0, 0.0))
}
