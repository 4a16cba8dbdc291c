//! The one config loader (`io::config_file`) behind the four file kinds: a bad key names the file
//! and its full dotted key; every path a pipeline names is resolved against its folder.

use kinescan::calib::boresight::BoresightConfig;
use kinescan::calib::latency::LatencyConfig;
use kinescan::io::config_file;
use kinescan::{app::sensitivity::load_sensitivity, pipeline::config, sim::Scenario};
use std::path::{Path, PathBuf};

fn shipped(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("pipelines")
        .join(name);
    std::fs::read_to_string(path).unwrap()
}

type Loader = fn(&Path) -> kinescan::Result<()>;

fn pipeline(p: &Path) -> kinescan::Result<()> {
    config::load(p, &[]).map(drop)
}
fn scenario(p: &Path) -> kinescan::Result<()> {
    Scenario::load(p).map(drop)
}
fn latency(p: &Path) -> kinescan::Result<()> {
    config_file::load::<LatencyConfig>(p, &[]).map(drop)
}
fn boresight(p: &Path) -> kinescan::Result<()> {
    config_file::load::<BoresightConfig>(p, &[]).map(drop)
}
fn sensitivity(p: &Path) -> kinescan::Result<()> {
    load_sensitivity(p).map(drop)
}

#[test]
fn a_bad_key_in_each_file_kind_names_the_file_and_the_full_dotted_key() {
    let cases: [(&str, &str, &str, Loader, &str); 6] = [
        (
            "demo_city_block.toml",
            "boresight_deg = [0.0, 0.0, 0.0]",
            "boresight_deg = [0.0, 0.0, \"x\"]",
            pipeline,
            "sensor.boresight_deg[2]",
        ),
        (
            "scenario_city_block.toml",
            "[origin]",
            "[effects]\nclock_drift_ppm = \"fast\"\n[origin]",
            scenario,
            "effects.clock_drift_ppm",
        ),
        (
            "scenario_city_block.toml",
            "max_speed_mps = 11.0",
            "max_speed_mps = 11.0\nmax_sped_mps = 11.0",
            scenario,
            "route.max_sped_mps",
        ),
        (
            "calib_latency.toml",
            "gate_m = 0.05",
            "gate_m = [0.05]",
            latency,
            "sphere.gate_m",
        ),
        (
            "calib_boresight.toml",
            "axis_n = [0.0, 0.0, 1.0]",
            "axis_n = [0.0, 0.0]",
            boresight,
            "tripod.axis_n",
        ),
        (
            "sensitivity_parking_lot_expected.toml",
            "count = 60",
            "count = 60\ncolour = 1",
            sensitivity,
            "scenario.colour",
        ),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (name, from, to, load, key) in cases {
        let text = shipped(name);
        assert!(text.contains(from), "{name}: {from}");
        let path = dir.path().join(name);
        std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
        let msg = load(&path).unwrap_err().to_string();
        let expected = format!("{}: key `{key}`", path.display());
        assert!(msg.starts_with(&expected), "{name}: {msg}");
    }
}

/// String leaves of a TOML value that contain `marker`.
fn marked(v: &toml::Value, marker: &str, out: &mut Vec<String>) {
    match v {
        toml::Value::String(s) if s.contains(marker) => out.push(s.clone()),
        toml::Value::Array(a) => a.iter().for_each(|x| marked(x, marker, out)),
        toml::Value::Table(t) => t.values().for_each(|x| marked(x, marker, out)),
        _ => {}
    }
}

/// Every path key of a pipeline, given relative, comes back joined to the file's folder: the
/// loader resolves `ConfigPath`s by type, not from a list of keys.
#[test]
fn every_path_of_a_loaded_pipeline_is_resolved_against_its_folder() {
    let text = shipped("demo_city_block.toml")
        .replace("survey/", "rel_survey/")
        .replace(
            "las = \"out/",
            "report = \"rel_report.json\"\nlas = \"rel_out/",
        )
        + "[sync]\npoints = \"rel_points.csv\"\ntargets = \"rel_targets.csv\"\n\
           [diagnose]\npatches = \"rel_patches.csv\"\nout = \"rel_diag\"\n";
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pipeline.toml");
    std::fs::write(&path, &text).unwrap();
    let mut given = Vec::new();
    marked(
        &text.parse::<toml::Table>().unwrap().into(),
        "rel_",
        &mut given,
    );
    let loaded = config::load(&path, &[]).unwrap();
    let mut resolved = Vec::new();
    marked(
        &toml::Value::try_from(&loaded.config).unwrap(),
        "rel_",
        &mut resolved,
    );
    let mut expected: Vec<String> = given
        .iter()
        .map(|g| dir.path().join(g).display().to_string())
        .collect();
    expected.sort();
    resolved.sort();
    assert_eq!(given.len(), 9, "every path key of the test file is marked");
    assert_eq!(resolved, expected);
    assert!(resolved.iter().all(|p| PathBuf::from(p).is_absolute()));
}
