//! The `kinescan` binary, run in a fresh temporary folder like a user would.

use crate::common;

use crate::common::kinescan;
use kinescan::io::profiles::{ProfileColumns, ProfileWriter, RawReturn};
use std::path::Path;
use std::process::Output;

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Two passes of a 100 Hz profile scanner, 360 returns a profile at 10 m, over the synthetic
/// trajectory.
fn survey(dir: &Path) {
    common::write_trajectory(dir);
    for (name, first) in [("pass1.ksprof", 100u32), ("pass2.ksprof", 900)] {
        let mut w = ProfileWriter::create(&dir.join(name), ProfileColumns::default()).unwrap();
        for n in first..first + 300 {
            for k in 0..360 {
                let beta = (k as f64 - 180.0).to_radians();
                w.push(&RawReturn {
                    profile: n,
                    beta_rad: beta,
                    range_m: 10.0,
                    intensity: 7,
                    ..Default::default()
                })
                .unwrap();
            }
        }
        w.finish().unwrap();
    }
    let pipeline = format!(
        "[inputs]\nsbet = \"traj.sbet\"\nprofiles = [\"pass1.ksprof\", \"pass2.ksprof\"]\n\n\
         [sensor]\nlever_arm_b_m = [0.5, 0.0, -1.5]\n\n[time]\nt0_s = {}\nperiod_s = 0.01\n\n\
         [output]\nlas = \"out/day.las\"\nsplit = \"per_input\"\n",
        common::T_START_S
    );
    std::fs::write(dir.join("pipeline.toml"), pipeline).unwrap();
}

#[test]
fn run_writes_one_las_per_pass_with_point_source_ids() {
    let dir = tempfile::tempdir().unwrap();
    survey(dir.path());
    let o = kinescan(
        dir.path(),
        &["run", "pipeline.toml", "--set", "latency.attitude_s=0.002"],
    );
    assert!(o.status.success(), "{}", text(&o));
    let out = text(&o);
    assert!(
        out.contains("216000 returns read, 216000 written, 0 rejected"),
        "{out}"
    );
    for (name, psid) in [("day_pass1.las", 1u16), ("day_pass2.las", 2)] {
        let mut r = las::Reader::from_path(dir.path().join("out").join(name)).unwrap();
        let pts: Vec<_> = r.read_all().unwrap().points().map(|p| p.unwrap()).collect();
        assert_eq!(pts.len(), 108_000);
        assert!(pts.iter().all(|p| p.point_source_id == psid));
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("out/day.report.json")).unwrap())
            .unwrap();
    assert_eq!(report["overrides"][0], "latency.attitude_s=0.002");
    assert_eq!(report["parameters"]["latency"]["attitude_s"], 0.002);
    assert_eq!(report["epsg"], 32632);
    assert_eq!(report["totals"]["read"], 216000);
    assert_eq!(report["files"][1]["role"], "sbet");
    assert_eq!(report["files"][1]["sha256"].as_str().unwrap().len(), 64);
}

#[test]
fn validate_accepts_good_and_names_bad_keys() {
    let dir = tempfile::tempdir().unwrap();
    survey(dir.path());
    let o = kinescan(dir.path(), &["validate", "pipeline.toml"]);
    assert!(o.status.success(), "{}", text(&o));
    let o = kinescan(
        dir.path(),
        &[
            "validate",
            "pipeline.toml",
            "--set",
            "sensor.lever_arm=[0,0,0]",
        ],
    );
    assert_eq!(o.status.code(), Some(1));
    let err = text(&o);
    assert!(
        err.contains("pipeline.toml") && err.contains("lever_arm"),
        "{err}"
    );
    std::fs::write(dir.path().join("traj.sbet"), [0u8; 100]).unwrap();
    let o = kinescan(dir.path(), &["validate", "pipeline.toml"]);
    assert!(
        !o.status.success() && text(&o).contains("traj.sbet"),
        "{}",
        text(&o)
    );
}

#[test]
fn info_and_import() {
    let dir = tempfile::tempdir().unwrap();
    survey(dir.path());
    let o = kinescan(dir.path(), &["info", "traj.sbet"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("200"), "{}", text(&o));
    let o = kinescan(dir.path(), &["info", "pass1.ksprof", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["records"], 108_000);
    std::fs::write(
        dir.path().join("p.csv"),
        "profile,beta_rad,range_m,intensity\n0,0.1,5.5,3\n1,0.2,,4\n",
    )
    .unwrap();
    let o = kinescan(dir.path(), &["--quiet", "import", "p.csv", "p.ksprof"]);
    assert!(o.status.success(), "{}", text(&o));
    let f = kinescan::io::profiles::ProfileFile::open(&dir.path().join("p.ksprof")).unwrap();
    assert_eq!((f.len(), f.get(1).range_m), (2, 0.0));
    std::fs::write(
        dir.path().join("bad.csv"),
        "profile,beta_rad,range_m,intensity,colour\n",
    )
    .unwrap();
    let o = kinescan(dir.path(), &["import", "bad.csv", "b.ksprof"]);
    assert!(
        !o.status.success() && text(&o).contains("colour"),
        "{}",
        text(&o)
    );
}

/// The commands a `--help` text lists (its `Commands:` section, `help` left out).
fn listed_commands(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(String::from)
        .collect()
}

/// Every command the binary lists, and every subcommand of a command group (`calibrate`),
/// found by walking the `--help` texts, shows an example in its help.
#[test]
fn every_command_has_examples_in_its_help() {
    let dir = tempfile::tempdir().unwrap();
    let mut todo: Vec<Vec<String>> = vec![vec![]];
    let mut leaves = Vec::new();
    while let Some(cmd) = todo.pop() {
        let args: Vec<&str> = cmd.iter().map(String::as_str).chain(["--help"]).collect();
        let o = kinescan(dir.path(), &args);
        assert!(o.status.success(), "{cmd:?}: {}", text(&o));
        let sub = listed_commands(&text(&o));
        if sub.is_empty() {
            assert!(text(&o).contains("Example"), "{cmd:?}: {}", text(&o));
            leaves.push(cmd.join(" "));
        }
        todo.extend(sub.into_iter().map(|s| [cmd.clone(), vec![s]].concat()));
    }
    // Nine top-level commands and calibrate's four subcommands (a help format change that
    // hid the lists would otherwise check nothing).
    assert!(leaves.len() >= 13, "{leaves:?}");
    assert!(
        leaves.iter().any(|l| l == "calibrate simulate-tripod"),
        "{leaves:?}"
    );
}

#[test]
fn calibrate_latency_end_to_end_from_a_simulated_table() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/calib_sim_table.toml");
    let o = kinescan(
        dir.path(),
        &[
            "--quiet",
            "calibrate",
            "simulate-table",
            cfg.to_str().unwrap(),
            "--out",
            "table",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    let o = kinescan(
        dir.path(),
        &[
            "calibrate",
            "latency",
            "table/calib_latency.toml",
            "--out",
            "res",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let (tau, sigma) = (
        v["latency_s"].as_f64().unwrap(),
        v["sigma_latency_s"].as_f64().unwrap(),
    );
    // The scenario injects 4.21 ms; 4 sigma covers a seed's scatter; the sigma bounded
    // (0.050 ms measured: calib_e2e's scenario) so it cannot grow to cover an error.
    assert!((tau - 0.00421).abs() < 4.0 * sigma, "{tau} +- {sigma}");
    assert!(sigma > 0.02e-3 && sigma < 0.1e-3, "sigma {sigma} s");
    assert!(dir.path().join("res/latency.json").exists());
}

/// Issue #24's messages, each read back in its new wording (each assertion fails on the old
/// text quoted beside it).
#[test]
fn messages_say_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    survey(d);
    // Was: "expected internally tagged enum FrameConfig".
    let o = kinescan(
        d,
        &["validate", "pipeline.toml", "--set", "output.frame=\"utm\""],
    );
    let e = text(&o);
    assert!(!o.status.success(), "{e}");
    assert!(
        e.contains("output.frame") && e.contains("frame = { kind = \"utm\" }"),
        "{e}"
    );
    assert!(!e.contains("internally tagged"), "{e}");
    // Was: "pipeline.toml: inputs: pipeline.toml: key `output.geoid`: ...".
    let o = kinescan(
        d,
        &[
            "validate",
            "pipeline.toml",
            "--set",
            "output.geoid=\"none.gtx\"",
        ],
    );
    let e = text(&o);
    assert!(!o.status.success() && e.contains("none.gtx"), "{e}");
    assert_eq!(e.matches("pipeline.toml").count(), 1, "{e}");
    // Was: "(7.73 M returns/s on 1 threads)" and indicatif's "7,728,778.1459/s".
    let o = kinescan(d, &["run", "pipeline.toml", "--threads", "1"]);
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    assert!(out.contains(" returns/s on 1 thread)"), "{out}");
    let rate = out
        .split(" rejected (")
        .nth(1)
        .and_then(|r| r.split(" returns/s").next())
        .unwrap();
    let digits = rate.chars().filter(char::is_ascii_digit).count();
    assert!(digits <= 3 && !rate.contains(','), "rate `{rate}`");
    // Was: "unknown field `day`" alone.
    std::fs::write(
        d.join("night.toml"),
        "[day]\ntemplate = \"pipeline.toml\"\nout = \"n\"\n",
    )
    .unwrap();
    let o = kinescan(d, &["run", "night.toml"]);
    let e = text(&o);
    assert!(
        !o.status.success() && e.contains("kinescan day night.toml"),
        "{e}"
    );
    // Was: JSON from `import` while `info` printed text.
    std::fs::write(
        d.join("p.csv"),
        "profile,beta_rad,range_m,intensity\n0,0.1,5.5,3\n1,0.2,,4\n",
    )
    .unwrap();
    let o = kinescan(d, &["import", "p.csv", "p.ksprof"]);
    let imported = text(&o);
    assert!(o.status.success(), "{imported}");
    let info = text(&kinescan(d, &["info", "p.ksprof"]));
    assert!(
        imported.ends_with(&info),
        "import:\n{imported}\ninfo:\n{info}"
    );
    assert!(!imported.contains('{'), "{imported}");
    let o = kinescan(d, &["import", "p.csv", "q.ksprof", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["records"], 2);
    // Was: "(paper 000)", "(paper 002)", "(conventions §6)".
    for args in [
        vec!["calibrate", "--help"],
        vec!["calibrate", "latency", "--help"],
        vec!["calibrate", "boresight", "--help"],
        vec!["import", "--help"],
        vec!["--help"],
    ] {
        let help = text(&kinescan(d, &args));
        assert!(
            !help.contains("paper 0") && !help.contains('§'),
            "{args:?}: {help}"
        );
    }
    let help = text(&kinescan(d, &["calibrate", "latency", "--help"]));
    assert!(help.contains("docs/calibration.md"), "{help}");
    // Was: "(or `--duration`)" for the option --duration-s.
    let scenario = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/pipelines/scenario_survey_day.toml"
    ))
    .unwrap();
    assert!(
        scenario.contains("`--duration-s`") && !scenario.contains("`--duration`"),
        "{scenario}"
    );
}

/// `info` reads LAS, LAZ and COPC headers (was: "not recognised"), and prints the SBET's
/// attitude and rate ranges and the SMRMSG's RMS ranges.
#[test]
fn info_reads_point_clouds_and_trajectory_ranges() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    survey(d);
    for (format, file, kind) in [
        ("las", "out/day_pass1.las", "LAS point cloud"),
        ("laz", "out/day_pass1.laz", "LAZ point cloud"),
        ("copc", "out/day_pass1.copc.laz", "COPC point cloud"),
    ] {
        let set = format!("output.format=\"{format}\"");
        let o = kinescan(d, &["-q", "run", "pipeline.toml", "--set", &set]);
        assert!(o.status.success(), "{}", text(&o));
        let o = kinescan(d, &["info", file]);
        let t = text(&o);
        assert!(o.status.success(), "{t}");
        for want in [
            kind,
            "LAS 1.4, point format 6",
            "points 108000 (by return 1: 108000)",
            "CRS: WGS 84 / UTM zone 32N (EPSG:32632)",
            "extra dimensions (2): range, mirror_angle",
        ] {
            assert!(t.contains(want), "{format}: no `{want}` in\n{t}");
        }
        let o = kinescan(d, &["info", file, "--json"]);
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["las"]["points"], 108_000, "{format}");
        assert_eq!(v["las"]["crs"]["epsg"], 32632, "{format}");
        let (min, max) = (&v["las"]["min"], &v["las"]["max"]);
        for k in 0..3 {
            let (lo, hi) = (min[k].as_f64().unwrap(), max[k].as_f64().unwrap());
            assert!(
                lo.is_finite() && hi > lo,
                "{format}: axis {k}: {lo} .. {hi}"
            );
        }
    }
    // The synthetic trajectory rolls and pitches +-30 deg and turns through every heading.
    let t = text(&kinescan(d, &["info", "traj.sbet"]));
    assert!(
        t.contains("roll -") && t.contains("largest angular rate"),
        "{t}"
    );
    let o = kinescan(d, &["info", "traj.sbet", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let roll = &v["sbet"]["roll_deg"];
    let (lo, hi) = (roll[0].as_f64().unwrap(), roll[1].as_f64().unwrap());
    // 200 Hz samples of 30 sin(0.7 t): within 0.01 deg of the extremes.
    assert!(
        (lo + 30.0).abs() < 0.01 && (hi - 30.0).abs() < 0.01,
        "roll {lo} .. {hi}"
    );
    // Yaw rate 15 m/s on a 30 m circle: 0.5 rad/s = 28.65 deg/s.
    let z_rate = v["sbet"]["max_abs_rate_dps"][2].as_f64().unwrap();
    assert!((z_rate - 28.648).abs() < 0.01, "{z_rate}");
    let t = text(&kinescan(d, &["info", "traj.smrmsg"]));
    assert!(t.contains("attitude RMS roll 0.300 .. 0.300"), "{t}");
    assert!(t.contains("position RMS north"), "{t}");
}
