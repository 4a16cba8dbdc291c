//! The cloud as `tpu` needs it: LAS mapped (LAZ decompressed into the staging folder first),
//! GPS time present and related to the trajectory's seconds of week, the CRS found and turned
//! into a map frame; clear errors naming the file otherwise.

use crate::geo::projection::MapFrame;
use crate::io::las::read::{decompress_laz, is_laz, GeoKeys, LasCrs, LasInput};
use crate::io::las::GpsTimeConvention;
use crate::io::las::SECONDS_PER_GPS_WEEK;
use crate::pipeline::config::FrameConfig;
use crate::trajectory::Trajectory;
use crate::{Error, Result};
use std::path::Path;

/// Opens the cloud: a LAS file mapped in place, a LAZ file decompressed to `scratch` first.
pub fn open(cloud: &Path, scratch: &Path) -> Result<LasInput> {
    if is_laz(cloud)? {
        decompress_laz(cloud, scratch)?;
        let mut input = LasInput::open(scratch)?;
        input.set_path(cloud);
        return Ok(input);
    }
    LasInput::open(cloud)
}

/// The map frame of the cloud's CRS. A WKT equal to the one `run` writes for the pipeline's
/// `output.frame` is that frame (local ENU has no EPSG code); otherwise the EPSG code: UTM
/// (326zz, 327zz), ECEF (4978) or a projected CRS of `geo::epsg`.
pub fn frame_of(
    input: &LasInput,
    configured: &FrameConfig,
    traj: &Trajectory,
) -> Result<(MapFrame, String)> {
    let crs = input.crs()?;
    let path = input.path();
    match crs {
        LasCrs::Wkt(wkt) => {
            if let Ok(f) = crate::pipeline::prepare::map_frame(configured, traj) {
                if f.wkt() == wkt {
                    return Ok((f, "WKT (the pipeline's output.frame)".into()));
                }
            }
            let upper = wkt.to_ascii_uppercase();
            if upper.contains("VERT_CS") || upper.contains("VERTCRS") {
                return Err(Error::bad_file(
                    path,
                    "the WKT CRS has a vertical CRS (orthometric heights): tpu needs WGS84 \
                     ellipsoidal heights",
                ));
            }
            let codes = epsg_codes(&wkt);
            for code in codes.iter().rev() {
                if let Some(f) = frame_of_code(*code) {
                    return Ok((f, format!("WKT, EPSG:{code}")));
                }
            }
            Err(Error::bad_file(
                path,
                format!(
                    "WKT CRS names no supported projected or geocentric EPSG code (found {codes:?}): \
                     tpu reads UTM, ECEF (4978), the projected CRSs of docs/output.md, or the \
                     WKT run wrote for output.frame"
                ),
            ))
        }
        LasCrs::GeoKeys(keys) => frame_of_geokeys(&keys).ok_or_else(|| {
            Error::bad_file(
                path,
                format!(
                    "GeoTIFF keys {keys:?} name no supported frame: tpu reads a projected CRS \
                     (UTM or a CRS of docs/output.md), a UTM projection (ProjectionGeoKey \
                     16001-16060, 16101-16160) or a geocentric model (GTModelTypeGeoKey 3); \
                     geographic coordinates are not read"
                ),
            )
        }),
    }
}

/// The frame of GeoTIFF keys: the projected CRS code; else a UTM projection code (on a
/// user-defined WGS84-like datum); else the geocentric model (ECEF).
fn frame_of_geokeys(keys: &GeoKeys) -> Option<(MapFrame, String)> {
    if let Some(code) = keys.projected.filter(|c| *c != 0 && *c != 32767) {
        let f = frame_of_code(u32::from(code))?;
        return Some((f, format!("GeoTIFF ProjectedCSTypeGeoKey EPSG:{code}")));
    }
    if let Some(code) = keys.projection {
        let f = match code {
            16001..=16060 => MapFrame::utm((code - 16000) as u8, true).ok()?,
            16101..=16160 => MapFrame::utm((code - 16100) as u8, false).ok()?,
            _ => return None,
        };
        let text =
            format!("GeoTIFF ProjectionGeoKey {code} (UTM, user-defined datum read as WGS84)");
        return Some((f, text));
    }
    if keys.model_type == Some(3) {
        return Some((
            MapFrame::Ecef,
            "GeoTIFF GTModelTypeGeoKey 3 (geocentric, WGS84)".into(),
        ));
    }
    None
}

/// The EPSG codes of a WKT in order (`AUTHORITY["EPSG","n"]` and `ID["EPSG",n]`).
fn epsg_codes(wkt: &str) -> Vec<u32> {
    let mut codes = Vec::new();
    for pat in ["AUTHORITY[\"EPSG\",", "ID[\"EPSG\","] {
        let mut rest = wkt;
        while let Some(i) = rest.find(pat) {
            let after = &rest[i + pat.len()..];
            let digits: String = after
                .trim_start_matches('"')
                .chars()
                .take_while(|c| c.is_ascii_digit())
                .collect();
            if let Ok(c) = digits.parse() {
                codes.push((i + (wkt.len() - rest.len()), c));
            }
            rest = after;
        }
    }
    codes.sort();
    codes.into_iter().map(|(_, c)| c).collect()
}

fn frame_of_code(code: u32) -> Option<MapFrame> {
    match code {
        32601..=32660 => MapFrame::utm((code - 32600) as u8, true).ok(),
        32701..=32760 => MapFrame::utm((code - 32700) as u8, false).ok(),
        4978 => Some(MapFrame::Ecef),
        _ => MapFrame::from_epsg(code).ok(),
    }
}

/// Refuses a cloud whose first and last points both fall outside the trajectory: a wrong
/// GPS week (adjusted standard time with another week), another day's SBET, or another
/// time system; the message gives the times.
pub fn check_times(
    input: &LasInput,
    time_at: usize,
    convention: GpsTimeConvention,
    traj: &Trajectory,
) -> Result<()> {
    let n = input.point_count as usize;
    if n == 0 {
        return Ok(());
    }
    let (t0, t1) = traj.span_s();
    let sow = |i: usize| input.stored_time(input.record(i), time_at) - convention.shift_s();
    let (first, last) = (sow(0), sow(n - 1));
    let inside = |t: f64| (t0..=t1).contains(&t);
    if inside(first) || inside(last) {
        return Ok(());
    }
    let hint = match convention {
        GpsTimeConvention::AdjustedStandard { gps_week } => {
            let weeks = ((first - t0) / SECONDS_PER_GPS_WEEK).round();
            if weeks != 0.0 && (first - t0 - weeks * SECONDS_PER_GPS_WEEK).abs() < 86_400.0 {
                format!(
                    ": the times fall {weeks} week(s) from the SBET with inputs.gps_week = \
                     {gps_week}; is the SBET from GPS week {}, or inputs.gps_week wrong?",
                    i64::from(gps_week) + weeks as i64
                )
            } else {
                format!(" (adjusted standard time read with inputs.gps_week = {gps_week})")
            }
        }
        GpsTimeConvention::WeekSeconds => {
            " (GPS seconds of week): is the SBET of another day, or the cloud's time another \
             system?"
                .into()
        }
    };
    Err(Error::bad_file(
        input.path(),
        format!(
            "point 0 at {first:.3} s and point {} at {last:.3} s of the GPS week are outside the \
             trajectory span {t0:.3} to {t1:.3} s{hint}",
            n - 1
        ),
    ))
}
