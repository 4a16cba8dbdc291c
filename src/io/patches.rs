//! Reference planar patches, CSV (conventions §6): header
//! `id,lat_deg,lon_deg,h_m,normal_e,normal_n,normal_u,half_length_m,half_height_m[,sigma_m]`.
//!
//! A patch is a rectangle on a plane: its centre (WGS84 geodetic, degrees in the file, radians
//! in [`PlanarPatch`], ellipsoidal height in m), its unit normal in local East-North-Up at the
//! centre, and its half sizes. Patch axes (see [`PlanarPatch::axes_enu`]): the length axis is
//! the horizontal direction in the plane, `up x normal` normalised; the height axis is
//! `normal x length` (the steepest direction in the plane, pointing uphill). A horizontal patch
//! (horizontal part of the normal below 1e-9) has length along East (West for a downward
//! normal) and height along North.
//! Rules: ids unique, latitude in [-90, 90], longitude in [-180, 180], finite numbers,
//! | |normal| - 1 | <= 1e-6, half sizes > 0, `sigma_m` (optional, empty allowed) > 0.

use super::atomic::AtomicFile;
use super::csv_text::{self, Lines, SeenIds};
use crate::geo::ellipsoid::{geodetic_to_ecef, r_enu_to_e, Geodetic};
use crate::{Error, Result};
use nalgebra::Vector3;
use std::io::Write;
use std::path::Path;

/// Required CSV columns of a patch file, in order; `sigma_m` may follow.
pub const PATCHES_HEADER: [&str; 9] = [
    "id",
    "lat_deg",
    "lon_deg",
    "h_m",
    "normal_e",
    "normal_n",
    "normal_u",
    "half_length_m",
    "half_height_m",
];

/// Tolerance on the length of a patch normal as read.
pub const NORMAL_UNIT_TOL: f64 = 1e-6;

/// One surveyed reference rectangle.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PlanarPatch {
    /// Identifier, unique within its file.
    pub id: String,
    /// Geodetic latitude of the centre, WGS84 (rad).
    pub lat_rad: f64,
    /// Longitude of the centre (rad), east positive.
    pub lon_rad: f64,
    /// Ellipsoidal height of the centre (m).
    pub h_m: f64,
    /// Unit normal in local East-North-Up at the centre, as read (unit to 1e-6).
    pub normal_enu: [f64; 3],
    /// Half size along the length axis (m), > 0.
    pub half_length_m: f64,
    /// Half size along the height axis (m), > 0.
    pub half_height_m: f64,
    /// 1-sigma uncertainty of the plane position along its normal (m), when surveyed.
    pub sigma_m: Option<f64>,
}

impl PlanarPatch {
    /// Centre in ECEF `e` (m).
    pub fn centre_ecef(&self) -> Vector3<f64> {
        geodetic_to_ecef(Geodetic {
            lat_rad: self.lat_rad,
            lon_rad: self.lon_rad,
            h_m: self.h_m,
        })
    }

    /// Unit normal in local ENU at the centre (renormalised).
    pub fn normal_enu(&self) -> Vector3<f64> {
        Vector3::from(self.normal_enu).normalize()
    }

    /// (length axis, height axis) in local ENU at the centre, unit vectors in the plane; with
    /// the normal they form a right-handed triad (length x height = normal).
    pub fn axes_enu(&self) -> (Vector3<f64>, Vector3<f64>) {
        let n = self.normal_enu();
        let horiz = Vector3::z().cross(&n);
        let length = if horiz.norm() < 1e-9 {
            Vector3::x() * n.z.signum()
        } else {
            horiz.normalize()
        };
        (length, n.cross(&length))
    }

    /// Coordinates of ECEF point `x_e` (m) in the patch frame: (along length, along height,
    /// along normal) from the centre (m).
    pub fn patch_coords_m(&self, x_e: &Vector3<f64>) -> Vector3<f64> {
        let d_enu = r_enu_to_e(self.lat_rad, self.lon_rad).transpose() * (x_e - self.centre_ecef());
        let (l, h) = self.axes_enu();
        Vector3::new(l.dot(&d_enu), h.dot(&d_enu), self.normal_enu().dot(&d_enu))
    }
}

/// Reads and validates a patch CSV; the first problem is reported with its 1-based line.
pub fn read_patches(path: &Path) -> Result<Vec<PlanarPatch>> {
    let mut lines = Lines::open(path)?;
    let has_sigma =
        csv_text::check_header(path, lines.header()?, &PATCHES_HEADER, &["sigma_m"])?[0];
    let mut seen = SeenIds::default();
    let mut out = Vec::new();
    while lines.advance()? {
        let mut f = [""; 10];
        let n = if has_sigma { 10 } else { 9 };
        csv_text::split_fields(&lines, &mut f[..n])?;
        let id = csv_text::identifier(&lines, f[0])?;
        seen.insert(&lines, &id)?;
        let mut v = [0.0; 8];
        for (k, slot) in v.iter_mut().enumerate() {
            *slot = csv_text::finite_f64(&lines, PATCHES_HEADER[k + 1], f[k + 1])?;
        }
        let (lat_rad, lon_rad) = csv_text::lat_lon_rad(&lines, v[0], v[1])?;
        let bad = |what: String| Error::bad_record(path, lines.at(), what);
        let normal_enu = [v[3], v[4], v[5]];
        let norm = Vector3::from(normal_enu).norm();
        if (norm - 1.0).abs() > NORMAL_UNIT_TOL {
            return Err(bad(format!(
                "normal has length {norm}, not 1 (tolerance {NORMAL_UNIT_TOL})"
            )));
        }
        for (name, s) in [("half_length_m", v[6]), ("half_height_m", v[7])] {
            if s <= 0.0 {
                return Err(bad(format!("{name} {s} must be > 0")));
            }
        }
        let sigma_m = match (has_sigma, f[9]) {
            (true, s) if !s.is_empty() => Some(csv_text::finite_f64(&lines, "sigma_m", s)?),
            _ => None,
        };
        if let Some(s) = sigma_m.filter(|s| *s <= 0.0) {
            return Err(bad(format!("sigma_m {s} must be > 0")));
        }
        out.push(PlanarPatch {
            id,
            lat_rad,
            lon_rad,
            h_m: v[2],
            normal_enu,
            half_length_m: v[6],
            half_height_m: v[7],
            sigma_m,
        });
    }
    if out.is_empty() {
        return Err(Error::bad_file(path, "no patches after the header"));
    }
    Ok(out)
}

fn writable(p: &PlanarPatch) -> bool {
    let n = p.normal_enu;
    [
        p.lat_rad,
        p.lon_rad,
        p.h_m,
        p.half_length_m,
        p.half_height_m,
    ]
    .iter()
    .chain(&n)
    .all(|v| v.is_finite())
        && p.lat_rad.to_degrees().abs() <= 90.0
        && p.lon_rad.to_degrees().abs() <= 180.0
        && (Vector3::from(n).norm() - 1.0).abs() <= NORMAL_UNIT_TOL
        && p.half_length_m > 0.0
        && p.half_height_m > 0.0
        && p.sigma_m.is_none_or(|s| s.is_finite() && s > 0.0)
}

/// Writes `patches` atomically (shortest round-trip formatting of every f64; angles in
/// degrees). The `sigma_m` column is written when any patch has one (empty for the others).
/// Refuses patches the reader would refuse (naming the 0-based item).
pub fn write_patches(path: &Path, patches: &[PlanarPatch]) -> Result<()> {
    let mut seen = std::collections::HashSet::new();
    for (i, p) in patches.iter().enumerate() {
        csv_text::check_writable_id(path, i, &p.id)?;
        if !seen.insert(p.id.as_str()) || !writable(p) {
            let msg = format!(
                "patch `{}` has a duplicate id or an invalid value: {p:?}",
                p.id
            );
            return Err(Error::bad_record(path, format!("item {i}"), msg));
        }
    }
    let with_sigma = patches.iter().any(|p| p.sigma_m.is_some());
    let mut out = AtomicFile::create(path)?;
    let mut header = PATCHES_HEADER.join(",");
    header.push_str(if with_sigma { ",sigma_m\n" } else { "\n" });
    out.write_all(header.as_bytes())?;
    for p in patches {
        let [e, n, u] = p.normal_enu;
        let sigma = match (with_sigma, p.sigma_m) {
            (true, Some(s)) => format!(",{s}"),
            (true, None) => ",".to_string(),
            (false, _) => String::new(),
        };
        writeln!(
            out.writer(),
            "{},{},{},{},{e},{n},{u},{},{}{sigma}",
            p.id,
            p.lat_rad.to_degrees(),
            p.lon_rad.to_degrees(),
            p.h_m,
            p.half_length_m,
            p.half_height_m
        )
        .map_err(|e| Error::io(path, e))?;
    }
    out.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wall() -> PlanarPatch {
        PlanarPatch {
            id: "wall-1".into(),
            lat_rad: 0.85,
            lon_rad: 0.12,
            h_m: 250.0,
            normal_enu: [1.0, 0.0, 0.0],
            half_length_m: 2.0,
            half_height_m: 1.5,
            sigma_m: Some(0.005),
        }
    }

    #[test]
    fn round_trip_and_optional_sigma() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("patches.csv");
        let s = 0.5f64.sqrt();
        let ground = PlanarPatch {
            id: "ground".into(),
            normal_enu: [0.0, 0.0, 1.0],
            sigma_m: None,
            ..wall()
        };
        let slope = PlanarPatch {
            id: "slope".into(),
            normal_enu: [0.0, s, s],
            ..wall()
        };
        let all = vec![wall(), ground, slope];
        write_patches(&path, &all).unwrap();
        let back = read_patches(&path).unwrap();
        assert_eq!(back.len(), 3);
        for (a, b) in all.iter().zip(&back) {
            assert_eq!(a.normal_enu, b.normal_enu);
            assert_eq!(a.sigma_m, b.sigma_m);
            assert_eq!(a.half_height_m, b.half_height_m);
            assert!((a.lat_rad - b.lat_rad).abs() < 1e-15);
        }
    }

    #[test]
    fn axes_follow_the_convention() {
        // Wall facing east: length along north, height up.
        let (l, h) = wall().axes_enu();
        assert!((l - Vector3::y()).norm() < 1e-15 && (h - Vector3::z()).norm() < 1e-15);
        // Ground: length east, height north.
        let g = PlanarPatch {
            normal_enu: [0.0, 0.0, 1.0],
            ..wall()
        };
        let (l, h) = g.axes_enu();
        assert!((l - Vector3::x()).norm() < 1e-15 && (h - Vector3::y()).norm() < 1e-15);
        // A point 1 m east and 0.5 m up of the wall centre: 1 m off the plane, 0.5 m up it.
        let p = wall();
        let x_e = p.centre_ecef() + r_enu_to_e(p.lat_rad, p.lon_rad) * Vector3::new(1.0, 0.0, 0.5);
        let c = p.patch_coords_m(&x_e);
        assert!((c - Vector3::new(0.0, 0.5, 1.0)).norm() < 1e-9, "{c}");
    }

    #[test]
    fn refuses_bad_patches() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.csv");
        let head = PATCHES_HEADER.join(",");
        let cases = [
            ("P,1,2,3,1,0.01,0,1,1", "line 2: normal has length"),
            ("P,1,2,3,1,0,0,0,1", "line 2: half_length_m 0 must be > 0"),
            ("P,1,2,3,1,0,0,1,-1", "line 2: half_height_m -1 must be > 0"),
            (
                "P,1,2,3,inf,0,0,1,1",
                "line 2: normal_e is inf (not finite)",
            ),
            (
                "P,1,2,3,1,0,0,1,1\nP,1,2,3,1,0,0,1,1",
                "line 3: duplicate id `P`",
            ),
        ];
        for (body, want) in cases {
            std::fs::write(&path, format!("{head}\n{body}\n")).unwrap();
            let e = read_patches(&path).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("p.csv"), "{e} lacks {want}");
        }
        std::fs::write(&path, format!("{head},sigma_m\nP,1,2,3,1,0,0,1,1,0\n")).unwrap();
        let e = read_patches(&path).unwrap_err().to_string();
        assert!(e.contains("line 2: sigma_m 0 must be > 0"), "{e}");
        std::fs::write(&path, format!("{head},colour\n")).unwrap();
        let e = read_patches(&path).unwrap_err().to_string();
        assert!(e.contains("unknown or misplaced column `colour`"), "{e}");
    }
}
