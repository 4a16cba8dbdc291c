//! Control / sync points, CSV (conventions §6): header `id,lat_deg,lon_deg,h_m,sigma_m`.
//!
//! Positions are WGS84 geodetic: latitude and longitude in degrees in the file (radians in
//! [`ControlPoint`]), ellipsoidal height in metres; `sigma_m` is the 1-sigma 3D position
//! uncertainty of the surveyed point (m). Rules: ids unique and non-empty, latitude in
//! [-90, 90], longitude in [-180, 180], every number finite, `sigma_m > 0`.

use super::atomic::AtomicFile;
use super::csv_text::{self, Lines, SeenIds};
use crate::{Error, Result};
use std::io::Write;
use std::path::Path;

/// CSV header of a control-point file.
pub const CONTROL_POINTS_HEADER: [&str; 5] = ["id", "lat_deg", "lon_deg", "h_m", "sigma_m"];

/// One surveyed control or sync point.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ControlPoint {
    /// Identifier, unique within its file.
    pub id: String,
    /// Geodetic latitude, WGS84 (rad).
    pub lat_rad: f64,
    /// Longitude, WGS84 (rad), east positive.
    pub lon_rad: f64,
    /// Ellipsoidal height (m).
    pub h_m: f64,
    /// 1-sigma position uncertainty (m), > 0.
    pub sigma_m: f64,
}

/// Reads and validates a control-point CSV; the first problem is reported with its 1-based
/// line number.
pub fn read_control_points(path: &Path) -> Result<Vec<ControlPoint>> {
    let mut lines = Lines::open(path)?;
    csv_text::check_header(path, lines.header()?, &CONTROL_POINTS_HEADER, &[])?;
    let mut seen = SeenIds::default();
    let mut out = Vec::new();
    while lines.advance()? {
        let mut fields = [""; 5];
        csv_text::split_fields(&lines, &mut fields)?;
        let id = csv_text::identifier(&lines, fields[0])?;
        seen.insert(&lines, &id)?;
        let lat_deg = csv_text::finite_f64(&lines, "lat_deg", fields[1])?;
        let lon_deg = csv_text::finite_f64(&lines, "lon_deg", fields[2])?;
        let h_m = csv_text::finite_f64(&lines, "h_m", fields[3])?;
        let sigma_m = csv_text::finite_f64(&lines, "sigma_m", fields[4])?;
        let (lat_rad, lon_rad) = csv_text::lat_lon_rad(&lines, lat_deg, lon_deg)?;
        if sigma_m <= 0.0 {
            let msg = format!("sigma_m {sigma_m} must be > 0");
            return Err(Error::bad_record(path, lines.at(), msg));
        }
        out.push(ControlPoint {
            id,
            lat_rad,
            lon_rad,
            h_m,
            sigma_m,
        });
    }
    if out.is_empty() {
        return Err(Error::bad_file(path, "no control points after the header"));
    }
    Ok(out)
}

/// Writes `points` atomically, angles in degrees with Rust's shortest round-trip formatting
/// (exact for the f64 degree value: far below the 1e-10 deg ~ 0.01 mm needed).
/// Refuses points the reader would refuse (naming the 0-based item).
pub fn write_control_points(path: &Path, points: &[ControlPoint]) -> Result<()> {
    let mut seen = std::collections::HashSet::new();
    for (i, p) in points.iter().enumerate() {
        csv_text::check_writable_id(path, i, &p.id)?;
        let ok = seen.insert(p.id.as_str())
            && [p.lat_rad, p.lon_rad, p.h_m, p.sigma_m]
                .iter()
                .all(|v| v.is_finite())
            && p.lat_rad.to_degrees().abs() <= 90.0
            && p.lon_rad.to_degrees().abs() <= 180.0
            && p.sigma_m > 0.0;
        if !ok {
            let msg = format!(
                "control point `{}` has a duplicate id or an invalid value: {p:?}",
                p.id
            );
            return Err(Error::bad_record(path, format!("item {i}"), msg));
        }
    }
    let mut out = AtomicFile::create(path)?;
    let mut text = CONTROL_POINTS_HEADER.join(",");
    text.push('\n');
    out.write_all(text.as_bytes())?;
    for p in points {
        let w = out.writer();
        writeln!(
            w,
            "{},{},{},{},{}",
            p.id,
            p.lat_rad.to_degrees(),
            p.lon_rad.to_degrees(),
            p.h_m,
            p.sigma_m
        )
        .map_err(|e| Error::io(path, e))?;
    }
    out.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_is_exact_in_degrees() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cp.csv");
        let pts = vec![
            ControlPoint {
                id: "CP1".into(),
                lat_rad: 0.8123456789012345,
                lon_rad: -0.2123456789012345,
                h_m: 312.3456,
                sigma_m: 0.012,
            },
            ControlPoint {
                id: "south-west".into(),
                lat_rad: -1.2,
                lon_rad: 3.0,
                h_m: -20.0,
                sigma_m: 0.5,
            },
        ];
        write_control_points(&path, &pts).unwrap();
        let back = read_control_points(&path).unwrap();
        for (a, b) in pts.iter().zip(&back) {
            assert_eq!(a.id, b.id);
            // deg -> rad -> deg conversions cost at most a few ulps: 1e-15 rad ~ 6 nm.
            assert!((a.lat_rad - b.lat_rad).abs() < 1e-15);
            assert!((a.lon_rad - b.lon_rad).abs() < 1e-15);
            assert_eq!(a.h_m, b.h_m);
            assert_eq!(a.sigma_m, b.sigma_m);
            assert_eq!(a.lat_rad.to_degrees(), b.lat_rad.to_degrees());
        }
    }

    #[test]
    fn accepts_bom_crlf_blank_lines_and_spaces() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cp.csv");
        let text = "\u{feff}id, lat_deg,lon_deg,h_m,sigma_m\r\n\r\nA, 45.5 ,-73.25,12,0.02\r\n";
        std::fs::write(&path, text).unwrap();
        let p = read_control_points(&path).unwrap();
        assert_eq!(p.len(), 1);
        assert_eq!(
            (p[0].id.as_str(), p[0].lat_rad),
            ("A", 45.5f64.to_radians())
        );
    }

    #[test]
    fn refuses_bad_points_with_line_numbers() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cp.csv");
        let cases = [
            (
                "A,10,20,5,0.01\nA,10,20,5,0.01\n",
                "line 3: duplicate id `A`",
            ),
            ("A,91,20,5,0.01\n", "line 2: lat_deg 91 is outside"),
            ("A,10,-181,5,0.01\n", "line 2: lon_deg -181 is outside"),
            ("A,10,20,5,0\n", "line 2: sigma_m 0 must be > 0"),
            ("A,10,20,NaN,0.1\n", "line 2: h_m is NaN (not finite)"),
            ("A,10,20,x,0.1\n", "line 2: h_m `x` is not a number"),
            ("A,10,20,5\n", "line 2: 4 fields where the header has 5"),
            ("", "no control points"),
        ];
        for (body, want) in cases {
            std::fs::write(&path, format!("id,lat_deg,lon_deg,h_m,sigma_m\n{body}")).unwrap();
            let e = read_control_points(&path).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("cp.csv"), "{e} lacks {want}");
        }
        std::fs::write(&path, "id,lat_deg,lon_deg,h_m,sigma\nA,1,2,3,4\n").unwrap();
        let e = read_control_points(&path).unwrap_err().to_string();
        assert!(e.contains("`sigma` where `sigma_m` is expected"), "{e}");
    }
}
