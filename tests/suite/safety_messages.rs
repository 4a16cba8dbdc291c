//! Messages a user can act on: the key, the file and line, said once; values that make no sense
//! refused; a file cut inside its last line refused.

use crate::common;

use crate::common::kinescan;
use kinescan::io::info::describe;
use kinescan::io::patches::read_patches;
use kinescan::io::points::read_control_points;
use kinescan::io::profiles::{ProfileColumns, ProfileWriter, RawReturn};
use kinescan::io::profiles_csv::import_csv;
use std::path::Path;

fn failure(dir: &Path, args: &[&str]) -> String {
    let o = kinescan(dir, args);
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "{args:?} accepted: {e}");
    e
}

#[test]
fn bad_values_name_their_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 10);
    let cases = [
        (
            "output.frame={kind=\"enu\",lat_deg=91,lon_deg=11,h_m=0}",
            "key `output.frame.lat_deg`: must be in [-90, 90] deg, got 91",
        ),
        (
            "output.frame={kind=\"enu\",lat_deg=48,lon_deg=400,h_m=0}",
            "key `output.frame.lon_deg`: must be in [-180, 180] deg, got 400",
        ),
        (
            "time.t0_s=nan",
            "key `time.t0_s`: must be a finite number, got NaN",
        ),
        (
            "time.period_s=1e-300",
            "key `time.period_s`: must be in [0.0001, 1] s, got 1e-300",
        ),
        (
            "sensor.lever_arm_b_m=[0,nan,0]",
            "key `sensor.lever_arm_b_m[1]`: must be a finite number, got NaN",
        ),
        (
            "latency.position_s=2",
            "key `latency.position_s`: must be finite and below 1 s in magnitude, got 2",
        ),
    ];
    for (set, want) in cases {
        for cmd in ["run", "validate"] {
            let e = failure(d, &[cmd, "pipeline.toml", "--set", set]);
            assert!(e.contains(want), "{cmd} --set {set}: `{e}` lacks `{want}`");
        }
    }
    let e = failure(d, &["run", "pipeline.toml", "--threads", "0"]);
    assert!(e.contains("--threads") && e.contains("at least 1"), "{e}");
    let e = failure(
        d,
        &[
            "run",
            "pipeline.toml",
            "--set",
            "time.model=\"hardware_return\"",
        ],
    );
    assert!(
        e.contains("time.model = \"hardware_return\"") && e.contains("pass.ksprof"),
        "{e}"
    );
    assert!(!e.contains("HardwareReturn"), "{e}");
}

#[test]
fn os_errors_are_printed_once() {
    let dir = tempfile::tempdir().unwrap();
    let e = failure(dir.path(), &["run", "missing.toml"]);
    assert_eq!(e.matches("No such file").count(), 1, "{e}");
    assert!(e.contains("missing.toml"), "{e}");
}

#[test]
fn a_directory_given_as_a_profile_file_is_called_a_directory() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 10);
    std::fs::create_dir(d.join("pass_dir.ksprof")).unwrap();
    let e = failure(
        d,
        &[
            "validate",
            "pipeline.toml",
            "--set",
            "inputs.profiles=[\"pass_dir.ksprof\"]",
        ],
    );
    assert!(
        e.contains("pass_dir.ksprof") && e.contains("is a directory"),
        "{e}"
    );
    let e = failure(d, &["info", "pass_dir.ksprof"]);
    assert!(
        e.contains("pass_dir.ksprof") && e.contains("directory"),
        "{e}"
    );
}

#[test]
fn info_counts_an_invalid_range_as_run_does() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("p.ksprof");
    let mut w = ProfileWriter::create(&p, ProfileColumns::default()).unwrap();
    for (k, range_m) in [10.0, -1.0, 10.0, f64::NAN].into_iter().enumerate() {
        w.push(&RawReturn {
            profile: k as u32,
            range_m,
            ..Default::default()
        })
        .unwrap();
    }
    w.finish().unwrap();
    let i = describe(&p).unwrap();
    assert_eq!(i.records, 4);
    let prof = i.profiles.as_ref().unwrap();
    assert_eq!(prof.invalid_returns, 2);
    assert_eq!(prof.tally.returns, 2);
    let first = prof.first_invalid.as_deref().unwrap();
    assert!(
        first.contains("record 1") && first.contains("negative"),
        "{first}"
    );
    assert!(
        i.to_string()
            .contains("invalid returns (rejected by run) 2"),
        "{i}"
    );
}

/// Writes `text` and returns its path.
fn file(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_file_cut_inside_its_last_line_is_refused_naming_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let want = |e: kinescan::Error, name: &str, line: &str| {
        let e = e.to_string();
        assert!(
            e.contains(name) && e.contains(line) && e.contains("no newline"),
            "{e}"
        );
    };
    // Intensity 13105 cut to 131: the line still parses, so only the missing newline tells.
    let csv = file(
        d,
        "cut.csv",
        "profile,beta_rad,range_m,intensity\n1,0.1,5,13105\n2,0.1,5,131",
    );
    want(
        import_csv(&csv, &d.join("cut.ksprof")).unwrap_err(),
        "cut.csv",
        "line 3",
    );
    assert!(!d.join("cut.ksprof").exists());
    want(describe(&csv).unwrap_err(), "cut.csv", "line 3");
    let points = file(
        d,
        "points.csv",
        "id,lat_deg,lon_deg,h_m,sigma_m\na,48.1,11.5,520,0.01\nb,48.1,11.5,520,0.0",
    );
    want(
        read_control_points(&points).unwrap_err(),
        "points.csv",
        "line 3",
    );
    let head = kinescan::io::patches::PATCHES_HEADER.join(",");
    let patches = file(
        d,
        "patches.csv",
        &format!("{head}\nf,48.1,11.5,520,0,0,1,2,0.0"),
    );
    want(read_patches(&patches).unwrap_err(), "patches.csv", "line 2");
    // With its newline the same line is accepted.
    let whole = file(
        d,
        "whole.csv",
        "profile,beta_rad,range_m,intensity\n1,0.1,5,131\n",
    );
    import_csv(&whole, &d.join("whole.ksprof")).unwrap();
}

#[test]
fn a_utm_frame_far_from_the_data_is_refused_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 10); // 11.575 E, 48.137 N: zone 32 (central meridian 9 E)
    let frame =
        |zone: u8, north: bool| format!("output.frame={{kind=\"utm\",zone={zone},north={north}}}");
    for cmd in ["run", "validate"] {
        let e = failure(d, &[cmd, "pipeline.toml", "--set", &frame(60, true)]);
        assert!(
            e.contains("key `output.frame.zone`") && e.contains("central meridian"),
            "{e}"
        );
        let e = failure(d, &[cmd, "pipeline.toml", "--set", &frame(32, false)]);
        assert!(e.contains("key `output.frame.north`"), "{e}");
    }
    // The neighbouring zone (central meridian 15 E, 3.4 deg away) is within the margin.
    let o = kinescan(d, &["validate", "pipeline.toml", "--set", &frame(33, true)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
