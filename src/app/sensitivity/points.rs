//! The points of a sensitivity study: flat ground, or returns of a simulated survey
//! georeferenced with the scenario's configured clock and sensor; and their input sigmas.

use super::config::{
    PlatformConfig, ScenarioPointsConfig, SensitivityConfig, SigmaSet, StudySensorConfig,
};
use crate::geo::ellipsoid::{ecef_to_geodetic, geodetic_to_ecef, r_enu_to_e, r_n_to_e, Geodetic};
use crate::geo::rotations::r_zyx;
use crate::io::profiles::ProfileFile;
use crate::sim::scanner::ScannerModel;
use crate::sim::{files, simulate, Scenario, SimOptions};
use crate::timing::{ReturnClock, TimeModel};
use crate::trajectory::{NavSigma, PoseCursor, Trajectory, TrajectoryOptions};
use crate::uncertainty::model::{Input, PointGeometry, N_INPUTS};
use crate::uncertainty::sobol::N_OUT;
use crate::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use std::path::Path;

/// The geometry of a flat-ground study point at range `rho` (m): `beta = acos(height / rho)`.
pub fn flat_ground_point(
    p: &PlatformConfig,
    sensor: &StudySensorConfig,
    scanner_height_m: f64,
    rho: f64,
) -> PointGeometry {
    let g = Geodetic {
        lat_rad: p.lat_deg.to_radians(),
        lon_rad: p.lon_deg.to_radians(),
        h_m: p.h_m,
    };
    let [r, pitch, h] = p.rph_deg.map(f64::to_radians);
    let [bx, by, bz] = sensor.boresight_deg.map(f64::to_radians);
    let (sh, ch) = h.sin_cos();
    PointGeometry {
        r_e_m: geodetic_to_ecef(g),
        lat_rad: g.lat_rad,
        lon_rad: g.lon_rad,
        h_m: g.h_m,
        r_b_to_n: r_zyx(r, pitch, h),
        v_n_mps: Vector3::new(ch, sh, 0.0) * p.speed_mps,
        omega_b_radps: Vector3::from(p.body_rate_deg_s.map(f64::to_radians)),
        lever_arm_b_m: sensor.lever_arm_b_m.into(),
        r_s_to_b: r_zyx(bx, by, bz),
        alpha_rad: sensor.alpha0_deg.to_radians(),
        beta_rad: (scanner_height_m / rho).min(1.0).acos(),
        range_m: rho,
        range_zero_m: 0.0,
    }
}

/// The returns of a simulated survey studied for `[scenario]`: the scenario is simulated into
/// a temporary directory, the returns are binned by range, and each chosen return gets the
/// pipeline's geometry: its time from the configured clock (conventions §2), the pose of the
/// navigation solution (`trajectory.sbet`) at that time, the configured sensor, and the
/// SMRMSG sigmas at that time.
pub fn scenario_points(s: &ScenarioPointsConfig) -> Result<Vec<(PointGeometry, NavSigma)>> {
    let dir = tempfile::tempdir().map_err(|e| Error::io(Path::new("(temporary directory)"), e))?;
    let opts = SimOptions {
        duration_s: s.duration_s,
        ..SimOptions::default()
    };
    simulate(&s.file, dir.path(), &opts)?;
    let model = ScannerModel::new(&Scenario::load(&s.file)?);
    let traj = Trajectory::open(
        &dir.path().join(files::SBET),
        Some(&dir.path().join(files::SMRMSG)),
        TrajectoryOptions::default(),
    )?;
    let profiles = ProfileFile::open(&dir.path().join(files::PROFILES))?;
    let chosen = pick_by_range(&profiles, s.range_m, s.count);
    let mut poses = PoseCursor::new(&traj, 0.0, 0.0);
    let mut nav_sigmas = traj
        .sigma_cursor()
        .ok_or_else(|| Error::Invalid("the simulated survey has no SMRMSG".into()))?;
    let gap = |t: f64| Error::Invalid(format!("simulated return at {t} s has no pose or sigma"));
    // The simulator's optional time tags are PPS profile starts (docs/simulator.md).
    let clock = ReturnClock {
        model: if profiles.columns().time {
            TimeModel::HardwareProfile
        } else {
            TimeModel::Software
        },
        clock: model.clock,
    };
    let mut out = Vec::with_capacity(chosen.len());
    for i in chosen {
        let r = profiles.get(i);
        let t = clock.time_of(&r);
        let pose = poses.at(t).map_err(|_| gap(t))?;
        let nav = nav_sigmas.at(t).map_err(|_| gap(t))?;
        let alpha = model.configured.alpha0_rad;
        let geom = PointGeometry::from_pose(&pose, &model.configured, alpha, r.beta_rad, r.range_m);
        out.push((geom, nav));
    }
    if out.is_empty() {
        return Err(Error::Invalid(format!(
            "{}: no simulated return between {} and {} m",
            s.file.display(),
            s.range_m[0],
            s.range_m[1]
        )));
    }
    Ok(out)
}

/// Indices (in file order) of the returns closest to the centres of `count` equal range bins
/// over `range_m`, one per non-empty bin.
fn pick_by_range(profiles: &ProfileFile, range_m: [f64; 2], count: usize) -> Vec<usize> {
    let width = (range_m[1] - range_m[0]) / count as f64;
    let mut best: Vec<Option<(f64, usize)>> = vec![None; count];
    for i in 0..profiles.len() {
        let rho = profiles.get(i).range_m;
        let bin = ((rho - range_m[0]) / width).floor();
        if !(rho > 0.0 && bin >= 0.0 && bin < count as f64) {
            continue;
        }
        let b = bin as usize;
        let off = (rho - range_m[0] - (b as f64 + 0.5) * width).abs();
        if best[b].is_none_or(|(o, _)| off < o) {
            best[b] = Some((off, i));
        }
    }
    let mut idx: Vec<usize> = best.into_iter().flatten().map(|(_, i)| i).collect();
    idx.sort_unstable();
    idx
}

/// The 1-sigma of every input for the study (model order): the sigma set, the INS sigmas of
/// `[ins]` if given, else `nav` (SMRMSG at the return), and `[timing]`.
pub fn study_sigmas(c: &SensitivityConfig, nav: Option<&NavSigma>) -> Result<[f64; N_INPUTS]> {
    let inputs = c
        .sigma_set
        .inputs(c.custom.as_ref())
        .ok_or_else(|| Error::Invalid("sigma_set = \"custom\" needs [custom]".into()))?;
    let nav = match (&c.ins, nav) {
        (Some(ins), _) => NavSigma {
            pos_ned_m: ins.sigma_position_ned_m.into(),
            att_rph_rad: ins.sigma_attitude_rph_deg.map(f64::to_radians).into(),
        },
        (None, Some(nav)) => *nav,
        (None, None) => return Err(Error::Invalid("no INS sigmas: [ins] is missing".into())),
    };
    let mut s = inputs.sigmas(&nav, [0.0, 0.0]);
    if c.sigma_set != SigmaSet::Custom {
        s[Input::Latency as usize] = c.timing.sigma_attitude_latency_s;
    }
    s[Input::ClockTime as usize] = s[Input::ClockTime as usize].hypot(c.timing.sigma_clock_time_s);
    Ok(s)
}

/// The study's points: flat ground, or the chosen returns of `[scenario]` with their SMRMSG
/// sigmas.
pub(super) fn study_geometries(
    c: &SensitivityConfig,
) -> Result<Vec<(PointGeometry, Option<NavSigma>)>> {
    if let Some(sc) = &c.scenario {
        let pts = scenario_points(sc)?;
        return Ok(pts.into_iter().map(|(g, n)| (g, Some(n))).collect());
    }
    let (Some(platform), Some(sensor), Some(p)) = (&c.platform, &c.sensor, &c.points) else {
        return Err(Error::Invalid("no points: [points] is missing".into()));
    };
    let rho = |k: usize| {
        let w = if p.count > 1 {
            k as f64 / (p.count - 1) as f64
        } else {
            0.0
        };
        p.range_m[0] + w * (p.range_m[1] - p.range_m[0])
    };
    Ok((0..p.count)
        .map(|k| {
            let g = flat_ground_point(platform, sensor, p.scanner_height_m, rho(k));
            (g, None)
        })
        .collect())
}

/// `R_e^enu` at the nominal point of `geom`.
pub fn r_e_to_enu_at_point(geom: &PointGeometry) -> Matrix3<f64> {
    let g = ecef_to_geodetic(&geom.point_e(&[0.0; N_INPUTS]));
    r_enu_to_e(g.lat_rad, g.lon_rad).transpose()
}

/// The exact model as a Sobol model: input errors to the E, N, U displacement (m).
pub fn enu_error_model(geom: &PointGeometry) -> impl Fn(&[f64]) -> [f64; N_OUT] + Sync + '_ {
    let nominal = geom.point_e(&[0.0; N_INPUTS]);
    let rot = r_e_to_enu_at_point(geom);
    move |e: &[f64]| {
        let e: [f64; N_INPUTS] = e.try_into().expect("model input length");
        let d = rot * (geom.point_e(&e) - nominal);
        [d.x, d.y, d.z]
    }
}

/// Elevation of the beam of `geom` above the local horizontal at the scanner (rad).
pub(super) fn beam_elevation_rad(geom: &PointGeometry) -> f64 {
    let x = geom.point_e(&[0.0; N_INPUTS]);
    let r_b_e = r_n_to_e(geom.lat_rad, geom.lon_rad) * geom.r_b_to_n;
    let scanner = geom.r_e_m + r_b_e * geom.lever_arm_b_m;
    let d = r_e_to_enu_at_point(geom) * (x - scanner);
    d.z.atan2(d.xy().norm())
}
