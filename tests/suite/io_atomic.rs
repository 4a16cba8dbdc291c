//! Every output kind goes through `io::atomic`: same permissions as an ordinarily created file,
//! no temporary left after success or after an error.

use kinescan::io::atomic::{write_atomic, write_json};
use kinescan::io::las::{GpsTimeConvention, LasPoint, LasWriter, LasWriterConfig, PointLayout};
use kinescan::plot::Plot;
use std::path::Path;

fn las_config() -> LasWriterConfig {
    let time = GpsTimeConvention::WeekSeconds;
    LasWriterConfig {
        layout: PointLayout::new([500_000.0, 5_000_000.0, 0.0], time, vec![]).unwrap(),
        wkt: "LOCAL_CS[\"test\"]".to_string(),
        system_identifier: "kinescan test".to_string(),
        file_source_id: 1,
        creation_day_of_year: 327,
        creation_year: 2026,
    }
}

fn write_las(path: &Path) {
    let mut w = LasWriter::create(path, las_config()).unwrap();
    let p = LasPoint {
        x: 500_001.0,
        y: 5_000_001.0,
        z: 1.0,
        return_number: 1,
        number_of_returns: 1,
        ..LasPoint::default()
    };
    w.write_points(&[p]).unwrap();
    w.finish().unwrap();
}

fn write_png(path: &Path) {
    Plot::new("modes", "x", "y")
        .line("l", &[(0.0, 0.0), (1.0, 1.0)])
        .save_png(path)
        .unwrap();
}

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[cfg(unix)]
#[test]
fn las_json_csv_png_outputs_have_the_mode_of_an_ordinary_file() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::File::create(d.join("plain")).unwrap();
    write_las(&d.join("a.las"));
    write_json(&d.join("a.json"), &serde_json::json!({"k": 1})).unwrap();
    write_atomic(&d.join("a.csv"), b"x,y\n1,2\n").unwrap();
    write_png(&d.join("a.png"));
    let mode = |n: &str| std::fs::metadata(d.join(n)).unwrap().permissions().mode() & 0o7777;
    for name in ["a.las", "a.json", "a.csv", "a.png"] {
        assert_eq!(mode(name), mode("plain"), "{name}: {:o}", mode(name));
    }
    assert_eq!(entries(d), ["a.csv", "a.json", "a.las", "a.png", "plain"]);
}

#[test]
fn no_temporary_left_after_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A LAS writer dropped before finish (a failed run) leaves nothing.
    let mut w = LasWriter::create(d.join("a.las"), las_config()).unwrap();
    w.write_points(&[LasPoint::default()]).unwrap_err();
    drop(w);
    // A rename onto a non-empty folder fails at publication, for every writer.
    for name in ["b.las", "b.json", "b.csv", "b.png"] {
        std::fs::create_dir_all(d.join(name).join("inside")).unwrap();
    }
    let mut w = LasWriter::create(d.join("b.las"), las_config()).unwrap();
    w.write_points(&[]).unwrap();
    let err = w.finish().unwrap_err().to_string();
    assert!(err.contains("b.las"), "{err}");
    write_json(&d.join("b.json"), &1).unwrap_err();
    write_atomic(&d.join("b.csv"), b"x\n").unwrap_err();
    let png = Plot::new("t", "x", "y").line("l", &[(0.0, 0.0), (1.0, 1.0)]);
    png.save_png(d.join("b.png")).unwrap_err();
    assert_eq!(entries(d), ["b.csv", "b.json", "b.las", "b.png"]);
}
