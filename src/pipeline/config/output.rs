//! `[output]`: the map frame, the LAS file(s) and what they hold.

use super::refusal::{refuse, require_finite, Refusal};
use crate::geo::ellipsoid::Geodetic;
use crate::geo::projection::MapFrame;
use crate::io::config_file::ConfigPath;
use serde::{Deserialize, Serialize};
/// Output mapping frame: a table with a `kind` (`output.frame = { kind = "utm" }`). A bare
/// name (`frame = "utm"`) is refused with the table to write instead (serde's own message,
/// "expected internally tagged enum FrameConfig", says nothing a user can act on).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self")]
#[serde(rename_all = "snake_case", tag = "kind", deny_unknown_fields)]
pub enum FrameConfig {
    /// UTM with ellipsoidal height; zone from the trajectory's first record unless given.
    Utm {
        /// Zone 1-60 (automatic when absent).
        #[serde(default)]
        zone: Option<u8>,
        /// Northern hemisphere (automatic when absent).
        #[serde(default)]
        north: Option<bool>,
    },
    /// Earth-centred, Earth-fixed WGS84.
    Ecef,
    /// Local East-North-Up about an origin (degrees, metres).
    Enu {
        /// Origin latitude (deg).
        lat_deg: f64,
        /// Origin longitude (deg).
        lon_deg: f64,
        /// Origin ellipsoidal height (m).
        h_m: f64,
    },
    /// A projected CRS by EPSG code (WGS84 or a datum with a stated Helmert to it), with
    /// WGS84 ellipsoidal height; see `geo::epsg`.
    Epsg {
        /// EPSG code, e.g. 2154 (RGF93 v1 / Lambert-93).
        code: u32,
    },
}

impl Serialize for FrameConfig {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        FrameConfig::serialize(self, s)
    }
}

impl<'de> Deserialize<'de> for FrameConfig {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Table;
        impl<'de> serde::de::Visitor<'de> for Table {
            type Value = FrameConfig;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a table such as { kind = \"utm\" }")
            }
            fn visit_str<E: serde::de::Error>(self, name: &str) -> Result<FrameConfig, E> {
                Err(E::custom(frame_name_refusal(name)))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> Result<FrameConfig, A::Error> {
                FrameConfig::deserialize(serde::de::value::MapAccessDeserializer::new(map))
            }
        }
        d.deserialize_any(Table)
    }
}

/// The refusal of a bare frame name `frame = "<name>"`.
fn frame_name_refusal(name: &str) -> String {
    let kind = match name {
        "utm" | "ecef" | "enu" | "epsg" => name,
        _ => "utm",
    };
    let example = match kind {
        "enu" => "{ kind = \"enu\", lat_deg = 48.1, lon_deg = 11.5, h_m = 520.0 }".to_string(),
        "epsg" => "{ kind = \"epsg\", code = 25832 }".to_string(),
        _ => format!("{{ kind = \"{kind}\" }}"),
    };
    format!(
        "the frame is a table, not a name: write `frame = {example}` (kinds: utm with optional \
         zone and north, ecef, enu with lat_deg, lon_deg, h_m, epsg with code; docs/output.md)"
    )
}

impl FrameConfig {
    /// Origin of a local frame as geodetic radians.
    pub fn enu_origin(&self) -> Option<Geodetic> {
        match *self {
            FrameConfig::Enu {
                lat_deg,
                lon_deg,
                h_m,
            } => Some(Geodetic {
                lat_rad: lat_deg.to_radians(),
                lon_rad: lon_deg.to_radians(),
                h_m,
            }),
            _ => None,
        }
    }
}

/// How the output is split into files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SplitMode {
    /// One LAS file: `path`.
    None,
    /// One file per profile file: `<stem>_<profile file stem>.las`.
    PerInput,
    /// At most `max_points_per_file` points each: `<stem>_0001.las`, `<stem>_0002.las`, ...
    MaxPoints,
}

/// The point cloud file format.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OutputFormat {
    /// LAS 1.4 (conventions §7).
    #[default]
    Las,
    /// LAZ 1.4: the same LAS compressed with LASzip in parallel chunks (`io::laz`).
    Laz,
    /// COPC 1.0: the same points as a clustered octree of LAZ chunks (`io::copc`), in the file
    /// `<stem>.copc.laz`.
    Copc,
}

impl OutputFormat {
    /// The file extension of the format (`las`, `laz`, `copc.laz`).
    pub fn extension(self) -> &'static str {
        match self {
            OutputFormat::Las => "las",
            OutputFormat::Laz => "laz",
            OutputFormat::Copc => "copc.laz",
        }
    }
}

/// What happens to a return that cannot be georeferenced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Strictness {
    /// Count it as rejected with its reason and go on.
    Count,
    /// Stop with an error naming the file and record.
    Fail,
}

/// `[output]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputConfig {
    /// Output LAS path (the base name when split); with `format = "laz"` the files take the
    /// `.laz` extension instead.
    pub las: ConfigPath,
    /// File format: `las` (default), `laz` or `copc`.
    #[serde(default)]
    pub format: OutputFormat,
    /// Run report path (JSON); default: `<las stem>.report.json` beside the LAS.
    #[serde(default)]
    pub report: Option<ConfigPath>,
    /// Mapping frame.
    #[serde(default = "default_frame")]
    pub frame: FrameConfig,
    /// Geoid grid (GTX or GeoTIFF, as PROJ ships them) for orthometric heights `H = h - N`;
    /// absent: WGS84 ellipsoidal heights. Needs a frame with a height axis (`utm`, `epsg`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geoid: Option<ConfigPath>,
    /// Coordinate scale (m per integer step); the quantisation error is half of it.
    #[serde(default = "default_scale_m")]
    pub scale_m: f64,
    /// LAS coordinate offset X, Y, Z in the map frame (m); default: the map coordinates of the
    /// first trajectory record rounded to 1 km. Points must lie within `2^31 * scale_m` of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset_m: Option<[f64; 3]>,
    /// Accept a run that writes no point (default: such a run fails and keeps the old output).
    #[serde(default)]
    pub allow_empty: bool,
    /// Largest share (0..1) of the returns read that may be rejected for any reason but a
    /// missing return (no echo): above it the run fails, publishing nothing, and names the
    /// likely cause (a wrong clock, range limits...). Default 0.05.
    #[serde(default = "default_max_rejected_share")]
    pub max_rejected_share: f64,
    /// File splitting.
    #[serde(default = "default_split")]
    pub split: SplitMode,
    /// Maximum points per file with `split = "max_points"`.
    #[serde(default)]
    pub max_points_per_file: Option<u64>,
    /// Per-return problems: counted (`count`) or fatal (`fail`).
    #[serde(default = "default_strictness")]
    pub strictness: Strictness,
    /// Write the measured range (m) as an extra dimension `range`.
    #[serde(default = "super::yes")]
    pub range_dimension: bool,
    /// Write the recorded mirror angle (deg, wrapped to -180..180) as an extra dimension
    /// `mirror_angle`; the LAS scan angle is the nadir-referenced angle LAS 1.4 defines.
    #[serde(default = "super::yes")]
    pub mirror_angle_dimension: bool,
    /// Write each point's 0-based record index in its profile file as the extra dimension
    /// `return_index` (float64, exact to 2^53), to trace a point back to its raw return.
    #[serde(default)]
    pub return_index_dimension: bool,
}

fn default_max_rejected_share() -> f64 {
    0.05
}

impl OutputConfig {
    /// Checks the scale, offset, split and frame.
    pub(super) fn check(&self) -> Result<(), Refusal> {
        if !(self.scale_m > 0.0 && self.scale_m <= 1e-3) {
            let v = self.scale_m;
            let problem = format!("must be in (0, 0.001] m (quantisation <= 0.5 mm), got {v}");
            return Err(refuse("output.scale_m", problem));
        }
        if !(0.0..=1.0).contains(&self.max_rejected_share) {
            let v = self.max_rejected_share;
            let problem = format!("a share: must be in [0, 1] (0.05 is 5%), got {v}");
            return Err(refuse("output.max_rejected_share", problem));
        }
        if let Some(offset) = &self.offset_m {
            require_finite(super::refusal::elements("output.offset_m", offset))?;
        }
        if self.split == SplitMode::MaxPoints && self.max_points_per_file.is_none_or(|n| n == 0) {
            let problem = "split = \"max_points\" needs max_points_per_file > 0";
            return Err(refuse("output.max_points_per_file", problem));
        }
        if self.geoid.is_some() && matches!(self.frame, FrameConfig::Ecef | FrameConfig::Enu { .. })
        {
            let problem = "orthometric heights need a frame whose Z is a height above the \
                           ellipsoid: frame kind \"utm\" or \"epsg\" (ECEF Z and local Up are not)";
            return Err(refuse("output.geoid", problem));
        }
        if self.geoid.is_some() && self.frame == (FrameConfig::Epsg { code: 4979 }) {
            let problem = "EPSG:4979 states ellipsoidal heights: orthometric heights from a geoid \
                           contradict it; use code = 4326 (horizontal, the geoid's heights as its \
                           vertical CRS) or leave output.geoid out";
            return Err(refuse("output.geoid", problem));
        }
        self.frame.check()
    }
}

impl FrameConfig {
    /// Checks the zone, the local origin or the EPSG code.
    fn check(&self) -> Result<(), Refusal> {
        match *self {
            FrameConfig::Utm { zone: Some(z), .. } if !(1..=60).contains(&z) => Err(refuse(
                "output.frame.zone",
                format!("UTM zone must be 1..60, got {z}"),
            )),
            FrameConfig::Enu {
                lat_deg,
                lon_deg,
                h_m,
            } => {
                if !(-90.0..=90.0).contains(&lat_deg) {
                    let problem = format!("must be in [-90, 90] deg, got {lat_deg}");
                    return Err(refuse("output.frame.lat_deg", problem));
                }
                if !(-180.0..=180.0).contains(&lon_deg) {
                    let problem = format!("must be in [-180, 180] deg, got {lon_deg}");
                    return Err(refuse("output.frame.lon_deg", problem));
                }
                if !h_m.is_finite() {
                    return Err(refuse(
                        "output.frame.h_m",
                        format!("must be finite, got {h_m}"),
                    ));
                }
                Ok(())
            }
            FrameConfig::Epsg { code } => MapFrame::from_epsg(code)
                .map(drop)
                .map_err(|why| refuse("output.frame.code", why.to_string())),
            _ => Ok(()),
        }
    }
}

fn default_frame() -> FrameConfig {
    FrameConfig::Utm {
        zone: None,
        north: None,
    }
}
fn default_scale_m() -> f64 {
    1e-4
}
fn default_split() -> SplitMode {
    SplitMode::None
}
fn default_strictness() -> Strictness {
    Strictness::Count
}
