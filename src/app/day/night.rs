//! The night's diagnosis (`[day.night] diagnose = true`): `kinescan diagnose` on each pass's
//! pipeline, with the clock the plan resolved for it, against the template's `[diagnose]`
//! patches, into `<out>/diagnosis_<pass>/` (published as its own set). A significant
//! correction is reported, not applied (`auto_correct = true` is not wired yet).

use super::config::LoadedDay;
use super::plan::{pass_pipeline, Plan};
use crate::app::diagnose::{self, Request};
use crate::{Error, Result};
use serde::Serialize;
use std::path::PathBuf;

/// One pass's diagnosis in the day report.
#[derive(Debug, Clone, Serialize)]
pub struct PassDiagnosis {
    /// Pass name.
    pub pass: String,
    /// The diagnosis folder (diagnosis.json, summary.md, plots).
    pub folder: PathBuf,
    /// The verdict as `kinescan diagnose` prints it.
    pub verdict: String,
    /// The correction it would apply, as `--set` lines (empty unless an effect is named).
    pub set: Vec<String>,
    /// Held-out chi2 per degree of freedom before and after the correction.
    pub chi2_per_dof: [f64; 2],
    /// Held-out RMS of the point-to-plane residuals before and after (m).
    pub rms_m: [f64; 2],
}

/// Diagnoses every pass of `day` (none unless `day.night.diagnose`).
pub fn diagnose_passes(day: &LoadedDay, plan: &Plan) -> Result<Vec<PassDiagnosis>> {
    let template = &day.template.config;
    let patches = match (&template.diagnose, day.config.day.night.diagnose) {
        (_, false) => return Ok(Vec::new()),
        (Some(d), true) => d.patches.as_ref().map(|p| p.to_path_buf()),
        (None, true) => None,
    };
    let Some(patches) = patches else {
        let problem = "day.night.diagnose needs the template's [diagnose] patches";
        return Err(Error::bad_file(&day.path, problem));
    };
    let out = day.config.day.out.to_path_buf();
    let mut found = Vec::new();
    for (pass, p) in day.config.passes.iter().enumerate() {
        let mut pipeline = pass_pipeline(day, pass, &out.join(format!("{}.las", p.name)));
        let clocks: Vec<_> = plan
            .inputs
            .iter()
            .filter(|i| i.pass == pass)
            .map(|i| i.clock)
            .collect();
        if clocks.windows(2).any(|w| w[0] != w[1]) {
            let problem = format!(
                "day.night.diagnose: pass {} has profile files with different synchronised \
                 clocks; diagnose them one by one with `kinescan diagnose`",
                p.name
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
        let folder = out.join(format!("diagnosis_{}", p.name));
        let req = Request {
            patches: patches.clone(),
            out_dir: folder.clone(),
        };
        let d = diagnose::run(&pipeline, &req)?;
        found.push(PassDiagnosis {
            pass: p.name.clone(),
            folder,
            verdict: d.headline(),
            set: d.set.clone(),
            chi2_per_dof: [d.gap.before.chi2_per_dof, d.gap.after.chi2_per_dof],
            rms_m: [d.gap.before.rms_m, d.gap.after.rms_m],
        });
    }
    Ok(found)
}
