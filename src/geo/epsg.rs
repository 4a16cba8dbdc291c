//! Projected CRSs named by EPSG code (docs/conventions.md §3): the definition comes from the
//! `crs-definitions` table (EPSG code -> PROJ.4 string and OGC WKT1, as exported by PROJ), the
//! projection maths from `proj4rs` (a pure-Rust port of PROJ.4's projections: Poder/Engsager
//! transverse Mercator, Lambert conformal conic, oblique and polar stereographic, Albers, ...).
//!
//! Accepted: projected CRSs whose datum is WGS84, or is tied to WGS84 by a Helmert
//! transformation stated in the definition (`+towgs84=` 3 or 7 parameters, position-vector
//! convention, as PROJ applies them; `+datum=NAD83` and `+datum=OSGB36` get the Helmert of the
//! EPSG transformation PROJ picks for them). Refused, each with
//! the reason: unknown codes, geographic and geocentric CRSs (their coordinates are angles or
//! ECEF, not map axes; use `kind = "ecef"` for ECEF), datums defined by a shift grid
//! (`+nadgrids`, NAD27, DHDN/potsdam in PROJ 9) or by nothing at all (an ellipsoid without a
//! transformation to WGS84), and projections `proj4rs` does not implement.
//!
//! Map coordinates: (easting, northing) in the CRS's unit (metre or US survey foot...) and, as
//! for UTM, Z = the WGS84 ellipsoidal height in metres (PROJ does the same for a 2D projected
//! target: the Helmert shifts latitude and longitude only). Sigmas along these axes are stated
//! in metres (docs/conventions.md §7): [`EpsgCrs::r_enu_to_grid_m`] is the Jacobian in metres of
//! grid distance per metre.

use std::collections::HashMap;
use std::fmt;
use std::sync::{LazyLock, Mutex};

use nalgebra::{Matrix3, Vector3};
use proj4rs::Proj;

use super::ellipsoid::{ecef_to_geodetic, geodetic_to_ecef, r_enu_to_e, Geodetic};
use super::epsg_axes::{NORTH_EAST, OTHER_AXES};

/// A projected CRS resolved from its EPSG code, with its exact forward and inverse projection.
pub struct EpsgCrs {
    code: u32,
    name: String,
    wkt: String,
    proj4: String,
    proj: Proj,
    wgs84: Proj,
}

impl fmt::Debug for EpsgCrs {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "EPSG:{} ({})", self.code, self.name)
    }
}

impl PartialEq for EpsgCrs {
    fn eq(&self, other: &Self) -> bool {
        self.code == other.code
    }
}

/// Datums accepted by name, with the Helmert to WGS84 (PROJ `+towgs84` form: m, arc-seconds,
/// ppm, position-vector rotations) of the EPSG transformation PROJ chooses for them: WGS84
/// (none), NAD83 (EPSG:1188, null), OSGB36 (EPSG:1314). The named datum is replaced by this
/// explicit Helmert before parsing: `proj4rs`'s own OSGB36 entry carries PROJ.4's older,
/// longer parameters (0.1502", ..., -20.4894 ppm), 2.9 mm away from EPSG:1314 in London.
const DATUMS_TIED_TO_WGS84: [(&str, &str); 3] = [
    ("WGS84", "+datum=WGS84"),
    ("NAD83", "+ellps=GRS80 +towgs84=0,0,0,0,0,0,0"),
    (
        "OSGB36",
        "+ellps=airy +towgs84=446.448,-125.157,542.06,0.15,0.247,0.842,-20.489",
    ),
];

/// Finite-difference step (m) of [`EpsgCrs::r_enu_to_grid_m`]: the central difference's
/// truncation is ~ (h / R)^2 ~ 1e-14 relative, the f64 rounding of grid coordinates
/// (<= 1e-9 m at 1e7 m) over 2 h is 5e-10 relative.
const JACOBIAN_STEP_M: f64 = 1.0;

impl EpsgCrs {
    /// The CRS for EPSG `code`, resolved once per process and kept for its lifetime (a handful
    /// of definitions a run at most). Errors say what is wrong with the code, in words.
    pub fn get(code: u32) -> Result<&'static EpsgCrs, String> {
        static CACHE: LazyLock<Mutex<HashMap<u32, &'static EpsgCrs>>> =
            LazyLock::new(|| Mutex::new(HashMap::new()));
        let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(crs) = cache.get(&code) {
            return Ok(crs);
        }
        let crs: &'static EpsgCrs = Box::leak(Box::new(Self::resolve(code)?));
        cache.insert(code, crs);
        Ok(crs)
    }

    fn resolve(code: u32) -> Result<EpsgCrs, String> {
        let def = u16::try_from(code)
            .ok()
            .and_then(crs_definitions::from_code)
            .ok_or_else(|| format!("EPSG:{code} is not a known EPSG CRS code"))?;
        let name = wkt_name(def.wkt).unwrap_or("unnamed").to_string();
        let label = format!("EPSG:{code} ({name})");
        check_kind(def.proj4).map_err(|why| format!("{label} {why}"))?;
        let proj4 = with_explicit_helmert(def.proj4).map_err(|why| format!("{label} {why}"))?;
        let proj = Proj::from_proj_string(&proj4)
            .map_err(|e| format!("{label}: its projection is not supported ({e})"))?;
        let wgs84 = Proj::from_proj_string("+proj=longlat +datum=WGS84 +no_defs")
            .map_err(|e| format!("WGS84 definition: {e}"))?;
        let crs = EpsgCrs {
            code,
            name,
            wkt: identifying_wkt(code, def.wkt),
            proj4,
            proj,
            wgs84,
        };
        // A projection whose forward or inverse fails at its own natural origin is unusable.
        let probe = Geodetic {
            lat_rad: crs.proj.latitude_of_origin().clamp(-1.5, 1.5),
            lon_rad: crs.proj.longitude_of_origin(),
            h_m: 0.0,
        };
        if !crs.geodetic_to_map(probe).iter().all(|v| v.is_finite()) {
            return Err(format!("{label}: its projection fails at its own origin"));
        }
        Ok(crs)
    }

    /// EPSG code.
    pub fn code(&self) -> u32 {
        self.code
    }

    /// CRS name (from the WKT), e.g. "RGF93 / Lambert-93".
    pub fn name(&self) -> &str {
        &self.name
    }

    /// OGC WKT1 of the CRS that PROJ identifies as its EPSG code (see [`identifying_wkt`]).
    pub fn wkt(&self) -> &str {
        &self.wkt
    }

    /// The PROJ.4 definition used for the maths.
    pub fn proj4(&self) -> &str {
        &self.proj4
    }

    /// Metres per unit of the grid coordinates (1 for metres, 1200/3937 for US survey feet).
    pub fn metres_per_unit(&self) -> f64 {
        self.proj.to_meter()
    }

    /// Geodetic WGS84 (rad, rad, m) to (easting, northing) in the CRS unit and the WGS84
    /// ellipsoidal height (m). NaN outside the projection's domain (e.g. the far hemisphere).
    pub fn geodetic_to_map(&self, g: Geodetic) -> Vector3<f64> {
        let mut p = (g.lon_rad, g.lat_rad, g.h_m);
        match proj4rs::transform::transform(&self.wgs84, &self.proj, &mut p) {
            Ok(()) => Vector3::new(p.0, p.1, g.h_m),
            Err(_) => Vector3::repeat(f64::NAN),
        }
    }

    /// Inverse of [`EpsgCrs::geodetic_to_map`]; NaN where the inverse projection fails.
    pub fn map_to_geodetic(&self, x_m: &Vector3<f64>) -> Geodetic {
        let mut p = (x_m.x, x_m.y, 0.0);
        match proj4rs::transform::transform(&self.proj, &self.wgs84, &mut p) {
            Ok(()) => Geodetic {
                lat_rad: p.1,
                lon_rad: p.0,
                h_m: x_m.z,
            },
            Err(_) => Geodetic {
                lat_rad: f64::NAN,
                lon_rad: f64::NAN,
                h_m: f64::NAN,
            },
        }
    }

    /// ECEF (m) to map coordinates.
    pub fn ecef_to_map(&self, x_e: &Vector3<f64>) -> Vector3<f64> {
        self.geodetic_to_map(ecef_to_geodetic(x_e))
    }

    /// `d x_grid / d x_enu` at the ECEF point `x_e`, the grid axes in metres (the CRS unit times
    /// [`EpsgCrs::metres_per_unit`]), the height axis unchanged: grid convergence, point scale
    /// and the reduction to the ellipsoid included. Central differences of the exact projection
    /// along the point's East, North, Up (see [`JACOBIAN_STEP_M`]).
    pub fn r_enu_to_grid_m(&self, x_e: &Vector3<f64>) -> Matrix3<f64> {
        let g = ecef_to_geodetic(x_e);
        let r = r_enu_to_e(g.lat_rad, g.lon_rad);
        let unit = Vector3::new(self.metres_per_unit(), self.metres_per_unit(), 1.0);
        let mut j = Matrix3::zeros();
        for i in 0..3 {
            let step = r.column(i) * JACOBIAN_STEP_M;
            let diff = self.ecef_to_map(&(x_e + step)) - self.ecef_to_map(&(x_e - step));
            j.set_column(i, &diff.component_mul(&unit).scale(0.5 / JACOBIAN_STEP_M));
        }
        j
    }

    /// Map coordinates to ECEF (m).
    pub fn map_to_ecef(&self, x_m: &Vector3<f64>) -> Vector3<f64> {
        geodetic_to_ecef(self.map_to_geodetic(x_m))
    }
}

/// The table's WKT1 made to identify as EPSG `code` in PROJ (`CRS.from_wkt(w).to_epsg()`,
/// checked by pyproj in CI over every code of docs/output.md): without `TOWGS84` nodes (with
/// one, PROJ reads a bound CRS, the CRS *plus* a transformation, which has no EPSG code; the
/// Helmert kinescan applied is documented, and a GIS tool picks its own transformation from
/// the EPSG code), and with the axis order of the EPSG definition (`epsg_axes`, generated from
/// PROJ's database): northing first where EPSG says so, no `AXIS` for polar axes. The LAS
/// coordinates stay easting, northing (traditional GIS order).
fn identifying_wkt(code: u32, table_wkt: &str) -> String {
    let mut wkt = strip_nodes(table_wkt, ",TOWGS84[");
    let north_east = u16::try_from(code).is_ok_and(|c| NORTH_EAST.binary_search(&c).is_ok());
    let other = u16::try_from(code).is_ok_and(|c| OTHER_AXES.binary_search(&c).is_ok());
    if north_east || other {
        wkt = strip_nodes(&wkt, ",AXIS[");
        if north_east {
            let authority = format!(",AUTHORITY[\"EPSG\",\"{code}\"]]");
            if let Some(at) = wkt.rfind(&authority) {
                wkt.insert_str(at, r#",AXIS["Northing",NORTH],AXIS["Easting",EAST]"#);
            }
        }
    }
    wkt
}

/// `wkt` without every node that starts with `start` (e.g. `,TOWGS84[`), brackets balanced.
fn strip_nodes(wkt: &str, start: &str) -> String {
    let mut out = String::with_capacity(wkt.len());
    let mut rest = wkt;
    while let Some(at) = rest.find(start) {
        out.push_str(&rest[..at]);
        let mut depth = 0usize;
        let mut end = rest.len();
        for (i, ch) in rest[at..].char_indices() {
            match ch {
                '[' => depth += 1,
                ']' => {
                    depth -= 1;
                    if depth == 0 {
                        end = at + i + 1;
                        break;
                    }
                }
                _ => {}
            }
        }
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

/// The name in `PROJCS["name",...` of a WKT1.
fn wkt_name(wkt: &str) -> Option<&str> {
    let rest = wkt.split_once("[\"")?.1;
    Some(rest.split_once('"')?.0)
}

/// Value of `+key=` in a PROJ.4 string.
fn proj4_value<'a>(proj4: &'a str, key: &str) -> Option<&'a str> {
    proj4
        .split_whitespace()
        .find_map(|t| t.strip_prefix('+')?.strip_prefix(key)?.strip_prefix('='))
}

/// Refuses geographic and geocentric CRSs.
fn check_kind(proj4: &str) -> Result<(), String> {
    match proj4_value(proj4, "proj") {
        Some("longlat" | "latlong" | "lonlat" | "latlon") => Err(
            "is a geographic CRS (latitude, longitude) kinescan does not write: the \
             geographic outputs are EPSG:4326, 4979 (ellipsoidal height) and 4258 (ETRS89); \
             else choose a projected CRS"
                .into(),
        ),
        Some("geocent") => {
            Err("is geocentric: use output.frame = { kind = \"ecef\" } for ECEF".into())
        }
        Some(_) => Ok(()),
        None => Err("has no projection".into()),
    }
}

/// The definition with its datum tied to WGS84 by an explicit Helmert: as given when it has
/// `+towgs84`, a named datum of [`DATUMS_TIED_TO_WGS84`] replaced by its Helmert; refuses
/// grid-based and unrelated datums.
fn with_explicit_helmert(proj4: &str) -> Result<String, String> {
    if let Some(grids) = proj4_value(proj4, "nadgrids") {
        return Err(format!(
            "has a datum defined by the shift grid(s) `{grids}`: only datums tied to WGS84 by \
             a Helmert transformation are supported"
        ));
    }
    if proj4_value(proj4, "towgs84").is_some() {
        return Ok(proj4.to_string());
    }
    let datum = proj4_value(proj4, "datum");
    match datum.and_then(|d| DATUMS_TIED_TO_WGS84.iter().find(|(name, _)| *name == d)) {
        Some((name, helmert)) => Ok(proj4.replace(&format!("+datum={name}"), helmert)),
        None => Err(match datum {
            Some(d) => format!(
                "has the datum `{d}`, which PROJ relates to WGS84 by a shift grid, not a Helmert \
             transformation: unsupported"
            ),
            None => "states no transformation of its datum to WGS84 (no towgs84 Helmert): \
                     unsupported datum"
                .into(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_say_why() {
        let err = |c| EpsgCrs::get(c).unwrap_err();
        assert!(err(1).contains("not a known EPSG"), "{}", err(1));
        assert!(err(4326).contains("geographic"), "{}", err(4326));
        assert!(err(4978).contains("geocentric"), "{}", err(4978));
        // NAD27 / UTM 18N: grid-based datum.
        assert!(err(26718).contains("shift grid"), "{}", err(26718));
        // GDA2020 / MGA 56: an ellipsoid and no stated transformation.
        assert!(err(7856).contains("unsupported datum"), "{}", err(7856));
        // Pseudo-Mercator's definition is a sphere with a null grid.
        assert!(err(3857).contains("shift grid"), "{}", err(3857));
    }

    #[test]
    fn resolves_and_names() {
        let crs = EpsgCrs::get(2154).unwrap();
        assert_eq!(crs.name(), "RGF93 / Lambert-93");
        assert!(crs.wkt().contains("AUTHORITY[\"EPSG\",\"2154\"]"));
        assert!(!crs.wkt().contains("TOWGS84"), "{}", crs.wkt());
        assert!(std::ptr::eq(crs, EpsgCrs::get(2154).unwrap()));
        let ft = EpsgCrs::get(2263).unwrap();
        assert!((ft.metres_per_unit() - 1200.0 / 3937.0).abs() < 1e-15);
    }

    /// The WKT loses its `TOWGS84` (nested brackets and all) and gets the EPSG axis order.
    #[test]
    fn identifying_wkt_strips_helmert_and_orders_axes() {
        let ne = EpsgCrs::get(3035).unwrap().wkt();
        assert!(!ne.contains("TOWGS84"), "{ne}");
        assert!(
            ne.ends_with(
                r#"AXIS["Northing",NORTH],AXIS["Easting",EAST],AUTHORITY["EPSG","3035"]]"#
            ),
            "{ne}"
        );
        let polar = EpsgCrs::get(3031).unwrap().wkt();
        assert!(!polar.contains("AXIS["), "{polar}");
        let en = EpsgCrs::get(25832).unwrap().wkt();
        assert!(
            en.contains(r#"AXIS["Easting",EAST],AXIS["Northing",NORTH]"#),
            "{en}"
        );
        assert_eq!(
            strip_nodes("A[x,T[1,B[2]],C[3]],T[4]", ",T["),
            "A[x,C[3]]".to_string()
        );
    }

    /// Forward then inverse returns the point (PROJ.4 inverses are iterated to ~1e-10 rad).
    #[test]
    fn round_trip() {
        let g = Geodetic {
            lat_rad: 52.37_f64.to_radians(),
            lon_rad: 4.9_f64.to_radians(),
            h_m: 40.0,
        };
        let crs = EpsgCrs::get(28992).unwrap();
        let back = crs.map_to_geodetic(&crs.geodetic_to_map(g));
        assert!((back.lat_rad - g.lat_rad).abs() < 1e-10);
        assert!((back.lon_rad - g.lon_rad).abs() < 1e-10);
        assert_eq!(back.h_m, g.h_m);
    }
}
