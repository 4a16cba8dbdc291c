//! Issue #23: implausible inputs refused at `validate` and before any output is touched, each
//! message naming the key or the file and record and the likely cause; and the messages the
//! issue found blaming the wrong thing. Each case failed on the code before the fix.

use crate::common::{self, kinescan, T_START_S};
use std::path::Path;
use std::process::Output;

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `o` failed and its message holds every one of `words` and none of `not`.
fn refused(o: &Output, words: &[&str], not: &[&str]) -> String {
    let e = stderr(o);
    assert!(!o.status.success(), "not refused: {e}");
    for w in words {
        assert!(e.contains(w), "`{w}` not in: {e}");
    }
    for w in not {
        assert!(!e.contains(w), "`{w}` (the wrong cause) in: {e}");
    }
    e
}

/// Rewrites SBET record `k` of `path` with `edit` applied to its 17 fields.
fn edit_sbet(path: &Path, k: usize, edit: impl Fn(&mut [f64; 17])) {
    let mut bytes = std::fs::read(path).unwrap();
    let rec = &mut bytes[k * 136..(k + 1) * 136];
    let mut f = [0.0; 17];
    for (i, v) in f.iter_mut().enumerate() {
        *v = f64::from_le_bytes(rec[8 * i..8 * i + 8].try_into().unwrap());
    }
    edit(&mut f);
    for (i, v) in f.iter().enumerate() {
        rec[8 * i..8 * i + 8].copy_from_slice(&v.to_le_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn a_gps_week_outside_the_gps_era_is_refused_by_validate() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    let o = kinescan(
        d,
        &[
            "validate",
            "pipeline.toml",
            "--set",
            "inputs.gps_week=3500000",
        ],
    );
    refused(&o, &["inputs.gps_week", "GPS era"], &[]);
    let o = kinescan(
        d,
        &["validate", "pipeline.toml", "--set", "inputs.gps_week=2394"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn t0_as_absolute_gps_time_is_refused_by_validate_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    let absolute = format!("time.t0_s={}", 2394.0 * 604_800.0 + T_START_S);
    for cmd in ["validate", "run"] {
        let o = kinescan(d, &[cmd, "pipeline.toml", "--set", &absolute]);
        refused(&o, &["time.t0_s", "absolute GPS time"], &["allow_empty"]);
    }
    assert!(!d.join("out/day.las").exists());
}

/// t0 one week early: every return outside the trajectory; the run names the clock and the
/// week (it blamed `output.allow_empty`).
#[test]
fn t0_in_the_wrong_week_is_named_by_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    let early = format!("time.t0_s={}", T_START_S - 604_800.0);
    let o = kinescan(d, &["run", "pipeline.toml", "--set", &early]);
    refused(
        &o,
        &["time.t0_s", "week", "nothing was published"],
        &["allow_empty"],
    );
    assert!(!d.join("out/day.las").exists());
}

/// 37% of a pass's returns after the trajectory's end: the run fails (it exited 0), names the
/// share, the clock and the limit, and publishes nothing; the limit raised, it runs.
#[test]
fn a_run_rejecting_more_than_max_rejected_share_fails_without_publishing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::write_trajectory(d);
    // Profiles 0..1000 at 0.01 s: 10 s, the last 3.7 s after the trajectory's end.
    common::write_ring_profiles(&d.join("pass.ksprof"), 0..1000);
    let t0 = T_START_S + common::DURATION_S - 6.3;
    let pipeline = format!(
        "[inputs]\nsbet = \"traj.sbet\"\nprofiles = [\"pass.ksprof\"]\n\n\
         [sensor]\nlever_arm_b_m = [0.5, 0.0, -1.5]\n\n[time]\nt0_s = {t0}\nperiod_s = 0.01\n\n\
         [output]\nlas = \"out/day.las\"\n"
    );
    std::fs::write(d.join("pipeline.toml"), pipeline).unwrap();
    let o = kinescan(d, &["run", "pipeline.toml"]);
    let e = refused(
        &o,
        &["time.t0_s", "max_rejected_share", "outside the trajectory"],
        &["allow_empty"],
    );
    assert!(e.contains("37.") || e.contains("36."), "{e}");
    assert!(!d.join("out/day.las").exists());
    let o = kinescan(
        d,
        &[
            "run",
            "pipeline.toml",
            "--set",
            "output.max_rejected_share=0.5",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("out/day.las").is_file());
}

/// An SBET record with height 1e7 m (or 1e300), a longitude jump, attitude in degrees: the
/// SBET and record are named by `validate`, `run` and `info` (they were blamed on the
/// profile file and `output.offset_m`, or on `output.frame.zone`).
#[test]
fn implausible_sbet_records_are_named_by_record() {
    type Edit = fn(&mut [f64; 17]);
    let cases: [(&str, Edit, &str); 5] = [
        ("altitude 1e7", |f| f[3] = 1e7, "altitude"),
        ("altitude 1e300", |f| f[3] = 1e300, "altitude"),
        ("longitude jump", |f| f[2] += 0.01, "position jumps"),
        ("heading in degrees", |f| f[9] = 200.0, "degrees"),
        ("roll in degrees", |f| f[7] = 25.0, "degrees"),
    ];
    for (case, edit, cause) in cases {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        common::one_pass_survey(d, 200);
        edit_sbet(&d.join("traj.sbet"), 1234, edit);
        for args in [
            &["validate", "pipeline.toml"][..],
            &["run", "pipeline.toml"],
            &["info", "traj.sbet"],
        ] {
            let o = kinescan(d, args);
            let e = stderr(&o) + &String::from_utf8_lossy(&o.stdout);
            assert!(
                e.contains("traj.sbet") && e.contains("record 123") && e.contains(cause),
                "{case}, {args:?}: {e}"
            );
            for wrong in ["offset_m", "frame.zone", "pass.ksprof"] {
                assert!(!e.contains(wrong), "{case}, {args:?}: {e}");
            }
        }
        assert!(!d.join("out/day.las").exists(), "{case}: run wrote outputs");
    }
}

/// Mirror angles in degrees (0..358.8) in a CSV profile file: refused at the line by
/// `import` and `validate`.
#[test]
fn mirror_angles_in_degrees_are_refused_at_their_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    let mut csv = String::from("profile,beta_rad,range_m,intensity\n");
    for n in 100..300 {
        for k in 0..300 {
            csv += &format!("{n},{},10.0,9\n", f64::from(k) * 1.2);
        }
    }
    std::fs::write(d.join("deg.csv"), csv).unwrap();
    let o = kinescan(d, &["import", "deg.csv", "deg.ksprof"]);
    refused(&o, &["deg.csv", "line 8", "beta_rad", "degrees"], &[]);
    assert!(!d.join("deg.ksprof").exists());
    let set = "inputs.profiles=[\"deg.csv\"]";
    let o = kinescan(d, &["validate", "pipeline.toml", "--set", set]);
    refused(&o, &["deg.csv", "beta_rad", "degrees"], &[]);
}

/// Mirror angles in degrees (0..358.8) in a binary profile file: refused naming the file and
/// record by `validate` and `run` (they ran into a wrong cloud) and by `info`.
#[test]
fn mirror_angles_in_degrees_are_refused_in_binary_profiles() {
    use kinescan::io::profiles::{ProfileColumns, ProfileWriter, RawReturn};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    let mut w = ProfileWriter::create(&d.join("deg.ksprof"), ProfileColumns::default()).unwrap();
    for n in 100..300 {
        for k in 0..300 {
            let r = RawReturn {
                profile: n,
                beta_rad: f64::from(k) * 1.2,
                range_m: 10.0,
                intensity: 9,
                ..Default::default()
            };
            w.push(&r).unwrap();
        }
    }
    w.finish().unwrap();
    let set = "inputs.profiles=[\"deg.ksprof\"]";
    for cmd in ["validate", "run"] {
        let o = kinescan(d, &[cmd, "pipeline.toml", "--set", set]);
        // Record 6 is the first beyond 2 pi (7.2); the sample reads every record of a file of
        // 60,000 (below ANGLE_SAMPLE_RECORDS).
        refused(&o, &["deg.ksprof", "record 6:", "beta_rad", "degrees"], &[]);
    }
    assert!(!d.join("out/day.las").exists());
    let o = kinescan(d, &["info", "deg.ksprof"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("record 6: beta_rad") && text.contains("degrees"),
        "{text}"
    );
}

/// A day pass with 30% of its returns after the trajectory's end (the limit is 5%): that pass
/// fails without publishing its file (a run would refuse it; the day published it), the other
/// pass is published, the morning report and the console name the pass and the cause, the
/// day exits with an error; with the template's limit raised, both are published.
#[test]
fn a_day_pass_rejecting_more_than_max_rejected_share_fails_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    // Profiles 1300..2300 at 0.01 s: 13 to 23 s of the 20 s trajectory, 3 s of 10 after it.
    common::write_ring_profiles(&d.join("late.ksprof"), 1300..2300);
    let day = "[day]\ntemplate = \"pipeline.toml\"\nout = \"night\"\nunit_s = 2.0\n\n\
               [[passes]]\nname = \"p01\"\nprofiles = [\"pass.ksprof\"]\n\n\
               [[passes]]\nname = \"p02\"\nprofiles = [\"late.ksprof\"]\n";
    std::fs::write(d.join("day.toml"), day).unwrap();
    let o = kinescan(d, &["day", "day.toml"]);
    let e = refused(
        &o,
        &[
            "pass p02",
            "% of the 36000 returns of pass p02 are rejected",
            "output.max_rejected_share = 0.05",
            "outside the trajectory",
            "not published",
        ],
        &["pass p01:"],
    );
    let out = d.join("night");
    assert!(out.join("p01.las").is_file(), "{e}");
    assert!(!out.join("p02.las").exists(), "{e}");
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        md.contains("pass p02 FAILED: ") && md.contains("its file is not published"),
        "{md}"
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("day.report.json")).unwrap()).unwrap();
    assert!(report["passes"][0].get("failed").is_none(), "{report}");
    assert!(report["passes"][1]["failed"].is_string(), "{report}");
    assert_eq!(report["outputs"].as_array().unwrap().len(), 1, "{report}");

    // The limit raised (a new template: a day folder's plan belongs to its template).
    let template = std::fs::read_to_string(d.join("pipeline.toml")).unwrap();
    // [output] is the template's last table.
    let raised = template + "max_rejected_share = 0.5\n";
    std::fs::write(d.join("raised.toml"), raised).unwrap();
    let day = day.replace("pipeline.toml", "raised.toml");
    std::fs::write(d.join("raised_day.toml"), day.replace("night", "raised")).unwrap();
    let o = kinescan(d, &["day", "raised_day.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = d.join("raised");
    assert!(out.join("p01.las").is_file() && out.join("p02.las").is_file());
}

/// `output.format = "laz"` with `output.las = out/x.laz`: the file the report lists exists
/// (it was removed after compression, exit 0).
#[test]
fn laz_output_named_laz_is_there() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    let o = kinescan(
        d,
        &[
            "run",
            "pipeline.toml",
            "--set",
            "output.format=\"laz\"",
            "--set",
            "output.las=\"out/x.laz\"",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("out/x.report.json")).unwrap()).unwrap();
    let listed = report["outputs"][0]["path"].as_str().unwrap();
    let bytes = report["outputs"][0]["bytes"].as_u64().unwrap();
    let file = d.join(listed);
    assert!(file.is_file(), "{listed} listed, not there");
    assert_eq!(std::fs::metadata(&file).unwrap().len(), bytes);
    let names: Vec<String> = std::fs::read_dir(d.join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.ends_with(".kinescan-lock"))
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

/// A second `day` on a folder another holds names the folder and the lock, not a
/// `night/day.las` that never exists.
#[test]
fn a_concurrent_day_refusal_names_the_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    let day = "[day]\ntemplate = \"pipeline.toml\"\nout = \"night\"\nunit_s = 1.0\n\n\
               [[passes]]\nname = \"p01\"\nprofiles = [\"pass.ksprof\"]\n";
    std::fs::write(d.join("day.toml"), day).unwrap();
    std::fs::create_dir(d.join("night")).unwrap();
    let lock = std::fs::File::create(d.join("night/.day.kinescan-lock")).unwrap();
    lock.try_lock().unwrap();
    let o = kinescan(d, &["day", "day.toml"]);
    refused(
        &o,
        &["another kinescan run", ".day.kinescan-lock", "night"],
        &["day.las"],
    );
}
