//! The diagnosis report: `diagnosis.json` (docs/conventions.md §8 schema first, then the
//! documented extras of docs/diagnosis.md) and `summary.md`, what a surveyor reads first.

use super::nuisance::screen;
use super::observe::{ObserveCounts, OFF_PLANE_SHARE};
use crate::io::atomic::write_atomic;
use crate::{Error, Result};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

pub mod plots;

/// File names in the diagnosis folder.
pub const DIAGNOSIS_JSON: &str = "diagnosis.json";
/// The summary for a surveyor.
pub const SUMMARY_MD: &str = "summary.md";

/// The verdict (docs/conventions.md §8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// One catalogue effect (or inseparable group, or combination) explains the gap.
    Effect,
    /// The survey agrees with its model.
    None,
    /// The survey departs from its model and no catalogue effect explains it.
    Unexplained,
}

/// Gap metrics on a set of references ("G" of docs/conventions.md §8).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GapMetrics {
    /// Chi-square of the residuals with their full (visit-block) covariance, per degree of
    /// freedom (1 for a survey that agrees with its model).
    pub chi2_per_dof: f64,
    /// RMS of the residuals (m).
    pub rms_m: f64,
    /// Mean residual (m).
    pub mean_m: f64,
    /// Share of residuals inside their 95% interval (0.95 for an honest model).
    pub coverage_95: f64,
    /// Number of residuals.
    pub n: usize,
}

/// Gap before and after the correction, on the held-out references.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GapBeforeAfter {
    /// With the configured values.
    pub before: GapMetrics,
    /// Re-processed with the estimate (or after the model-free correction; or as before).
    pub after: GapMetrics,
    /// The sd of `before.chi2_per_dof` and `after.chi2_per_dof` under a model that holds:
    /// `sqrt(2 / n)` for a known model, widened by the learned navigation model's sampling
    /// error (docs/diagnosis.md, "The nuisance").
    pub before_chi2_per_dof_sd: f64,
    pub after_chi2_per_dof_sd: f64,
    /// Re-processed with an estimate: the held-out chi2/dof of the survey observed again with
    /// the estimate's own covariance added to the held-out covariance, over all its held-out
    /// returns; the statistic the verdict tests (docs/diagnosis.md, "Selection and verdict",
    /// 6). Otherwise `after.chi2_per_dof`.
    pub after_chi2_per_dof_given_estimate: f64,
    /// Both over the same returns: re-processed, the held-out returns both observations
    /// found (matched by pass and record, docs/diagnosis.md "Reading the report"); false only
    /// when they share none, each then over its own.
    pub same_returns: bool,
}

/// Variance inflation of one effect on this geometry.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObservabilityRow {
    /// Effect name.
    pub effect: String,
    /// Variance inflation factor (1 = independent of the others).
    pub vif: f64,
}

/// Observability of the catalogue on this survey, before solving.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObservabilityReport {
    /// Condition number of the scaled normal matrix of all effects.
    pub condition_number: f64,
    /// Per effect.
    pub effects: Vec<ObservabilityRow>,
    /// Effects without any signature on these references.
    pub unobservable: Vec<String>,
}

/// Effects the data cannot separate (|correlation| > 0.9).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupReport {
    /// Members, the preferred first: the one the explanation takes and the re-run corrects
    /// (the catalogue's most common cause, unless the held-out references support another).
    pub members: Vec<String>,
    /// The data that would separate them.
    pub hint: String,
    /// Members joined by the residuals, not by the geometry: the named group's effect, added
    /// with one of these in its place, is not significant (docs/diagnosis.md, "Selection and
    /// verdict", 4a).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub rivals: Vec<String>,
    /// The largest |correlation| between two members' estimates fitted together.
    pub max_abs_correlation: f64,
    /// Whether the first member is the catalogue's most common cause of the group (else the
    /// held-out references chose it).
    #[serde(skip)]
    pub first_is_preferred: bool,
}

/// One tested candidate (an effect, one member of a group, or a combination).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CandidateReport {
    /// Effect names.
    pub effects: Vec<String>,
    /// Estimates on the fit split, in the effects' units.
    pub estimate: Vec<f64>,
    /// Their 1-sigma.
    pub sigma: Vec<f64>,
    /// Chi-square reduction on the held-out split.
    pub held_out_chi2_reduction: f64,
    /// p-value of the likelihood-ratio test on the fit split.
    pub p_value: f64,
    /// One-sided p-value of the held-out score along the correction.
    pub held_out_p_value: f64,
    /// Significant under Holm control at the family-wise level.
    pub significant: bool,
}

/// One bin of a covariate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BinReport {
    /// Lower and upper covariate value of the bin (equal for a categorical level).
    pub range: [f64; 2],
    /// Returns in the bin.
    pub n: usize,
    /// Mean normalised residual (or offset, m, for a correction).
    pub mean: f64,
}

/// The test of one covariate: do the normalised residuals depend on it?
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CovariateReport {
    /// Covariate name (docs/conventions.md §8).
    pub covariate: String,
    /// p-value.
    pub p_value: f64,
    /// The bins tested.
    pub bins: Vec<BinReport>,
}

/// A model-free correction: a binned offset along one covariate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelFreeReport {
    /// Covariate name.
    pub covariate: String,
    /// Offsets (m) per bin, fitted on the fit split.
    pub bins: Vec<BinReport>,
    /// Share of the held-out excess chi-square it closes.
    pub closed_fraction: f64,
}

/// `diagnosis.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Diagnosis {
    /// docs/conventions.md §8.
    pub verdict: Verdict,
    /// The named effect(s); an inseparable group lists all its members, the preferred first
    /// (the one the re-run corrects: docs/conventions.md §8).
    pub effects: Vec<String>,
    /// Estimate per name in `effects` (unit of the name).
    pub estimate: BTreeMap<String, f64>,
    /// 1-sigma per name in `effects`.
    pub sigma: BTreeMap<String, f64>,
    /// Covariates where the gap (or what remains of it) lies, most significant first.
    pub located_in: Vec<String>,
    /// On the held-out references.
    pub gap: GapBeforeAfter,
    /// `--set` lines that re-run the pipeline with the effect added (a joint diagnosis of
    /// several pipelines: the lines they all share).
    pub set: Vec<String>,
    /// Extra, a joint diagnosis of several pipelines only (a day's passes): each pipeline's
    /// `--set` lines, in the order given (the same correction added to each one's values).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub pipeline_sets: Vec<Vec<String>>,
    /// Extra: why the verdict (one sentence).
    pub reason: String,
    /// Extra: reference ids of the fit and held-out halves, and the split seed.
    pub split: SplitReport,
    /// Extra: observability of every effect on this geometry, before solving.
    pub observability: ObservabilityReport,
    /// Extra: inseparable groups.
    pub groups: Vec<GroupReport>,
    /// Extra: every tested candidate, best held-out chi-square reduction first.
    pub candidates: Vec<CandidateReport>,
    /// Extra: covariate tests, most significant first.
    pub covariate_tests: Vec<CovariateReport>,
    /// Extra: the model-free correction (verdict `unexplained`).
    pub model_free: Option<ModelFreeReport>,
    /// For every catalogue name: the smallest |size| (the name's unit) this survey would name
    /// with 90% probability at the verdict's test level (docs/diagnosis.md, "Power"); null
    /// for an effect without signature on these references.
    pub detectable: BTreeMap<String, Option<f64>>,
    /// The navigation error model the statistics used and how it was obtained
    /// (docs/diagnosis.md, "The nuisance").
    pub nuisance: crate::app::diagnose::nuisance::Nuisance,
    /// Extra (`rates`, `velocities`): the SBET's body-rate fields against the rates of its own
    /// attitude and its velocity fields against the velocity of its positions, and which the
    /// signatures used (`sbet_fields`, or `trajectory` when the fields are empty or disagree).
    #[serde(flatten)]
    pub motion: crate::trajectory::MotionChecks,
    /// Extra: returns set aside as foreign to their reference, by reference
    /// (docs/diagnosis.md, "Foreign returns").
    pub foreign: screen::Screening,
    /// Extra: what happened to every return.
    pub counts: ObserveCounts,
    /// Extra: PNG files written beside the report.
    pub plots: Vec<String>,
}

/// The split of the references.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SplitReport {
    /// Seed of the split.
    pub seed: u64,
    /// Reference ids fitted on.
    pub fit: Vec<String>,
    /// Reference ids held out.
    pub held_out: Vec<String>,
}

impl Diagnosis {
    /// Writes `diagnosis.json` and `summary.md` into `dir` (atomically each).
    pub fn write(&self, dir: &Path, pipeline: &Path) -> Result<()> {
        let json = serde_json::to_string_pretty(self)
            .map_err(|e| Error::Invalid(format!("diagnosis JSON: {e}")))?;
        write_atomic(&dir.join(DIAGNOSIS_JSON), format!("{json}\n").as_bytes())?;
        write_atomic(&dir.join(SUMMARY_MD), self.summary(pipeline).as_bytes())
    }

    /// The correction of a joint diagnosis: each pipeline's `--set` lines.
    fn write_pipeline_sets(&self, s: &mut String) {
        let _ = writeln!(
            s,
            "## The correction, per pipeline\n\nThe {} pipelines were diagnosed jointly; the \
             correction adds the same values to each one's own (diagnosis.json \
             `pipeline_sets`):\n",
            self.pipeline_sets.len()
        );
        for (k, lines) in self.pipeline_sets.iter().enumerate() {
            let sets: Vec<String> = lines.iter().map(|l| format!("`--set '{l}'`")).collect();
            let _ = writeln!(s, "- pipeline {k}: {}", sets.join(" "));
        }
        s.push('\n');
    }

    /// The navigation error model used, and whence.
    fn write_nuisance(&self, s: &mut String) {
        let n = &self.nuisance;
        // Three decimals, or three significant digits below 0.01 (a white share at its bound).
        let f = |v: f64| {
            if v != 0.0 && v.abs() < 0.01 {
                format!("{v:.2e}")
            } else {
                format!("{v:.3}")
            }
        };
        let p = |x: &crate::app::diagnose::nuisance::Parameter, unit: &str| match x.sigma {
            Some(sd) => format!("{} +- {}{unit} ({})", f(x.value), f(sd), x.source),
            None => format!("{}{unit} ({})", f(x.value), x.source),
        };
        let _ = writeln!(
            s,
            "## Navigation error model
"
        );
        let _ = writeln!(
            s,
            "Correlation times: position {}, attitude {}; true / SMRMSG sigma: position {}, \
             attitude {}; white noise per SBET record, share of the SMRMSG variance: position {}, \
             attitude {} (diagnosis.json `nuisance`).\n",
            p(&n.position_tau_s, " s"),
            p(&n.attitude_tau_s, " s"),
            p(&n.position_scale, ""),
            p(&n.attitude_scale, ""),
            p(&n.position_white_share, ""),
            p(&n.attitude_white_share, "")
        );
        for (block, log_sd, prior) in n.scales_left_to_prior() {
            let _ = writeln!(
                s,
                "This survey does not determine the {block} scale (its log-sd {log_sd:.2} \
                 against the prior's {prior:.2}): each sigma is averaged over what the prior \
                 allows, right on average and short where the SMRMSG is far off \
                 (docs/diagnosis.md, *Reading the report*). A longer survey determines it; \
                 `diagnose.nav_{block}_scale` sets it.\n"
            );
        }
        if let Some(slow) = &n.slow {
            let (what, verb) = if slow.used {
                ("used", "exceeds")
            } else {
                ("not used", "does not exceed")
            };
            let _ = writeln!(
                s,
                "A second, slow process per block ({what}: twice its log-likelihood ratio, {:.1}, \
                 {verb} {:.2}): share of the SMRMSG variance position {}, attitude {}; \
                 correlation time position {}, attitude {}.\n",
                slow.lr_statistic,
                slow.lr_threshold,
                p(&slow.position_share, ""),
                p(&slow.attitude_share, ""),
                p(&slow.position_tau_s, " s"),
                p(&slow.attitude_tau_s, " s")
            );
            if slow.in_tests {
                let _ = writeln!(
                    s,
                    "The survey cannot reject it either: the tests take their largest p-value \
                     under it too, and each estimate's sigma is the larger of the two models'.
"
                );
            }
        }
    }

    /// "No effect larger than ...": what this survey would have named with 90% probability.
    fn write_detectable(&self, s: &mut String) {
        let _ = writeln!(
            s,
            "## What this survey could have found

No catalogue effect is named; each would \
             have been named with 90% probability from this size (diagnosis.json `detectable`):\n"
        );
        let _ = writeln!(s, "| effect | detectable from |\n|---|---:|");
        for (name, d) in &self.detectable {
            let v = d.map_or("no signature here".to_string(), |v| format!("{v:.3e}"));
            let _ = writeln!(s, "| {name} | {v} |");
        }
        s.push('\n');
    }

    /// Patches whose returns lay off their plane as a whole, by patch.
    fn write_displaced(&self, s: &mut String) {
        let displaced = &self.counts.displaced_patches;
        if displaced.is_empty() {
            return;
        }
        let _ = writeln!(
            s,
            "\nPatches off their plane: on {} patches more than {:.0}% of the returns inside the \
             rectangle and within 1 m of the plane were beyond `plane_tolerance_m`. The \
             configuration (or the patch file) is off by more than that tolerance; these \
             patches were observed about each visit's median distance from the plane instead \
             of cut.\n\n| patch | share off the plane | median offset (m) |\n|---|---:|---:|",
            displaced.len(),
            100.0 * OFF_PLANE_SHARE
        );
        for d in displaced {
            let _ = writeln!(
                s,
                "| {} | {:.0}% | {:+.3} |",
                d.id,
                100.0 * d.off_plane_share,
                d.median_offset_m
            );
        }
    }

    /// Returns set aside as foreign to their reference, by reference.
    fn write_foreign(&self, s: &mut String) {
        let f = &self.foreign;
        let _ = writeln!(
            s,
            "\nForeign returns (off their reference's surface by more than {} sigma: people, cars, \
             objects in front, edges; or together, with their {} m square of the patch, by more \
             than {} times the squares' spread: kerbs, frames): {} set aside ({} with {} \
             squares); {} weighted down (off by {}-{} sigma: counted as at {} sigma); {} on \
             references left out as mostly foreign{}.",
            screen::THRESHOLD,
            screen::CELL_M,
            screen::CELL_THRESHOLD,
            f.set_aside,
            f.by_place,
            f.squares_set_aside,
            f.down_weighted,
            screen::SOFT,
            screen::THRESHOLD,
            screen::SOFT,
            f.on_unused_references,
            if f.unused_references.is_empty() {
                String::new()
            } else {
                format!(" ({})", f.unused_references.join(", "))
            }
        );
        if !f.by_reference.is_empty() {
            let _ = writeln!(
                s,
                "\n| reference | observations | set aside | with their square | weighted down |\n\
                 |---|---:|---:|---:|---:|"
            );
            for (id, r) in &f.by_reference {
                let _ = writeln!(
                    s,
                    "| {id} | {} | {} | {} | {} |",
                    r.observations, r.set_aside, r.by_place, r.down_weighted
                );
            }
        }
    }

    /// The one-line verdict.
    pub fn headline(&self) -> String {
        match self.verdict {
            Verdict::Effect => {
                let named: Vec<String> = self
                    .effects
                    .iter()
                    .map(|e| format!("{e} = {:.4e} +- {:.1e}", self.estimate[e], self.sigma[e]))
                    .collect();
                format!("effect: {}", named.join(", "))
            }
            Verdict::None => "none: the survey agrees with its model".into(),
            Verdict::Unexplained => format!(
                "unexplained: no catalogue effect closes the gap; it lies in {}",
                if self.located_in.is_empty() {
                    "no single covariate".to_string()
                } else {
                    self.located_in.join(", ")
                }
            ),
        }
    }

    /// The named groups of more than one effect: which effects the references cannot tell
    /// apart, which one the re-run uses, and what data would separate them.
    fn write_named_groups(&self, s: &mut String) {
        let named = self
            .groups
            .iter()
            .filter(|g| g.members.len() > 1 && self.effects.contains(&g.members[0]));
        for (i, g) in named.enumerate() {
            if i == 0 {
                let _ = writeln!(s, "## Effects these references cannot tell apart\n");
            }
            let list = |m: &[String]| {
                m.iter()
                    .map(|m| format!("`{m}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            let (why, corrected) = if g.rivals.is_empty() {
                let corrected = if g.first_is_preferred {
                    "the more common cause"
                } else {
                    "the one the held-out references fit better"
                };
                (
                    "|correlation| > 0.9 on these references".to_string(),
                    corrected,
                )
            } else {
                (
                    format!(
                        "|correlation| up to {:.2} on these references, and `{}` is not \
                         significant beside any one of {} put in its place",
                        g.max_abs_correlation,
                        g.members[0],
                        list(&g.rivals)
                    ),
                    "the one the selection chose",
                )
            };
            let _ = writeln!(
                s,
                "The residuals fit each of {} about as well ({why}): the estimate of each is \
                 what it would be if it alone were the cause. The re-run corrects `{}` \
                 ({corrected}). To tell them apart: {}.\n",
                list(&g.members),
                g.members[0],
                g.hint
            );
        }
    }

    /// `summary.md`: verdict, gap before/after, where it lies, the re-run, the plots, the data.
    pub fn summary(&self, pipeline: &Path) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "# Diagnosis of {}\n", pipeline.display());
        let _ = writeln!(s, "**Verdict: {}**\n", self.headline());
        let _ = writeln!(s, "{}\n", self.reason);
        self.write_named_groups(&mut s);
        let _ = writeln!(s, "## Gap on the held-out references\n");
        let _ = writeln!(
            s,
            "| | chi2/dof | RMS (mm) | mean (mm) | 95% coverage | returns |"
        );
        let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|");
        for (name, g) in [("before", &self.gap.before), ("after", &self.gap.after)] {
            let _ = writeln!(
                s,
                "| {name} | {:.2} | {:.1} | {:+.1} | {:.1}% | {} |",
                g.chi2_per_dof,
                g.rms_m * 1e3,
                g.mean_m * 1e3,
                g.coverage_95 * 100.0,
                g.n
            );
        }
        let returns = if !self.set.is_empty() && self.gap.same_returns {
            "Before and after are over the same held-out returns: those the survey observed \
             again with the correction still finds on the references (the tests in the verdict \
             take each observation's own). "
        } else if self.gap.same_returns {
            ""
        } else {
            "The survey observed again shares no held-out return with the first observation: \
             before and after are each over its own. "
        };
        let _ = writeln!(
            s,
            "\n{returns}An honest model gives chi2/dof near 1 and 95% coverage near 95%.\n"
        );
        self.write_nuisance(&mut s);
        if self.verdict == Verdict::None {
            self.write_detectable(&mut s);
        }
        if !self.covariate_tests.is_empty() {
            let _ = writeln!(s, "## Where the gap lies\n");
            let _ = writeln!(s, "| covariate | p-value |\n|---|---:|");
            for t in self.covariate_tests.iter().take(6) {
                let _ = writeln!(s, "| {} | {:.2e} |", t.covariate, t.p_value);
            }
            s.push('\n');
        }
        if let Some(m) = &self.model_free {
            let _ = writeln!(s, "{}\n", model_free_line(m, &self.gap));
        }
        if !self.pipeline_sets.is_empty() {
            self.write_pipeline_sets(&mut s);
        } else if !self.set.is_empty() {
            let _ = writeln!(s, "## Re-run with the correction\n\n```");
            let sets: Vec<String> = self.set.iter().map(|l| format!("--set '{l}'")).collect();
            let _ = writeln!(s, "kinescan run {} {}", pipeline.display(), sets.join(" "));
            let _ = writeln!(
                s,
                "```\n\nor `kinescan run {}` in this folder.\n",
                super::confirm::reprocess::CORRECTED_PIPELINE
            );
        }
        if !self.plots.is_empty() {
            let _ = writeln!(s, "## Plots\n");
            for p in &self.plots {
                let _ = writeln!(s, "![{p}]({p})\n");
            }
        }
        let c = &self.counts;
        let _ = writeln!(s, "## Data used\n");
        let _ = writeln!(
            s,
            "{} returns read; {} on {} of {} patches ({} kept as observations, {} thinned, {} in \
             short visits); {} off the patches, {} near a patch but off its plane, {} not \
             georeferenced. Fitted on {} references, tested on {} held out.",
            c.returns_read,
            c.on_patches,
            c.patches_read - c.patches_without_observations.len(),
            c.patches_read,
            c.observations,
            c.thinned,
            c.in_short_visits,
            c.off_patches,
            c.off_plane,
            c.rejected.values().sum::<u64>(),
            self.split.fit.len(),
            self.split.held_out.len()
        );
        self.write_displaced(&mut s);
        self.write_foreign(&mut s);
        let (r, v) = (&self.motion.rates, &self.motion.velocities);
        let source = |m: crate::trajectory::MotionSource, of: &str| match m {
            crate::trajectory::MotionSource::SbetFields => "the SBET's own fields".to_string(),
            crate::trajectory::MotionSource::Trajectory => {
                format!(
                    "derived from the trajectory's {of} (the SBET fields are empty or disagree)"
                )
            }
        };
        let _ = writeln!(
            s,
            "\nBody rates for the timing signatures: {} (SBET rate fields rms {:.3} deg/s, \
             rates of its attitude {:.3} deg/s, difference {:.3} deg/s). Velocities: {} \
             (SBET velocity fields rms {:.3} m/s, velocity of its positions {:.3} m/s, \
             difference {:.3} m/s).",
            source(r.source, "attitude"),
            r.fields_rms_radps.to_degrees(),
            r.derived_rms_radps.to_degrees(),
            r.difference_rms_radps.to_degrees(),
            source(v.source, "positions"),
            v.fields_rms_mps,
            v.derived_rms_mps,
            v.difference_rms_mps
        );
        if c.control_points_read > 0 {
            let _ = writeln!(
                s,
                "\nControl points: {} returns on the targets of {} of {} points, {} visits \
                 observed ({} centroid observations), {} returns in visits left out ({} not \
                 flat). Points without a visit: {}.",
                c.on_targets,
                c.control_points_read - c.control_points_without_observations.len(),
                c.control_points_read,
                c.target_visits,
                c.target_observations,
                c.target_returns_unused,
                c.target_visits_not_flat,
                if c.control_points_without_observations.is_empty() {
                    "none".to_string()
                } else {
                    c.control_points_without_observations.join(", ")
                }
            );
        }
        s
    }
}

/// The summary's sentence on the model-free correction `m`, against the held-out gap `gap`
/// (after = with the correction): a share of the excess where the chi-square over every
/// held-out return was significantly above 1 (3 of its sds), else the chi2/dof it moves, since
/// structure confirmed beside a chi-square that passed leaves no excess to take a share of.
fn model_free_line(m: &ModelFreeReport, gap: &GapBeforeAfter) -> String {
    let before = gap.before.chi2_per_dof;
    if before - 1.0 > 3.0 * gap.before_chi2_per_dof_sd {
        format!(
            "A model-free offset binned along `{}` closes {:.0}% of the held-out excess \
             chi-square (diagnosis.json `model_free`).",
            m.covariate,
            m.closed_fraction * 100.0
        )
    } else {
        format!(
            "A model-free offset binned along `{}` takes the held-out chi2/dof from {before:.3} \
             to {:.3}; over every held-out return there was no significant excess \
             (diagnosis.json `model_free`).",
            m.covariate, gap.after.chi2_per_dof
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The model-free sentence gives a share only where there was a significant excess.
    #[test]
    fn model_free_line_gives_a_share_only_of_a_significant_excess() {
        let g = |chi2_per_dof: f64| GapMetrics {
            chi2_per_dof,
            rms_m: 0.01,
            mean_m: 0.0,
            coverage_95: 0.95,
            n: 5000,
        };
        let m = ModelFreeReport {
            covariate: "range_m".into(),
            bins: Vec::new(),
            closed_fraction: 0.9,
        };
        let gap = |before: f64, after: f64| GapBeforeAfter {
            before: g(before),
            after: g(after),
            before_chi2_per_dof_sd: 0.02,
            after_chi2_per_dof_sd: 0.02,
            after_chi2_per_dof_given_estimate: after,
            same_returns: true,
        };
        let excess = model_free_line(&m, &gap(1.5, 1.05));
        assert!(
            excess.contains("closes 90% of the held-out excess"),
            "{excess}"
        );
        // 0.995 with structure confirmed: no share of an excess that is not there.
        let none = model_free_line(&m, &gap(0.995, 0.778));
        assert!(
            none.contains("from 0.995 to 0.778") && !none.contains('%'),
            "{none}"
        );
        // Above 1 by less than 3 sds: still no share.
        assert!(!model_free_line(&m, &gap(1.05, 1.0)).contains('%'));
    }
}
