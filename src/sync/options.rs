//! What [`super::estimate`] is given: the sync targets and the settings.

use crate::geo::ellipsoid::{geodetic_to_ecef, r_enu_to_e, Geodetic};
use crate::io::patches::PlanarPatch;
use crate::io::points::ControlPoint;
use crate::timing::Mirror;
use crate::{Error, Result};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Which estimate the result carries as its answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// One observation per sighting (the paper's method).
    Paper,
    /// Every return on the targets' surveyed planes.
    Refined,
    /// The refined estimator where it constrains the clock better than the paper method (its
    /// sigma t0 below the paper's), else the paper method; the answer's method and, on a
    /// fall-back, the refined estimator's reason are in the result.
    Auto,
}

/// A surveyed sync target: its centre (sync point) and, for the refined estimator, the unit
/// normal of its flat face.
#[derive(Debug, Clone, PartialEq)]
pub struct SyncTarget {
    /// Identifier (from the control-point file).
    pub id: String,
    /// Centre (ECEF, m).
    pub centre_e_m: Vector3<f64>,
    /// 1-sigma position uncertainty of the centre (m).
    pub sigma_m: f64,
    /// Unit normal of the face (ECEF), when surveyed.
    pub normal_e: Option<Vector3<f64>>,
    /// Half length (horizontal, in the face) and half height of the face (m), when surveyed:
    /// returns within `EDGE_MARGIN_M` of its boundary are not used by the refined estimator.
    pub half_size_m: Option<[f64; 2]>,
}

impl SyncTarget {
    /// Targets from control points, with face normals from the patches of the same id.
    pub fn from_surveys(points: &[ControlPoint], patches: &[PlanarPatch]) -> Vec<SyncTarget> {
        points
            .iter()
            .map(|p| {
                let patch = patches.iter().find(|q| q.id == p.id);
                let normal_e = patch.map(|q| {
                    let n = Vector3::from(q.normal_enu);
                    (r_enu_to_e(q.lat_rad, q.lon_rad) * n).normalize()
                });
                SyncTarget {
                    id: p.id.clone(),
                    centre_e_m: geodetic_to_ecef(Geodetic {
                        lat_rad: p.lat_rad,
                        lon_rad: p.lon_rad,
                        h_m: p.h_m,
                    }),
                    sigma_m: p.sigma_m,
                    normal_e,
                    half_size_m: patch.map(|q| [q.half_length_m, q.half_height_m]),
                }
            })
            .collect()
    }
}

/// Settings of [`super::estimate`].
#[derive(Debug, Clone, PartialEq)]
pub struct SyncOptions {
    /// Approximate t0 (s): where detection looks.
    pub t0_approx_s: f64,
    /// Approximate (nominal) mirror period (s).
    pub period_approx_s: f64,
    /// Mirror geometry.
    pub mirror: Mirror,
    /// Detection looks this far (s) either side of the predicted sighting.
    pub window_s: f64,
    /// Returns at or above this intensity can belong to a target.
    pub min_intensity: u16,
    /// Targets further than this from the scanner are not looked for (m).
    pub max_range_m: f64,
    /// Largest gap between returns of one target across the profile (m).
    pub cluster_gap_m: f64,
    /// Which estimate is the answer.
    pub method: Method,
    /// Estimate the attitude latency jointly (refined method only).
    pub estimate_latency: bool,
    /// Attitude latency assumed when not estimated (s).
    pub attitude_latency_s: f64,
    /// Range noise, 1 sigma (m).
    pub sigma_range_m: f64,
    /// Mirror and cone angle noise, 1 sigma (rad).
    pub sigma_angle_rad: f64,
    /// Sightings must span at least this long (s), or T is not constrained.
    pub min_span_s: f64,
    /// Normalised residual above which a sighting is an outlier.
    pub outlier_sigma: f64,
    /// The latency is reported only with a sigma below this (s).
    pub max_latency_sigma_s: f64,
}

impl SyncOptions {
    /// Defaults for everything but the approximate clock and mirror.
    pub fn new(t0_approx_s: f64, period_approx_s: f64, mirror: Mirror) -> Self {
        SyncOptions {
            t0_approx_s,
            period_approx_s,
            mirror,
            window_s: 1.0,
            min_intensity: 60000,
            max_range_m: 30.0,
            cluster_gap_m: 0.3,
            method: Method::Refined,
            estimate_latency: false,
            attitude_latency_s: 0.0,
            sigma_range_m: 0.005,
            sigma_angle_rad: 0.002f64.to_radians(),
            min_span_s: 30.0,
            outlier_sigma: 5.0,
            max_latency_sigma_s: 0.002,
        }
    }
}

pub(super) fn check_options(o: &SyncOptions) -> Result<()> {
    let bad = |k: &str, m: String| Err(Error::config("sync options", k, m));
    if !(o.period_approx_s > 0.0 && o.period_approx_s <= 1.0) {
        return bad(
            "period_approx_s",
            format!("must be in (0, 1] s, got {}", o.period_approx_s),
        );
    }
    if !o.t0_approx_s.is_finite() {
        return bad("t0_approx_s", "must be finite".into());
    }
    if !(o.window_s > 0.0 && o.window_s.is_finite()) {
        return bad("window_s", format!("must be > 0, got {}", o.window_s));
    }
    if o.estimate_latency && o.method == Method::Paper {
        return bad(
            "estimate_latency",
            "the latency is estimated by the refined method only".into(),
        );
    }
    Ok(())
}
