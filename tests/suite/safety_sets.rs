//! Every command publishes its folder as one set (docs/robustness.md): a command that cannot
//! write its whole set fails naming a file of its output folder and leaves the previous set
//! byte for byte, with no temporary. The disk (a tmpfs) holds the previous set, its largest
//! file again and half of the rest: enough for a command that replaces its files one by one
//! (so such a command would succeed and fail the test), not for a second whole set. The second
//! run uses another seed, so its files differ from the first's: a file replaced before the
//! failure would show in the tree's hashes.
#![cfg(target_os = "linux")]

use kinescan::calib::latency::run_latency_calibration;
use kinescan::calib::sim_table::run_table_simulation;
use kinescan::sim::{simulate_scenario, Scenario, SimOptions};
use std::path::{Path, PathBuf};

/// Runs `command(seed, out)` once to size the set, then on the tmpfs described above: seed 1
/// succeeds, seed 2 must fail and leave seed 1's set as it was.
fn keeps_previous_set(
    test: &str,
    out: &Path,
    command: impl Fn(u64, &Path) -> kinescan::Result<()>,
) {
    command(1, out).unwrap();
    let pages: Vec<u64> = std::fs::read_dir(out)
        .unwrap()
        .map(|e| crate::common::pages(e.unwrap().metadata().unwrap().len()))
        .collect();
    let (set, largest) = (
        pages.iter().sum::<u64>(),
        crate::common::max_of(pages.iter().map(|&p| p as f64)) as u64,
    );
    std::fs::remove_dir_all(out).unwrap();
    std::fs::create_dir(out).unwrap();
    let kib = 4 * (set + largest + (set - largest) / 2);
    let Some(_tmpfs) = crate::common::mount_tmpfs(out, kib, test) else {
        return;
    };
    command(1, out).unwrap();
    let before = crate::common::tree(out);
    assert!(before.len() >= 3, "{before:?}");
    let e = command(2, out).unwrap_err().to_string();
    assert!(e.contains("No space left"), "{e}");
    assert!(
        e.contains(&*out.to_string_lossy()),
        "names no output file: {e}"
    );
    assert!(!e.contains(".kinescan-"), "a temporary named: {e}");
    assert_eq!(
        crate::common::tree(out),
        before,
        "{test}: previous set changed"
    );
}

fn pipelines(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("pipelines")
        .join(name)
}

/// `pipelines/calib_sim_table.toml` with another seed, written into `dir`.
fn table_config(dir: &Path, seed: u64) -> PathBuf {
    let text = std::fs::read_to_string(pipelines("calib_sim_table.toml")).unwrap();
    assert!(text.contains("\nseed = 1\n"));
    let path = dir.join(format!("table_{seed}.toml"));
    std::fs::write(
        &path,
        text.replace("\nseed = 1\n", &format!("\nseed = {seed}\n")),
    )
    .unwrap();
    path
}

#[test]
fn a_simulation_that_cannot_write_its_set_keeps_the_previous_one() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("survey");
    let mut sc = Scenario::load(&pipelines("scenario_city_block.toml")).unwrap();
    sc.duration_s = 4.0;
    let test = "a_simulation_that_cannot_write_its_set_keeps_the_previous_one";
    keeps_previous_set(test, &out, |seed, out| {
        let sc = Scenario { seed, ..sc.clone() };
        simulate_scenario(&sc, out, &SimOptions::default()).map(drop)
    });
}

#[test]
fn a_table_simulation_that_cannot_write_its_set_keeps_the_previous_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let test = "a_table_simulation_that_cannot_write_its_set_keeps_the_previous_one";
    keeps_previous_set(test, &d.join("table"), |seed, out| {
        run_table_simulation(&table_config(d, seed), out).map(drop)
    });
}

#[test]
fn a_latency_calibration_that_cannot_write_its_set_keeps_the_previous_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for seed in [1, 2] {
        run_table_simulation(&table_config(d, seed), &d.join(format!("lab{seed}"))).unwrap();
    }
    let test = "a_latency_calibration_that_cannot_write_its_set_keeps_the_previous_one";
    keeps_previous_set(test, &d.join("calib"), |seed, out| {
        let config = d.join(format!("lab{seed}")).join("calib_latency.toml");
        run_latency_calibration(&config, out).map(drop)
    });
}
