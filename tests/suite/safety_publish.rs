//! A run publishes its outputs only when it succeeded: a failed, empty or interrupted run
//! leaves the previous outputs exactly as they were.

use crate::common;

use crate::common::kinescan;
use kinescan::io::profiles::{ProfileColumns, ProfileWriter, RawReturn};
use std::path::Path;
use std::process::{Command, Output};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_run_that_writes_no_point_fails_and_keeps_the_old_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 50);
    assert!(kinescan(d, &["run", "pipeline.toml"]).status.success());
    let before = common::tree(&d.join("out"));
    // t0 far before the trajectory: every return falls outside it.
    let o = kinescan(d, &["run", "pipeline.toml", "--set", "time.t0_s=1000"]);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    // Named by its cause, the clock (issue #23: it blamed `output.allow_empty`).
    assert!(
        e.contains("time.t0_s") && e.contains("1800 returns") && !e.contains("allow_empty"),
        "{e}"
    );
    assert_eq!(
        common::tree(&d.join("out")),
        before,
        "the failed run changed the outputs"
    );
    // Allowed explicitly: an empty LAS and its report.
    let o = kinescan(
        d,
        &[
            "run",
            "pipeline.toml",
            "--set",
            "time.t0_s=1000",
            "--set",
            "output.allow_empty=true",
            "--set",
            "output.max_rejected_share=1",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_ne!(common::tree(&d.join("out")), before);
}

/// Writes a profile file of `profiles` profiles from counter 100 (36 returns each at 10 m);
/// `edit(record, &mut return)` may spoil some.
fn profiles(path: &Path, profiles: u32, edit: impl Fn(usize, &mut RawReturn)) {
    let mut w = ProfileWriter::create(path, ProfileColumns::default()).unwrap();
    let mut i = 0;
    for n in 100..100 + profiles {
        for k in 0..36 {
            let mut r = RawReturn {
                profile: n,
                beta_rad: (k as f64 * 10.0 - 180.0).to_radians(),
                range_m: 10.0,
                intensity: 7,
                ..Default::default()
            };
            edit(i, &mut r);
            w.push(&r).unwrap();
            i += 1;
        }
    }
    w.finish().unwrap();
}

/// Names in `dir` (sorted), the stem's lock file left out.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.ends_with(".kinescan-lock"))
        .collect();
    v.sort();
    v
}

/// No temporary file or staging folder of any kinescan process.
fn assert_no_temp(dir: &Path) {
    let temps: Vec<String> = names(dir)
        .into_iter()
        .filter(|n| n.contains(".kinescan-") || n.ends_with(".tmp"))
        .collect();
    assert!(
        temps.is_empty(),
        "temporaries left in {}: {temps:?}",
        dir.display()
    );
}

#[test]
fn a_run_failing_late_publishes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 1000); // 36,000 returns: three chunks of the executor
    let split = [
        "--set",
        "output.split=\"max_points\"",
        "--set",
        "output.max_points_per_file=5000",
    ];
    let mut args = vec!["run", "pipeline.toml"];
    args.extend(split);
    assert!(kinescan(d, &args).status.success());
    let before = common::tree(&d.join("out"));
    assert_eq!(before.len(), 9, "8 parts and the report: {before:?}");
    // A counter decrease in the last profile, after six parts are full.
    profiles(&d.join("late_decrease.ksprof"), 1000, |i, r| {
        if i >= 999 * 36 {
            r.profile = 50;
        }
    });
    // A negative range late, fatal with strictness = "fail".
    profiles(&d.join("late_bad.ksprof"), 1000, |i, r| {
        if i == 34_000 {
            r.range_m = -1.0;
        }
    });
    let cases = [
        (
            "inputs.profiles=[\"late_decrease.ksprof\"]",
            "output.strictness=\"count\"",
            "decreases",
        ),
        (
            "inputs.profiles=[\"late_bad.ksprof\"]",
            "output.strictness=\"fail\"",
            "record 34000",
        ),
    ];
    for (input, strictness, want) in cases {
        let mut a = args.clone();
        a.extend(["--set", input, "--set", strictness]);
        let o = kinescan(d, &a);
        let e = stderr(&o);
        assert!(!o.status.success() && e.contains(want), "{input}: {e}");
        assert_eq!(
            common::tree(&d.join("out")),
            before,
            "{input}: the failed run changed the outputs"
        );
        assert_no_temp(&d.join("out"));
    }
}

#[test]
fn a_rerun_with_fewer_split_files_removes_the_previous_ones() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 50);
    let run = |max: &str| {
        let max = format!("output.max_points_per_file={max}");
        let args = [
            "run",
            "pipeline.toml",
            "--set",
            "output.split=\"max_points\"",
            "--set",
            &max,
        ];
        let o = kinescan(d, &args);
        assert!(o.status.success(), "{}", stderr(&o));
    };
    run("300");
    assert_eq!(names(&d.join("out")).len(), 7);
    run("700");
    assert_eq!(
        names(&d.join("out")),
        [
            "day.report.json",
            "day_0001.las",
            "day_0002.las",
            "day_0003.las"
        ]
    );
}

#[test]
fn a_las_range_problem_names_the_csv_line_and_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 5);
    let mut csv = String::from("profile,beta_rad,range_m,intensity\n");
    for n in 100..105 {
        csv += &format!("{n},0.5,10.0,9\n\n");
    }
    std::fs::write(d.join("pass.csv"), csv).unwrap();
    // Offset 0 with 0.1 mm steps reaches 214 km: UTM northings (5,300 km) do not fit.
    let o = kinescan(
        d,
        &[
            "run",
            "pipeline.toml",
            "--set",
            "inputs.profiles=[\"pass.csv\"]",
            "--set",
            "output.offset_m=[0.0, 0.0, 0.0]",
        ],
    );
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(e.contains("pass.csv") && e.contains("line 2"), "{e}");
    assert!(
        e.contains("output.offset_m") && e.contains("output.scale_m"),
        "{e}"
    );
    assert!(
        !e.contains("kinescan-") && !e.contains(".ksprof"),
        "an internal file named: {e}"
    );
}

/// A survey long enough to interrupt: 3,000,000 returns (15,000 profiles of 200 at 1 kHz)
/// with per-point uncertainty, run on one thread (several seconds).
fn long_survey(dir: &Path) {
    common::write_trajectory(dir);
    let mut w = ProfileWriter::create(&dir.join("long.ksprof"), ProfileColumns::default()).unwrap();
    for n in 0..15_000u32 {
        for k in 0..200 {
            w.push(&RawReturn {
                profile: n,
                beta_rad: (k as f64 * 1.8 - 180.0).to_radians(),
                range_m: 10.0,
                intensity: 7,
                ..Default::default()
            })
            .unwrap();
        }
    }
    w.finish().unwrap();
    let pipeline = format!(
        "[inputs]\nsbet = \"traj.sbet\"\nsmrmsg = \"traj.smrmsg\"\nprofiles = [\"long.ksprof\"]\n\n\
         [sensor]\nlever_arm_b_m = [0.5, 0.0, -1.5]\n\n[time]\nt0_s = {}\nperiod_s = 0.001\n\n\
         [output]\nlas = \"out/day.las\"\n\n[uncertainty]\nsigma_lever_arm_b_m = [0.002, 0.002, 0.002]\n\
         sigma_boresight_deg = [0.002, 0.002, 0.002]\nsigma_alpha_deg = 0.002\nsigma_beta_deg = 0.002\n\
         sigma_range_m = 0.004\nsigma_range_zero_m = 0.001\nclock_covariance_s2 = [[1e-10, 0.0], [0.0, 1e-16]]\n\
         sigma_attitude_latency_s = 0.0001\nwrite_95 = true\nwrite_shares = true\n",
        common::T_START_S + 0.5
    );
    std::fs::write(dir.join("long.toml"), pipeline).unwrap();
}

/// Starts `kinescan run long.toml --threads 1` and waits until it writes (its staging folder
/// exists in `out`).
fn start_long_run(d: &Path) -> std::process::Child {
    let child = Command::new(env!("CARGO_BIN_EXE_kinescan"))
        .args(["run", "long.toml", "--threads", "1", "--quiet"])
        .current_dir(d)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    while !names(&d.join("out"))
        .iter()
        .any(|n| n.contains(".kinescan-"))
    {
        assert!(
            started.elapsed().as_secs() < 60,
            "the run never started writing"
        );
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child
}

#[cfg(unix)]
#[test]
fn sigint_sigterm_and_sigkill_leave_the_old_outputs_and_no_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    long_survey(d);
    std::fs::create_dir(d.join("out")).unwrap();
    std::fs::write(d.join("out/day.las"), b"previous LAS").unwrap();
    std::fs::write(d.join("out/day.report.json"), b"{}").unwrap();
    let before = common::tree(&d.join("out"));
    for (signal, name) in [("-INT", "SIGINT"), ("-TERM", "SIGTERM")] {
        let child = start_long_run(d);
        let kill = Command::new("kill")
            .args([signal, &child.id().to_string()])
            .status();
        assert!(kill.unwrap().success());
        let o = child.wait_with_output().unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(130), "{name}: {e}");
        assert_eq!(e.lines().count(), 1, "{name}: one line: {e}");
        assert!(e.contains("interrupted"), "{name}: {e}");
        assert_eq!(
            common::tree(&d.join("out")),
            before,
            "{name} changed the outputs"
        );
        assert_no_temp(&d.join("out"));
    }
    // SIGKILL cannot be caught: the staging folder stays until the next run removes it.
    let mut child = start_long_run(d);
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(
        names(&d.join("out")).len(),
        3,
        "{:?}",
        names(&d.join("out"))
    );
    assert_eq!(
        common::tree(&d.join("out")),
        before,
        "SIGKILL changed the outputs"
    );
    let o = kinescan(d, &["run", "long.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_no_temp(&d.join("out"));
    assert_eq!(names(&d.join("out")), ["day.las", "day.report.json"]);
}

/// The X scale factor in a LAS header (bytes 131..139).
fn las_x_scale(path: &Path) -> f64 {
    let bytes = std::fs::read(path).unwrap();
    f64::from_le_bytes(bytes[131..139].try_into().unwrap())
}

#[test]
fn two_concurrent_runs_never_leave_a_las_and_a_report_of_different_runs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 300);
    let trials = 20;
    let (mut both_ran, mut refused) = (0, 0);
    for _ in 0..trials {
        // Two runs told apart by their coordinate scale (in the LAS header and the report).
        let spawn = |scale: &str| {
            Command::new(env!("CARGO_BIN_EXE_kinescan"))
                .args(["run", "pipeline.toml", "--quiet", "--set"])
                .arg(format!("output.scale_m={scale}"))
                .current_dir(d)
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        };
        let (a, b) = (spawn("0.0001"), spawn("0.0002"));
        let outs = [a.wait_with_output().unwrap(), b.wait_with_output().unwrap()];
        let ok = outs.iter().filter(|o| o.status.success()).count();
        assert!(
            ok >= 1,
            "neither run succeeded: {:?}",
            outs.map(|o| stderr(&o))
        );
        for o in outs.iter().filter(|o| !o.status.success()) {
            let e = stderr(o);
            assert!(e.contains("another kinescan run is writing"), "{e}");
            refused += 1;
        }
        both_ran += (ok == 2) as u32;
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(d.join("out/day.report.json")).unwrap()).unwrap();
        let reported = report["parameters"]["output"]["scale_m"].as_f64().unwrap();
        assert_eq!(
            las_x_scale(&d.join("out/day.las")),
            reported,
            "LAS and report of two runs"
        );
        assert_no_temp(&d.join("out"));
    }
    eprintln!(
        "{trials} races: {refused} runs refused by the lock, {both_ran} with both runs through"
    );
}

#[cfg(target_os = "linux")]
#[test]
fn a_full_disk_keeps_the_old_outputs_and_leaves_no_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    // 1 MiB: room for the first run's outputs (1,800 points), not for the second's (36,000).
    let Some(_tmpfs) = common::mount_tmpfs(&out, 1024, "a_full_disk_keeps_the_old_outputs") else {
        return;
    };
    common::one_pass_survey(d, 50);
    assert!(kinescan(d, &["run", "pipeline.toml"]).status.success());
    let before = common::tree(&out);
    profiles(&d.join("big.ksprof"), 1000, |_, _| {});
    let o = kinescan(
        d,
        &[
            "run",
            "pipeline.toml",
            "--set",
            "inputs.profiles=[\"big.ksprof\"]",
        ],
    );
    assert_full_disk_kept(&o, &out, "out/day.las", &before);
}

/// A run that failed on a full disk: exit non-zero, the message names `file` (its user path,
/// never a temporary) with the OS's text once, the outputs in `out` are `before`, no temporary.
fn assert_full_disk_kept(o: &Output, out: &Path, file: &str, before: &[(String, Vec<u8>)]) {
    let e = stderr(o);
    assert!(!o.status.success(), "{e}");
    assert!(
        e.contains(file) && e.matches("No space left").count() == 1,
        "{e}"
    );
    assert!(!e.contains(".kinescan-"), "a temporary named: {e}");
    assert_eq!(
        common::tree(out),
        before,
        "the failed run changed the outputs"
    );
    assert_no_temp(out);
}

/// The disk fills at the report: a tmpfs sized from a first run's measured LAS and report so
/// that the old outputs and the new LAS fit but the new report does not (it gets half its
/// pages). The run fails naming the report, the old LAS and report stay byte for byte, no
/// temporary is left, and the next run that fits publishes.
#[cfg(target_os = "linux")]
#[test]
fn a_disk_full_at_the_report_keeps_the_old_las_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 50);
    assert!(kinescan(d, &["run", "pipeline.toml"]).status.success());
    let size = |f: &str| std::fs::metadata(d.join("out").join(f)).unwrap().len();
    let (las, report) = (
        common::pages(size("day.las")),
        common::pages(size("day.report.json")),
    );
    std::fs::remove_dir_all(d.join("out")).unwrap();
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    // Old LAS and report, the new LAS, and half the new report's pages.
    let kib = 4 * (2 * las + report + report / 2);
    let Some(_tmpfs) = common::mount_tmpfs(&out, kib, "a_disk_full_at_the_report") else {
        return;
    };
    assert!(kinescan(d, &["run", "pipeline.toml"]).status.success());
    let before = common::tree(&out);
    let o = kinescan(d, &["run", "pipeline.toml"]);
    assert_full_disk_kept(&o, &out, "out/day.report.json", &before);
    // The next run, with fewer points, fits and publishes its own set.
    profiles(&d.join("small.ksprof"), 10, |_, _| {});
    let small = [
        "run",
        "pipeline.toml",
        "--set",
        "inputs.profiles=[\"small.ksprof\"]",
    ];
    let o = kinescan(d, &small);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_ne!(common::tree(&out), before);
    assert_no_temp(&out);
}
