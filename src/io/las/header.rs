//! The public header block and the VLRs (WKT CRS, Extra Bytes descriptors), serialised with
//! the `las` crate's raw types.

use super::{ExtraDim, GpsTimeConvention, LasSummary, LasWriterConfig, POINT_FORMAT};
use crate::{Error, Result};
use las::raw::vlr::RecordLength;
use las::Version;

/// Bytes of the LAS 1.4 public header block.
pub(super) use super::public_header::HEADER_1_4 as HEADER_SIZE;
use super::public_header::{EXTRA_BYTES_DESCRIPTOR_LEN, VLR_HEADER_LEN as VLR_HEADER_SIZE};
const GLOBAL_ENCODING_GPS_ADJUSTED: u16 = 1 << 0;
const GLOBAL_ENCODING_WKT: u16 = 1 << 4;

/// The 375-byte LAS 1.4 public header block of a file holding the points `summary` describes
/// (legacy counts zero: format 6).
pub(super) fn header_bytes(
    config: &LasWriterConfig,
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
            number_of_point_records: summary.point_count,
            number_of_points_by_return: summary.points_by_return,
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
pub(super) fn vlr_bytes(config: &LasWriterConfig) -> Result<Vec<u8>> {
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
    assert_eq!(out.len() - start, VLR_HEADER_SIZE + usize::from(len));
    Ok(())
}

/// LAS 1.4 R15 EXTRA_BYTES struct (192 bytes): reserved[2], data_type, options (bit 3: scale
/// given; no no_data, min, max or offset), name[32], unused[4], no_data[3], min[3], max[3],
/// scale[3] (f64 at 112, only the first used), offset[3], description[32]; unused fields zero.
pub(crate) fn extra_bytes_descriptor(dim: &ExtraDim) -> [u8; EXTRA_BYTES_DESCRIPTOR_LEN] {
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
