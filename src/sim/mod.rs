//! Survey simulator: a scenario file in, a complete simulated survey and its truth out, in the
//! project's own input formats. See docs/simulator.md for the models and every parameter.
//!
//! Frames: the scene lives in a local East-North-Up frame about the scenario origin; beams
//! come from the pipeline's own `georef::beam_e` in ECEF and are rotated into the scene frame
//! (a rigid transform) for ray casting. Output is generated block by block (memory flat in
//! duration); profiles are generated in parallel, each with its own random stream derived
//! from (seed, profile number), and written in order, so files are byte-identical for any
//! thread count.

mod checker;
pub(crate) mod dynamics;
pub(crate) mod effects;
pub(crate) mod foreign;
pub(crate) mod gnss;
pub(crate) mod imu;
pub(crate) mod nav;
mod outputs;
pub mod raw;
mod references;
pub(crate) mod route;
pub(crate) mod scanner;
pub mod scenario;
pub(crate) mod scene;
pub(crate) mod world;

pub use effects::Effects;
pub use outputs::{read_truth_points, TRUTH_HEADER_BYTES, TRUTH_MAGIC, TRUTH_RECORD_BYTES};
pub use scenario::Scenario;

use crate::io::profiles::{ProfileColumns, ProfileWriter};
use crate::io::publish::publish_folder;
use crate::trajectory::NavSample;
use crate::{Error, Result};
use dynamics::{Frame, TruthGen};
use rayon::prelude::*;
use route::Route;
use scanner::{ScannerModel, TruthWindow};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Progress callback: (profiles done, profiles in total).
pub type Progress = Box<dyn Fn(u64, u64) + Send + Sync>;

/// Run options that are not part of the scenario.
#[derive(Default)]
pub struct SimOptions {
    /// Worker threads (None: rayon's default pool). Output does not depend on it.
    pub threads: Option<usize>,
    /// Called after every block of profiles.
    pub progress: Option<Progress>,
    /// Also write `profiles.csv` (in addition to the scenario's `output.profiles_csv`).
    pub profiles_csv: bool,
    /// Replace the scenario's `duration_s` (s), e.g. to scale the survey-day scenario.
    pub duration_s: Option<f64>,
}

/// What a run produced.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SimSummary {
    /// Profiles written.
    pub profiles: u64,
    /// Returns written (including missing ones).
    pub returns: u64,
    /// Returns with a range.
    pub valid_returns: u64,
    /// SBET records.
    pub sbet_records: u64,
    /// Wall-clock time of the run (s).
    pub elapsed_s: f64,
    /// Output directory.
    pub out_dir: PathBuf,
    /// Files written, relative to `out_dir`.
    pub files: Vec<String>,
}

/// Output file names inside the output directory.
pub mod files {
    /// Navigation solution (with injected errors).
    pub const SBET: &str = "trajectory.sbet";
    /// Its accuracy file.
    pub const SMRMSG: &str = "trajectory.smrmsg";
    /// True trajectory.
    pub const TRUTH_SBET: &str = "truth.sbet";
    /// Binary profiles.
    pub const PROFILES: &str = "profiles.bin";
    /// Profiles as CSV (on request).
    pub const PROFILES_CSV: &str = "profiles.csv";
    /// Per-return true ECEF coordinates.
    pub const TRUTH_POINTS: &str = "truth_points.bin";
    /// Sync targets and spheres.
    pub const CONTROL_POINTS: &str = "control_points.csv";
    /// Reference facades and ground.
    pub const PATCHES: &str = "patches.csv";
    /// Every true parameter and injected effect.
    pub const TRUTH_JSON: &str = "truth.json";
    /// Every file a simulation may write.
    pub const ALL: [&str; 12] = [
        super::raw::files::IMU,
        super::raw::files::GNSS,
        super::raw::files::RAW_TRUTH,
        SBET,
        SMRMSG,
        TRUTH_SBET,
        PROFILES,
        PROFILES_CSV,
        TRUTH_POINTS,
        CONTROL_POINTS,
        PATCHES,
        TRUTH_JSON,
    ];
}

/// Simulates the survey described by `scenario_path` into `out_dir` (created if missing).
pub fn simulate(scenario_path: &Path, out_dir: &Path, opts: &SimOptions) -> Result<SimSummary> {
    let sc = Scenario::load(scenario_path)?;
    crate::io::paths::check_collisions(
        &[("scenario file".into(), scenario_path.to_path_buf())],
        &crate::io::paths::in_out_dir(out_dir, &files::ALL),
    )?;
    simulate_scenario(&sc, out_dir, opts)
}

/// Simulates an already loaded scenario (see [`simulate`]), for `opts.duration_s` when given.
pub fn simulate_scenario(sc: &Scenario, out_dir: &Path, opts: &SimOptions) -> Result<SimSummary> {
    let scaled;
    let sc = match opts.duration_s {
        Some(d) => {
            let mut s = sc.clone();
            s.duration_s = d;
            s.validate("--duration-s")?;
            scaled = s;
            &scaled
        }
        None => sc,
    };
    match opts.threads {
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| Error::Invalid(format!("thread pool: {e}")))?
            .install(|| publish(sc, out_dir, opts)),
        None => publish(sc, out_dir, opts),
    }
}

/// Simulates into the staging folder of `out_dir` and publishes the files as one set,
/// `truth.json` last.
fn publish(sc: &Scenario, out_dir: &Path, opts: &SimOptions) -> Result<SimSummary> {
    publish_folder(
        out_dir,
        "simulation",
        files::TRUTH_JSON,
        &files::ALL,
        |dir| run(sc, out_dir, dir, opts),
    )
}

/// Simulates `sc` for `out_dir` (named in the summary), writing into `dir`.
fn run(sc: &Scenario, out_dir: &Path, dir: &Path, opts: &SimOptions) -> Result<SimSummary> {
    let started = Instant::now();
    let o = &sc.origin;
    let frame = Frame::new(o.lat_deg.to_radians(), o.lon_deg.to_radians(), o.h_m);
    let route = Route::new(&sc.route, sc.vehicle.lane_offset_m, &sc.name)?;
    let mut world = world::build(&sc.scene, sc.seed);
    let foreign = foreign::Foreign::place(&mut world, sc, &route, &frame);
    let p = |name: &str| dir.join(name);
    let mut written = vec![files::SBET, files::SMRMSG];
    let truth_sbet = sc.output.truth_sbet.then(|| p(files::TRUTH_SBET));
    let nav_counts = nav::write_nav(
        sc,
        TruthGen::new(sc, route.clone(), frame),
        &nav::NavPaths {
            sbet: &p(files::SBET),
            smrmsg: &p(files::SMRMSG),
            truth_sbet: truth_sbet.as_deref(),
        },
    )?;
    if truth_sbet.is_some() {
        written.push(files::TRUTH_SBET);
    }
    if sc.raw.is_some() {
        raw::write_raw(sc, dir)?;
        written.extend([raw::files::IMU, raw::files::GNSS, raw::files::RAW_TRUTH]);
    }
    let model = ScannerModel::new(sc);
    let scan = scan(
        sc,
        &model,
        &world,
        foreign.as_ref(),
        frame,
        route.clone(),
        dir,
        opts,
    )?;
    written.push(files::PROFILES);
    if opts.profiles_csv || sc.output.profiles_csv {
        crate::io::profiles_csv::export_csv(&p(files::PROFILES), &p(files::PROFILES_CSV))?;
        written.push(files::PROFILES_CSV);
    }
    if sc.output.truth_points {
        written.push(files::TRUTH_POINTS);
    }
    let foreign_counts = outputs::write_references(
        sc,
        &world,
        &route,
        frame,
        &scan.surface_hits,
        foreign.as_ref(),
        dir,
    )?;
    written.extend([files::CONTROL_POINTS, files::PATCHES]);
    let summary = SimSummary {
        profiles: scan.profiles,
        returns: scan.returns,
        valid_returns: scan.valid,
        sbet_records: nav_counts.sbet_records,
        elapsed_s: started.elapsed().as_secs_f64(),
        out_dir: out_dir.to_path_buf(),
        files: written
            .iter()
            .map(|s| s.to_string())
            .chain([files::TRUTH_JSON.into()])
            .collect(),
    };
    let foreign = foreign.map(|f| outputs::ForeignSummary {
        things: f.len(),
        mixed_returns: scan.mixed,
        counts: foreign_counts,
    });
    outputs::write_truth_json(
        sc,
        &world,
        &model,
        &route,
        &nav_counts,
        &summary,
        foreign.as_ref(),
        dir,
    )?;
    Ok(summary)
}

struct ScanResult {
    profiles: u64,
    returns: u64,
    valid: u64,
    surface_hits: Vec<u32>,
    /// Mixed returns at the edges of foreign things.
    mixed: u64,
}

/// Generates and writes every profile, block by block.
#[allow(clippy::too_many_arguments)]
fn scan(
    sc: &Scenario,
    model: &ScannerModel,
    world: &world::World,
    foreign: Option<&foreign::Foreign>,
    frame: Frame,
    route: Route,
    out_dir: &Path,
    opts: &SimOptions,
) -> Result<ScanResult> {
    let rate = sc.vehicle.nav_rate_hz;
    let t_end = sc.start_time_s + sc.duration_s - sc.scanner.end_margin_s;
    let (n_first, n_end) = model.profile_span(model.clock.t0_s, t_end);
    let mut writer = ProfileWriter::create(
        &out_dir.join(files::PROFILES),
        ProfileColumns {
            alpha: false,
            time: sc.scanner.pps_time_tags,
        },
    )?;
    let mut truth_out = sc
        .output
        .truth_points
        .then(|| outputs::TruthPointsWriter::create(&out_dir.join(files::TRUTH_POINTS)))
        .transpose()?;
    let mut gen = TruthGen::new(sc, route, frame);
    let mut buf: VecDeque<NavSample> = VecDeque::new();
    let mut base = 0u64;
    let block = ((0.5 / model.clock.period_s).round() as u32).max(1);
    let keys = foreign.map_or(world.scene.objects.len() * 8, |f| f.surface_keys());
    let mut surface_hits = vec![0u32; keys];
    let (mut returns, mut valid, mut mixed) = (0u64, 0u64, 0u64);
    let want_truth = truth_out.is_some();
    let mut na = n_first;
    while na < n_end {
        let nb = (na + block).min(n_end);
        let t_lo = model.time_bounds(na).0;
        let t_hi = model.time_bounds(nb - 1).1;
        let k_lo = (((t_lo - sc.start_time_s) * rate).floor() as u64).saturating_sub(2);
        let k_hi = ((t_hi - sc.start_time_s) * rate).ceil() as u64 + 2;
        while gen.next_index() <= k_hi {
            buf.push_back(NavSample::from_sbet(&gen.next_sample()));
        }
        while base < k_lo && buf.len() > 2 {
            buf.pop_front();
            base += 1;
        }
        let window = TruthWindow {
            samples: buf.make_contiguous(),
        };
        let scene = &world.scene;
        let outs: Vec<scanner::ProfileOut> = (na..nb)
            .into_par_iter()
            .map(|n| scanner::profile(model, scene, foreign, &frame, &window, n, want_truth))
            .collect();
        for o in &outs {
            writer.push_encoded(&o.records)?;
            if let Some(t) = truth_out.as_mut() {
                t.push_encoded(&o.truth)?;
            }
            for &s in &o.surfaces {
                surface_hits[s as usize] += 1;
            }
            returns += model.points_per_profile() as u64;
            valid += o.valid as u64;
            mixed += o.mixed as u64;
        }
        if let Some(cb) = &opts.progress {
            cb((nb - n_first) as u64, (n_end - n_first) as u64);
        }
        na = nb;
    }
    writer.finish()?;
    if let Some(t) = truth_out {
        t.finish()?;
    }
    Ok(ScanResult {
        profiles: (n_end - n_first) as u64,
        returns,
        valid,
        surface_hits,
        mixed,
    })
}
