//! Geoid grids: the geoid undulation `N` (m) above the WGS84 ellipsoid on a regular
//! latitude/longitude grid, for orthometric heights `H = h - N` (docs/conventions.md §3).
//!
//! Formats, as PROJ ships them:
//! - GTX (NOAA VDatum): a 40-byte big-endian header (south latitude, west longitude, latitude
//!   step, longitude step as f64 degrees; rows, columns as i32), then rows x columns big-endian
//!   f32 from the south row to the north, west to east in a row; -88.8888 marks no data.
//! - GeoTIFF (PROJ's grid format): one Float32 band, `ModelTiepoint` and `ModelPixelScale`
//!   tags in degrees, rows from north to south; `PixelIsArea` (the default) puts the tie point
//!   at a cell corner, so the first node is half a cell inside it, `PixelIsPoint` on the node.
//!
//! Interpolation is PROJ's bilinear: with `x`, `y` the fractional node position,
//! `N = (1-fx)(1-fy) N00 + fx(1-fy) N10 + (1-fx)fy N01 + fx fy N11`; a point outside the nodes'
//! extent or next to a no-data node has no value.

use std::path::{Path, PathBuf};

use super::ellipsoid::{WGS84_A, WGS84_E2};
use super::geoid_vertical::GRID_VERTICAL_CRS;
use crate::{Error, Result};

/// Value GTX files use for "no data".
const GTX_NO_DATA: f32 = -88.8888;
/// Longitude (deg) of a grid spanning the whole globe wraps; anything narrower does not.
const FULL_CIRCLE_DEG: f64 = 360.0;

/// A geoid undulation grid in memory.
#[derive(Debug, Clone)]
pub struct GeoidGrid {
    name: String,
    path: PathBuf,
    south_deg: f64,
    west_deg: f64,
    dlat_deg: f64,
    dlon_deg: f64,
    rows: usize,
    cols: usize,
    /// Row-major from the south row, west to east; NaN for no data.
    n_m: Vec<f32>,
}

/// The extent of a grid's nodes (deg).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridExtent {
    /// Southernmost node latitude.
    pub south_deg: f64,
    /// Northernmost node latitude.
    pub north_deg: f64,
    /// Westernmost node longitude.
    pub west_deg: f64,
    /// Easternmost node longitude.
    pub east_deg: f64,
}

impl GeoidGrid {
    /// Reads a GTX (`.gtx`) or GeoTIFF (`.tif`, `.tiff`) grid; errors name the file.
    pub fn open(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("gtx") => Self::from_gtx(path, &bytes),
            Some("tif" | "tiff") => {
                let g = super::geoid_tiff::read(path, &bytes)?;
                Self::new(path, g.corner_step_deg, g.rows, g.cols, g.n_m)
            }
            _ => Err(Error::bad_file(
                path,
                "unknown geoid grid format: expected a .gtx or .tif/.tiff file",
            )),
        }
    }

    fn from_gtx(path: &Path, bytes: &[u8]) -> Result<Self> {
        let bad = |problem: String| Error::bad_file(path, problem);
        if bytes.len() < 40 {
            return Err(bad(format!(
                "GTX header needs 40 bytes, the file has {}",
                bytes.len()
            )));
        }
        let f64_at = |i: usize| f64::from_be_bytes(bytes[i..i + 8].try_into().expect("8 bytes"));
        let i32_at = |i: usize| i32::from_be_bytes(bytes[i..i + 4].try_into().expect("4 bytes"));
        let (rows, cols) = (i32_at(32), i32_at(36));
        if rows < 2 || cols < 2 {
            return Err(bad(format!(
                "GTX header: {rows} rows x {cols} columns, need at least 2 x 2"
            )));
        }
        let (rows, cols) = (rows as usize, cols as usize);
        let expected = 40 + rows * cols * 4;
        if bytes.len() != expected {
            return Err(bad(format!(
                "GTX of {rows} x {cols} nodes needs {expected} bytes, the file has {}",
                bytes.len()
            )));
        }
        let n_m = bytes[40..]
            .chunks_exact(4)
            .map(|c| f32::from_be_bytes(c.try_into().expect("4 bytes")))
            .map(|v| if v == GTX_NO_DATA { f32::NAN } else { v })
            .collect();
        Self::new(
            path,
            [f64_at(0), f64_at(8), f64_at(16), f64_at(24)],
            rows,
            cols,
            n_m,
        )
    }

    /// A grid from its south-west node, steps (deg) and south-to-north rows of values.
    pub(crate) fn new(
        path: &Path,
        [south_deg, west_deg, dlat_deg, dlon_deg]: [f64; 4],
        rows: usize,
        cols: usize,
        n_m: Vec<f32>,
    ) -> Result<Self> {
        let ok = south_deg.is_finite()
            && west_deg.is_finite()
            && dlat_deg > 0.0
            && dlon_deg > 0.0
            && south_deg >= -90.0
            && south_deg + dlat_deg * (rows - 1) as f64 <= 90.0 + 1e-9;
        if !ok || n_m.len() != rows * cols {
            return Err(Error::bad_file(
                path,
                format!(
                    "geoid grid geometry is not valid: south {south_deg} deg, west {west_deg} \
                     deg, steps {dlat_deg} x {dlon_deg} deg, {rows} x {cols} nodes"
                ),
            ));
        }
        Ok(GeoidGrid {
            name: path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            path: path.to_path_buf(),
            south_deg,
            west_deg,
            dlat_deg,
            dlon_deg,
            rows,
            cols,
            n_m,
        })
    }

    /// The grid's file name, e.g. `us_noaa_g2018u0.tif` (used in the WKT and the report).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The vertical CRS PROJ ties to this grid (by file name, `geoid_vertical`, generated from
    /// PROJ's database): its EPSG code and WKT1, e.g. 5703 (NAVD88 height) for
    /// `us_noaa_g2018u0.tif`; `None` for a grid PROJ does not know.
    pub fn vertical_crs(&self) -> Option<(u32, &'static str)> {
        GRID_VERTICAL_CRS
            .binary_search_by(|(name, _, _)| (*name).cmp(self.name.as_str()))
            .ok()
            .map(|i| (GRID_VERTICAL_CRS[i].1, GRID_VERTICAL_CRS[i].2))
    }

    /// OGC WKT1 of the compound CRS: the horizontal CRS `horizontal_wkt` (named
    /// `horizontal_name`) with heights above this grid's geoid: the grid's EPSG vertical CRS
    /// when PROJ knows the grid ([`GeoidGrid::vertical_crs`], `AUTHORITY["EPSG",code]`), else
    /// a `VERT_CS` named after the grid file (orthometric datum type 2005, metres, up).
    ///
    /// When the horizontal CRS's linear unit is not the metre (`metres_per_unit` != 1, e.g. US
    /// survey feet), the heights are written in that unit: the vertical CRS takes the
    /// horizontal CRS's `UNIT` node and a name with the unit, as EPSG names such CRSs
    /// ("NAVD88 height (ftUS)", which PROJ identifies as EPSG:6360); its authority code, that
    /// of the metre CRS, is dropped.
    pub fn compound_wkt(
        &self,
        horizontal_name: &str,
        horizontal_wkt: &str,
        metres_per_unit: f64,
    ) -> String {
        let grid = self.name.replace('"', "'");
        let metre = r#"UNIT["metre",1,AUTHORITY["EPSG","9001"]]"#;
        let fallback = format!(
            r#"VERT_CS["{grid} height",VERT_DATUM["{grid}",2005],{metre},AXIS["Gravity-related height",UP]]"#
        );
        let mut vertical = self
            .vertical_crs()
            .map_or(fallback, |(_, wkt)| wkt.to_string());
        if metres_per_unit != 1.0 {
            let unit = horizontal_wkt
                .rfind("UNIT[")
                .map(|at| balanced_node(&horizontal_wkt[at..]))
                .unwrap_or(metre);
            let unit_name = unit.split('"').nth(1).unwrap_or("");
            let suffix = match unit_name {
                "US survey foot" => " (ftUS)",
                "foot" => " (ft)",
                _ => "",
            };
            if let Some(end) = vertical[9..].find('"') {
                vertical.insert_str(9 + end, suffix);
            }
            vertical = vertical.replace(metre, unit);
            if let Some(at) = vertical.rfind(",AUTHORITY[") {
                if vertical[at..].matches('[').count() == 1 {
                    vertical.replace_range(at..vertical.len() - 1, "");
                }
            }
        }
        let vname = vertical.split('"').nth(1).unwrap_or("height").to_string();
        format!(r#"COMPD_CS["{horizontal_name} + {vname}",{horizontal_wkt},{vertical}]"#)
    }

    /// The grid's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Extent of the nodes (deg).
    pub fn extent(&self) -> GridExtent {
        GridExtent {
            south_deg: self.south_deg,
            north_deg: self.south_deg + self.dlat_deg * (self.rows - 1) as f64,
            west_deg: self.west_deg,
            east_deg: self.west_deg + self.dlon_deg * (self.cols - 1) as f64,
        }
    }

    /// Whether the grid has nodes around every point within `margin_m` (horizontal distance)
    /// of latitude and longitude (rad). Conservative: the margin is turned into degrees with
    /// the smallest radii of curvature (meridian `a (1 - e^2)`, parallel `a cos(lat)`).
    pub fn covers_around(&self, lat_rad: f64, lon_rad: f64, margin_m: f64) -> bool {
        let e = self.extent();
        let lat_deg = lat_rad.to_degrees();
        let dlat_deg = (margin_m / (WGS84_A * (1.0 - WGS84_E2))).to_degrees();
        if !(lat_deg - dlat_deg >= e.south_deg && lat_deg + dlat_deg <= e.north_deg) {
            return false;
        }
        if self.wraps() {
            return true;
        }
        let widest_lat_rad = (lat_deg.abs() + dlat_deg).min(90.0).to_radians();
        let dlon_deg = (margin_m / (WGS84_A * widest_lat_rad.cos())).to_degrees();
        let from_west_deg =
            (lon_rad.to_degrees() - dlon_deg - e.west_deg).rem_euclid(FULL_CIRCLE_DEG);
        from_west_deg + 2.0 * dlon_deg <= e.east_deg - e.west_deg
    }

    fn wraps(&self) -> bool {
        self.dlon_deg * self.cols as f64 >= FULL_CIRCLE_DEG - 1e-9
    }

    /// Geoid undulation N (m) at WGS84 latitude and longitude (rad), bilinear as PROJ; `None`
    /// outside the grid or next to a no-data node.
    pub fn undulation_m(&self, lat_rad: f64, lon_rad: f64) -> Option<f64> {
        let y = (lat_rad.to_degrees() - self.south_deg) / self.dlat_deg;
        let mut lon = lon_rad.to_degrees() - self.west_deg;
        lon = lon.rem_euclid(FULL_CIRCLE_DEG);
        let x = lon / self.dlon_deg;
        let (ix, fx) = self.cell(x, self.cols, self.wraps())?;
        let (iy, fy) = self.cell(y, self.rows, false)?;
        let ix1 = if ix + 1 == self.cols { 0 } else { ix + 1 };
        let nodes = [
            ((1.0 - fx) * (1.0 - fy), iy, ix),
            (fx * (1.0 - fy), iy, ix1),
            ((1.0 - fx) * fy, iy + 1, ix),
            (fx * fy, iy + 1, ix1),
        ];
        // A node of weight 0 (a point on a cell edge) does not matter, even with no data.
        let v: f64 = nodes
            .iter()
            .filter(|(w, _, _)| *w != 0.0)
            .map(|&(w, r, c)| w * self.n_m[r * self.cols + c] as f64)
            .sum();
        v.is_finite().then_some(v)
    }

    /// Lower node index and fraction of a fractional position `x` along `n` nodes; the last
    /// node belongs to the cell below it, a wrapping axis has `n` cells.
    fn cell(&self, x: f64, n: usize, wraps: bool) -> Option<(usize, f64)> {
        let cells = if wraps { n } else { n - 1 } as f64;
        if !(x >= -1e-9 && x <= cells + 1e-9) {
            return None;
        }
        let x = x.clamp(0.0, cells);
        let i = (x.floor() as usize).min(cells as usize - 1);
        Some((i, x - i as f64))
    }
}

/// The WKT node at the start of `wkt` (`NAME[...]`, brackets balanced), or all of `wkt`.
fn balanced_node(wkt: &str) -> &str {
    let mut depth = 0usize;
    for (i, ch) in wkt.char_indices() {
        match ch {
            '[' => depth += 1,
            ']' => {
                depth = depth.saturating_sub(1);
                if depth == 0 {
                    return &wkt[..=i];
                }
            }
            _ => {}
        }
    }
    wkt
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gtx(rows: i32, cols: i32, values: &[f32]) -> Vec<u8> {
        let mut b = Vec::new();
        for v in [10.0_f64, 20.0, 0.5, 0.25] {
            b.extend(v.to_be_bytes());
        }
        b.extend(rows.to_be_bytes());
        b.extend(cols.to_be_bytes());
        for v in values {
            b.extend(v.to_be_bytes());
        }
        b
    }

    #[test]
    fn bilinear_inside_none_outside() {
        let values = [1.0, 2.0, 3.0, 5.0, 7.0, GTX_NO_DATA];
        let g = GeoidGrid::from_gtx(Path::new("t.gtx"), &gtx(2, 3, &values)).unwrap();
        let n = |lat: f64, lon: f64| g.undulation_m(lat.to_radians(), lon.to_radians());
        assert_eq!(n(10.0, 20.0), Some(1.0));
        assert_eq!(n(10.5, 20.25), Some(7.0));
        // Centre of the first cell: mean of 1, 2, 5, 7.
        assert!((n(10.25, 20.125).unwrap() - 3.75).abs() < 1e-12);
        assert_eq!(n(10.25, 20.375), None, "no-data node");
        assert_eq!(n(9.99, 20.1), None);
        assert_eq!(n(10.1, 20.51), None);
        assert!(GeoidGrid::from_gtx(Path::new("t.gtx"), &gtx(2, 3, &values[..5])).is_err());
    }

    #[test]
    fn coverage_with_a_margin() {
        // Nodes over 10..10.5 N, 20..20.5 E.
        let g = GeoidGrid::from_gtx(Path::new("t.gtx"), &gtx(2, 3, &[0.0; 6])).unwrap();
        let covers =
            |lat: f64, lon: f64, m: f64| g.covers_around(lat.to_radians(), lon.to_radians(), m);
        assert!(covers(10.25, 20.25, 0.0));
        // 0.25 deg of latitude is 27.6 km; of longitude at 10.25 N about 27.4 km.
        assert!(covers(10.25, 20.25, 27_000.0));
        assert!(!covers(10.25, 20.25, 28_000.0));
        assert!(
            !covers(10.25, 20.49, 2_000.0),
            "east edge within the margin"
        );
        assert!(!covers(10.25, 20.51, 0.0));
        assert!(!covers(10.25, 19.25, 0.0));
    }
}
