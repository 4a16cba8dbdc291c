//! What the night does besides georeferencing: the one diagnosis of the day's mount (its passes
//! jointly) and, with `auto_correct = true`, the re-processing of every pass with the correction
//! it names, on the simulated day of `day.rs` with a catalogue effect injected.

use crate::day::{
    assert_counts_add_up, day_file, kinescan, las_files, ok, simulated_day_of, simulated_day_with,
    three_passes, PASSES,
};
use kinescan::geo::projection::MapFrame;
use kinescan::sim::read_truth_points;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The injected effect: the sensor's true range zero is 3 cm beyond the template's.
const RANGE_ZERO_ERROR: &str = "range_zero_error_m = 0.03";
/// The `[day.night]` that applies the diagnosed corrections.
const AUTO_CORRECT: &str = "diagnose = true\nauto_correct = true";

/// The simulated day (with `effects` injected) and a template diagnosing against its patches.
fn diagnosed_day(dir: &Path, effects: &str) {
    simulated_day_with(dir, effects);
    diagnosing_template(dir);
}

/// Adds `[diagnose]` (the simulated patches) to the day's template.
fn diagnosing_template(dir: &Path) {
    let template = std::fs::read_to_string(dir.join("template.toml")).unwrap();
    std::fs::write(
        dir.join("template.toml"),
        template + "[diagnose]\npatches = \"patches.csv\"\n",
    )
    .unwrap();
}

/// Writes the day file `<name>.toml` (three passes, per-pass layout, into `<name>/`) with
/// `night` (lines of `[day.night]`).
fn night_day(dir: &Path, name: &str, night: &str) -> PathBuf {
    let day = day_file(dir, name, name, "{ kind = \"per_pass\" }", &three_passes());
    let text = std::fs::read_to_string(&day).unwrap();
    // The night table before the first pass (TOML: after it would belong to the pass).
    let night = format!("\n[day.night]\n{night}\n\n[[passes]]");
    std::fs::write(&day, text.replacen("\n[[passes]]", &night, 1)).unwrap();
    day
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// `[day.night] diagnose = true` on a day without any effect: the passes diagnosed jointly
/// into `<out>/diagnosis/`, verdict `none`; the day report and the morning report carry that
/// verdict for every pass, as the one `diagnosis.json` gives it.
#[test]
fn the_night_diagnoses_the_day_s_mount_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    diagnosed_day(d, "");
    let day = night_day(d, "night", "diagnose = true");
    ok(kinescan(&["day", day.to_str().unwrap(), "-q"]));
    let report = json(&d.join("night/day.report.json"));
    let diagnosis = report["diagnosis"].as_array().unwrap();
    assert_eq!(diagnosis.len(), PASSES.len());
    let md = std::fs::read_to_string(d.join("night/report.md")).unwrap();
    let own = json(&d.join("night/diagnosis/diagnosis.json"));
    assert_eq!(own["verdict"], "none", "{}", own["reason"]);
    for (k, pass) in PASSES.iter().enumerate() {
        assert_eq!(diagnosis[k]["pass"], *pass);
        let verdict = diagnosis[k]["verdict"].as_str().unwrap();
        assert!(verdict.starts_with("none: "), "{pass}: {verdict:?}");
        assert_eq!(diagnosis[k]["set"], serde_json::json!([]));
        assert!(md.contains(&format!("| {pass} | {verdict} |")), "{md}");
    }
    // Every pass's returns are in the one diagnosis: its passes are the day's profile files.
    let passes: std::collections::BTreeSet<u64> = own["covariate_tests"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t["covariate"] == "pass")
        .flat_map(|t| t["bins"].as_array().unwrap().iter())
        .map(|b| b["range"][0].as_f64().unwrap() as u64)
        .collect();
    assert_eq!(passes.len(), PASSES.len(), "{}", own["covariate_tests"]);
}

/// RMS (m) of the 3D distance of each point of the LAS file `las` to its true position:
/// the pass's returns in record order, those the simulator marks missing left out (the files
/// must hold exactly the others).
fn rms_to_truth(las: &Path, truth: &[[f64; 3]]) -> f64 {
    let frame = MapFrame::utm(32, true).unwrap();
    let expected: Vec<Vector3<f64>> = truth
        .iter()
        .filter(|t| !t[0].is_nan())
        .map(|t| frame.ecef_to_map(&Vector3::new(t[0], t[1], t[2])))
        .collect();
    let mut reader = las::Reader::from_path(las).unwrap();
    let points: Vec<las::Point> = reader
        .read_all()
        .unwrap()
        .points()
        .map(Result::unwrap)
        .collect();
    assert_eq!(points.len(), expected.len(), "{}", las.display());
    let sum: f64 = points
        .iter()
        .zip(&expected)
        .map(|(p, t)| (Vector3::new(p.x, p.y, p.z) - t).norm_squared())
        .sum();
    (sum / points.len() as f64).sqrt()
}

/// The inode of the day's `diagnosis.json` (a new diagnosis publishes a new file).
fn diagnosis_inode(out: &Path) -> u64 {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(out.join("diagnosis/diagnosis.json"))
        .unwrap()
        .ino()
}

/// The truth points of each pass file (the passes cut the simulated drive by profile).
fn truth_per_pass(dir: &Path) -> Vec<Vec<[f64; 3]>> {
    let truth = read_truth_points(&dir.join("truth_points.bin")).unwrap();
    let mut at = 0;
    PASSES
        .iter()
        .map(|p| {
            let n = kinescan::io::profiles::ProfileFile::open(&dir.join(format!("{p}.ksprof")))
                .unwrap()
                .len();
            at += n;
            truth[at - n..at].to_vec()
        })
        .collect()
}

/// `auto_correct = true` on a day whose sensor has a range zero error of 3 cm the template
/// does not know: every pass whose diagnosis names an effect is re-processed with its
/// correction and lands closer to the truth than without it; the reports say which
/// correction, with its estimate and sigma and the gap before and after; a re-run resumes
/// every unit, corrected ones included. `auto_correct = false` leaves the bytes of a day
/// without diagnosis.
#[test]
fn auto_correct_re_processes_a_pass_with_its_diagnosed_correction() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    diagnosed_day(d, RANGE_ZERO_ERROR);
    let plain = night_day(d, "plain", "diagnose = false");
    let reported = night_day(d, "reported", "diagnose = true");
    let corrected = night_day(d, "corrected", AUTO_CORRECT);
    for day in [&plain, &reported, &corrected] {
        ok(kinescan(&["day", day.to_str().unwrap(), "-q"]));
    }
    let (plain_las, reported_las) = (las_files(&d.join("plain")), las_files(&d.join("reported")));
    assert!(
        plain_las == reported_las,
        "auto_correct = false changed the day's files"
    );

    let out = d.join("corrected");
    assert_counts_add_up(&out);
    let report = json(&out.join("day.report.json"));
    let other = json(&d.join("reported/day.report.json"));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let truth = truth_per_pass(d);
    let joint = json(&out.join("diagnosis/diagnosis.json"));
    assert!(!out.join("diagnosis/corrected.toml").exists());
    let mut applied = 0;
    for (k, pass) in PASSES.iter().enumerate() {
        let diag = &report["diagnosis"][k];
        // The same diagnosis whether applied or reported.
        assert_eq!(diag["verdict"], other["diagnosis"][k]["verdict"], "{pass}");
        assert_eq!(diag["set"], other["diagnosis"][k]["set"], "{pass}");
        assert!(other["diagnosis"][k].get("applied").is_none());
        let file = format!("{pass}.las");
        let before = rms_to_truth(&d.join("reported").join(&file), &truth[k]);
        let after = rms_to_truth(&out.join(&file), &truth[k]);
        let Some(a) = diag.get("applied") else {
            assert!(
                !diag["verdict"].as_str().unwrap().starts_with("effect"),
                "{diag}"
            );
            let same = std::fs::read(out.join(&file)).unwrap();
            assert!(same == std::fs::read(d.join("reported").join(&file)).unwrap());
            continue;
        };
        applied += 1;
        println!(
            "{pass}: {} -> RMS to truth {before:.4} m -> {after:.4} m",
            diag["set"]
        );
        assert!(after < 0.5 * before, "{pass}: {before} m -> {after} m");
        let effect = &a["effects"][0];
        let (estimate, sigma) = (
            effect["estimate"].as_f64().unwrap(),
            effect["sigma"].as_f64(),
        );
        println!("{pass}: {} = {estimate} +- {sigma:?}", effect["effect"]);
        assert!(sigma.unwrap() > 0.0);
        let set = diag["set"][0].as_str().unwrap();
        assert!(
            md.contains(&format!("applied: {set}"))
                && md.contains(&format!(
                    "{} = {estimate:.4e} +- ",
                    effect["effect"].as_str().unwrap()
                )),
            "{md}"
        );
        // The one diagnosis re-processed every pass with its own lines for its gap after.
        assert_eq!(joint["pipeline_sets"][k], diag["set"], "{pass}");
        let chi2 = diag["chi2_per_dof"].as_array().unwrap();
        // Both present and finite (None < Some(x) holds, and a NaN is written as null).
        let (after, before) = (chi2[1].as_f64().unwrap(), chi2[0].as_f64().unwrap());
        assert!(after.is_finite() && after < before, "{diag}");
        // The pass's output is its corrected units' files.
        let units: Vec<&str> = a["units"]
            .as_array()
            .unwrap()
            .iter()
            .map(|u| u.as_str().unwrap())
            .collect();
        assert!(!units.is_empty());
        for u in &units {
            assert!(out.join("units").join(format!("{u}.las")).is_file(), "{u}");
        }
    }
    assert_eq!(applied, PASSES.len(), "{}", report["diagnosis"]);

    // A re-run resumes: no unit (corrected ones included) runs again, no diagnosis again.
    let journal = std::fs::read(out.join("journal.jsonl")).unwrap();
    let before = las_files(&out);
    let diagnosis_file = diagnosis_inode(&out);
    ok(kinescan(&["day", corrected.to_str().unwrap(), "-q"]));
    assert_eq!(std::fs::read(out.join("journal.jsonl")).unwrap(), journal);
    assert_eq!(diagnosis_inode(&out), diagnosis_file, "diagnosed again");
    assert!(las_files(&out) == before);
    let again = json(&out.join("day.report.json"));
    assert_eq!(again["diagnosis"], report["diagnosis"]);
    assert!(again["timings_s"].get("corrected_units").is_some());

    // The states a kill leaves, made exactly, then resumed: the same files each time.
    let corrected_units: Vec<String> = report["diagnosis"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|d| d["applied"]["units"].as_array().unwrap())
        .map(|u| u.as_str().unwrap().to_string())
        .collect();
    let (last, rest) = corrected_units.split_last().unwrap();
    // Killed in the corrected units: the last one's file renamed into place but not journalled,
    // the pass before without its corrected units at all.
    let p02: Vec<String> = rest
        .iter()
        .filter(|u| u.starts_with("p02"))
        .cloned()
        .collect();
    forget_units(&out, std::slice::from_ref(last), &p02);
    resume_to(&corrected, &before);
    // Killed before the corrections were written: no corrected unit, no corrections.json.
    forget_units(&out, &[], &corrected_units);
    std::fs::remove_file(out.join("corrections.json")).unwrap();
    resume_to(&corrected, &before);
    assert!(out.join("corrections.json").is_file());
}

/// Leaves the day in `out` as a kill before its merge would: the published files gone, the
/// journal lines of `unjournalled` and `removed` dropped, the unit files of `removed` too.
fn forget_units(out: &Path, unjournalled: &[String], removed: &[String]) {
    for f in las_files(out).iter().map(|(name, _)| name) {
        std::fs::remove_file(out.join(f)).unwrap();
    }
    std::fs::remove_file(out.join("day.report.json")).unwrap();
    let journal = std::fs::read_to_string(out.join("journal.jsonl")).unwrap();
    let dropped = |line: &&str| {
        let unit = json_line_unit(line);
        unjournalled.contains(&unit) || removed.contains(&unit)
    };
    let kept: Vec<&str> = journal.lines().filter(|l| !dropped(l)).collect();
    assert!(kept.len() < journal.lines().count());
    std::fs::write(out.join("journal.jsonl"), kept.join("\n") + "\n").unwrap();
    for u in removed {
        std::fs::remove_file(out.join("units").join(format!("{u}.las"))).unwrap();
    }
}

fn json_line_unit(line: &str) -> String {
    let v: serde_json::Value = serde_json::from_str(line).unwrap();
    v["unit"].as_str().unwrap().to_string()
}

/// Runs `day` again: its files are `expected` and its report's counts add up.
fn resume_to(day: &Path, expected: &[(String, Vec<u8>)]) {
    ok(kinescan(&["day", day.to_str().unwrap(), "-q"]));
    let out = day.with_extension("");
    assert!(las_files(&out) == expected, "resumed files differ");
    assert_counts_add_up(&out);
}

/// An auto-corrected day killed at seeded points (in its diagnosis, its corrected units or
/// its merge) and resumed: the bytes of the uninterrupted day.
#[test]
fn a_killed_auto_corrected_day_resumes_to_identical_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    diagnosed_day(d, RANGE_ZERO_ERROR);
    let whole = night_day(d, "whole", AUTO_CORRECT);
    let killed = night_day(d, "killed", AUTO_CORRECT);
    // Each run killed a seeded moment after the plan's units are all journalled, so in the
    // night's diagnosis or after it, whatever the machine's speed (a kill timed on the whole
    // run alone, about 0.5 s, interrupted none of five runs in the loaded full suite; this
    // way five of five).
    crate::day::assert_kills_resume_when(&whole, &killed, 3, |rng, run_s, out, _| {
        let units = json(&d.join("whole/day.report.json"))["units"].as_u64();
        let units = units.unwrap() as usize;
        crate::day::wait_for_journal(out, units - 1, 10.0 * run_s);
        std::thread::sleep(Duration::from_secs_f64(rng.range(0.0, 0.2) * run_s));
    });
}

/// The simulated sensor's true boresight about x is 0.1 deg beyond the template's (the issue's
/// case: two passes of one mount were corrected by 0.10045 and 0.10205 deg).
const BORESIGHT_ERROR: &str = "boresight_error_deg = [0.1, 0.0, 0.0]";

/// `(estimate, sigma)` of `effect` in the diagnosis `d` (a `diagnosis.json`).
fn named(d: &serde_json::Value, effect: &str) -> (f64, f64) {
    assert_eq!(d["verdict"], "effect", "{}", d["reason"]);
    let (x, s) = (&d["estimate"][effect], &d["sigma"][effect]);
    (x.as_f64().unwrap(), s.as_f64().unwrap())
}

/// The base drive, 20 returns a profile, three laps of its loop (56 s each): cut into the
/// day's three passes, each pass one lap over the same patches.
fn three_laps(effects: &str) -> String {
    crate::sim_support::BASE
        .replace("points_per_profile = 300", "points_per_profile = 20")
        .replace("duration_s = 14.0", "duration_s = 168.0")
        .replace("[origin]", &format!("[effects]\n{effects}\n[origin]"))
}

/// Three laps of one loop with a boresight error of 0.1 deg, one lap a pass: the passes see the
/// same patches, so each pass diagnosed on its own splits them as the day's diagnosis does
/// (checked) and the sigmas compare. The day's one diagnosis holds every pass's observations,
/// names the error within 3 sigma of the truth with a sigma below each pass's own and within
/// 20% of the passes' information combined, `1/sqrt(sum s_k^-2)` (not equal: the joint
/// diagnosis learns one navigation model on all laps, and the laps' navigation errors, 56 s
/// apart, are correlated; measured 9% below), and every pass is re-processed with the same
/// `--set` lines.
#[test]
fn passes_over_the_same_patches_diagnosed_jointly_shrink_the_sigma() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    simulated_day_of(d, &three_laps(BORESIGHT_ERROR));
    diagnosing_template(d);
    let day = night_day(d, "laps", AUTO_CORRECT);
    ok(kinescan(&["day", day.to_str().unwrap(), "-q"]));
    let out = d.join("laps");
    let joint_json = json(&out.join("diagnosis/diagnosis.json"));
    let (joint, sigma) = named(&joint_json, "boresight_x_deg");
    // Each pass diagnosed on its own: the template with the pass's profile file.
    let template = std::fs::read_to_string(d.join("template.toml")).unwrap();
    let (mut precision, mut observations) = (0.0, 0);
    for pass in PASSES {
        let pipeline = d.join(format!("{pass}.toml"));
        let files = format!("profiles = [\"{pass}.ksprof\"]");
        std::fs::write(&pipeline, template.replace("profiles = []", &files)).unwrap();
        let folder = d.join(format!("alone_{pass}"));
        let args = ["diagnose", pipeline.to_str().unwrap(), "--out"];
        ok(kinescan(
            &[&args[..], &[folder.to_str().unwrap(), "-q"]].concat(),
        ));
        let alone = json(&folder.join("diagnosis.json"));
        assert_eq!(alone["split"], joint_json["split"], "{pass}");
        let (x, s) = named(&alone, "boresight_x_deg");
        println!("{pass} alone: {x:.5} +- {s:.5} deg");
        assert!(sigma < s, "{pass}: joint sigma {sigma} deg, alone {s} deg");
        precision += s.powi(-2);
        observations += alone["counts"]["observations"].as_u64().unwrap();
    }
    let combined = precision.sqrt().recip();
    println!("joint: {joint:.5} +- {sigma:.5} deg (combined: +- {combined:.5})");
    assert!(
        (sigma / combined - 1.0).abs() < 0.2,
        "{sigma} vs {combined}"
    );
    assert!((joint - 0.1).abs() < 3.0 * sigma, "{joint} +- {sigma} deg");
    let joint_observations = joint_json["counts"]["observations"].as_u64();
    assert_eq!(joint_observations, Some(observations));

    let report = json(&out.join("day.report.json"));
    let diagnosis = report["diagnosis"].as_array().unwrap();
    assert_eq!(diagnosis.len(), PASSES.len());
    let set = &diagnosis[0]["set"];
    assert!(
        set[0]
            .as_str()
            .unwrap()
            .starts_with("sensor.boresight_deg="),
        "{set}"
    );
    for (pass, diag) in PASSES.iter().zip(diagnosis) {
        assert_eq!(&diag["set"], set, "{pass}");
        let units = diag["applied"]["units"].as_array().unwrap();
        assert!(!units.is_empty(), "{pass}");
        for u in units {
            let u = u.as_str().unwrap();
            assert!(u.starts_with(pass), "{u}");
            assert!(out.join("units").join(format!("{u}.las")).is_file(), "{u}");
        }
    }
}
