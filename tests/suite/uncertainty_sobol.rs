//! Sobol machinery against analytic indices, and the sensitivity study end to end.

use kinescan::app::sensitivity::{load_sensitivity, run_sensitivity};
use kinescan::uncertainty::sobol::SaltelliDesign;
use std::path::{Path, PathBuf};

/// `y = x1 + x2 + x1 x3` with `x ~ N(0, s^2)`, s = (1, 0.5, 0.8): V = 1 + 0.25 + 0.64;
/// S1 = 1/V, S2 = 0.25/V, S3 = 0; ST1 = 1.64/V, ST2 = 0.25/V, ST3 = 0.64/V. The closed group
/// {x1, x3} has first-order index 1.64/V. Estimates must fall within 3 times their 95%
/// bootstrap half-width (5.9 standard errors) and within 0.02.
#[test]
fn indices_match_an_analytic_model_with_interaction() {
    let sigmas = [1.0, 0.5, 0.8];
    let factors = vec![vec![0], vec![1], vec![2], vec![0, 2]];
    let v = 1.0 + 0.25 + 0.64;
    let first = [1.0 / v, 0.25 / v, 0.0, 1.64 / v];
    let total = [1.64 / v, 0.25 / v, 0.64 / v, 1.64 / v];
    let design = SaltelliDesign::new(&sigmas, factors, 1 << 15, 5);
    let s = design
        .evaluate(|x: &[f64]| {
            let y = x[0] + x[1] + x[0] * x[2];
            [y, 2.0 * y, -y]
        })
        .analyze(100, 6);
    for f in 0..4 {
        for (est, truth) in [
            (s.combined[f].first, first[f]),
            (s.combined[f].total, total[f]),
        ] {
            let conf = crate::common::max_of([s.combined[f].first_conf, s.combined[f].total_conf]);
            println!("factor {f}: {est:.4} vs {truth:.4} (+-{conf:.4})");
            assert!(
                (est - truth).abs() <= crate::common::min_of([3.0 * conf, 0.02]),
                "factor {f}"
            );
        }
    }
    // The 3-vector output is one output scaled: the combined index equals each component's.
    assert!((s.per_output[1][0].first - s.combined[0].first).abs() < 1e-12);
}

fn study_file(dir: &Path, extra: &str) -> std::path::PathBuf {
    let text = format!(
        r#"sigma_set = "expected"
samples = 2048
bootstrap = 50
seed = 3
{extra}
[ins]
sigma_position_ned_m = [0.02, 0.02, 0.025]
sigma_attitude_rph_deg = [0.005, 0.005, 0.015]
[platform]
lat_deg = 43.8
lon_deg = -79.5
h_m = 200.0
speed_mps = 5.0
[sensor]
lever_arm_b_m = [-0.5, 0.0, -1.5]
[points]
scanner_height_m = 2.5
range_m = [5.0, 80.0]
count = 4
"#
    );
    let path = dir.join("study.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// The study writes its tables; at these small sigmas the model is additive, so every
/// factor's Sobol indices equal its analytic linear share within their 95% half-width plus
/// 0.01, and the group first-order indices sum to 1 within 3 times the root-sum-square of
/// their half-widths.
#[test]
fn study_tables_and_additivity() {
    let dir = tempfile::tempdir().unwrap();
    let path = study_file(dir.path(), "");
    let out = dir.path().join("out");
    let report = run_sensitivity(&path, &out).unwrap();
    for name in [
        "sensitivity_points.csv",
        "share_vs_range.csv",
        "sensitivity.json",
    ] {
        assert!(out.join(name).is_file(), "{name}");
    }
    let csv = std::fs::read_to_string(out.join("sensitivity_points.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 4 * 24 * 4);
    check_plots(&report.outputs, &out);
    for p in &report.points {
        let (mut group_sum, mut conf_sq) = (0.0, 0.0);
        for f in &p.factors {
            for (s, linear) in f.sobol.iter().zip(f.linear_share) {
                for est in [s.first, s.total] {
                    let tol = crate::common::max_of([s.first_conf, s.total_conf]) + 0.01;
                    assert!(
                        (est - linear).abs() <= tol,
                        "{} at {} m: {est} vs linear {linear}",
                        f.factor,
                        p.range_m,
                    );
                }
            }
            let s = f.sobol[3];
            if f.kind == "group" {
                group_sum += s.first;
                conf_sq += s.first_conf * s.first_conf;
            }
        }
        let tol = 3.0 * conf_sq.sqrt();
        assert!(
            (group_sum - 1.0).abs() < tol,
            "groups sum {group_sum} +- {tol}"
        );
        for k in 0..3 {
            assert!((p.sigma_enu_mc_m[k] / p.sigma_enu_m[k] - 1.0).abs() < 0.05);
        }
    }
}

/// The share-against-range plots: one per output for the groups, and the per-input ones listed
/// in the report; each decodes as a 1000 x 700 PNG and shows its first factor's markers and
/// line (so the data, not just the axes and legend, were drawn).
fn check_plots(outputs: &[PathBuf], out: &Path) {
    let pngs: Vec<&PathBuf> = outputs
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    for o in ["east", "north", "up", "total"] {
        let p = out.join(format!("share_vs_range_{o}.png"));
        assert!(pngs.contains(&&p), "{} not written", p.display());
    }
    assert!(pngs.len() > 4, "no per-input plot");
    for path in pngs {
        let p = crate::common::plot_pixels(path);
        assert_eq!((p.width, p.height), (1000, 700), "{}", path.display());
        // The legend key shows under 100 px of each colour; the first factor's markers and line add more.
        assert!(
            p.first_series > 200,
            "{}: {} pixels of the first factor",
            path.display(),
            p.first_series
        );
    }
}

/// Study files are refused with the key named: unknown key, custom set without `[custom]`.
#[test]
fn bad_study_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = study_file(dir.path(), "colour = 1");
    let err = load_sensitivity(&path).unwrap_err().to_string();
    assert!(err.contains("colour"), "{err}");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("colour = 1", "")
        .replace("\"expected\"", "\"custom\"");
    std::fs::write(&path, text).unwrap();
    let err = load_sensitivity(&path).unwrap_err().to_string();
    assert!(err.contains("custom"), "{err}");
}
