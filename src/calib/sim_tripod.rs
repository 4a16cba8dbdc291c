//! Tripod boresight scenario and the Monte Carlo of paper 002, section 5.
//!
//! A tripod stands with its apex at the NED origin, axis `tripod_axis_n` (apex towards feet),
//! legs `leg_from_axis_deg` off the axis at the given azimuths. At each site the IMU has the
//! given attitude; the scanner (true boresight `Rz Ry Rx(misalignment) * R_nom`) is placed so
//! that its beam `beta = 0` crosses the tripod axis `cut_depth_m` below the apex at
//! `scanner_distance_m`; its scan plane cuts the three legs at the ellipse centres, which get
//! isotropic Gaussian in-plane noise `sigma_centre_m`; the raw returns of each site's scan
//! ([`TripodScenario::simulate_scan`]) are written too, for the centre fit from scans. Defaults are the paper's simulation:
//! legs at 60 deg, sites (roll, pitch, heading) = (-20, 0, 30), (0, 20, 120), (20, -20, 240) deg,
//! and a scanner whose scan plane is horizontal in the body (`R_nom`: mirror axis `x_s` along
//! body down, `beta = 0` forward; convention angles (0, -90, 180) deg), which the paper's sites need:
//! a scan plane must be within ~30 deg of horizontal to cut all three legs of a standing
//! tripod at any heading. The paper does not say how its sites' angles compose:
//! `site_rotation` selects the conventions' order (default) or the order of the paper's printed matrix.

use super::boresight::{estimate_boresight, BoresightSetup, TripodSite};
use super::ellipse::{beam, CutShape};
use crate::geo::rotations::{r_b_to_n, r_zyx, rot_x, rot_y, rot_z, zyx_angles};
use crate::io::atomic::{write_atomic, write_json};
use crate::io::config_file;
use crate::io::publish::publish_folder;
use crate::plot::Plot;
use crate::{Error, Result};
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::Path;

/// Tripod scenario (TOML keys as fields; every key optional, defaults = paper 002).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct TripodScenario {
    /// Random seed.
    pub seed: u64,
    /// Leg angle from the tripod axis (deg).
    pub leg_from_axis_deg: f64,
    /// Leg azimuths about the axis (deg).
    pub leg_azimuths_deg: [f64; 3],
    /// Leg length from the apex (m).
    pub leg_length_m: f64,
    /// Tripod axis, apex towards feet, NED.
    pub tripod_axis_n: [f64; 3],
    /// Depth below the apex, along the axis, where beam `beta = 0` crosses the axis (m).
    pub cut_depth_m: f64,
    /// Optical centre to that crossing point (m).
    pub scanner_distance_m: f64,
    /// IMU roll, pitch, heading per site (deg), composed as `site_rotation` says.
    pub sites_deg: Vec<[f64; 3]>,
    /// How `sites_deg` compose into the body-to-NED rotation (default: the conventions').
    pub site_rotation: SiteRotation,
    /// Nominal boresight (deg, convention).
    pub nominal_boresight_deg: [f64; 3],
    /// True misalignment about body x, y, z on top of the nominal (deg).
    pub misalignment_deg: [f64; 3],
    /// Ellipse-centre noise, 1 sigma, in-plane isotropic (m).
    pub sigma_centre_m: f64,
    /// IMU attitude noise per site, 1 sigma (deg).
    pub sigma_attitude_deg: [f64; 3],
    /// Monte Carlo trials run by [`run_tripod_simulation`] (0: none).
    pub monte_carlo_trials: usize,
    /// Leg radius for the raw scans (m).
    pub leg_radius_m: f64,
    /// Range noise of the raw scans, 1 sigma (m).
    pub sigma_range_m: f64,
    /// Mirror-angle step of the raw scans (deg); a full turn is scanned.
    pub beta_step_deg: f64,
    /// Largest range (m); beams that hit nothing nearer are missing returns (range 0).
    pub max_range_m: f64,
}

impl Default for TripodScenario {
    fn default() -> Self {
        Self {
            seed: 1,
            leg_from_axis_deg: 60.0,
            leg_azimuths_deg: [15.0, 135.0, 255.0],
            leg_length_m: 2.5,
            tripod_axis_n: [0.0, 0.0, 1.0],
            cut_depth_m: 0.5,
            scanner_distance_m: 1.0,
            sites_deg: vec![[-20.0, 0.0, 30.0], [0.0, 20.0, 120.0], [20.0, -20.0, 240.0]],
            site_rotation: SiteRotation::Zyx,
            nominal_boresight_deg: [0.0, -90.0, 180.0],
            misalignment_deg: [0.5, -0.3, 1.0],
            sigma_centre_m: 0.001,
            sigma_attitude_deg: [0.0, 0.0, 0.0],
            monte_carlo_trials: 0,
            leg_radius_m: 0.025,
            sigma_range_m: 0.002,
            beta_step_deg: 0.1,
            max_range_m: 30.0,
        }
    }
}

/// Composition of a site's (roll, pitch, heading) into `R_b^n`. Paper 002 does not say how its
/// simulated sites compose; the two readings give very different heading observability
/// (docs/calibration.md, "Why the paper's error levels are not reached").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SiteRotation {
    /// convention: `R_b^n = Rz(heading) Ry(pitch) Rx(roll)`.
    Zyx,
    /// The order of paper 002's printed matrix: `R_b^n = Rx(roll) Ry(pitch) Rz(heading)`.
    Xyz,
}

impl TripodScenario {
    /// Body-to-NED rotation of site `k` (index into `sites_deg`).
    pub fn site_r_b_to_n(&self, k: usize) -> Matrix3<f64> {
        let [r, p, h] = self.sites_deg[k].map(f64::to_radians);
        match self.site_rotation {
            SiteRotation::Zyx => r_b_to_n(r, p, h),
            SiteRotation::Xyz => rot_x(r) * rot_y(p) * rot_z(h),
        }
    }

    /// convention attitude angles (roll, pitch, heading; rad) of site `k`: what its IMU reports.
    pub fn site_attitude_rad(&self, k: usize) -> [f64; 3] {
        let (r, p, h) = zyx_angles(&self.site_r_b_to_n(k));
        [r, p, h]
    }

    fn axis(&self) -> Vector3<f64> {
        Vector3::from(self.tripod_axis_n).normalize()
    }

    /// Unit leg directions in NED.
    fn legs_n(&self) -> [Vector3<f64>; 3] {
        let a = self.axis();
        let helper = if a.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = a.cross(&helper).normalize();
        let e2 = a.cross(&e1);
        let (s, c) = self.leg_from_axis_deg.to_radians().sin_cos();
        self.leg_azimuths_deg.map(|az| {
            let (sa, ca) = az.to_radians().sin_cos();
            a * c + (e1 * ca + e2 * sa) * s
        })
    }

    fn r_nominal(&self) -> Matrix3<f64> {
        let [x, y, z] = self.nominal_boresight_deg.map(f64::to_radians);
        r_zyx(x, y, z)
    }

    /// True `R_s^b`.
    pub fn true_r_s_to_b(&self) -> Matrix3<f64> {
        let [x, y, z] = self.misalignment_deg.map(f64::to_radians);
        r_zyx(x, y, z) * self.r_nominal()
    }

    /// The setup a calibration of this scenario uses (true leg angles, nominal boresight).
    pub fn calibration_setup(&self) -> BoresightSetup {
        let e = self.legs_n();
        BoresightSetup {
            cos_leg_angles: [e[0].dot(&e[1]), e[0].dot(&e[2]), e[1].dot(&e[2])],
            tripod_axis_n: self.axis(),
            r_nominal_s_to_b: self.r_nominal(),
        }
    }

    /// Inter-leg angles (deg) for leg pairs (1,2), (1,3), (2,3).
    pub fn leg_angles_deg(&self) -> [f64; 3] {
        self.calibration_setup()
            .cos_leg_angles
            .map(|c| c.acos().to_degrees())
    }

    /// Raw returns of site `k` with attitude `site_r_b_to_n(k)`: each beam is cast against the
    /// three leg cuts (ellipses, [`CutShape::of_leg`]) and the floor (the plane through the
    /// feet, normal to the axis); nearest hit, plus Gaussian range noise `sigma_range_m`;
    /// range 0 (missing) beyond `max_range_m`. Intensity: 100 on a leg, 30 on the floor.
    pub fn simulate_scan(&self, k: usize, rng: &mut ChaCha8Rng) -> Result<Vec<(f64, f64, f64)>> {
        let noise = Normal::new(0.0, self.sigma_range_m)
            .map_err(|e| Error::config("tripod scenario", "sigma_range_m", e.to_string()))?;
        if !(self.beta_step_deg > 0.0 && self.leg_radius_m > 0.0) {
            return Err(Error::config(
                "tripod scenario",
                "beta_step_deg / leg_radius_m",
                "must be > 0",
            ));
        }
        let r_s_n = self.site_r_b_to_n(k) * self.true_r_s_to_b();
        let centres = self.true_centres(k)?;
        let legs_s = self.legs_n().map(|e| r_s_n.transpose() * e);
        let origin =
            self.axis() * self.cut_depth_m - r_s_n * Vector3::z() * self.scanner_distance_m;
        let floor_depth = self.leg_length_m * self.leg_from_axis_deg.to_radians().cos();
        let n_beams = (360.0 / self.beta_step_deg).round() as usize;
        let mut out = Vec::with_capacity(n_beams);
        for j in 0..n_beams {
            let beta = -PI + j as f64 * self.beta_step_deg.to_radians();
            let u = beam(beta);
            let mut hit: Option<(f64, f64)> = None;
            for (c, l) in centres.iter().zip(&legs_s) {
                let shape = CutShape::of_leg(l, self.leg_radius_m).ok_or_else(|| {
                    Error::Invalid("tripod scenario: a leg lies in the scan plane".into())
                })?;
                if let Some(t) = shape.beam_hit(c, &u) {
                    if hit.is_none_or(|(h, _)| t < h) {
                        hit = Some((t, 100.0));
                    }
                }
            }
            let dir_n = r_s_n * Vector3::new(0.0, u.x, u.y);
            let along = dir_n.dot(&self.axis());
            if along > 1e-9 {
                let t = (floor_depth - origin.dot(&self.axis())) / along;
                if t > 0.0 && hit.is_none_or(|(h, _)| t < h) {
                    hit = Some((t, 30.0));
                }
            }
            out.push(match hit {
                Some((t, i)) if t < self.max_range_m => (beta, t + noise.sample(rng), i),
                _ => (beta, 0.0, 0.0),
            });
        }
        Ok(out)
    }

    /// Noise-free ellipse centres `(y_s, z_s)` of the three legs at site `k` (m).
    fn true_centres(&self, k: usize) -> Result<[Vector2<f64>; 3]> {
        let r_s_n = self.site_r_b_to_n(k) * self.true_r_s_to_b();
        let m = r_s_n * Vector3::x();
        let q = self.axis() * self.cut_depth_m;
        let origin = q - r_s_n * Vector3::z() * self.scanner_distance_m;
        let mut out = [Vector2::zeros(); 3];
        for (i, e) in self.legs_n().iter().enumerate() {
            let s = m.dot(&q) / m.dot(e);
            if !(s > 0.0 && s < self.leg_length_m) {
                return Err(Error::Invalid(format!(
                    "tripod scenario: site {}: the scan plane misses leg {} (cut at {s:.2} m along a {} m leg)",
                    k + 1,
                    i + 1,
                    self.leg_length_m
                )));
            }
            let c_s = r_s_n.transpose() * (e * s - origin);
            out[i] = Vector2::new(c_s.y, c_s.z);
        }
        Ok(out)
    }
}

/// Simulates the sites: noisy ellipse centres and (noisy) IMU attitudes, seeded by `rng`.
pub fn simulate_sites(sc: &TripodScenario, rng: &mut ChaCha8Rng) -> Result<Vec<TripodSite>> {
    let nc = Normal::new(0.0, sc.sigma_centre_m)
        .map_err(|e| Error::config("tripod scenario", "sigma_centre_m", e.to_string()))?;
    let sig_att = sc.sigma_attitude_deg.map(f64::to_radians);
    let mut out = Vec::new();
    for k in 0..sc.sites_deg.len() {
        let centres = sc
            .true_centres(k)?
            .map(|c| c + Vector2::new(nc.sample(rng), nc.sample(rng)));
        let mut attitude_rad = sc.site_attitude_rad(k);
        for (a, s) in attitude_rad.iter_mut().zip(sig_att) {
            *a += s * Normal::new(0.0, 1.0)
                .map_err(|e| Error::Invalid(e.to_string()))?
                .sample(rng);
        }
        out.push(TripodSite {
            site: k as u64 + 1,
            centres_s_m: centres,
            cov_centre_s_m2: [Matrix2::identity() * sc.sigma_centre_m.powi(2); 3],
            attitude_rad,
            sigma_attitude_rad: sig_att,
        });
    }
    Ok(out)
}

/// Monte Carlo of the boresight estimate (paper 002, section 5).
#[derive(Debug, Clone, Serialize)]
pub struct MonteCarloSummary {
    /// Ellipse-centre noise (m).
    pub sigma_centre_m: f64,
    /// Trials.
    pub trials: usize,
    /// Mean misalignment error (deg), roll/pitch/heading of the boresight.
    pub mean_error_deg: [f64; 3],
    /// Empirical standard deviation of the error (deg).
    pub empirical_sigma_deg: [f64; 3],
    /// RMS predicted sigma (deg).
    pub predicted_sigma_deg: [f64; 3],
    /// 99th percentile of |error| (deg).
    pub p99_abs_error_deg: [f64; 3],
    /// Largest |error| (deg).
    pub max_abs_error_deg: [f64; 3],
    /// Share of trials converged in <= 5 iterations.
    pub share_converged_within_5: f64,
    /// Largest iteration count.
    pub max_iterations: usize,
    /// Errors per trial (deg).
    #[serde(skip)]
    pub errors_deg: Vec<[f64; 3]>,
}

/// Runs `trials` noisy realisations of `sc` (seeded by `sc.seed`), estimating the boresight each
/// time; errors are misalignment estimate minus truth (deg).
pub fn run_monte_carlo(sc: &TripodScenario, trials: usize) -> Result<MonteCarloSummary> {
    let setup = sc.calibration_setup();
    let mut rng = ChaCha8Rng::seed_from_u64(sc.seed);
    let (mut errors, mut pred_var, mut iters) = (Vec::new(), [0.0; 3], Vec::new());
    for _ in 0..trials {
        let sites = simulate_sites(sc, &mut rng)?;
        let r = estimate_boresight(&sites, &setup)?;
        errors.push([0, 1, 2].map(|k| r.misalignment_deg[k] - sc.misalignment_deg[k]));
        for (k, v) in pred_var.iter_mut().enumerate() {
            *v += r.cov_misalignment_deg2[k][k] / trials as f64;
        }
        iters.push(r.iterations);
    }
    let n = trials as f64;
    let mean = [0, 1, 2].map(|k| errors.iter().map(|e| e[k]).sum::<f64>() / n);
    let sd = [0, 1, 2]
        .map(|k| (errors.iter().map(|e| (e[k] - mean[k]).powi(2)).sum::<f64>() / (n - 1.0)).sqrt());
    let quantile = |k: usize, q: f64| {
        let mut a: Vec<f64> = errors.iter().map(|e| e[k].abs()).collect();
        a.sort_by(f64::total_cmp);
        a[((q * (a.len() - 1) as f64).round() as usize).min(a.len() - 1)]
    };
    Ok(MonteCarloSummary {
        sigma_centre_m: sc.sigma_centre_m,
        trials,
        mean_error_deg: mean,
        empirical_sigma_deg: sd,
        predicted_sigma_deg: pred_var.map(f64::sqrt),
        p99_abs_error_deg: [0, 1, 2].map(|k| quantile(k, 0.99)),
        max_abs_error_deg: [0, 1, 2].map(|k| quantile(k, 1.0)),
        share_converged_within_5: iters.iter().filter(|&&i| i <= 5).count() as f64 / n,
        max_iterations: iters.iter().copied().max().unwrap_or(0),
        errors_deg: errors,
    })
}

/// Histogram of one error component: `(bin_low_deg, bin_high_deg, count)` over `bins` equal bins
/// spanning +-max|error|. This is the data of the PNG histograms (paper 002, figs 4-5).
pub fn histogram_bins(
    errors_deg: &[[f64; 3]],
    component: usize,
    bins: usize,
) -> Vec<(f64, f64, usize)> {
    let lim = errors_deg
        .iter()
        .map(|e| e[component].abs())
        .fold(0.0, f64::max)
        .max(1e-12);
    let width = 2.0 * lim / bins as f64;
    let mut counts = vec![0; bins];
    for e in errors_deg {
        counts[(((e[component] + lim) / width) as usize).min(bins - 1)] += 1;
    }
    counts
        .into_iter()
        .enumerate()
        .map(|(i, c)| (-lim + i as f64 * width, -lim + (i + 1) as f64 * width, c))
        .collect()
}

/// Angle names of the misalignment components, in order.
const ANGLES: [&str; 3] = ["roll", "pitch", "heading"];

/// Writes a Monte Carlo's outputs into `out_dir` atomically, tagged by the noise in mm:
/// `boresight_mc_<mm>mm.json` (summary), `..._errors.csv` (per trial), `..._histograms.csv`
/// (40 bins per angle, from [`histogram_bins`]) and one PNG histogram per angle,
/// `..._<roll|pitch|heading>.png` (paper 002, figs 4-5: 40 bins over the errors' range, x axis
/// symmetric about 0).
pub fn write_monte_carlo_outputs(out_dir: &Path, mc: &MonteCarloSummary) -> Result<()> {
    let mm = mc.sigma_centre_m * 1e3;
    let tag = format!("boresight_mc_{mm}mm");
    write_json(&out_dir.join(format!("{tag}.json")), mc)?;
    let mut s = String::from("trial,roll_error_deg,pitch_error_deg,heading_error_deg\n");
    for (i, e) in mc.errors_deg.iter().enumerate() {
        let _ = writeln!(s, "{i},{:.8},{:.8},{:.8}", e[0], e[1], e[2]);
    }
    write_atomic(&out_dir.join(format!("{tag}_errors.csv")), s.as_bytes())?;
    let mut h = String::from("angle,bin_low_deg,bin_high_deg,count\n");
    for (k, name) in ANGLES.iter().enumerate() {
        let bins = histogram_bins(&mc.errors_deg, k, 40);
        for (lo, hi, c) in &bins {
            let _ = writeln!(h, "{name},{lo:.8},{hi:.8},{c}");
        }
        let values: Vec<f64> = mc.errors_deg.iter().map(|e| e[k]).collect();
        let lim = bins.last().map_or(1.0, |b| b.1);
        Plot::new(
            &format!(
                "Boresight {name} error, {mm} mm ellipse-centre noise, {} trials",
                mc.trials
            ),
            &format!("{name} error (deg)"),
            "trials",
        )
        .x_range(-lim, lim)
        .histogram(
            &format!("sigma {:.4} deg", mc.empirical_sigma_deg[k]),
            &values,
            40,
        )
        .save_png(out_dir.join(format!("{tag}_{name}.png")))?;
    }
    write_atomic(&out_dir.join(format!("{tag}_histograms.csv")), h.as_bytes())
}

/// Files a tripod simulation writes into its output folder (besides the Monte Carlo's
/// `boresight_mc_*` files).
pub const OUTPUT_FILES: [&str; 6] = [
    "tripod_centres.csv",
    "tripod_sites.csv",
    "calib_boresight.toml",
    "tripod_scans.csv",
    "calib_boresight_scans.toml",
    "truth.json",
];

/// Writes one realisation as a lab would record it (`tripod_centres.csv`, `tripod_sites.csv`),
/// the calibration config `calib_boresight.toml` that reads them, the raw returns of each
/// site `tripod_scans.csv` (`site,beta_rad,range_m,intensity`, [`TripodScenario::simulate_scan`],
/// seeded from `seed`) with `calib_boresight_scans.toml` that reads those instead of the
/// centres, and `truth.json`.
pub fn write_tripod_run(sc: &TripodScenario, sites: &[TripodSite], out_dir: &Path) -> Result<()> {
    let mut c = String::from("site,leg,y_s_m,z_s_m,sigma_m\n");
    let mut a = String::from(
        "site,roll_deg,pitch_deg,heading_deg,sigma_roll_deg,sigma_pitch_deg,sigma_heading_deg\n",
    );
    for s in sites {
        for (i, p) in s.centres_s_m.iter().enumerate() {
            let _ = writeln!(
                c,
                "{},{},{:.7},{:.7},{}",
                s.site,
                i + 1,
                p.x,
                p.y,
                (0.5 * s.cov_centre_s_m2[i].trace()).sqrt()
            );
        }
        let [r, p, h] = s.attitude_rad.map(f64::to_degrees);
        let [sr, sp, sh] = s.sigma_attitude_rad.map(f64::to_degrees);
        let _ = writeln!(a, "{},{r:.10},{p:.10},{h:.10},{sr},{sp},{sh}", s.site);
    }
    write_atomic(&out_dir.join("tripod_centres.csv"), c.as_bytes())?;
    write_atomic(&out_dir.join("tripod_sites.csv"), a.as_bytes())?;
    let cfg = format!(
        "# Written by the tripod simulator (seed {}).\n[files]\ncentres = \"tripod_centres.csv\"\n\
         sites = \"tripod_sites.csv\"\n\n[tripod]\nleg_angles_deg = {:?}\naxis_n = {:?}\n\n\
         [scanner]\nnominal_boresight_deg = {:?}\n",
        sc.seed,
        sc.leg_angles_deg(),
        sc.tripod_axis_n,
        sc.nominal_boresight_deg
    );
    write_atomic(&out_dir.join("calib_boresight.toml"), cfg.as_bytes())?;
    let mut rng = ChaCha8Rng::seed_from_u64(sc.seed ^ 0x5ca7);
    let mut scans = String::from("site,beta_rad,range_m,intensity\n");
    for s in sites {
        for (beta, range, intensity) in sc.simulate_scan(s.site as usize - 1, &mut rng)? {
            let _ = writeln!(scans, "{},{beta:.9},{range:.5},{intensity}", s.site);
        }
    }
    write_atomic(&out_dir.join("tripod_scans.csv"), scans.as_bytes())?;
    let cfg_scans = cfg
        .replace(
            "centres = \"tripod_centres.csv\"",
            "scans = \"tripod_scans.csv\"",
        )
        .replace(
            "\n\n[scanner]\n",
            &format!(
                "\nleg_radius_m = {}\n\n[scanner]\nsigma_range_m = {}\n",
                sc.leg_radius_m, sc.sigma_range_m
            ),
        );
    write_atomic(
        &out_dir.join("calib_boresight_scans.toml"),
        cfg_scans.as_bytes(),
    )?;
    let truth = zyx_angles(&sc.true_r_s_to_b());
    write_json(
        &out_dir.join("truth.json"),
        &serde_json::json!({
            "misalignment_deg": sc.misalignment_deg,
            "boresight_deg": [truth.0.to_degrees(), truth.1.to_degrees(), truth.2.to_degrees()],
            "scenario": sc,
        }),
    )
}

/// `kinescan simulate` for the tripod (paper 002, section 5): reads a [`TripodScenario`] TOML at
/// `config_path` (unknown keys refused) and writes atomically into `out_dir` one realisation as
/// a lab records it (`tripod_centres.csv`: ellipse centres in the scan plane, m;
/// `tripod_sites.csv`: IMU attitudes, convention angles in deg; `tripod_scans.csv`: raw returns),
/// the calibration configs `calib_boresight.toml` (centres), `calib_boresight_scans.toml`
/// (scans) and `truth.json` ([`write_tripod_run`]). With
/// `monte_carlo_trials > 0` it also runs the Monte Carlo and writes its outputs
/// ([`write_monte_carlo_outputs`]: JSON summary, per-trial errors, histogram CSV and one PNG per
/// angle) and returns the serialisable summary (errors in deg, misalignment about body x, y, z);
/// otherwise `None`.
pub fn run_tripod_simulation(
    config_path: &Path,
    out_dir: &Path,
) -> Result<Option<MonteCarloSummary>> {
    let sc: TripodScenario = config_file::load(config_path, &[])?.value;
    crate::io::paths::check_collisions(
        &[("config file".into(), config_path.to_path_buf())],
        &crate::io::paths::in_out_dir(out_dir, &OUTPUT_FILES),
    )?;
    let mut rng = ChaCha8Rng::seed_from_u64(sc.seed);
    let sites = simulate_sites(&sc, &mut rng)?;
    publish_folder(out_dir, "tripod", "truth.json", &OUTPUT_FILES, |dir| {
        write_tripod_run(&sc, &sites, dir)?;
        if sc.monte_carlo_trials == 0 {
            return Ok(None);
        }
        let mc = run_monte_carlo(&sc, sc.monte_carlo_trials)?;
        write_monte_carlo_outputs(dir, &mc)?;
        Ok(Some(mc))
    })
}
