//! Mapping frames `m` for output (conventions §3): UTM with ellipsoidal height, ECEF, or local
//! East-North-Up about a stated origin.
//!
//! UTM (`geo::utm`) uses the Krüger n-series of the transverse Mercator projection to sixth
//! order in the third flattening `n` (Karney 2011, "Transverse Mercator with an accuracy of a few
//! nanometres", J. Geodesy 85(8), eqs. 7-11, 35-36), evaluated with Clenshaw summation in complex
//! arithmetic. Karney reports this series good to a few nanometres out to ~4000 km from the
//! central meridian. Tested: against PROJ (pyproj) forward and inverse agree to < 1e-6 m
//! (measured <= 1.1e-7 m, the oracle's printed resolution) for points up to 6 deg of longitude
//! from the central meridian, latitudes to 80 deg (`tests/geodesy.rs`); the coefficient
//! polynomials are checked against exact conformal/rectifying latitudes (unit tests).
//!
//! Speed: the coefficients are compile-time constants and ECEF -> UTM avoids ECEF -> geodetic
//! trigonometry (Newton on tan(lat), the longitude by rotating x, y): about 115 ns per point on
//! the project machine, against about 135 ns for [`ecef_to_geodetic`] alone.
//!
//! Zones are the plain 6-degree zones: [`MapFrame::utm_for`] does **not** apply the Norway (32V)
//! or Svalbard (31X-37X) exceptions; name the zone explicitly to use them.

use std::fmt;

use nalgebra::{Complex, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::ellipsoid::{
    ecef_to_geodetic, geodetic_to_ecef, r_enu_to_e, Geodetic, WGS84_A, WGS84_E2,
};
use super::epsg::EpsgCrs;
use super::utm::{
    central_meridian_rad, false_northing_m, tm_inverse, tm_scale_convergence, tm_zeta, utm_point,
    Lat, RECT_A_M,
};
pub use super::utm::{UTM_FALSE_EASTING_M, UTM_FALSE_NORTHING_SOUTH_M, UTM_K0};
use crate::{Error, Result};

/// A mapping frame for output coordinates (conventions §3). Map coordinates are a `Vector3` whose
/// meaning depends on the variant:
/// - `Utm`: (easting, northing, ellipsoidal height) in m, WGS84, k0 = 0.9996, false easting
///   500 000 m, false northing 0 (north) or 10 000 000 m (south). Height is *ellipsoidal*.
/// - `Ecef`: WGS84 ECEF (x, y, z) in m (EPSG:4978).
/// - `LocalEnu`: East, North, Up (m) in the tangent frame at `origin`, relative to the origin.
/// - `Epsg`: (easting, northing) of a projected CRS in its unit, WGS84 ellipsoidal height (m)
///   (see `geo::epsg`).
///
/// Serialised internally tagged, e.g. TOML `{ kind = "utm", zone = 32, north = true }`,
/// `{ kind = "ecef" }`, `{ kind = "local_enu", origin = { lat_rad = .., lon_rad = .., h_m = .. } }`,
/// `{ kind = "epsg", code = 2154 }`.
/// Deserialisation validates (zone 1..=60, finite origin with |lat| <= pi/2, a supported EPSG
/// code).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "MapFrameDef", into = "MapFrameDef")]
pub enum MapFrame {
    /// Universal Transverse Mercator zone `zone` (1..=60) of the northern (`north`) or southern
    /// hemisphere, with ellipsoidal height.
    Utm {
        /// Zone number 1..=60; central meridian (6 * zone - 183) deg.
        zone: u8,
        /// Northern-hemisphere false northing (0) when true, southern (1e7 m) when false.
        north: bool,
    },
    /// WGS84 ECEF.
    Ecef,
    /// Local East-North-Up about a geodetic origin (rad, rad, m).
    LocalEnu {
        /// Origin of the frame; its ENU axes are the map axes.
        origin: Geodetic,
    },
    /// A projected CRS by EPSG code, with WGS84 ellipsoidal height.
    Epsg {
        /// The resolved CRS (one per code and process).
        crs: &'static EpsgCrs,
    },
    /// Geographic coordinates by EPSG code ([`GEOGRAPHIC_CODES`]: WGS 84 2D and 3D, ETRS89):
    /// X longitude and Y latitude in degrees (longitude in (-180, 180]), Z the ellipsoidal
    /// height in metres. ETRS89 is taken as WGS84 (the null transformation PROJ applies, as
    /// for the projected ETRS89 codes; their ellipsoids differ by 0.1 mm).
    Geographic {
        /// 4326, 4979 or 4258.
        code: u32,
    },
}

/// The geographic CRSs a map frame can be ([`MapFrame::Geographic`]): WGS 84 (2D), WGS 84
/// (3D, ellipsoidal height) and ETRS89.
pub const GEOGRAPHIC_CODES: [u32; 3] = [4326, 4979, 4258];

/// Unvalidated mirror of [`MapFrame`] used for (de)serialisation.
#[derive(Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum MapFrameDef {
    Utm { zone: u8, north: bool },
    Ecef,
    LocalEnu { origin: Geodetic },
    Epsg { code: u32 },
}

impl From<MapFrame> for MapFrameDef {
    fn from(f: MapFrame) -> Self {
        match f {
            MapFrame::Utm { zone, north } => MapFrameDef::Utm { zone, north },
            MapFrame::Ecef => MapFrameDef::Ecef,
            MapFrame::LocalEnu { origin } => MapFrameDef::LocalEnu { origin },
            MapFrame::Epsg { crs } => MapFrameDef::Epsg { code: crs.code() },
            MapFrame::Geographic { code } => MapFrameDef::Epsg { code },
        }
    }
}

impl TryFrom<MapFrameDef> for MapFrame {
    type Error = Error;
    fn try_from(d: MapFrameDef) -> Result<Self> {
        let f = match d {
            MapFrameDef::Utm { zone, north } => MapFrame::Utm { zone, north },
            MapFrameDef::Ecef => MapFrame::Ecef,
            MapFrameDef::LocalEnu { origin } => MapFrame::LocalEnu { origin },
            MapFrameDef::Epsg { code } => MapFrame::from_epsg(code)?,
        };
        f.validate()?;
        Ok(f)
    }
}

impl fmt::Display for MapFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MapFrame::Utm { zone, north } => {
                write!(
                    f,
                    "WGS 84 / UTM zone {zone}{}",
                    if *north { 'N' } else { 'S' }
                )
            }
            MapFrame::Ecef => write!(f, "WGS 84 ECEF"),
            MapFrame::LocalEnu { origin } => write!(
                f,
                "local ENU at lat {:.9} deg, lon {:.9} deg, h {:.4} m (WGS 84)",
                origin.lat_rad.to_degrees(),
                origin.lon_rad.to_degrees(),
                origin.h_m
            ),
            MapFrame::Epsg { crs } => f.write_str(crs.name()),
            MapFrame::Geographic { code } => f.write_str(match code {
                4979 => "WGS 84 (3D)",
                4258 => "ETRS89",
                _ => "WGS 84",
            }),
        }
    }
}

impl MapFrame {
    /// UTM zone `zone` (1..=60), northern hemisphere when `north`.
    pub fn utm(zone: u8, north: bool) -> Result<Self> {
        let f = MapFrame::Utm { zone, north };
        f.validate()?;
        Ok(f)
    }

    /// The standard 6-degree UTM zone containing longitude `lon_rad` (any value, wrapped), north
    /// when `lat_rad >= 0`. No Norway/Svalbard exceptions. Longitudes on a zone boundary go to
    /// the eastern zone (180 deg = -180 deg is zone 1).
    pub fn utm_for(lon_rad: f64, lat_rad: f64) -> Result<Self> {
        if !lon_rad.is_finite() || !lat_rad.is_finite() {
            return Err(Error::Invalid(format!(
                "UTM zone for non-finite position (lon {lon_rad} rad, lat {lat_rad} rad)"
            )));
        }
        let lon_deg = (lon_rad.to_degrees() + 180.0).rem_euclid(360.0);
        let zone = ((lon_deg / 6.0).floor() as u8).min(59) + 1;
        Ok(MapFrame::Utm {
            zone,
            north: lat_rad >= 0.0,
        })
    }

    /// Longitude of `lon_rad` from the central meridian of a UTM frame (deg, wrapped to
    /// [-180, 180)); `None` for other frames.
    pub fn utm_offset_deg(&self, lon_rad: f64) -> Option<f64> {
        match *self {
            MapFrame::Utm { zone, .. } => {
                let d = (lon_rad - central_meridian_rad(zone)).to_degrees();
                Some((d + 180.0).rem_euclid(360.0) - 180.0)
            }
            _ => None,
        }
    }

    /// The CRS EPSG `code`: a geographic one of [`GEOGRAPHIC_CODES`], or a projected CRS on
    /// WGS84 or with a stated Helmert to it (refused with the reason: unknown codes, other
    /// geographic and geocentric CRSs, grid-shift datums, projections `proj4rs` lacks).
    pub fn from_epsg(code: u32) -> Result<Self> {
        if GEOGRAPHIC_CODES.contains(&code) {
            return Ok(MapFrame::Geographic { code });
        }
        EpsgCrs::get(code)
            .map(|crs| MapFrame::Epsg { crs })
            .map_err(Error::Invalid)
    }

    /// Local ENU frame about `origin`.
    pub fn local_enu(origin: Geodetic) -> Result<Self> {
        let f = MapFrame::LocalEnu { origin };
        f.validate()?;
        Ok(f)
    }

    /// Checks the parameters: zone 1..=60; origin finite with |lat| <= pi/2.
    pub fn validate(&self) -> Result<()> {
        match *self {
            MapFrame::Utm { zone, .. } if !(1..=60).contains(&zone) => {
                Err(Error::Invalid(format!("UTM zone {zone} is not in 1..=60")))
            }
            MapFrame::LocalEnu { origin: o }
                if !(o.lat_rad.abs() <= std::f64::consts::FRAC_PI_2
                    && o.lon_rad.is_finite()
                    && o.h_m.is_finite()) =>
            {
                Err(Error::Invalid(format!(
                    "local ENU origin {o:?} is not a valid position"
                )))
            }
            _ => Ok(()),
        }
    }

    /// ECEF `e` (m) to map coordinates (see [`MapFrame`] for their meaning).
    #[inline]
    pub fn ecef_to_map(&self, x_e: &Vector3<f64>) -> Vector3<f64> {
        match *self {
            MapFrame::Utm { zone, north } => {
                let (lat, sin_dlon, cos_dlon, h_m) = utm_point(zone, x_e);
                let zeta = tm_zeta(lat, sin_dlon, cos_dlon);
                Vector3::new(
                    UTM_FALSE_EASTING_M + UTM_K0 * RECT_A_M * zeta.im,
                    false_northing_m(north) + UTM_K0 * RECT_A_M * zeta.re,
                    h_m,
                )
            }
            MapFrame::Ecef => *x_e,
            MapFrame::LocalEnu { origin } => {
                r_enu_to_e(origin.lat_rad, origin.lon_rad).transpose()
                    * (x_e - geodetic_to_ecef(origin))
            }
            MapFrame::Epsg { crs } => crs.ecef_to_map(x_e),
            MapFrame::Geographic { .. } => degrees_of(ecef_to_geodetic(x_e)),
        }
    }

    /// Geodetic (rad, rad, m) to map coordinates.
    #[inline]
    pub fn geodetic_to_map(&self, g: Geodetic) -> Vector3<f64> {
        match *self {
            MapFrame::Utm { zone, north } => {
                let (sin_dlon, cos_dlon) = (g.lon_rad - central_meridian_rad(zone)).sin_cos();
                let zeta = tm_zeta(Lat::from_rad(g.lat_rad), sin_dlon, cos_dlon);
                Vector3::new(
                    UTM_FALSE_EASTING_M + UTM_K0 * RECT_A_M * zeta.im,
                    false_northing_m(north) + UTM_K0 * RECT_A_M * zeta.re,
                    g.h_m,
                )
            }
            MapFrame::Epsg { crs } => crs.geodetic_to_map(g),
            MapFrame::Geographic { .. } => degrees_of(g),
            _ => self.ecef_to_map(&geodetic_to_ecef(g)),
        }
    }

    /// Map coordinates to geodetic (rad, rad, m), longitude in (-pi, pi].
    pub fn map_to_geodetic(&self, x_m: &Vector3<f64>) -> Geodetic {
        match *self {
            MapFrame::Utm { zone, north } => {
                let zeta = Complex::new(
                    (x_m.y - false_northing_m(north)) / (UTM_K0 * RECT_A_M),
                    (x_m.x - UTM_FALSE_EASTING_M) / (UTM_K0 * RECT_A_M),
                );
                let (lat_rad, dlon_rad) = tm_inverse(zeta);
                Geodetic {
                    lat_rad,
                    lon_rad: super::rotations::wrap_pi(central_meridian_rad(zone) + dlon_rad),
                    h_m: x_m.z,
                }
            }
            MapFrame::Epsg { crs } => crs.map_to_geodetic(x_m),
            MapFrame::Geographic { .. } => Geodetic {
                lat_rad: x_m.y.to_radians(),
                lon_rad: x_m.x.to_radians(),
                h_m: x_m.z,
            },
            _ => ecef_to_geodetic(&self.map_to_ecef(x_m)),
        }
    }

    /// Map coordinates to ECEF `e` (m).
    pub fn map_to_ecef(&self, x_m: &Vector3<f64>) -> Vector3<f64> {
        match *self {
            MapFrame::Utm { .. } => geodetic_to_ecef(self.map_to_geodetic(x_m)),
            MapFrame::Ecef => *x_m,
            MapFrame::LocalEnu { origin } => {
                geodetic_to_ecef(origin) + r_enu_to_e(origin.lat_rad, origin.lon_rad) * x_m
            }
            MapFrame::Epsg { crs } => crs.map_to_ecef(x_m),
            MapFrame::Geographic { .. } => geodetic_to_ecef(self.map_to_geodetic(x_m)),
        }
    }

    /// EPSG code of the frame: 326zz (UTM north), 327zz (UTM south), 4978 (ECEF), the code of
    /// an EPSG frame; `None` for local ENU. The projected codes are horizontal only: the height
    /// is ellipsoidal (WGS84).
    pub fn epsg(&self) -> Option<u32> {
        match *self {
            MapFrame::Utm { zone, north } => Some(if north { 32600 } else { 32700 } + zone as u32),
            MapFrame::Ecef => Some(4978),
            MapFrame::LocalEnu { .. } => None,
            MapFrame::Epsg { crs } => Some(crs.code()),
            MapFrame::Geographic { code } => Some(code),
        }
    }

    /// Whether X and Y are longitude and latitude in degrees ([`MapFrame::Geographic`]).
    pub fn is_geographic(&self) -> bool {
        matches!(self, MapFrame::Geographic { .. })
    }

    /// Metres per unit of the map axes: 1 but for an EPSG CRS in feet (1200/3937 for US survey
    /// feet). The pipeline computes in metres and writes Z and the sigmas in this unit too
    /// (docs/output.md). A geographic frame has X and Y in degrees but Z and the sigmas in
    /// metres: 1.
    pub fn metres_per_unit(&self) -> f64 {
        match self {
            MapFrame::Epsg { crs } => crs.metres_per_unit(),
            _ => 1.0,
        }
    }

    /// OGC WKT1 (one line) of the frame, for the LAS WKT CRS VLR.
    ///
    /// UTM is a `PROJCS` and ECEF a `GEOCCS` carrying `AUTHORITY["EPSG",..]`, so PROJ/pyproj
    /// identify them (`CRS.from_wkt(w).to_epsg()` gives [`MapFrame::epsg`]; checked by
    /// `tests/oracle/make_geodesy_oracle.py --check`). The UTM WKT is horizontal; Z in the file
    /// is WGS84 ellipsoidal height. Local ENU is an engineering `LOCAL_CS` (local datum type
    /// 32767, as PROJ writes it) with axes East, North, Up (m) whose name and datum state the
    /// WGS84 origin in degrees (9 decimals, < 0.1 mm) and metres; it has no EPSG code.
    pub fn wkt(&self) -> String {
        const DATUM: &str = r#"DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]]"#;
        const METRE: &str = r#"UNIT["metre",1,AUTHORITY["EPSG","9001"]]"#;
        match *self {
            MapFrame::Utm { zone, north } => format!(
                concat!(
                    r#"PROJCS["{name}",GEOGCS["WGS 84",{datum},"#,
                    r#"UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],"#,
                    r#"AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],"#,
                    r#"PARAMETER["latitude_of_origin",0],PARAMETER["central_meridian",{cm}],"#,
                    r#"PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],"#,
                    r#"PARAMETER["false_northing",{fn_m}],{metre},AXIS["Easting",EAST],"#,
                    r#"AXIS["Northing",NORTH],AUTHORITY["EPSG","{epsg}"]]"#
                ),
                name = self,
                datum = DATUM,
                cm = 6 * zone as i32 - 183,
                fn_m = false_northing_m(north),
                metre = METRE,
                epsg = self.epsg().unwrap_or_default(),
            ),
            MapFrame::Ecef => format!(
                concat!(
                    r#"GEOCCS["WGS 84",{datum},{metre},AXIS["Geocentric X",OTHER],"#,
                    r#"AXIS["Geocentric Y",OTHER],AXIS["Geocentric Z",NORTH],"#,
                    r#"AUTHORITY["EPSG","4978"]]"#
                ),
                datum = DATUM,
                metre = METRE
            ),
            MapFrame::LocalEnu { .. } => format!(
                concat!(
                    r#"LOCAL_CS["{name}",LOCAL_DATUM["{name}",32767],{metre},"#,
                    r#"AXIS["Easting",EAST],AXIS["Northing",NORTH],AXIS["Up",UP]]"#
                ),
                name = self,
                metre = METRE
            ),
            MapFrame::Epsg { crs } => crs.wkt().to_string(),
            MapFrame::Geographic { code: 4979 } => format!(
                // WKT1 has no 3D geographic CRS PROJ identifies: WKT2 (ISO 19162:2019), which
                // PROJ, pyproj and laspy read.
                concat!(
                    r#"GEOGCRS["WGS 84",DATUM["World Geodetic System 1984",ELLIPSOID["WGS 84","#,
                    r#"6378137,298.257223563,LENGTHUNIT["metre",1]]],PRIMEM["Greenwich",0,"#,
                    r#"{deg}],CS[ellipsoidal,3],AXIS["geodetic latitude (Lat)",north,ORDER[1],"#,
                    r#"{deg}],AXIS["geodetic longitude (Lon)",east,ORDER[2],{deg}],"#,
                    r#"AXIS["ellipsoidal height (h)",up,ORDER[3],LENGTHUNIT["metre",1]],"#,
                    r#"ID["EPSG",4979]]"#
                ),
                deg = r#"ANGLEUNIT["degree",0.0174532925199433]"#
            ),
            MapFrame::Geographic { code } => {
                let datum = match code {
                    4258 => concat!(
                        r#"DATUM["European_Terrestrial_Reference_System_1989",SPHEROID["GRS 1980","#,
                        r#"6378137,298.257222101,AUTHORITY["EPSG","7019"]],AUTHORITY["EPSG","6258"]],"#,
                        r#"PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]]"#
                    ),
                    _ => DATUM,
                };
                // No AXIS nodes: with them (longitude first, as X holds it) PROJ no longer
                // identifies the code; LAS readers take X as longitude (docs/output.md).
                format!(
                    concat!(
                        r#"GEOGCS["{name}",{datum},"#,
                        r#"UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],"#,
                        r#"AUTHORITY["EPSG","{code}"]]"#
                    ),
                    name = self,
                    datum = datum,
                    code = code
                )
            }
        }
    }

    /// Jacobian `d x_m / d x_enu` at the ECEF point `x_e`: the linear map from a small
    /// displacement in the local East-North-Up frame *at the point* to a displacement along the
    /// map axes. Use it to carry a point's ENU covariance `C` to the map axes as `J C J^T`.
    ///
    /// - UTM: `[[k R(gamma) D, 0], [0, 1]]` with `R(gamma)` the counter-clockwise rotation by
    ///   the grid convergence `gamma` (grid north's bearing, clockwise from true north), `k` the
    ///   point scale factor, and `D = diag(N/(N+h), M/(M+h))` the reduction of the horizontal
    ///   displacement at height `h` to the ellipsoid (N, M the prime-vertical and meridian
    ///   radii); the height axis is unchanged.
    /// - ECEF: `R_enu^e` at the point.
    /// - Local ENU: `R_e^enu(origin) * R_enu^e(point)`.
    /// - EPSG: the CRS's grid axes (`EpsgCrs::r_enu_to_grid_m`) in metres whatever the CRS unit.
    /// - Geographic: the identity (sigmas in metres along East, North, Up).
    ///
    /// Exact derivative (checked against central finite differences to 1e-8 in
    /// `tests/frames.rs`).
    pub fn r_enu_to_map_axes(&self, x_e: &Vector3<f64>) -> Matrix3<f64> {
        match *self {
            MapFrame::Utm { zone, .. } => {
                let (lat, sin_dlon, cos_dlon, h_m) = utm_point(zone, x_e);
                let kg = tm_scale_convergence(lat, sin_dlon, cos_dlon);
                // N / (N + h) and M / (M + h) with N = a / w, M = a (1 - e^2) / w^3.
                let w = (1.0 - WGS84_E2 * lat.sin * lat.sin).sqrt();
                let de = WGS84_A / (WGS84_A + h_m * w);
                let m_m = WGS84_A * (1.0 - WGS84_E2) / (w * w * w);
                let dn = m_m / (m_m + h_m);
                Matrix3::new(
                    kg.re * de,
                    -kg.im * dn,
                    0.0,
                    kg.im * de,
                    kg.re * dn,
                    0.0,
                    0.0,
                    0.0,
                    1.0,
                )
            }
            MapFrame::Ecef => {
                let g = ecef_to_geodetic(x_e);
                r_enu_to_e(g.lat_rad, g.lon_rad)
            }
            MapFrame::LocalEnu { origin } => {
                let g = ecef_to_geodetic(x_e);
                r_enu_to_e(origin.lat_rad, origin.lon_rad).transpose()
                    * r_enu_to_e(g.lat_rad, g.lon_rad)
            }
            MapFrame::Epsg { crs } => crs.r_enu_to_grid_m(x_e),
            // Sigmas in metres along East (X, longitude), North (Y, latitude) and Up.
            MapFrame::Geographic { .. } => Matrix3::identity(),
        }
    }
}

/// Geographic map coordinates of `g`: longitude, latitude (deg), height (m).
fn degrees_of(g: Geodetic) -> Vector3<f64> {
    Vector3::new(g.lon_rad.to_degrees(), g.lat_rad.to_degrees(), g.h_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zone_selection() {
        let z = |lon_deg: f64, lat_deg: f64| {
            MapFrame::utm_for(lon_deg.to_radians(), lat_deg.to_radians()).unwrap()
        };
        assert_eq!(
            z(9.0, 48.0),
            MapFrame::Utm {
                zone: 32,
                north: true
            }
        );
        assert_eq!(
            z(-180.0, -1.0),
            MapFrame::Utm {
                zone: 1,
                north: false
            }
        );
        assert_eq!(
            z(180.0, 0.0),
            MapFrame::Utm {
                zone: 1,
                north: true
            }
        );
        assert_eq!(
            z(179.999, 0.0),
            MapFrame::Utm {
                zone: 60,
                north: true
            }
        );
        assert_eq!(
            z(6.0, 10.0),
            MapFrame::Utm {
                zone: 32,
                north: true
            }
        );
        assert_eq!(
            z(5.999_999, 10.0),
            MapFrame::Utm {
                zone: 31,
                north: true
            }
        );
        assert!(MapFrame::utm_for(f64::NAN, 0.0).is_err());
        assert!(MapFrame::utm(0, true).is_err() && MapFrame::utm(61, true).is_err());
    }

    #[test]
    fn serde_round_trip_and_validation() {
        for f in [
            MapFrame::Utm {
                zone: 33,
                north: false,
            },
            MapFrame::Ecef,
            MapFrame::LocalEnu {
                origin: Geodetic {
                    lat_rad: 0.8,
                    lon_rad: -2.0,
                    h_m: 12.5,
                },
            },
        ] {
            let s = toml::to_string(&f).unwrap();
            assert_eq!(toml::from_str::<MapFrame>(&s).unwrap(), f, "{s}");
        }
        let bad = toml::from_str::<MapFrame>("kind = \"utm\"\nzone = 61\nnorth = true\n");
        assert!(bad.unwrap_err().to_string().contains("61"));
        assert!(toml::from_str::<MapFrame>("kind = \"utm\"\nzone = 3\n").is_err());
    }

    #[test]
    fn epsg_codes() {
        assert_eq!(
            MapFrame::Utm {
                zone: 7,
                north: true
            }
            .epsg(),
            Some(32607)
        );
        assert_eq!(
            MapFrame::Utm {
                zone: 60,
                north: false
            }
            .epsg(),
            Some(32760)
        );
        assert_eq!(MapFrame::Ecef.epsg(), Some(4978));
    }
}
