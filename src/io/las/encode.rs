//! Point records: [`encode_points`] turns a chunk of [`LasPoint`]s into record bytes and
//! [`ChunkStats`] (pure, allocation-free per point, safe to run on many threads at once).

use super::{
    ExtraType, PointLayout, CORE_RECORD_LEN, FRACTION_SCALE, MAX_EXTRA_DIMS, SCAN_ANGLE_UNIT_DEG,
};
use crate::{Error, Result};

const NUMBER_OF_RETURNS_MAX: u8 = 15;
const SCAN_ANGLE_MAX_COUNTS: f64 = 30_000.0;

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

/// Stores the value `v` of an extra dimension of type `data_type` at the start of `out`.
#[inline]
pub fn encode_extra(data_type: ExtraType, v: f64, out: &mut [u8]) {
    match data_type {
        ExtraType::F32 => out[..4].copy_from_slice(&(v as f32).to_le_bytes()),
        ExtraType::F64 => out[..8].copy_from_slice(&v.to_le_bytes()),
        // Clamped to 0..=1 (NaN is stored as 0).
        ExtraType::FractionU8 => {
            let q = v.clamp(0.0, 1.0) / FRACTION_SCALE;
            out[0] = if q.is_nan() { 0 } else { round_small(q) as u8 };
        }
    }
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
    let extras: Vec<(ExtraType, usize)> = (layout.extra_dims.iter())
        .zip(&layout.extra_offsets)
        .map(|(dim, &at)| (dim.data_type, at))
        .collect();
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
        let (core, extra_bytes) = rec.split_at_mut(CORE_RECORD_LEN);
        let core: &mut [u8; CORE_RECORD_LEN] = core.try_into().expect("30 bytes");
        core[0..4].copy_from_slice(&counts[0].to_le_bytes());
        core[4..8].copy_from_slice(&counts[1].to_le_bytes());
        core[8..12].copy_from_slice(&counts[2].to_le_bytes());
        core[12..14].copy_from_slice(&p.intensity.to_le_bytes());
        core[14] = p.return_number | (p.number_of_returns << 4);
        core[15] = 0; // classification flags, scanner channel, scan direction, edge of line
        core[16] = p.classification;
        core[17] = p.user_data;
        core[18..20].copy_from_slice(&scan_angle.to_le_bytes());
        core[20..22].copy_from_slice(&p.point_source_id.to_le_bytes());
        core[22..30].copy_from_slice(&gps_time.to_le_bytes());
        for (&(data_type, at), &v) in extras.iter().zip(&p.extra) {
            let at = at - CORE_RECORD_LEN;
            encode_extra(data_type, v, &mut extra_bytes[at..]);
        }
        stats.add(counts, p.return_number, gps_time);
    }
    Ok(stats)
}

/// Bound below which [`round_small`] is exact (2^52: every such f64 has a fractional part
/// representable exactly after its integer part is subtracted).
const ROUND_SMALL_MAX: f64 = 4_503_599_627_370_496.0;

/// `x.round()` (half away from zero) for `|x| < 2^52`, in integer arithmetic: the same value
/// as `f64::round`, without its libm call.
#[inline]
fn round_small(x: f64) -> i64 {
    debug_assert!(x.abs() < ROUND_SMALL_MAX);
    let truncated = x as i64;
    let fraction = x - truncated as f64; // exact for |x| < 2^52
                                         // Branch-free: the fraction of a coordinate is random, a branch on it mispredicts.
    truncated + i64::from(fraction >= 0.5) - i64::from(fraction <= -0.5)
}

/// `round((v - offset) / scale)` as i32; `None` beyond i32 or not finite.
#[inline]
fn counts_of(v: f64, scale: f64, offset: f64) -> Option<i32> {
    let q = (v - offset) / scale;
    // Beyond 2^32 the rounded value cannot be an i32 anyway (and NaN fails the test).
    if q.abs() < 4_294_967_296.0 {
        i32::try_from(round_small(q)).ok()
    } else {
        None
    }
}

/// The stored counts of coordinate `v` on `axis` (0, 1, 2: X, Y, Z) of point `index`.
#[inline]
fn quantise(v: f64, axis: usize, layout: &PointLayout, index: usize) -> Result<i32> {
    match counts_of(v, layout.scale_m[axis], layout.offset_m[axis]) {
        Some(counts) => Ok(counts),
        None => Err(beyond_las(v, axis, layout, index)),
    }
}

/// Why coordinate `v` on `axis` of point `index` cannot be stored.
#[cold]
#[inline(never)]
fn beyond_las(v: f64, axis: usize, layout: &PointLayout, index: usize) -> Error {
    let (scale, offset) = (layout.scale_m[axis], layout.offset_m[axis]);
    let name = ["X", "Y", "Z"][axis];
    if !v.is_finite() {
        return Error::Invalid(format!("LAS point {index} of the chunk: {name} is {v}"));
    }
    let reach_m = f64::from(i32::MAX) * scale;
    Error::Invalid(format!(
        "LAS point {index} of the chunk: {name} = {v} m is {:.3} m beyond what LAS can store with \
         scale {scale} m and offset {offset} m (offset +- {reach_m:.3} m); set the offset near \
         the data (e.g. the first point rounded) or use a coarser scale",
        (v - offset).abs() - reach_m
    ))
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
    let q = deg / SCAN_ANGLE_UNIT_DEG;
    // Within 2 * 30,000 counts `round_small` is exact; beyond, the angle is refused anyway.
    if q.abs() < 2.0 * SCAN_ANGLE_MAX_COUNTS {
        let counts = round_small(q);
        if counts.abs() <= SCAN_ANGLE_MAX_COUNTS as i64 {
            return Ok(counts as i16);
        }
    }
    Err(Error::Invalid(format!(
        "LAS point {index} of the chunk: scan angle {deg} deg outside -180..=180 deg"
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The integer rounding gives `f64::round`'s value (output bytes depend on it), halves and
    /// their neighbours included; and the i32 range check of the coordinates is unchanged.
    #[test]
    fn round_small_is_f64_round() {
        let mut xs = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            -2.5,
            0.49999999999999994,
        ];
        xs.extend([0.5f64.next_down(), 0.5f64.next_up(), (-0.5f64).next_up()]);
        xs.extend([
            2_147_483_647.5,
            -2_147_483_648.5,
            2_147_483_647.4,
            -2_147_483_648.4,
        ]);
        xs.push(ROUND_SMALL_MAX.next_down());
        let mut state = 0x2545_f491_4f6c_dd1d_u64; // fixed seed: reproducible sample
        for k in 0..200_000 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            let unit = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            // Magnitudes 1 to 1e12, and exact halves.
            let x = unit * 10f64.powi(k % 13);
            xs.extend([x, x.trunc() + 0.5, x.trunc() - 0.5]);
        }
        for x in xs {
            assert_eq!(round_small(x) as f64, x.round(), "x = {x:e}");
            let before = x.round();
            let expect = (before >= f64::from(i32::MIN) && before <= f64::from(i32::MAX))
                .then_some(before as i32);
            assert_eq!(counts_of(x, 1.0, 0.0), expect, "x = {x:e}");
        }
        for x in [f64::NAN, f64::INFINITY, -1e20, 4_294_967_296.0] {
            assert_eq!(counts_of(x, 1.0, 0.0), None);
        }
    }
}
