//! The LAS bytes of the round-trip cases and of a survey with per-point uncertainty are pinned
//! by their SHA-256, computed before the pipeline was restructured into stages: any change of
//! the output bytes (a refactor that reorders arithmetic, a changed header field or extra
//! dimension) fails here. A deliberate change of the output re-pins these hashes in the same
//! commit and says why.

use crate::common::write_trajectory;
use crate::pipeline_roundtrip::{clock, fixture};
use crate::uncertainty_pipeline::{write_pipeline, write_profiles, FULL};
use kinescan::io::profiles::{ProfileColumns, ProfileFile, ProfileWriter, RawReturn};
use kinescan::pipeline::config;
use kinescan::pipeline::{run, RunOptions};
use sha2::{Digest, Sha256};
use std::path::Path;

fn quiet(threads: usize) -> RunOptions {
    RunOptions {
        threads: Some(threads),
        progress: false,
        chunk_returns: 1000,
    }
}

/// Runs `pipeline` with `set` and gives the SHA-256 (hex) of the LAS it wrote at `las`.
fn las_sha256(pipeline: &Path, set: &[String], las: &Path) -> String {
    run(&config::load(pipeline, set).unwrap(), &quiet(2)).unwrap();
    let bytes = std::fs::read(las).unwrap();
    Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Writes copies of `pass1.ksprof` with hardware time tags, per return and per profile.
fn write_tagged(d: &Path) {
    let src = ProfileFile::open(&d.join("pass1.ksprof")).unwrap();
    let c = clock();
    let cols = ProfileColumns {
        alpha: true,
        time: true,
    };
    let mut per_return = ProfileWriter::create(&d.join("ret.ksprof"), cols).unwrap();
    let mut per_profile = ProfileWriter::create(&d.join("prof.ksprof"), cols).unwrap();
    for i in 0..src.len() {
        let r = src.get(i);
        let t_n = c.t0_s + c.period_s * r.profile as f64;
        per_profile.push(&RawReturn { time_s: t_n, ..r }).unwrap();
        let time_s = c.time_of(r.profile, r.beta_rad);
        per_return.push(&RawReturn { time_s, ..r }).unwrap();
    }
    per_return.finish().unwrap();
    per_profile.finish().unwrap();
}

#[test]
fn round_trip_las_bytes_are_unchanged() {
    let f = fixture(3_000);
    let d = f.dir.path();
    kinescan::io::profiles_csv::export_csv(&d.join("pass1.ksprof"), &d.join("pass1.csv")).unwrap();
    write_tagged(d);
    let enu = "output.frame={ kind = \"enu\", lat_deg = 48.5, lon_deg = 9.0, h_m = 500.0 }";
    // The CSV input and per-return hardware tags equal to the software clock's times give
    // the same bytes as the binary software-clock case.
    let cases: [(&str, Vec<&str>, &str); 7] = [
        (
            "utm",
            vec![],
            "a6a66b16bfc0180876d2e299373b7cf6f98dee4db22a9a58ac3744f7b2fe25bf",
        ),
        (
            "ecef",
            vec!["output.frame={ kind = \"ecef\" }"],
            "5b3a8941c6e93542aae659b28eb29cc0c7a6f60bd3df0f91ae03c78091bb31fd",
        ),
        (
            "enu",
            vec![enu],
            "ad733121dbeaa613c6c04e9d1489312643fdb0aaf50954939fcbcd72b38b2431",
        ),
        (
            "csv",
            vec!["inputs.profiles=[\"pass1.csv\"]"],
            "a6a66b16bfc0180876d2e299373b7cf6f98dee4db22a9a58ac3744f7b2fe25bf",
        ),
        (
            "hardware_return",
            vec![
                "inputs.profiles=[\"ret.ksprof\"]",
                "time.model=\"hardware_return\"",
            ],
            "a6a66b16bfc0180876d2e299373b7cf6f98dee4db22a9a58ac3744f7b2fe25bf",
        ),
        (
            "hardware_profile",
            vec![
                "inputs.profiles=[\"prof.ksprof\"]",
                "time.model=\"hardware_profile\"",
            ],
            "3df730679c1a1d853677753cc6d0d7497fb4a2a112ed0b5f564b74e6b2472b67",
        ),
        (
            "return_index",
            vec!["output.return_index_dimension=true"],
            "ad6bafddd9fdd450f1ef18cff3306bb466cfb80088a0f5f4cc7a131141eac570",
        ),
    ];
    let mut failed = Vec::new();
    for (name, set, expect) in cases {
        let las = format!("out/{name}.las");
        let mut set: Vec<String> = set.into_iter().map(String::from).collect();
        set.push(format!("output.las=\"{las}\""));
        let got = las_sha256(&d.join("pipeline.toml"), &set, &d.join(&las));
        println!("{name}: {got}");
        if got != expect {
            failed.push(format!("{name}: {got}, pinned {expect}"));
        }
    }
    assert!(failed.is_empty(), "LAS bytes changed: {failed:#?}");
}

#[test]
fn uncertainty_las_bytes_are_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    write_trajectory(dir.path());
    write_profiles(&dir.path().join("pass.ksprof"), 2);
    let path = write_pipeline(dir.path(), "traj.smrmsg", FULL);
    let got = las_sha256(&path, &[], &dir.path().join("out/cloud.las"));
    println!("uncertainty: {got}");
    assert_eq!(
        got, "03defcf938616a79c9dbde5f0136e024391bc463309f4d1a96b1b6470df79a38",
        "LAS bytes with write_95 and write_shares changed"
    );
}
