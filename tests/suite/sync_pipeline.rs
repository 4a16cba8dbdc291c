//! The `[sync]` pipeline stage: a simulated survey run through `kinescan run` with t0 known
//! only approximately; the sync estimate replaces `[time]`, goes in the run report with its
//! sigmas, sightings and plots; bad `[sync]` tables are refused naming the key.

use crate::sync_support;

use kinescan::geo::ellipsoid::{ecef_to_geodetic, r_enu_to_e};
use kinescan::io::patches::{write_patches, PlanarPatch};
use kinescan::pipeline::config;
use kinescan::pipeline::{run, RunOptions};
use std::path::Path;
use sync_support::{scenario, survey, PAPER};

fn pipeline_text(s: &sync_support::Survey, sync: &str, time_t0: &str) -> String {
    let l = s.sensor.lever_arm_b_m;
    format!(
        r#"
[inputs]
sbet = "trajectory.sbet"
smrmsg = "trajectory.smrmsg"
profiles = ["profiles.bin"]
[sensor]
lever_arm_b_m = [{}, {}, {}]
max_range_m = 15.0
[time]
period_s = {}
{time_t0}
[output]
las = "out/cloud.las"
[sync]
{sync}
"#,
        l.x, l.y, l.z, s.clock.period_s
    )
}

fn write_targets(s: &sync_support::Survey, dir: &Path) {
    let patches: Vec<PlanarPatch> = s
        .targets
        .iter()
        .map(|t| {
            let g = ecef_to_geodetic(&t.centre_e_m);
            let n = r_enu_to_e(g.lat_rad, g.lon_rad).transpose() * t.normal_e.unwrap();
            PlanarPatch {
                id: t.id.clone(),
                lat_rad: g.lat_rad,
                lon_rad: g.lon_rad,
                h_m: g.h_m,
                normal_enu: [n.x, n.y, n.z],
                half_length_m: 0.25,
                half_height_m: 0.25,
                sigma_m: Some(t.sigma_m),
            }
        })
        .collect();
    write_patches(&dir.join("sync_targets.csv"), &patches).unwrap();
}

#[test]
fn sync_stage_feeds_georeferencing_and_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let s = survey(&scenario(PAPER, 11), dir.path());
    write_targets(&s, dir.path());
    let sync = format!(
        "points = \"control_points.csv\"\ntargets = \"sync_targets.csv\"\nt0_approx_s = {}\n\
         method = \"refined\"\nsigma_range_m = 0.004\nmax_range_m = 15.0",
        s.true_t0_s + 0.2
    );
    let path = dir.path().join("run.toml");
    std::fs::write(&path, pipeline_text(&s, &sync, "")).unwrap();
    let loaded = config::load(&path, &[]).unwrap();
    let opts = RunOptions {
        progress: false,
        ..Default::default()
    };
    let report = run(&loaded, &opts).unwrap();
    assert_eq!(report.sync.len(), 1);
    let c = report.sync[0].result.clock;
    // 4 sigma: a false failure once in ~16000 runs.
    assert!((c.t0_s - s.true_t0_s).abs() < 4.0 * c.sigma_t0_s, "{c:?}");
    assert!(
        (c.period_s - s.true_period_s).abs() < 4.0 * c.sigma_period_s,
        "{c:?}"
    );
    // The sigmas themselves bounded, so they cannot grow to cover an error: at this geometry
    // the refined estimator's Cramer-Rao bound is 0.63 ms for t0 and 1.1e-7 s for T (mean of
    // 50 seeds, sync_paper_stats.rs); 3x that.
    assert!(c.sigma_t0_s > 0.0 && c.sigma_t0_s < 2e-3, "{c:?}");
    assert!(c.sigma_period_s > 0.0 && c.sigma_period_s < 3.3e-7, "{c:?}");
    assert!(report.stages.iter().any(|st| st.stage == "sync"));
    assert_eq!(report.sync[0].plots.len(), 2);
    assert!(report.sync[0].plots.iter().all(|p| p.exists()));
    let json = serde_json::to_value(&report).unwrap();
    let r = &json["sync"][0]["result"];
    assert_eq!(r["method"], "refined");
    assert!(r["clock"]["cov_t0_period"][1][1].as_f64().unwrap() > 0.0);
    assert_eq!(r["sightings"].as_array().unwrap().len(), 8);
    // `method = "auto"` in a pipeline: the refined estimate (it beats the paper method here),
    // reported as such, the same bytes as `refined`.
    let auto = ["sync.method = \"auto\"".to_string()];
    let again = run(&config::load(&path, &auto).unwrap(), &opts).unwrap();
    assert_eq!(again.sync[0].result.method, kinescan::sync::Method::Refined);
    assert_eq!(again.sync[0].result.clock, c);
    // The LAS times come from the synchronised clock: the first point's GPS time is that of
    // the first written return.
    let span = report.inputs[0].time_span_s.unwrap();
    assert!((span.0 - c.t0_s).abs() < 0.1, "{span:?} vs t0 {}", c.t0_s);

    // The sync covariance replaces the configured clock covariance in the uncertainty: a
    // configured sigma_t0 of 1 s would give metre-level sigmas (speed 2-9 m/s), the sync's
    // ~1 ms gives millimetres: at most 9 mm at 9 m/s, with the SMRMSG's 5/5/10 mm position and
    // 0.003/0.003/0.008 deg attitude (<= 2 mm at the 15 m range limit) at most 15 mm per axis.
    // Bounds 5 mm (the 10 mm down sigma alone exceeds it) to 5 cm.
    let unc = "\n[uncertainty]\nsigma_lever_arm_b_m = [0.0, 0.0, 0.0]\nsigma_boresight_deg = [0.0, 0.0, 0.0]\n\
               sigma_alpha_deg = 0.0\nsigma_beta_deg = 0.0\nsigma_range_m = 0.0\nsigma_range_zero_m = 0.0\n\
               clock_covariance_s2 = [[1.0, 0.0], [0.0, 1e-6]]\nsigma_attitude_latency_s = 0.0\n\
               write_95 = false\nwrite_shares = false\n";
    std::fs::write(&path, pipeline_text(&s, &sync, "") + unc).unwrap();
    run(&config::load(&path, &[]).unwrap(), &opts).unwrap();
    let mut r = las::Reader::from_path(dir.path().join("out/cloud.las")).unwrap();
    let pts = r.read_all().unwrap();
    let sigmas = pts.points().flat_map(|p| {
        let e = p.unwrap().extra_bytes;
        (4..16)
            .step_by(4)
            .map(move |o| f32::from_le_bytes(e[o..o + 4].try_into().unwrap()) as f64)
    });
    let worst_sigma = crate::common::max_of(sigmas);
    println!("sync pipeline: largest LAS sigma {worst_sigma:.4} m");
    assert!(
        worst_sigma > 0.005 && worst_sigma < 0.05,
        "largest sigma {worst_sigma} m"
    );
}

#[test]
fn bad_sync_tables_are_refused_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let s = survey(&scenario(PAPER, 12), dir.path());
    let path = dir.path().join("run.toml");
    let cases = [
        ("points = \"p.csv\"\nwindow = 1.0", "", "sync.window"),
        ("points = \"p.csv\"", "", "sync.t0_approx_s"),
        (
            "points = \"p.csv\"\nwindow_s = 0.0",
            "t0_s = 1.0",
            "sync.window_s",
        ),
        (
            "points = \"p.csv\"\nestimate_latency = true",
            "t0_s = 1.0",
            "sync.estimate_latency",
        ),
    ];
    for (sync, t0, key) in cases {
        std::fs::write(&path, pipeline_text(&s, sync, t0)).unwrap();
        let e = config::load(&path, &[]).unwrap_err().to_string();
        assert!(e.contains(key), "{e} lacks {key}");
    }
}
