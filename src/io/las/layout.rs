//! The record layout of a LAS file: extra dimensions, GPS time convention, scale and offset.

use super::{
    ADJUSTED_GPS_TIME_OFFSET_S, CORE_RECORD_LEN, DEFAULT_SCALE_M, MAX_EXTRA_DIMS,
    SECONDS_PER_GPS_WEEK,
};
use crate::{Error, Result};

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
    pub(super) scale_m: [f64; 3],
    pub(super) offset_m: [f64; 3],
    pub(super) time: GpsTimeConvention,
    pub(super) extra_dims: Vec<ExtraDim>,
    pub(super) extra_offsets: Vec<usize>,
    pub(super) record_len: usize,
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
    /// The coordinate (m) that the stored integer `count` of axis `axis` (0 X, 1 Y, 2 Z)
    /// stands for: `count * scale + offset`.
    pub fn coordinate_m(&self, axis: usize, count: i32) -> f64 {
        f64::from(count) * self.scale_m[axis] + self.offset_m[axis]
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
pub(super) fn check_ascii_field(what: &str, text: &str, min_len: usize) -> Result<()> {
    if text.len() < min_len || text.len() > 32 || !text.is_ascii() || text.contains('\0') {
        return Err(Error::Invalid(format!(
            "LAS {what} `{text}` must be {min_len} to 32 ASCII characters without NUL"
        )));
    }
    Ok(())
}
