//! Reads what a LAS 1.0-1.4, LAZ or COPC file says about itself without its points: the public
//! header (version, point format, counts, scale, offset, extent), the CRS (WKT VLR, or the
//! GeoTIFF keys' EPSG code), the Extra Bytes descriptors and whether the points are compressed
//! (LASzip) or clustered (COPC). LAZ and COPC keep the header and VLRs uncompressed, so one
//! reader serves all three (`kinescan info`). Reading a cloud's points (`kinescan tpu`) is
//! [`super::read`].
//! Errors name the file and what is wrong.

use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use super::public_header::{
    record_ids, text, u16_at, u64_at, PublicHeader, EVLR_HEADER_LEN as EVLR_HEADER,
    EXTRA_BYTES_DESCRIPTOR_LEN as EXTRA_BYTES_DESCRIPTOR, HEADER_1_4, VLR_HEADER_LEN as VLR_HEADER,
};
use crate::{Error, Result};

/// One Extra Bytes dimension as its descriptor states it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ExtraDimInfo {
    /// Name.
    pub name: String,
    /// LAS data type code (1-10; 0 for undocumented bytes).
    pub data_type: u8,
    /// Description.
    pub description: String,
}

/// The CRS a LAS file states.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CrsInfo {
    /// The WKT's name (`PROJCS["name"`...) or `GeoTIFF keys`.
    pub name: String,
    /// The top-level `AUTHORITY["EPSG",code]` of the WKT, or the GeoTIFF keys' projected or
    /// geographic CRS code.
    pub epsg: Option<u32>,
    /// The vertical CRS's EPSG code of a compound WKT (`COMPD_CS`).
    pub vertical_epsg: Option<u32>,
    /// The WKT (None for GeoTIFF keys).
    pub wkt: Option<String>,
}

/// What a LAS, LAZ or COPC file's header and VLRs say.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LasHeaderInfo {
    /// LAS version (major, minor).
    pub version: (u8, u8),
    /// Point data record format (0-10), without the compression bit.
    pub point_format: u8,
    /// Bytes per point record (uncompressed).
    pub record_length: u16,
    /// Points compressed by LASzip (LAZ or COPC).
    pub compressed: bool,
    /// A COPC file (its `copc` info VLR first).
    pub copc: bool,
    /// Number of point records.
    pub points: u64,
    /// Points by return number 1..=15 (1..=5 before LAS 1.4).
    pub points_by_return: Vec<u64>,
    /// Scale and offset of X, Y, Z.
    pub scale: [f64; 3],
    /// Offset of X, Y, Z.
    pub offset: [f64; 3],
    /// Header minimum X, Y, Z.
    pub min: [f64; 3],
    /// Header maximum X, Y, Z.
    pub max: [f64; 3],
    /// System identifier and generating software.
    pub system: String,
    /// Generating software.
    pub software: String,
    /// Creation day of year and year (0, 0 when unknown).
    pub created: (u16, u16),
    /// GPS time is adjusted standard GPS time (global encoding bit 0).
    pub adjusted_gps_time: bool,
    /// The CRS, if stated.
    pub crs: Option<CrsInfo>,
    /// Extra Bytes dimensions, in record order.
    pub extra_dims: Vec<ExtraDimInfo>,
    /// (user id, record id) of every VLR and EVLR.
    pub vlrs: Vec<(String, u16)>,
}

/// Whether `bytes` start like a LAS file (`LASF`).
pub fn is_las(bytes: &[u8]) -> bool {
    bytes.starts_with(b"LASF")
}

/// Reads the header, VLRs and EVLRs of the LAS/LAZ/COPC file `path` (not its points).
pub fn read_header(path: &Path) -> Result<LasHeaderInfo> {
    let bad = |problem: String| Error::bad_file(path, problem);
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let size = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut head = vec![0u8; HEADER_1_4.min(size as usize)];
    file.read_exact(&mut head).map_err(|e| Error::io(path, e))?;
    let Some(h) = PublicHeader::parse(&head) else {
        return Err(bad(
            "not a LAS file: no `LASF` signature and 227-byte header".into(),
        ));
    };
    let header_size = h.header_size;
    let point_offset = h.offset_to_points;
    let vlr_count = h.vlr_count;
    let mut info = LasHeaderInfo {
        version: h.version,
        point_format: h.point_format(),
        record_length: h.record_len,
        compressed: h.compressed(),
        copc: false,
        points: h.point_count(),
        points_by_return: h.points_by_return(),
        scale: h.scale,
        offset: h.offset,
        min: h.min,
        max: h.max,
        system: h.system.clone(),
        software: h.software.clone(),
        created: h.created,
        adjusted_gps_time: h.global_encoding & 1 != 0,
        crs: None,
        extra_dims: Vec::new(),
        vlrs: Vec::new(),
    };
    // VLRs between the header and the points; EVLRs after the points (LAS 1.4). Read with
    // seeks: a cloud's points are never read.
    let mut read_at = |at: u64, len: usize| -> Result<Vec<u8>> {
        if at.saturating_add(len as u64) > size {
            return Err(bad(format!(
                "a VLR at byte {at} ({len} B) runs past the end of the file ({size} B): truncated"
            )));
        }
        let mut buf = vec![0u8; len];
        file.seek(SeekFrom::Start(at))
            .map_err(|e| Error::io(path, e))?;
        file.read_exact(&mut buf).map_err(|e| Error::io(path, e))?;
        Ok(buf)
    };
    let mut records: Vec<(String, u16, Vec<u8>)> = Vec::new();
    let mut at = header_size as u64;
    for k in 0..vlr_count {
        if at + VLR_HEADER as u64 > point_offset {
            return Err(bad(format!(
                "VLR {k} of {vlr_count} runs past the start of the points ({point_offset} B): \
                 truncated or corrupt header"
            )));
        }
        let vh = read_at(at, VLR_HEADER)?;
        let len = usize::from(u16_at(&vh, 20));
        let body = read_at(at + VLR_HEADER as u64, len)?;
        let (user, id) = record_ids(&vh);
        records.push((user, id, body));
        at += (VLR_HEADER + len) as u64;
    }
    if h.las14.is_some() {
        let (mut at, count) = h.evlrs();
        for k in 0..count {
            if at == 0 {
                return Err(bad(format!(
                    "EVLR {k} of {count}: no EVLR start in the header"
                )));
            }
            let eh = read_at(at, EVLR_HEADER)?;
            let len = u64_at(&eh, 20);
            let (user, id) = record_ids(&eh);
            // Only the records read below are loaded (the COPC hierarchy is skipped).
            let wanted = matches!(
                (user.as_str(), id),
                ("LASF_Projection", 2112) | ("LASF_Spec", 4)
            );
            let body = if wanted {
                read_at(
                    at + EVLR_HEADER as u64,
                    usize::try_from(len).unwrap_or(usize::MAX),
                )?
            } else {
                Vec::new()
            };
            records.push((user, id, body));
            at = at.saturating_add(EVLR_HEADER as u64).saturating_add(len);
        }
    }
    for (k, (user, id, body)) in records.iter().enumerate() {
        info.vlrs.push((user.clone(), *id));
        match (user.as_str(), *id) {
            ("copc", 1) if k == 0 => info.copc = true,
            ("LASF_Projection", 2112) => {
                let wkt = text(body);
                info.crs = Some(crs_of_wkt(&wkt));
            }
            ("LASF_Projection", 34735) if info.crs.is_none() => {
                info.crs = Some(crs_of_geotiff_keys(body));
            }
            ("LASF_Spec", 4) => {
                info.extra_dims = body
                    .chunks_exact(EXTRA_BYTES_DESCRIPTOR)
                    .map(|d| ExtraDimInfo {
                        name: text(&d[4..36]),
                        data_type: d[2],
                        description: text(&d[160..192]),
                    })
                    .collect();
            }
            _ => {}
        }
    }
    Ok(info)
}

/// (byte index, EPSG code) of each `AUTHORITY` node at bracket depth `depth` of `wkt` (1: the
/// top-level CRS's own; inside a `COMPD_CS`, 2 are its parts').
fn authorities_at_depth(wkt: &str, depth: usize) -> Vec<(usize, u32)> {
    const NODE: &str = ",AUTHORITY[\"EPSG\",\"";
    let mut found = Vec::new();
    let mut level = 0usize;
    for (i, ch) in wkt.char_indices() {
        match ch {
            '[' => level += 1,
            ']' => level = level.saturating_sub(1),
            ',' if level == depth && wkt[i..].starts_with(NODE) => {
                let rest = &wkt[i + NODE.len()..];
                if let Some(code) = rest.split('"').next().and_then(|c| c.parse().ok()) {
                    found.push((i, code));
                }
            }
            _ => {}
        }
    }
    found
}

/// Name and EPSG codes of a WKT1.
pub fn crs_of_wkt(wkt: &str) -> CrsInfo {
    let name = wkt.split('"').nth(1).unwrap_or("unnamed").to_string();
    let top = authorities_at_depth(wkt, 1).first().map(|a| a.1);
    let (epsg, vertical_epsg) = match (wkt.starts_with("COMPD_CS["), wkt.find("VERT_CS[")) {
        (true, Some(vertical_at)) => {
            // The parts' own authorities sit at depth 2: the horizontal's before VERT_CS.
            let parts = authorities_at_depth(wkt, 2);
            let horizontal = parts.iter().find(|a| a.0 < vertical_at).map(|a| a.1);
            let vertical = parts.iter().find(|a| a.0 > vertical_at).map(|a| a.1);
            (top.or(horizontal), vertical)
        }
        _ => (top, None),
    };
    CrsInfo {
        name,
        epsg,
        vertical_epsg,
        wkt: Some(wkt.to_string()),
    }
}

/// The projected (3072) or geographic (2048) CRS code of a GeoTIFF key directory.
fn crs_of_geotiff_keys(body: &[u8]) -> CrsInfo {
    let keys = body.len() / 8;
    let key = |wanted: u16| {
        (1..keys)
            .map(|k| 8 * k)
            .find(|&at| u16_at(body, at) == wanted && u16_at(body, at + 2) == 0)
            .map(|at| u32::from(u16_at(body, at + 6)))
    };
    CrsInfo {
        name: "GeoTIFF keys".into(),
        epsg: key(3072).or_else(|| key(2048)),
        vertical_epsg: key(4096),
        wkt: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Corrupt headers are refused naming the file, never a panic or a huge allocation.
    #[test]
    fn corrupt_headers_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.las");
        let mut h = vec![0u8; HEADER_1_4];
        h[..4].copy_from_slice(b"LASF");
        (h[24], h[25]) = (1, 4);
        h[94..96].copy_from_slice(&(HEADER_1_4 as u16).to_le_bytes());
        h[96..100].copy_from_slice(&(HEADER_1_4 as u32).to_le_bytes());
        // One EVLR whose start lies far beyond the file.
        h[235..243].copy_from_slice(&(u64::MAX - 10).to_le_bytes());
        h[243..247].copy_from_slice(&1u32.to_le_bytes());
        std::fs::write(&path, &h).unwrap();
        let e = read_header(&path).unwrap_err().to_string();
        assert!(e.contains("bad.las") && e.contains("past the end"), "{e}");
        // A VLR count the header has no room for.
        h[100..104].copy_from_slice(&3u32.to_le_bytes());
        std::fs::write(&path, &h).unwrap();
        let e = read_header(&path).unwrap_err().to_string();
        assert!(e.contains("VLR 0 of 3"), "{e}");
        std::fs::write(&path, b"LASF").unwrap();
        assert!(read_header(&path).is_err());
    }

    #[test]
    fn wkt_codes_at_the_right_depth() {
        let p = r#"PROJCS["X",GEOGCS["G",AUTHORITY["EPSG","4326"]],AUTHORITY["EPSG","32632"]]"#;
        let c = crs_of_wkt(p);
        assert_eq!(
            (c.name.as_str(), c.epsg, c.vertical_epsg),
            ("X", Some(32632), None)
        );
        let compound = format!(
            r#"COMPD_CS["X + H",{p},VERT_CS["H",VERT_DATUM["D",2005,AUTHORITY["EPSG","5103"]],AUTHORITY["EPSG","5703"]]]"#
        );
        let c = crs_of_wkt(&compound);
        assert_eq!((c.epsg, c.vertical_epsg), (Some(32632), Some(5703)));
    }
}
