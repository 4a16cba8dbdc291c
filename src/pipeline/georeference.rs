//! Stage 4, **georeference** (+ uncertainty): one raw return to a map point, per return.
//!
//! [`ReturnGeoreferencer`] is the reusable per-return API (the pipeline's executor and the
//! diagnosis use it): built from the resolved configuration of one input (sensor, resolved
//! clock with its latencies, output frame, optional `[uncertainty]`), it takes a
//! [`RawReturn`] and per-thread [`ReturnCursors`] and gives a [`GeoreferencedReturn`]: the
//! return's time `t` (and its partials with respect to the clock), the pose (position at `t`,
//! attitude at `t + tau`), the conventions §4 terms, the ECEF point and the map point; and, with
//! `[uncertainty]`, the propagation's inputs ([`ReturnGeoreferencer::variance_inputs`]) or the full
//! geometry for partials ([`ReturnGeoreferencer::geometry`]). A return that cannot be
//! georeferenced gives its [`RejectReason`].
//!
//! The pieces, in the order they are applied: [`ReturnFilter`] (finite values, missing
//! return, range limits), the time model ([`crate::timing::ReturnClock`]), the pose lookup
//! ([`crate::trajectory::PoseCursor`] with the latencies), the equation
//! ([`crate::georef::ReturnTerms`]), the map projection ([`MapProjector`]).

use super::config::{SensorConfig, UncertaintyConfig};
use super::report::RejectReason;
use super::sync::ResolvedClock;
use crate::geo::geoid::GeoidGrid;
use crate::geo::local::{LocalLatLon, LocalProjection};
use crate::geo::projection::MapFrame;
use crate::georef::{ReturnTerms, Sensor};
use crate::io::profiles::{ProfileColumns, RawReturn};
use crate::trajectory::{NavGap, NavSigma, Pose, PoseCursor, SigmaCursor, Trajectory};
use crate::uncertainty::model::FrameCache;
use crate::uncertainty::propagate::{Propagator, ReturnInputs};
use crate::uncertainty::PointGeometry;
use nalgebra::Vector3;

impl From<NavGap> for RejectReason {
    fn from(g: NavGap) -> Self {
        match g {
            NavGap::OutsideTrajectory => RejectReason::OutsideTrajectory,
            NavGap::TrajectoryGap => RejectReason::TrajectoryGap,
            NavGap::OutsideAccuracy => RejectReason::OutsideAccuracy,
        }
    }
}

/// The per-return checks before georeferencing: finite values, missing return, range limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReturnFilter {
    /// The file has per-return alpha (else `alpha0_rad` is used).
    alpha_column: bool,
    /// The file has time tags (checked for finiteness).
    time_column: bool,
    /// Out-of-plane angle without an alpha column (rad).
    alpha0_rad: f64,
    /// Its `(sin, cos)`, computed once.
    alpha0_sin_cos: (f64, f64),
    /// Shortest accepted range (m).
    min_range_m: f64,
    /// Longest accepted range (m).
    max_range_m: f64,
}

impl ReturnFilter {
    /// The filter for a file with `columns` and the `[sensor]` limits.
    pub fn new(s: &SensorConfig, columns: ProfileColumns) -> Self {
        ReturnFilter {
            alpha_column: columns.alpha,
            time_column: columns.time,
            alpha0_rad: s.alpha0_deg.to_radians(),
            alpha0_sin_cos: s.alpha0_deg.to_radians().sin_cos(),
            min_range_m: s.min_range_m,
            max_range_m: s.max_range_m,
        }
    }

    /// The return's alpha (rad) if it may be georeferenced, else why not.
    #[inline]
    pub fn check(&self, r: &RawReturn) -> Result<f64, RejectReason> {
        let alpha = if self.alpha_column {
            r.alpha_rad
        } else {
            self.alpha0_rad
        };
        let finite = r.beta_rad.is_finite() && r.range_m.is_finite() && alpha.is_finite();
        if !finite || (self.time_column && !r.time_s.is_finite()) {
            return Err(RejectReason::NonFinite);
        }
        if r.range_m == 0.0 {
            return Err(RejectReason::MissingReturn);
        }
        if !(self.min_range_m..=self.max_range_m).contains(&r.range_m) {
            return Err(RejectReason::RangeOutOfLimits);
        }
        Ok(alpha)
    }

    /// `(sin, cos)` of a return's alpha given by [`Self::check`].
    #[inline]
    pub fn sin_cos_alpha(&self, alpha_rad: f64) -> (f64, f64) {
        if self.alpha_column {
            alpha_rad.sin_cos()
        } else {
            self.alpha0_sin_cos
        }
    }
}

/// Distance (m) the vehicle may move from the local projection's centre before re-expanding;
/// points further than `EXPANSION_RADIUS_M - RECENTRE_M` from the vehicle may fall back to the
/// exact projection.
const RECENTRE_M: f64 = 100.0;

/// The map projection expanded about the vehicle ([`LocalProjection`]), re-expanded when the
/// vehicle has moved [`RECENTRE_M`] from the expansion centre; with a geoid grid, Z becomes the
/// orthometric height `h - N`, `N` interpolated at the point's latitude and longitude (expanded
/// about the same centre: [`LocalLatLon`]). One per thread.
#[derive(Debug, Clone)]
pub struct MapProjector<'a> {
    frame: MapFrame,
    geoid: Option<&'a GeoidGrid>,
    local: Option<(LocalProjection, LocalLatLon)>,
}

impl<'a> MapProjector<'a> {
    /// A projector to `frame` (heights above `geoid` when given), expanded at the first use.
    pub fn new(frame: MapFrame, geoid: Option<&'a GeoidGrid>) -> Self {
        MapProjector {
            frame,
            geoid,
            local: None,
        }
    }

    /// Map coordinates (m) of ECEF `x_e_m` seen from the vehicle at ECEF `vehicle_e_m`; a
    /// point where the geoid grid has no value (a no-data node) is rejected.
    #[inline]
    pub fn to_map(
        &mut self,
        vehicle_e_m: &Vector3<f64>,
        x_e_m: &Vector3<f64>,
    ) -> Result<Vector3<f64>, RejectReason> {
        let stale = self.local.as_ref().is_none_or(|(l, _)| {
            (l.centre_e() - vehicle_e_m).norm_squared() > RECENTRE_M * RECENTRE_M
        });
        if stale {
            let projection = LocalProjection::new(self.frame, *vehicle_e_m);
            self.local = Some((projection, LocalLatLon::new(*vehicle_e_m)));
        }
        let (projection, lat_lon) = self.local.as_ref().expect("set above");
        let mut x_map_m = projection.ecef_to_map(x_e_m);
        if let Some(grid) = self.geoid {
            let (lat_rad, lon_rad) = lat_lon.lat_lon_rad(x_e_m);
            x_map_m.z -= grid
                .undulation_m(lat_rad, lon_rad)
                .ok_or(RejectReason::NoGeoidValue)?;
        }
        Ok(x_map_m)
    }
}

/// Per-thread state of a [`ReturnGeoreferencer`]: interpolation cursors and projection caches
/// (returns given in time order are fastest).
pub struct ReturnCursors<'a> {
    poses: PoseCursor<'a>,
    projector: MapProjector<'a>,
    /// SMRMSG sigmas and the uncertainty's frame cache (with `[uncertainty]`).
    sigmas: Option<(SigmaCursor<'a>, FrameCache)>,
}

/// One return georeferenced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeoreferencedReturn {
    /// GPS time of the return (s).
    pub t_s: f64,
    /// Partials of `t_s` with respect to the clock parameters (t0, T).
    pub dt_dclock: [f64; 2],
    /// Out-of-plane angle alpha used (rad).
    pub alpha_rad: f64,
    /// Position at `t` (+ position latency), attitude at `t + tau`.
    pub pose: Pose,
    /// SMRMSG sigmas at `t` (with `[uncertainty]`).
    pub nav_sigma: Option<NavSigma>,
    /// The conventions §4 terms (rotations, beam, lever arm).
    pub terms: ReturnTerms,
    /// ECEF point (m).
    pub x_e_m: Vector3<f64>,
    /// Map point (m) in the output frame; Z orthometric with a geoid grid.
    pub x_map_m: Vector3<f64>,
    /// LAS 1.4 scan angle (rad): from nadir, positive to the right looking forward
    /// ([`ReturnTerms::scan_angle_rad`]).
    pub scan_angle_rad: f64,
}

/// Georeferences the returns of one input (module docs).
#[derive(Debug, Clone)]
pub struct ReturnGeoreferencer<'a> {
    traj: &'a Trajectory,
    filter: ReturnFilter,
    clock: ResolvedClock,
    sensor: Sensor,
    frame: MapFrame,
    geoid: Option<&'a GeoidGrid>,
    propagator: Option<Propagator>,
}

impl<'a> ReturnGeoreferencer<'a> {
    /// For a profile file with `columns`, the `[sensor]` table, the input's resolved clock,
    /// the output frame and the optional `[uncertainty]` table (its timing sigmas are taken
    /// from `clock`).
    pub fn new(
        traj: &'a Trajectory,
        sensor: &SensorConfig,
        columns: ProfileColumns,
        clock: ResolvedClock,
        frame: MapFrame,
        uncertainty: Option<&UncertaintyConfig>,
    ) -> Self {
        let filter = ReturnFilter::new(sensor, columns);
        let sensor = sensor.sensor();
        let propagator = uncertainty.map(|u| {
            let mut inputs = u.inputs();
            inputs.clock_covariance_s2 = clock.clock_covariance_s2;
            inputs.sigma_attitude_latency_s = clock.sigma_attitude_latency_s;
            Propagator::new(
                inputs,
                u.write_shares,
                sensor.lever_arm_b_m,
                sensor.r_s_to_b,
            )
        });
        ReturnGeoreferencer {
            traj,
            filter,
            clock,
            sensor,
            frame,
            geoid: None,
            propagator,
        }
    }

    /// Heights above the geoid of `grid` (`H = h - N`) instead of the ellipsoid.
    pub fn with_geoid(mut self, grid: Option<&'a GeoidGrid>) -> Self {
        self.geoid = grid;
        self
    }

    /// Fresh cursors (one per thread or chunk of returns).
    pub fn cursors(&self) -> ReturnCursors<'a> {
        let c = &self.clock;
        ReturnCursors {
            poses: PoseCursor::new(self.traj, c.attitude_latency_s, c.position_latency_s),
            projector: MapProjector::new(self.frame, self.geoid),
            sigmas: self
                .propagator
                .as_ref()
                .and_then(|_| self.traj.sigma_cursor())
                .map(|c| (c, FrameCache::new(self.frame))),
        }
    }

    /// The sensor used.
    pub fn sensor(&self) -> &Sensor {
        &self.sensor
    }

    /// The resolved clock used.
    pub fn clock(&self) -> &ResolvedClock {
        &self.clock
    }

    /// Georeferences `r`, or says why it cannot be.
    #[inline]
    pub fn georeference(
        &self,
        r: &RawReturn,
        cursors: &mut ReturnCursors,
    ) -> Result<GeoreferencedReturn, RejectReason> {
        let alpha_rad = self.filter.check(r)?;
        let (t_s, dt_dclock) = self.clock.clock.time_and_partials(r);
        let pose = cursors.poses.at(t_s)?;
        let nav_sigma = match cursors.sigmas.as_mut() {
            Some((sigmas, _)) => Some(sigmas.at(t_s)?),
            None => None,
        };
        let sin_cos_alpha = self.filter.sin_cos_alpha(alpha_rad);
        let terms = ReturnTerms::of_pose(&pose, &self.sensor, r.range_m, sin_cos_alpha, r.beta_rad);
        let x_e_m = terms.point_e(&pose.nav.r_e_m);
        let x_map_m = cursors.projector.to_map(&pose.nav.r_e_m, &x_e_m)?;
        Ok(GeoreferencedReturn {
            t_s,
            dt_dclock,
            alpha_rad,
            pose,
            nav_sigma,
            terms,
            x_e_m,
            x_map_m,
            scan_angle_rad: terms.scan_angle_rad(&self.sensor.lever_arm_b_m),
        })
    }

    /// The propagator of `[uncertainty]`, if configured.
    pub fn propagator(&self) -> Option<&Propagator> {
        self.propagator.as_ref()
    }

    /// What the propagation of a georeferenced return reads (with `[uncertainty]`): its
    /// variances are [`Propagator::variances_of`] these, or a
    /// [`crate::uncertainty::batch::VarianceBatch`]'s.
    #[inline]
    pub fn variance_inputs(
        &self,
        g: &GeoreferencedReturn,
        cursors: &mut ReturnCursors,
    ) -> Option<ReturnInputs> {
        let ((_, frames), nav_sigma) = (cursors.sigmas.as_mut()?, g.nav_sigma.as_ref()?);
        self.propagator.as_ref()?;
        // Reuses the georeferencing terms; the map axes and the local-level turn come from
        // the cache.
        let (r_n_to_map, dtheta) = frames.frames(&g.x_e_m, &g.pose.nav);
        Some(ReturnInputs::new(
            r_n_to_map,
            dtheta,
            &g.terms,
            &g.pose.omega_b_radps,
            &g.pose.nav.v_n_mps,
            nav_sigma,
            g.dt_dclock,
        ))
    }

    /// The full geometry of a georeferenced return, for the uncertainty model's partials
    /// ([`PointGeometry::jacobian_e`] and friends).
    pub fn geometry(&self, r: &RawReturn, g: &GeoreferencedReturn) -> PointGeometry {
        PointGeometry::from_pose(&g.pose, &self.sensor, g.alpha_rad, r.beta_rad, r.range_m)
    }
}
