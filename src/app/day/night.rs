//! The night's diagnosis (`[day.night] diagnose = true`): one diagnosis of the day's mount
//! (one template, one `[sensor]`): `kinescan diagnose` of every pass's pipeline jointly, each
//! with the clock the plan resolved for it, against the template's `[diagnose]` patches, into
//! `<out>/diagnosis/` (published as its own set). A significant correction is reported; with
//! `auto_correct = true` the one correction is applied to every diagnosed pass: its units run
//! again with it ([`Correction`]) and their files make the pass's output. The corrections are
//! decided once and kept in `<out>/corrections.json` (written before any corrected unit
//! runs), so a restart re-processes with exactly the same ones.

use super::config::LoadedDay;
use super::plan::{pass_pipeline, Plan, PlannedClock, Unit};
use crate::app::diagnose::report::Verdict;
use crate::app::diagnose::{self, Request};
use crate::io::atomic::write_json;
use crate::pipeline::config::LoadedPipeline;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

pub use super::config::CORRECTIONS;

/// The folder of the day's diagnosis in the day's output folder.
pub const DIAGNOSIS_FOLDER: &str = "diagnosis";

/// One pass's diagnosis in the day report: the day's joint diagnosis, the pass's own `--set`
/// lines.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PassDiagnosis {
    /// Pass name.
    pub pass: String,
    /// The diagnosis folder (diagnosis.json, summary.md, plots): the day's one.
    pub folder: PathBuf,
    /// The verdict as `kinescan diagnose` prints it.
    pub verdict: String,
    /// The correction of this pass, as `--set` lines (empty unless an effect is named).
    pub set: Vec<String>,
    /// Held-out chi2 per degree of freedom before and after the correction.
    pub chi2_per_dof: [f64; 2],
    /// Held-out RMS of the point-to-plane residuals before and after (m).
    pub rms_m: [f64; 2],
    /// The correction as applied to the pass (`auto_correct = true`); none when reported only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub applied: Option<AppliedCorrection>,
}

/// A correction applied to a pass: the pass's output is made of its re-processed units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AppliedCorrection {
    /// The effects the diagnosis named, with their estimates and 1-sigma (the effect's unit).
    pub effects: Vec<EffectEstimate>,
    /// The re-processed work units (`<unit>-c<8 hex digits of the set lines' SHA-256>`).
    pub units: Vec<String>,
}

/// One named effect.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectEstimate {
    /// Catalogue name (docs/conventions.md §8).
    pub effect: String,
    /// Estimate.
    pub estimate: f64,
    /// Its 1-sigma.
    pub sigma: f64,
}

/// `<out>/corrections.json`: the night's diagnosis of every pass, for the plan it was made on.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Decided {
    /// The plan's fingerprint with the patch file's SHA-256.
    fingerprint: String,
    diagnosis: Vec<PassDiagnosis>,
}

/// The night's diagnosis of every pass of `day` (none unless `day.night.diagnose`); with
/// `auto_correct`, read back from `<out>/corrections.json` or made and written there. A pass
/// `failed` names (not published) is not diagnosed. With `progress`, a bar shows the
/// diagnosis' stages (when stderr is a terminal).
pub fn diagnosis(
    day: &LoadedDay,
    plan: &Plan,
    failed: &[Option<String>],
    progress: bool,
) -> Result<Vec<PassDiagnosis>> {
    let night = &day.config.day.night;
    if !night.diagnose {
        return Ok(Vec::new());
    }
    let patches = patches(day)?;
    if !night.auto_correct {
        return diagnose_passes(day, plan, &patches, failed, progress);
    }
    let path = day.config.day.out.join(CORRECTIONS);
    let fingerprint = fingerprint(plan, &patches)?;
    if let Some(decided) = read_decided(&path, &fingerprint)? {
        return Ok(decided.diagnosis);
    }
    let diagnosis = diagnose_passes(day, plan, &patches, failed, progress)?;
    let decided = Decided {
        fingerprint,
        diagnosis,
    };
    write_json(&path, &decided)?;
    Ok(decided.diagnosis)
}

/// The template's `[diagnose] patches`.
fn patches(day: &LoadedDay) -> Result<PathBuf> {
    let section = day.template.config.diagnose.as_ref();
    section
        .and_then(|d| d.patches.as_ref())
        .map(|p| p.to_path_buf())
        .ok_or_else(|| {
            let problem = "day.night.diagnose needs the template's [diagnose] patches";
            Error::bad_file(&day.path, problem)
        })
}

/// Diagnoses the passes jointly (one mount), marking the correction `auto_correct` applies
/// to each.
fn diagnose_passes(
    day: &LoadedDay,
    plan: &Plan,
    patches: &Path,
    failed: &[Option<String>],
    progress: bool,
) -> Result<Vec<PassDiagnosis>> {
    let out = day.config.day.out.to_path_buf();
    let passes: Vec<usize> = (0..day.config.passes.len())
        .filter(|&pass| failed[pass].is_none())
        .collect();
    let mut pipelines = Vec::with_capacity(passes.len());
    for &pass in &passes {
        let las = out.join(format!("{}.las", day.config.passes[pass].name));
        let mut pipeline = resolved_pipeline(day, plan, pass, &las)?;
        // The template's own setting, not the units' (what a corrected pipeline carries).
        pipeline.config.output.allow_empty = day.template.config.output.allow_empty;
        pipelines.push(pipeline);
    }
    let Some(first) = pipelines.first() else {
        return Ok(Vec::new());
    };
    let folder = out.join(DIAGNOSIS_FOLDER);
    let req = Request {
        patches: patches.to_path_buf(),
        control_points: first
            .config
            .diagnose
            .as_ref()
            .and_then(|d| d.control_points.as_ref())
            .map(|c| c.to_path_buf()),
        out_dir: folder.clone(),
    };
    let bar = if progress {
        crate::progress::stages(0, "diagnosing the day")
    } else {
        indicatif::ProgressBar::hidden()
    };
    let d = diagnose::run_joint(&pipelines, &req, &bar)?;
    let corrects = day.config.day.night.auto_correct && d.verdict == Verdict::Effect;
    let effects: Vec<EffectEstimate> = d
        .effects
        .iter()
        .map(|e| EffectEstimate {
            effect: e.clone(),
            estimate: d.estimate[e],
            sigma: d.sigma[e],
        })
        .collect();
    let found = passes.iter().enumerate().map(|(k, &pass)| {
        let set = d.pipeline_sets.get(k).unwrap_or(&d.set).clone();
        let applied = (corrects && !set.is_empty()).then(|| AppliedCorrection {
            effects: effects.clone(),
            units: plan
                .units
                .iter()
                .filter(|u| u.pass == pass)
                .map(|u| corrected_unit_id(u, &set))
                .collect(),
        });
        PassDiagnosis {
            pass: day.config.passes[pass].name.clone(),
            folder: folder.clone(),
            verdict: d.headline(),
            set,
            chi2_per_dof: [d.gap.before.chi2_per_dof, d.gap.after.chi2_per_dof],
            rms_m: [d.gap.before.rms_m, d.gap.after.rms_m],
            applied,
        }
    });
    Ok(found.collect())
}

/// The pipeline pass `pass` is processed with, writing `las`: the template with its profile
/// files and the clock the plan resolved for it written into `[time]` and `[latency]` (no
/// `[sync]`). What its diagnosis runs on and its correction is added to. A pass whose profile
/// files were synchronised to different clocks is refused.
pub fn resolved_pipeline(
    day: &LoadedDay,
    plan: &Plan,
    pass: usize,
    las: &Path,
) -> Result<LoadedPipeline> {
    let mut pipeline = pass_pipeline(day, pass, las);
    let clocks: Vec<PlannedClock> = plan
        .inputs
        .iter()
        .filter(|i| i.pass == pass)
        .map(|i| i.clock)
        .collect();
    if clocks.windows(2).any(|w| w[0] != w[1]) {
        let problem = format!(
            "day.night.diagnose: pass {} has profile files with different synchronised \
             clocks; diagnose them one by one with `kinescan diagnose`",
            day.config.passes[pass].name
        );
        return Err(Error::bad_file(&day.path, problem));
    }
    if let Some(clock) = clocks.first() {
        let c = &mut pipeline.config;
        c.time.t0_s = Some(clock.t0_s);
        c.time.period_s = clock.period_s;
        c.latency.attitude_s = clock.attitude_latency_s;
        c.sync = None;
    }
    Ok(pipeline)
}

/// The id of `unit` re-processed with the correction `set`.
fn corrected_unit_id(unit: &Unit, set: &[String]) -> String {
    let digest = Sha256::digest(set.join("\n").as_bytes());
    format!("{}-c{}", unit.id, &crate::io::digest::hex(&digest)[..8])
}

/// A pass re-processed with its applied correction.
pub struct Correction {
    /// Index of the pass in the day file.
    pub pass: usize,
    /// The pass's resolved pipeline with the correction added (its output set per unit).
    pub pipeline: LoadedPipeline,
    set: Vec<String>,
}

impl Correction {
    /// The correction of the pass of `d` when one is applied.
    pub fn of(day: &LoadedDay, plan: &Plan, d: &PassDiagnosis) -> Result<Option<Correction>> {
        if d.applied.is_none() {
            return Ok(None);
        }
        let Some(pass) = day.config.passes.iter().position(|p| p.name == d.pass) else {
            let problem = format!("{CORRECTIONS} names a pass `{}` not in the day", d.pass);
            return Err(Error::bad_file(&day.path, problem));
        };
        let units = day.config.day.out.join("units");
        let resolved = resolved_pipeline(day, plan, pass, &units.join("x.las"))?;
        Ok(Some(Correction {
            pass,
            pipeline: resolved.with_overrides(&d.set)?,
            set: d.set.clone(),
        }))
    }

    /// The id of `unit` re-processed with this correction.
    pub fn unit_id(&self, unit: &Unit) -> String {
        corrected_unit_id(unit, &self.set)
    }

    /// The clock of an input of the pass: the plan's `planned` (its covariances from the sync)
    /// with t0, T and the attitude latency as the corrected pipeline has them.
    pub fn clock(&self, planned: &PlannedClock) -> PlannedClock {
        let c = &self.pipeline.config;
        PlannedClock {
            t0_s: c.time.t0_s.unwrap_or(planned.t0_s),
            period_s: c.time.period_s,
            attitude_latency_s: c.latency.attitude_s,
            ..*planned
        }
    }
}

/// The fingerprint of a night's corrections: the plan's with the patch file's content.
fn fingerprint(plan: &Plan, patches: &Path) -> Result<String> {
    let bytes = std::fs::read(patches).map_err(|e| Error::io(patches, e))?;
    let mut h = Sha256::new();
    h.update(plan.fingerprint.as_bytes());
    h.update(&bytes);
    Ok(crate::io::digest::hex(&h.finalize()))
}

/// The corrections at `path`, if there; refused when made for another plan or patch file.
fn read_decided(path: &Path, fingerprint: &str) -> Result<Option<Decided>> {
    let text = match std::fs::read(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(path, e)),
    };
    let decided: Decided = serde_json::from_slice(&text)
        .map_err(|e| Error::bad_file(path, format!("not a day's corrections: {e}")))?;
    if decided.fingerprint != fingerprint {
        let problem = "made for another plan or patch file: remove it to diagnose the day again";
        return Err(Error::bad_file(path, problem));
    }
    Ok(Some(decided))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A restart reads the corrections back: every number as written, to the bit (serde_json's
    /// `float_roundtrip`; its default parser is off by an ulp on some, as on this RMS).
    #[test]
    fn corrections_read_back_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(CORRECTIONS);
        let d = PassDiagnosis {
            pass: "p01".into(),
            folder: dir.path().join(DIAGNOSIS_FOLDER),
            verdict: "effect: range_zero_m = 3.0000e-2 +- 7.6e-4".into(),
            set: vec!["sensor.range_zero_m=0.049999999955242784".into()],
            chi2_per_dof: [2.6255228312744725, 6.983812383831755e-15],
            rms_m: [0.02588622305060796, 6.763862891222691e-10],
            applied: Some(AppliedCorrection {
                effects: vec![EffectEstimate {
                    effect: "range_zero_m".into(),
                    estimate: 0.029999999955242784,
                    sigma: 0.0007645918264642078,
                }],
                units: vec!["p01-0-0000-c568d75dd".into()],
            }),
        };
        let decided = Decided {
            fingerprint: "f".into(),
            diagnosis: vec![d.clone()],
        };
        write_json(&path, &decided).unwrap();
        let back = read_decided(&path, "f").unwrap().unwrap();
        assert_eq!(back.diagnosis, [d]);
        let e = read_decided(&path, "g").err().unwrap().to_string();
        assert!(e.contains(CORRECTIONS) && e.contains("remove it"), "{e}");
    }
}
