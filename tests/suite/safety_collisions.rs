//! No command may write over one of its inputs (by path, symbolic link or hard link), and no
//! two outputs may be one file: refused before any work, naming both keys, the input's bytes
//! unchanged (SHA-256 before and after).

use crate::common;

use crate::common::kinescan;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::process::Output;

fn sha256(path: &Path) -> Vec<u8> {
    Sha256::digest(std::fs::read(path).unwrap()).to_vec()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A survey with every pipeline input kind: SBET, SMRMSG, a binary and a CSV profile file,
/// sync points and targets.
fn survey(dir: &Path) {
    common::write_trajectory(dir);
    common::write_ring_profiles(&dir.join("pass1.ksprof"), 100..150);
    let mut csv = String::from("profile,beta_rad,range_m,intensity\n");
    for n in 200..250 {
        csv += &format!("{n},0.5,10.0,9\n");
    }
    std::fs::write(dir.join("pass2.csv"), csv).unwrap();
    std::fs::write(dir.join("points.csv"), "id,x_m,y_m,z_m\n").unwrap();
    std::fs::write(dir.join("targets.csv"), "id\n").unwrap();
    let pipeline = format!(
        "[inputs]\nsbet = \"traj.sbet\"\nsmrmsg = \"traj.smrmsg\"\n\
         profiles = [\"pass1.ksprof\", \"pass2.csv\"]\n\n\
         [sensor]\nlever_arm_b_m = [0.5, 0.0, -1.5]\n\n[time]\nt0_s = {}\nperiod_s = 0.01\n\n\
         [sync]\npoints = \"points.csv\"\ntargets = \"targets.csv\"\n\n\
         [output]\nlas = \"out/day.las\"\n",
        common::T_START_S
    );
    std::fs::write(dir.join("pipeline.toml"), pipeline).unwrap();
}

/// Every input of the survey, by the key that names it.
const INPUTS: [(&str, &str); 7] = [
    ("pipeline file", "pipeline.toml"),
    ("inputs.sbet", "traj.sbet"),
    ("inputs.smrmsg", "traj.smrmsg"),
    ("inputs.profiles[0]", "pass1.ksprof"),
    ("inputs.profiles[1]", "pass2.csv"),
    ("sync.points", "points.csv"),
    ("sync.targets", "targets.csv"),
];

/// Runs `run` and `validate` with `--set <out_key>=<out_path>`; both must refuse naming both
/// keys, and `input` must keep its bytes.
fn refused(dir: &Path, out_key: &str, out_path: &str, input_key: &str, input: &str) {
    let before = sha256(&dir.join(input));
    for cmd in ["run", "validate"] {
        let set = format!("{out_key}={out_path}");
        let o = kinescan(dir, &[cmd, "pipeline.toml", "--set", &set]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{cmd} {set} accepted: {e}");
        assert!(
            e.contains(&format!("`{out_key}`")) && e.contains(&format!("`{input_key}`")),
            "{cmd} {set}: the error must name both keys: {e}"
        );
        assert!(e.contains("is the same file as the input"), "{e}");
        assert_eq!(
            sha256(&dir.join(input)),
            before,
            "{cmd} {set} changed {input}"
        );
    }
}

#[test]
fn las_or_report_over_each_input_kind_is_refused_by_run_and_validate() {
    let dir = tempfile::tempdir().unwrap();
    survey(dir.path());
    for (key, file) in INPUTS {
        refused(dir.path(), "output.las", file, key, file);
        refused(dir.path(), "output.report", file, key, file);
    }
}

#[cfg(unix)]
#[test]
fn symbolic_and_hard_links_to_an_input_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    survey(dir.path());
    let d = dir.path();
    std::fs::create_dir(d.join("out")).unwrap();
    std::os::unix::fs::symlink(d.join("pass1.ksprof"), d.join("out/sym.las")).unwrap();
    std::fs::hard_link(d.join("traj.sbet"), d.join("out/hard.json")).unwrap();
    refused(
        d,
        "output.las",
        "out/sym.las",
        "inputs.profiles[0]",
        "pass1.ksprof",
    );
    refused(
        d,
        "output.report",
        "out/hard.json",
        "inputs.sbet",
        "traj.sbet",
    );
    // A profile input given through a link to the output is the same file too.
    std::os::unix::fs::symlink(d.join("pass1.ksprof"), d.join("link.ksprof")).unwrap();
    let before = sha256(&d.join("pass1.ksprof"));
    let o = kinescan(
        d,
        &[
            "run",
            "pipeline.toml",
            "--set",
            "inputs.profiles=[\"link.ksprof\"]",
            "--set",
            "output.las=pass1.ksprof",
        ],
    );
    assert!(!o.status.success() && stderr(&o).contains("inputs.profiles[0]"));
    assert_eq!(sha256(&d.join("pass1.ksprof")), before);
}

#[test]
fn outputs_colliding_with_each_other_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    survey(dir.path());
    let d = dir.path();
    // The report set to the LAS path.
    let o = kinescan(
        d,
        &[
            "validate",
            "pipeline.toml",
            "--set",
            "output.report=out/day.las",
        ],
    );
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(
        e.contains("`output.report`") && e.contains("`output.las`"),
        "{e}"
    );
    // Two profile files with one stem split per input: one output name for both.
    std::fs::create_dir(d.join("b")).unwrap();
    std::fs::copy(d.join("pass1.ksprof"), d.join("b/pass1.ksprof")).unwrap();
    let o = kinescan(
        d,
        &[
            "validate",
            "pipeline.toml",
            "--set",
            "inputs.profiles=[\"pass1.ksprof\", \"b/pass1.ksprof\"]",
            "--set",
            "output.split=\"per_input\"",
        ],
    );
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(
        e.contains("inputs.profiles[0]") && e.contains("inputs.profiles[1]"),
        "{e}"
    );
    assert!(e.contains("day_pass1.las"), "{e}");
}

#[test]
fn import_over_its_own_csv_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    survey(dir.path());
    let d = dir.path();
    let before = sha256(&d.join("pass2.csv"));
    let o = kinescan(d, &["import", "pass2.csv", "./pass2.csv"]);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(
        e.contains("CSV argument") && e.contains("OUTPUT argument"),
        "{e}"
    );
    assert_eq!(sha256(&d.join("pass2.csv")), before);
}

#[test]
fn simulate_calibrate_and_sensitivity_refuse_to_write_over_their_config() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    std::fs::create_dir(d.join("out")).unwrap();
    // Each config copied into the output folder under a name the command writes there.
    let cases = [
        (
            "simulate",
            "scenario_city_block.toml",
            "truth.json",
            "scenario file",
        ),
        (
            "calibrate simulate-table",
            "calib_sim_table.toml",
            "truth.json",
            "config file",
        ),
        (
            "calibrate simulate-tripod",
            "calib_sim_tripod.toml",
            "truth.json",
            "config file",
        ),
        (
            "calibrate latency",
            "calib_latency.toml",
            "latency.json",
            "config file",
        ),
        (
            "calibrate boresight",
            "calib_boresight.toml",
            "boresight.json",
            "config file",
        ),
        (
            "sensitivity",
            "sensitivity_parking_lot_expected.toml",
            "sensitivity.json",
            "config file",
        ),
    ];
    for (cmd, config, name, key) in cases {
        let target = d.join("out").join(name);
        std::fs::copy(root.join("pipelines").join(config), &target).unwrap();
        let before = sha256(&target);
        let mut args: Vec<&str> = cmd.split(' ').collect();
        let target_s = target.to_str().unwrap();
        args.extend([target_s, "--out", "out"]);
        let o = kinescan(d, &args);
        let e = stderr(&o);
        assert!(!o.status.success(), "{cmd}: {e}");
        assert!(
            e.contains(&format!("`--out {name}`")) && e.contains(key),
            "{cmd}: {e}"
        );
        assert_eq!(sha256(&target), before, "{cmd} changed its config");
        std::fs::remove_file(&target).unwrap();
    }
}
