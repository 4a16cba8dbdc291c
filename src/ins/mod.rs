//! The loosely coupled INS/GNSS Kalman filter and Rauch-Tung-Striebel smoother (paper 004
//! §2.2; docs/trajectory.md): raw IMU records and GNSS fixes in, the smoothed trajectory as
//! SBET + SMRMSG at the IMU rate out, with a run report and the smoothed errors'
//! autocorrelation per component (the error model `diagnose` can use).
//!
//! Modules: `earth` (gravity, rates), `mechanisation` (strapdown in NED and its inverse, which
//! the simulator uses), `imu_model` (IMU grades), `filter` (21-state error-state filter),
//! `smoother` (forward pass storage, RTS, autocorrelation), `align` (initial alignment),
//! `config` (the TOML file). It sits at the navigation layer: it uses `geo` and `io` only.

pub mod align;
pub mod config;
pub mod earth;
pub mod filter;
pub mod imu_model;
pub mod mechanisation;
pub mod smoother;

use crate::io::gnss::{GnssFile, GnssRecord};
use crate::io::imu::ImuFile;
use crate::io::sbet::{SbetRecord, SbetWriter};
use crate::io::smrmsg::{SmrmsgRecord, SmrmsgWriter, RAD_PER_ARCMIN};
use crate::{Error, Result};
use config::TrajectoryConfig;
use nalgebra::Vector3;
use serde::Serialize;
use smoother::{AutoCorrelation, Estimate, FilterStats, COMPONENTS};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A GNSS gap (outage) longer than three fix intervals.
#[derive(Debug, Clone, Serialize)]
pub struct GnssGap {
    /// Last fix before the gap (s).
    pub from_s: f64,
    /// First fix after it (s).
    pub to_s: f64,
    /// Largest smoothed horizontal position sigma inside it (m).
    pub max_horizontal_sigma_m: f64,
}

/// What `kinescan trajectory` did.
#[derive(Debug, Clone, Serialize)]
pub struct TrajectoryReport {
    /// Configuration file (with --set when overridden).
    pub config: String,
    /// The alignment.
    pub alignment: align::AlignmentReport,
    /// Forward-pass counts (GNSS used and rejected by the innovation test).
    pub filter: FilterStats,
    /// GNSS gaps longer than three fix intervals, with the smoothed sigma inside.
    pub gnss_gaps: Vec<GnssGap>,
    /// SBET/SMRMSG records written.
    pub records: u64,
    /// Span of the solution (s).
    pub span_s: f64,
    /// Wall-clock time (s) and span / wall-clock time.
    pub elapsed_s: f64,
    /// Span over wall-clock time.
    pub realtime_factor: f64,
    /// Bytes of the stored forward pass held in memory (0: spilled to a temporary file).
    pub stored_bytes: usize,
    /// Bytes of the stored forward pass written to a temporary file beside the SBET (removed
    /// at the end; the smoother's epochs add 0.9 times as much).
    pub spilled_bytes: usize,
    /// Files written.
    pub outputs: Vec<PathBuf>,
}

/// The error-model file: the smoothed errors' autocorrelation per component.
#[derive(Debug, Clone, Serialize)]
pub struct ErrorModel {
    /// Component names, in the order of the arrays.
    pub components: Vec<&'static str>,
    /// The autocorrelation.
    #[serde(flatten)]
    pub autocorrelation: AutoCorrelation,
}

/// Where `kinescan trajectory` writes its run report by default: `<sbet stem>.report.json`
/// beside the SBET (the morning report of `kinescan day` looks there for the GNSS gaps).
pub fn report_path(sbet: &Path) -> PathBuf {
    default_beside(sbet, ".report.json")
}

fn default_beside(sbet: &Path, suffix: &str) -> PathBuf {
    let stem = sbet
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    sbet.with_file_name(format!("{stem}{suffix}"))
}

/// SBET record of an estimate (wander angle 0: x/y velocity north/east).
pub fn sbet_record(e: &Estimate) -> SbetRecord {
    let (roll, pitch, heading) = mechanisation::euler(&e.nav);
    SbetRecord {
        time_s: e.nav.time_s,
        lat_rad: e.nav.lat_rad,
        lon_rad: e.nav.lon_rad,
        alt_m: e.nav.h_m,
        vel_x_mps: e.nav.v_n.x,
        vel_y_mps: e.nav.v_n.y,
        vel_z_mps: e.nav.v_n.z,
        roll_rad: roll,
        pitch_rad: pitch,
        platform_heading_rad: heading,
        wander_rad: 0.0,
        acc_x_mps2: e.f_b.x,
        acc_y_mps2: e.f_b.y,
        acc_z_mps2: e.f_b.z,
        rate_x_radps: e.w_b.x,
        rate_y_radps: e.w_b.y,
        rate_z_radps: e.w_b.z,
    }
}

/// Position (m, NED) and attitude (rad, NED `phi`) error of an estimate against the truth,
/// estimate minus truth, and its covariance: what the NEES tests use.
pub fn error6(
    e: &Estimate,
    truth: &mechanisation::NavState,
) -> (nalgebra::Vector6<f64>, nalgebra::Matrix6<f64>) {
    let dp = truth.ned_to(e.nav.lat_rad, e.nav.lon_rad, e.nav.h_m);
    // R_est = R(-phi) R_true.
    let phi = -(e.nav.q_b_n * truth.q_b_n.inverse()).scaled_axis();
    let mut x = nalgebra::Vector6::zeros();
    x.fixed_rows_mut::<3>(0).copy_from(&dp);
    x.fixed_rows_mut::<3>(3).copy_from(&phi);
    let idx = [0, 1, 2, 6, 7, 8];
    let c = nalgebra::Matrix6::from_fn(|i, j| e.cov[(idx[i], idx[j])]);
    (x, c)
}

/// Roll, pitch, heading sigmas (rad) of an estimate.
pub fn euler_sigmas(e: &Estimate) -> Vector3<f64> {
    let j = smoother::euler_jacobian(&e.nav);
    let c = j * e.cov.fixed_view::<3, 3>(6, 6) * j.transpose();
    Vector3::new(c[(0, 0)], c[(1, 1)], c[(2, 2)]).map(|v| v.max(0.0).sqrt())
}

/// SMRMSG record of an estimate.
pub fn smrmsg_record(e: &Estimate) -> SmrmsgRecord {
    let s = |i: usize| e.cov[(i, i)].max(0.0).sqrt();
    let a = euler_sigmas(e) / RAD_PER_ARCMIN;
    SmrmsgRecord {
        time_s: e.nav.time_s,
        north_m: s(0),
        east_m: s(1),
        down_m: s(2),
        vel_north_mps: s(3),
        vel_east_mps: s(4),
        vel_down_mps: s(5),
        roll_arcmin: a.x,
        pitch_arcmin: a.y,
        heading_arcmin: a.z,
    }
}

fn gaps(gnss: &[GnssRecord], t0: f64, t1: f64) -> Vec<GnssGap> {
    let mut dts: Vec<f64> = gnss.windows(2).map(|w| w[1].time_s - w[0].time_s).collect();
    if dts.is_empty() {
        return Vec::new();
    }
    dts.sort_by(f64::total_cmp);
    let nominal = dts[dts.len() / 2];
    gnss.windows(2)
        .filter(|w| {
            w[1].time_s - w[0].time_s > 3.0 * nominal && w[1].time_s > t0 && w[0].time_s < t1
        })
        .map(|w| GnssGap {
            from_s: w[0].time_s,
            to_s: w[1].time_s,
            max_horizontal_sigma_m: 0.0,
        })
        .collect()
}

/// Runs `kinescan trajectory CONFIG`: alignment, filter, smoother; writes the SBET, SMRMSG,
/// report and error model.
pub fn run(config_path: &Path, overrides: &[String]) -> Result<TrajectoryReport> {
    let started = Instant::now();
    let (cfg, source) = TrajectoryConfig::load(config_path, overrides)?;
    run_config(&cfg, &source, started)
}

/// [`run`] for a loaded configuration.
pub fn run_config(
    cfg: &TrajectoryConfig,
    source: &str,
    started: Instant,
) -> Result<TrajectoryReport> {
    let report_file = cfg
        .output
        .report
        .as_ref()
        .map(|p| p.to_path_buf())
        .unwrap_or_else(|| report_path(&cfg.output.sbet));
    let model_path = cfg
        .output
        .error_model
        .as_ref()
        .map(|p| p.to_path_buf())
        .unwrap_or_else(|| default_beside(&cfg.output.sbet, ".error_model.json"));
    let mut outputs: Vec<(String, PathBuf)> = vec![
        ("output.sbet".into(), cfg.output.sbet.to_path_buf()),
        ("output.smrmsg".into(), cfg.output.smrmsg.to_path_buf()),
        ("output.report".into(), report_file.clone()),
        ("output.error_model".into(), model_path.clone()),
    ];
    if let Some(f) = &cfg.output.filtered_sbet {
        outputs.push(("output.filtered_sbet".into(), f.to_path_buf()));
    }
    crate::io::paths::check_collisions(
        &[
            ("inputs.imu".into(), cfg.inputs.imu.to_path_buf()),
            ("inputs.gnss".into(), cfg.inputs.gnss.to_path_buf()),
        ],
        &outputs,
    )?;
    let imu = ImuFile::open(&cfg.inputs.imu)?;
    // Each pass faults in what it reads and releases it behind (resident memory flat in the
    // length; the validation at open releases as it goes).
    imu.release(0..imu.len());
    let gnss: Vec<GnssRecord> = {
        let f = GnssFile::open(&cfg.inputs.gnss)?;
        (0..f.len()).map(|i| f.record(i)).collect()
    };
    let grade = imu_model::grade(&cfg.imu.grade)
        .ok_or_else(|| Error::config(source, "imu.grade", "unknown grade"))?;
    let lever = Vector3::from(cfg.gnss.lever_arm_b_m);
    let (start, alignment) = align::align(
        &imu,
        &gnss,
        &cfg.alignment,
        &grade,
        lever,
        cfg.gnss.innovation_gate,
    )
    .map_err(|e| Error::Invalid(format!("{}: {e}", cfg.inputs.imu.display())))?;
    for p in outputs.iter().map(|o| &o.1) {
        if let Some(d) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(d).map_err(|e| Error::io(d, e))?;
        }
    }
    let mut filtered = cfg
        .output
        .filtered_sbet
        .as_ref()
        .map(|p| SbetWriter::create(p))
        .transpose()?;
    let mut filt_err: Option<Error> = None;
    let scratch = match cfg.output.sbet.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let fwd = smoother::forward_in(
        &imu,
        &gnss,
        start,
        cfg.gnss.max_rejected_run,
        Some(&scratch),
        &mut |e| {
            if let Some(w) = filtered.as_mut() {
                if let Err(x) = w.push(&sbet_record(e)) {
                    filt_err.get_or_insert(x);
                }
            }
        },
    )?;
    if let Some(e) = filt_err {
        return Err(e);
    }
    if let Some(w) = filtered {
        w.finish()?;
    }
    let mut sbet = SbetWriter::create(&cfg.output.sbet)?;
    let mut smr = SmrmsgWriter::create(&cfg.output.smrmsg)?;
    let (t0, t1) = (alignment.start_time_s, imu.time_s(imu.len() - 1));
    let mut gnss_gaps = gaps(&gnss, t0, t1);
    let mut records = 0u64;
    let acf = smoother::smooth(&imu, &fwd, &mut |e| {
        sbet.push(&sbet_record(e))?;
        smr.push(&smrmsg_record(e))?;
        records += 1;
        let t = e.nav.time_s;
        if let Some(g) = gnss_gaps.iter_mut().find(|g| t > g.from_s && t < g.to_s) {
            let h = (e.cov[(0, 0)] + e.cov[(1, 1)]).max(0.0).sqrt();
            g.max_horizontal_sigma_m = g.max_horizontal_sigma_m.max(h);
        }
        Ok(())
    })?;
    sbet.finish()?;
    smr.finish()?;
    crate::io::atomic::write_json(
        &model_path,
        &ErrorModel {
            components: COMPONENTS.to_vec(),
            autocorrelation: acf,
        },
    )?;
    let elapsed_s = started.elapsed().as_secs_f64();
    let span_s = t1 - t0;
    let report = TrajectoryReport {
        config: source.to_string(),
        alignment,
        filter: fwd.stats.clone(),
        gnss_gaps,
        records,
        span_s,
        elapsed_s,
        realtime_factor: span_s / elapsed_s.max(1e-9),
        stored_bytes: fwd.bytes(),
        spilled_bytes: fwd.spilled_bytes(),
        outputs: outputs.into_iter().map(|o| o.1).collect(),
    };
    crate::io::atomic::write_json(&report_file, &report)?;
    Ok(report)
}
