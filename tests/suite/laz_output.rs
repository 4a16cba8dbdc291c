//! LAZ output: the compressed file holds the LAS's header, VLRs and point records, restored
//! byte for byte by the `laz` crate's sequential decompressor (an independent path from the
//! parallel compressor). Set `KINESCAN_LAZ_OUT=/dir` to keep `cloud.las` and `cloud.laz` for
//! `python3 tests/laz_check.py` (laspy with the lazrs backend, run in CI).

use std::path::Path;

use kinescan::io::las::{
    ExtraDim, GpsTimeConvention, LasPoint, LasWriter, LasWriterConfig, PointLayout, MAX_EXTRA_DIMS,
};
use kinescan::io::laz::{compress_las, CHUNK_POINTS};
use kinescan::pipeline::{config, run, RunOptions};

const OFFSET_M: [f64; 3] = [691_000.0, 5_335_000.0, 500.0];

/// A deterministic cloud with four extra dimensions, more than two LASzip chunks.
pub fn write_las(path: &Path, n: usize) {
    let dims = vec![
        ExtraDim::f32("sigma_x", "1-sigma along X (m)"),
        ExtraDim::f32("sigma_y", "1-sigma along Y (m)"),
        ExtraDim::f32("sigma_z", "1-sigma along Z (m)"),
        ExtraDim::f64("range", "scanner range (m)"),
    ];
    let time = GpsTimeConvention::AdjustedStandard { gps_week: 2398 };
    let cfg = LasWriterConfig {
        layout: PointLayout::new(OFFSET_M, time, dims).unwrap(),
        wkt: kinescan::geo::projection::MapFrame::utm(32, true)
            .unwrap()
            .wkt(),
        system_identifier: "kinescan test".into(),
        file_source_id: 3,
        creation_day_of_year: 327,
        creation_year: 2026,
    };
    let mut rng = crate::common::Lcg(5);
    let points: Vec<LasPoint> = (0..n)
        .map(|i| {
            let s = i as f64 * 0.01;
            let mut extra = [0.0; MAX_EXTRA_DIMS];
            extra[..4].copy_from_slice(&[
                0.005 + 0.01 * rng.uniform(),
                0.005 + 0.01 * rng.uniform(),
                0.01 + 0.02 * rng.uniform(),
                2.0 + 60.0 * rng.uniform(),
            ]);
            LasPoint {
                x: OFFSET_M[0] + 30.0 * s.sin() + rng.range(-0.5, 0.5),
                y: OFFSET_M[1] + s,
                z: OFFSET_M[2] + 10.0 * (0.3 * s).cos() + rng.range(-0.1, 0.1),
                intensity: (rng.uniform() * 4000.0) as u16,
                return_number: 1,
                number_of_returns: 1,
                scan_angle_deg: rng.range(-90.0, 90.0),
                gps_time: 345_600.0 + i as f64 * 2e-6,
                point_source_id: 1,
                classification: 0,
                user_data: 0,
                extra,
            }
        })
        .collect();
    let mut w = LasWriter::create(path, cfg).unwrap();
    w.write_points(&points).unwrap();
    w.finish().unwrap();
}

fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes(b[i..i + 4].try_into().unwrap())
}

/// (offset to points, the laszip VLR's data) of a LAZ file.
fn laszip_vlr(b: &[u8]) -> (usize, Vec<u8>) {
    let mut at = 375;
    for _ in 0..u32_at(b, 100) {
        let record_id = u16::from_le_bytes([b[at + 18], b[at + 19]]);
        let len = usize::from(u16::from_le_bytes([b[at + 20], b[at + 21]]));
        if record_id == 22204 {
            return (u32_at(b, 96) as usize, b[at + 54..at + 54 + len].to_vec());
        }
        at += 54 + len;
    }
    panic!("no laszip VLR");
}

/// The LAZ `b` holds the LAS `a`: the same header except the point offset, the VLR count and
/// the compression bit, the same VLRs, and records restored byte for byte by the `laz` crate's
/// sequential decompressor.
fn assert_restores(a: &[u8], b: &[u8]) {
    // Header: only the point offset, the VLR count and the compression bit differ.
    let las_offset = u32_at(a, 96) as usize;
    assert_eq!(a[..96], b[..96]);
    assert_eq!(u32_at(b, 100), u32_at(a, 100) + 1);
    assert_eq!(b[104], a[104] | 0x80);
    assert_eq!(a[105..375], b[105..375]);
    assert_eq!(a[375..las_offset], b[375..las_offset], "VLRs kept");
    let (laz_offset, vlr) = laszip_vlr(b);
    let vlr = laz::LazVlr::from_buffer(&vlr).unwrap();
    let mut records = vec![0u8; a.len() - las_offset];
    // The chunk table offset is absolute in the file: decompress from the file, not a slice.
    let mut file = std::io::Cursor::new(b);
    file.set_position(laz_offset as u64);
    let mut decompressor = laz::LasZipDecompressor::new(file, vlr).unwrap();
    laz::LazDecompressor::decompress_many(&mut decompressor, &mut records).unwrap();
    assert!(records == a[las_offset..], "decompressed records differ");
}

#[test]
fn laz_restores_the_las_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let keep = std::env::var_os("KINESCAN_LAZ_OUT");
    let out = keep.as_deref().map_or(dir.path(), Path::new);
    let (las, laz) = (out.join("cloud.las"), out.join("cloud.laz"));
    let n = 2 * CHUNK_POINTS as usize + 1234;
    write_las(&las, n);
    let summary = compress_las(&las, &laz).unwrap();
    let (a, b) = (std::fs::read(&las).unwrap(), std::fs::read(&laz).unwrap());
    assert_eq!(summary.point_count, n as u64);
    assert_eq!(summary.laz_bytes, b.len() as u64);
    println!(
        "{n} points: LAS {} bytes, LAZ {} bytes ({:.1} %)",
        a.len(),
        b.len(),
        100.0 * b.len() as f64 / a.len() as f64
    );
    assert_restores(&a, &b);
    // Same input, same bytes.
    let again = out.join("again.laz");
    compress_las(&las, &again).unwrap();
    assert!(std::fs::read(&again).unwrap() == b);
}

#[test]
fn laz_refuses_a_file_that_is_not_our_las() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.las");
    std::fs::write(&bad, b"LASF but not really").unwrap();
    let err = compress_las(&bad, &dir.path().join("bad.laz")).unwrap_err();
    assert!(err.to_string().contains("bad.las"), "{err}");
    assert!(!dir.path().join("bad.laz").exists());
}

/// Runs the round-trip fixture of `rows` returns with full uncertainty twice: as LAS
/// (`out/cloud.las`), then in `format` as `out/<stem>.las`; the second run's report.
pub fn run_las_and(
    rows: usize,
    format: &str,
    stem: &str,
) -> (
    crate::pipeline_roundtrip::Fixture,
    kinescan::pipeline::report::RunReport,
) {
    let f = crate::pipeline_roundtrip::fixture(rows);
    let path = f.dir.path().join("pipeline.toml");
    let mut text = std::fs::read_to_string(&path).unwrap();
    text.push_str(crate::uncertainty_pipeline::FULL);
    std::fs::write(&path, text).unwrap();
    let opts = RunOptions {
        threads: Some(2),
        progress: false,
        chunk_returns: 1000,
    };
    run(&config::load(&path, &[]).unwrap(), &opts).unwrap();
    let set = [
        format!("output.format = \"{format}\""),
        format!("output.las = \"out/{stem}.las\""),
    ];
    let report = run(&config::load(&path, &set).unwrap(), &opts).unwrap();
    (f, report)
}

/// `output.format = "laz"` (more than one LASzip chunk): the run publishes `<stem>.laz` (no LAS
/// beside it) holding exactly
/// the LAS the same run writes with `format = "las"`, extra dimensions included; the report
/// names the LAZ, its size and the compression stage. With `KINESCAN_LAZ_OUT` set, both files
/// are kept as `pipeline.las` and `pipeline.laz` for tests/laz_check.py (laspy, in CI).
#[test]
fn pipeline_writes_laz_holding_the_same_las() {
    let (f, report) = run_las_and(CHUNK_POINTS as usize + 5_000, "laz", "packed");
    let out = f.dir.path().join("out");
    assert!(!out.join("packed.las").exists(), "the LAS is not published");
    let (las, laz) = (out.join("cloud.las"), out.join("packed.laz"));
    let (a, b) = (std::fs::read(&las).unwrap(), std::fs::read(&laz).unwrap());
    assert_eq!(report.outputs.len(), 1);
    assert_eq!(report.outputs[0].path, laz);
    assert_eq!(report.outputs[0].bytes, b.len() as u64);
    assert!(report.stages.iter().any(|s| s.stage == "compress"));
    assert_restores(&a, &b);
    if let Some(keep) = std::env::var_os("KINESCAN_LAZ_OUT") {
        std::fs::copy(&las, Path::new(&keep).join("pipeline.las")).unwrap();
        std::fs::copy(&laz, Path::new(&keep).join("pipeline.laz")).unwrap();
    }
}
