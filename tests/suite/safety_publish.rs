//! A run publishes its outputs only when it succeeded: a failed, empty or interrupted run
//! leaves the previous outputs exactly as they were.

use crate::common;

use kinescan::io::profiles::{ProfileColumns, ProfileWriter, RawReturn};
use sha2::{Digest, Sha256};
use std::path::Path;
use std::process::{Command, Output};

fn kinescan(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kinescan"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// SHA-256 of every file under `dir`, by relative path (sorted).
fn tree(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        let name = e.file_name().to_string_lossy().into_owned();
        if e.file_type().unwrap().is_dir() {
            for (n, h) in tree(&e.path()) {
                out.push((format!("{name}/{n}"), h));
            }
        } else {
            out.push((
                name,
                Sha256::digest(std::fs::read(e.path()).unwrap()).to_vec(),
            ));
        }
    }
    out.sort();
    out
}

/// A one-pass survey of `profiles` profiles (36 returns each at 10 m) and its pipeline.
fn survey(dir: &Path, profiles: u32) {
    common::write_trajectory(dir);
    let mut w = ProfileWriter::create(&dir.join("pass.ksprof"), ProfileColumns::default()).unwrap();
    for n in 100..100 + profiles {
        for k in 0..36 {
            w.push(&RawReturn {
                profile: n,
                beta_rad: (k as f64 * 10.0 - 180.0).to_radians(),
                range_m: 10.0,
                intensity: 7,
                ..Default::default()
            })
            .unwrap();
        }
    }
    w.finish().unwrap();
    let pipeline = format!(
        "[inputs]\nsbet = \"traj.sbet\"\nprofiles = [\"pass.ksprof\"]\n\n\
         [sensor]\nlever_arm_b_m = [0.5, 0.0, -1.5]\n\n[time]\nt0_s = {}\nperiod_s = 0.01\n\n\
         [output]\nlas = \"out/day.las\"\n",
        common::T_START_S
    );
    std::fs::write(dir.join("pipeline.toml"), pipeline).unwrap();
}

#[test]
fn a_run_that_writes_no_point_fails_and_keeps_the_old_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    survey(d, 50);
    assert!(kinescan(d, &["run", "pipeline.toml"]).status.success());
    let before = tree(&d.join("out"));
    // t0 far before the trajectory: every return falls outside it.
    let o = kinescan(d, &["run", "pipeline.toml", "--set", "time.t0_s=1000"]);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(
        e.contains("output.allow_empty") && e.contains("no point written from 1800"),
        "{e}"
    );
    assert_eq!(
        tree(&d.join("out")),
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
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_ne!(tree(&d.join("out")), before);
}
