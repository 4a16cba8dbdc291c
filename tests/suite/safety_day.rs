//! Issue #23: `day` and `demo` keep the input promise of every other command (no output, and
//! no file a command removes, is an input, its config or outside its folder; a previous
//! report's list is a hint, never a licence to delete), a profile file given twice is refused,
//! `--threads` is clamped, and the staging folders of dead processes go. Each test reproduces
//! a case of the issue exactly (they failed on the code before the fix, see the commit).

use crate::common::{self, kinescan, tree};
use sha2::{Digest, Sha256};
use std::path::Path;
use std::process::Output;

fn sha256(path: &Path) -> Vec<u8> {
    Sha256::digest(std::fs::read(path).unwrap()).to_vec()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn ok(o: &Output) {
    assert!(o.status.success(), "kinescan failed: {}", stderr(o));
}

fn refused(o: &Output, words: &[&str]) -> String {
    let e = stderr(o);
    assert!(!o.status.success(), "not refused: {e}");
    for w in words {
        assert!(e.contains(w), "`{w}` not in: {e}");
    }
    e
}

/// The synthetic survey (`traj.sbet`, `pass.ksprof` of 200 profiles, `pipeline.toml`) and a
/// day file `day.toml` with one pass `p01` of `profiles` into `out`.
fn day_survey(dir: &Path, out: &str, profiles: &[&str]) {
    common::one_pass_survey(dir, 200);
    day_file(dir, out, profiles);
}

fn day_file(dir: &Path, out: &str, profiles: &[&str]) {
    let files: Vec<String> = profiles.iter().map(|f| format!("\"{f}\"")).collect();
    let text = format!(
        "[day]\ntemplate = \"pipeline.toml\"\nout = \"{out}\"\nunit_s = 1.0\n\n\
         [[passes]]\nname = \"p01\"\nprofiles = [{}]\n",
        files.join(", ")
    );
    std::fs::write(dir.join("day.toml"), text).unwrap();
}

#[test]
fn day_refuses_a_pass_output_over_a_profile_input_in_its_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    day_survey(d, "dsurv", &["dsurv/p01.las"]);
    std::fs::create_dir(d.join("dsurv")).unwrap();
    std::fs::copy(d.join("pass.ksprof"), d.join("dsurv/p01.las")).unwrap();
    let before = sha256(&d.join("dsurv/p01.las"));
    let o = kinescan(d, &["day", "day.toml"]);
    refused(&o, &["passes[0].profiles[0]", "p01.las", "same file"]);
    assert_eq!(sha256(&d.join("dsurv/p01.las")), before);
}

#[test]
fn day_refuses_a_template_where_the_morning_report_goes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    day_survey(d, "night", &["pass.ksprof"]);
    std::fs::create_dir(d.join("night")).unwrap();
    std::fs::rename(d.join("pipeline.toml"), d.join("night/report.md")).unwrap();
    let text = std::fs::read_to_string(d.join("day.toml")).unwrap();
    let text = text.replace("\"pipeline.toml\"", "\"night/report.md\"");
    std::fs::write(d.join("day.toml"), text).unwrap();
    let before = sha256(&d.join("night/report.md"));
    let o = kinescan(d, &["day", "day.toml"]);
    refused(&o, &["day.template", "report.md"]);
    assert_eq!(sha256(&d.join("night/report.md")), before);
}

/// A previous `day.report.json` edited to list the input SBET and a file outside the folder:
/// the next day deletes neither.
#[test]
fn day_removes_no_input_and_nothing_outside_its_folder_that_a_report_lists() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    day_survey(d, "night", &["pass.ksprof"]);
    ok(&kinescan(d, &["day", "day.toml"]));
    let outside = d.join("keep.txt");
    std::fs::write(&outside, b"not the day's").unwrap();
    let report = d.join("night/day.report.json");
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let outputs = json["outputs"].as_array_mut().unwrap();
    for p in [d.join("traj.sbet"), outside.clone(), d.join("pass.ksprof")] {
        outputs.push(serde_json::json!({"path": p, "points": 1}));
    }
    std::fs::write(&report, serde_json::to_vec(&json).unwrap()).unwrap();
    let inputs = [d.join("traj.sbet"), d.join("pass.ksprof"), outside];
    let before: Vec<Vec<u8>> = inputs.iter().map(|p| sha256(p)).collect();
    ok(&kinescan(d, &["day", "day.toml"]));
    let after: Vec<Vec<u8>> = inputs.iter().map(|p| sha256(p)).collect();
    assert_eq!(after, before);
    assert!(d.join("night/p01.las").is_file());
}

/// Day into `night1`, `cp -a night1 night2`, the day file pointed at `night2`, the refusal
/// followed (plan, journal and units removed), re-run: `night1` keeps its LAS file.
#[test]
fn a_copied_night_folder_never_deletes_the_original_nights_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    day_survey(d, "night1", &["pass.ksprof"]);
    ok(&kinescan(d, &["day", "day.toml"]));
    let night1 = tree(&d.join("night1"));
    assert!(night1.iter().any(|(n, _)| n == "p01.las"), "{night1:?}");
    let cp = std::process::Command::new("cp")
        .args(["-a", "night1", "night2"])
        .current_dir(d)
        .status()
        .unwrap();
    assert!(cp.success());
    day_file(d, "night2", &["pass.ksprof"]);
    if !kinescan(d, &["day", "day.toml"]).status.success() {
        std::fs::remove_file(d.join("night2/plan.json")).unwrap();
        std::fs::remove_file(d.join("night2/journal.jsonl")).unwrap();
        std::fs::remove_dir_all(d.join("night2/units")).unwrap();
        ok(&kinescan(d, &["day", "day.toml"]));
    }
    assert_eq!(tree(&d.join("night1")), night1);
    assert!(d.join("night2/p01.las").is_file());
}

/// `kinescan demo --out .` in a project folder refuses before touching anything.
#[test]
fn demo_refuses_a_folder_it_did_not_make() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("pipeline.toml"), "# a project's own pipeline\n").unwrap();
    std::fs::create_dir(d.join("survey")).unwrap();
    std::fs::write(d.join("survey/profiles.csv"), "profile,beta_rad\n").unwrap();
    let before = tree(d);
    let o = kinescan(d, &["demo", "--out", "."]);
    refused(&o, &["not made by `kinescan demo`", "--out"]);
    assert_eq!(tree(d), before);
}

/// The same profile file twice (by path, through a symbolic link, as a copy) in `run`,
/// `validate` and a `day` pass: refused, nothing written.
#[test]
fn a_profile_file_given_twice_is_refused_by_run_validate_and_day() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    day_survey(d, "night", &["pass.ksprof", "twin.ksprof"]);
    std::fs::copy(d.join("pass.ksprof"), d.join("copy.ksprof")).unwrap();
    std::os::unix::fs::symlink(d.join("pass.ksprof"), d.join("link.ksprof")).unwrap();
    for twin in ["pass.ksprof", "./pass.ksprof", "link.ksprof", "copy.ksprof"] {
        let set = format!("inputs.profiles=[\"pass.ksprof\", \"{twin}\"]");
        for cmd in ["run", "validate"] {
            let o = kinescan(d, &[cmd, "pipeline.toml", "--set", &set]);
            refused(&o, &["inputs.profiles[1]", "inputs.profiles[0]", "twice"]);
        }
        assert!(!d.join("out").exists(), "{twin}: run wrote outputs");
        day_file(d, "night", &["pass.ksprof", twin]);
        let o = kinescan(d, &["day", "day.toml"]);
        refused(
            &o,
            &["passes[0].profiles[1]", "passes[0].profiles[0]", "twice"],
        );
        assert!(
            !d.join("night/p01.las").exists(),
            "{twin}: day wrote outputs"
        );
    }
}

/// `--threads 100000` starts at most 4 threads per CPU, says so, and runs as fast as usual.
#[test]
fn an_absurd_thread_count_is_clamped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    let started = std::time::Instant::now();
    let o = kinescan(d, &["run", "pipeline.toml", "--threads", "100000"]);
    ok(&o);
    // The whole run takes ~0.1 s; 100,000 threads took over 60 s before the clamp.
    let seconds = started.elapsed().as_secs_f64();
    assert!(seconds < 20.0, "{seconds} s");
    let e = stderr(&o);
    assert!(
        e.contains("warning: --threads 100000") && e.contains("CPUs"),
        "{e}"
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("out/day.report.json")).unwrap()).unwrap();
    let cpus = std::thread::available_parallelism().unwrap().get() as u64;
    let threads = report["threads"].as_u64().unwrap();
    assert!(threads >= 1 && threads <= 4 * cpus, "{threads} threads");
}

/// A killed diagnosis's staging folder (a dead process's id) is removed by the next
/// diagnosis into the folder, even one that then fails.
#[test]
fn diagnose_removes_the_staging_folder_of_a_dead_process() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    // Beyond Linux's largest pid (2^22): no process has it.
    let stale = d.join("diag/.diagnosis.kinescan-4194999-abc123.tmp");
    std::fs::create_dir_all(&stale).unwrap();
    std::fs::write(stale.join("diagnosis.json"), b"{}").unwrap();
    // One patch far from the survey: the diagnosis fails after staging.
    let patches = "id,lat_deg,lon_deg,h_m,normal_e,normal_n,normal_u,half_length_m,half_height_m\n\
                   far,10.0,10.0,0.0,0.0,0.0,1.0,1.0,1.0\n";
    std::fs::write(d.join("patches.csv"), patches).unwrap();
    let o = kinescan(
        d,
        &[
            "diagnose",
            "pipeline.toml",
            "--patches",
            "patches.csv",
            "--out",
            "diag",
        ],
    );
    assert!(!stale.exists(), "stale staging folder left: {}", stderr(&o));
}

/// `diagnose --out FILE` says that the folder is a file (it said "File exists (os error 17)").
#[test]
fn diagnose_into_a_file_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    std::fs::write(d.join("patches.csv"), "id\n").unwrap();
    std::fs::write(d.join("notes.txt"), "mine").unwrap();
    let o = kinescan(
        d,
        &[
            "diagnose",
            "pipeline.toml",
            "--patches",
            "patches.csv",
            "--out",
            "notes.txt",
        ],
    );
    let e = refused(&o, &["notes.txt", "is a file, not a folder"]);
    assert!(!e.contains("os error 17"), "{e}");
    assert_eq!(std::fs::read(d.join("notes.txt")).unwrap(), b"mine");
}

/// A run killed between the renames of its set (three split parts and the report; the test
/// hook aborts the process after the second rename, as `strace -e inject=rename:signal=KILL`
/// would): the folder mixes two runs and `info` says so; the next command that writes the
/// folder (here a run that then fails) first completes the publication from its journal, and
/// the folder holds the killed run's whole set, which `info` confirms.
#[test]
fn a_kill_between_the_renames_of_a_set_is_completed_by_the_next_command() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::one_pass_survey(d, 200);
    let split = [
        "--set",
        "output.split=\"max_points\"",
        "--set",
        "output.max_points_per_file=3000",
    ];
    let run = |extra: &[&str], envs: &[(&str, &str)]| {
        let mut args = vec!["run", "pipeline.toml", "--threads", "1"];
        args.extend_from_slice(&split);
        args.extend_from_slice(extra);
        std::process::Command::new(env!("CARGO_BIN_EXE_kinescan"))
            .args(&args)
            .envs(envs.iter().copied())
            .current_dir(d)
            .output()
            .unwrap()
    };
    let parts = ["day_0001.las", "day_0002.las", "day_0003.las"];
    ok(&run(&[], &[]));
    let old: Vec<Vec<u8>> = parts
        .iter()
        .map(|p| sha256(&d.join("out").join(p)))
        .collect();
    // The new set's bytes, from the same run into another folder.
    let latency = ["--set", "latency.attitude_s=0.001"];
    let reference = [&latency[..], &["--set", "output.las=\"ref/day.las\""]].concat();
    ok(&run(&reference, &[]));
    let new: Vec<Vec<u8>> = parts
        .iter()
        .map(|p| sha256(&d.join("ref").join(p)))
        .collect();
    assert!(old.iter().zip(&new).all(|(o, n)| o != n), "the runs differ");
    let o = run(&latency, &[("KINESCAN_TEST_ABORT_AFTER_RENAMES", "2")]);
    assert!(!o.status.success(), "the hook did not stop the run");
    let mid: Vec<Vec<u8>> = parts
        .iter()
        .map(|p| sha256(&d.join("out").join(p)))
        .collect();
    assert_eq!(mid, [new[0].clone(), new[1].clone(), old[2].clone()]);
    let info = kinescan(d, &["info", "out"]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(!info.status.success(), "{text}");
    assert!(text.contains("interrupted publication"), "{text}");
    // The next command writing the folder: completes, then fails on its own (no t0).
    let o = run(&["--set", "time.t0_s=1000"], &[]);
    refused_plain(&o);
    let after: Vec<Vec<u8>> = parts
        .iter()
        .map(|p| sha256(&d.join("out").join(p)))
        .collect();
    assert_eq!(after, new);
    let info = kinescan(d, &["info", "out"]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(info.status.success() && text.contains("whole"), "{text}");
    let left: Vec<String> = std::fs::read_dir(d.join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".kinescan-") && !n.ends_with(".kinescan-lock"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    // A report lists every output with its SHA-256; a changed file makes the set not whole.
    std::fs::write(d.join("out/day_0002.las"), b"changed").unwrap();
    let info = kinescan(d, &["info", "out"]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        !info.status.success() && text.contains("day_0002.las has other bytes"),
        "{text}"
    );
}

fn refused_plain(o: &Output) {
    assert!(!o.status.success(), "not refused: {}", stderr(o));
}
