//! `kinescan diagnose`: where a survey departs from its model, which catalogue effect causes
//! it, and how far the gap shrinks once that effect is added (docs/diagnosis.md).
//!
//! Data flow: [`observe`] (returns on reference patches -> observations) -> the statistics
//! (split by reference, observability, selection, location, model-free correction) ->
//! [`reprocess`] (the chosen effects added to the pipeline, the held-out references observed
//! again) -> [`report`] and [`plots`] (diagnosis.json, summary.md, PNGs, corrected.toml).

pub mod analysis;
pub mod continuous;
mod design;
pub mod fit;
pub mod locate;
pub mod metrics;
pub mod model;
pub mod nuisance;
pub mod observability;
pub mod observe;
pub mod plots;
pub mod power;
pub mod report;
pub mod reprocess;
pub mod screen;
pub mod select;

use crate::io::publish::publish_folder;
use crate::pipeline::config::{DiagnoseConfig, LoadedPipeline};
use crate::Result;
use std::path::{Path, PathBuf};

/// What to diagnose against and where to write.
#[derive(Debug, Clone)]
pub struct Request {
    /// Reference planar patches (patch CSV).
    pub patches: PathBuf,
    /// Control points (control-point CSV: target face centres), optional references.
    pub control_points: Option<PathBuf>,
    /// Output folder (created if missing).
    pub out_dir: PathBuf,
}

impl Request {
    /// The diagnosis of pipeline `p`: `patches`, `control_points` and `out_dir` when given
    /// (the command line), else its `[diagnose]` table's `patches`, `control_points` and
    /// `out`; the folder defaults to `diagnosis`. None without patches.
    pub fn of(
        p: &LoadedPipeline,
        patches: Option<PathBuf>,
        control_points: Option<PathBuf>,
        out_dir: Option<PathBuf>,
    ) -> Option<Self> {
        let section = p.config.diagnose.clone().unwrap_or_default();
        Some(Request {
            patches: patches.or(section.patches.map(PathBuf::from))?,
            control_points: control_points.or(section.control_points.map(PathBuf::from)),
            out_dir: out_dir
                .or(section.out.map(PathBuf::from))
                .unwrap_or_else(|| PathBuf::from("diagnosis")),
        })
    }
}

/// What the statistics conclude on one observation set (the seam between the statistics and
/// the report).
struct Statistics {
    /// Reference indices fitted on and held out.
    fit: Vec<usize>,
    held_out: Vec<usize>,
    verdict: report::Verdict,
    /// Named effects: (effect, estimate, sigma), the re-processed ones first.
    named: Vec<(model::Effect, f64, f64)>,
    /// The effects re-processed with (a group's preferred member, or a combination).
    applied: Vec<(model::Effect, f64)>,
    reason: String,
    before: report::GapMetrics,
    observability: report::ObservabilityReport,
    groups: Vec<report::GroupReport>,
    candidates: Vec<report::CandidateReport>,
    covariate_tests: Vec<report::CovariateReport>,
    /// Covariates where the gap lies (Holm-significant tests), in rank order.
    located_in: Vec<String>,
    /// The model-free correction and the held-out gap after it.
    model_free: Option<(report::ModelFreeReport, report::GapMetrics)>,
    /// Normalised residual of every observation under the null model.
    normalised: Vec<f64>,
    /// Smallest size of every catalogue effect named with 90% probability.
    detectable: Vec<(model::Effect, Option<f64>)>,
}

/// What the statistics learned from the survey before testing it: the returns set aside as
/// foreign, and the navigation error model.
struct Learned {
    screening: screen::Screening,
    nuisance: nuisance::Nuisance,
}

impl Learned {
    /// Screens `set` for foreign returns and estimates the navigation error model on its fit
    /// references; returns the set the statistics run on (screened, model applied).
    fn from(
        set: &model::ObservationSet,
        cfg: &DiagnoseConfig,
    ) -> Result<(Self, model::ObservationSet)> {
        let (screened, screening) = screen::screen(set, cfg.max_foreign_share);
        let split = fit::split(&screened, cfg.seed)?;
        let held = nuisance::Held {
            position_tau_s: cfg.nav_position_tau_s,
            attitude_tau_s: cfg.nav_attitude_tau_s,
            position_scale: cfg.nav_position_scale,
            attitude_scale: cfg.nav_attitude_scale,
        };
        let start = screened
            .nav_tau_s
            .unwrap_or(crate::pipeline::config::START_NAV_TAU_S);
        let nuisance = nuisance::estimate(&screened, &split.fit, &held, start)?;
        let applied = nuisance::apply(&screened, &nuisance);
        Ok((
            Learned {
                screening,
                nuisance,
            },
            applied,
        ))
    }

    /// The same screening and navigation model on a survey observed again.
    fn apply(&self, set: &model::ObservationSet) -> model::ObservationSet {
        let (screened, _) = screen::screen(set, self.screening.max_foreign_share);
        nuisance::apply(&screened, &self.nuisance)
    }
}

/// Covariates shown in plots (the leading ones of the tests).
const PLOTTED_COVARIATES: usize = 3;

/// Diagnoses pipeline `p` against the reference patches (and control points) of `req`;
/// writes the report files into `req.out_dir` and returns the report.
pub fn run(p: &LoadedPipeline, req: &Request) -> Result<report::Diagnosis> {
    observe::check_pipeline(p)?;
    let cfg = p.config.diagnose.clone().unwrap_or_default();
    check_collisions(p, req)?;
    let refs = observe::References::read(&req.patches, req.control_points.as_deref())?;
    let mut observed = observe::observe(p, &refs, &cfg)?;
    let (learned, set) = Learned::from(&observed.set, &cfg)?;
    observed.set = set;
    let stats = statistics(&observed.set, &cfg)?;
    let names = output_names();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    publish_folder(
        &req.out_dir,
        "diagnosis",
        report::DIAGNOSIS_JSON,
        &names,
        |dir| write_outputs(p, req, &refs, (observed, learned), stats, dir),
    )
}

/// Everything after the statistics, written into the staging folder `dir` (published by
/// [`run`] as one set): the re-processing, the plots, the report.
fn write_outputs(
    p: &LoadedPipeline,
    req: &Request,
    refs: &observe::References,
    (observed, learned): (observe::Observed, Learned),
    stats: Statistics,
    dir: &Path,
) -> Result<report::Diagnosis> {
    let cfg = p.config.diagnose.clone().unwrap_or_default();
    let set = &observed.set;
    let ids = |refs: &[usize]| -> Vec<String> {
        refs.iter().map(|&r| set.reference_ids[r].clone()).collect()
    };
    let held_out_ids = ids(&stats.held_out);
    let before_normalised = held_out_values(set, &stats.held_out, &stats.normalised);
    let (set_lines, after, after_normalised) = match (&stats.verdict, &stats.model_free) {
        (report::Verdict::Effect, _) => {
            let lines = reprocess::set_lines(&p.config, &stats.applied)?;
            let corrected = reprocess::corrected(p, &lines, &req.out_dir)?;
            let again = learned.apply(&observe::observe(&corrected, refs, &cfg)?.set);
            let held = references_of(&again, &held_out_ids);
            let (after, normalised) = gap_of(&again, &held)?;
            reprocess::write_pipeline(
                &corrected.config,
                &p.path,
                &lines,
                &dir.join(reprocess::CORRECTED_PIPELINE),
            )?;
            (lines, after, normalised)
        }
        (_, Some((_, after))) => (Vec::new(), *after, Vec::new()),
        _ => (Vec::new(), stats.before, Vec::new()),
    };
    let mut plot_files = Vec::new();
    for t in stats.covariate_tests.iter().take(PLOTTED_COVARIATES) {
        let Some(c) = model::Covariate::ALL
            .iter()
            .find(|c| c.name() == t.covariate)
        else {
            continue;
        };
        let points: Vec<(f64, f64)> = set
            .observations
            .iter()
            .zip(&stats.normalised)
            .map(|(o, &z)| (c.value(&o.covariates), z))
            .collect();
        let plot = plots::covariate_plot(&t.covariate, &points, &t.bins);
        let file = plots::covariate_file(&t.covariate);
        plot_files.push(plots::write_png(&plot, dir, &file)?);
    }
    if !after_normalised.is_empty() {
        let plot = plots::before_after_plot(&before_normalised, &after_normalised);
        plot_files.push(plots::write_png(&plot, dir, plots::BEFORE_AFTER)?);
    }
    let d = report::Diagnosis {
        verdict: stats.verdict,
        effects: stats
            .named
            .iter()
            .map(|(e, _, _)| e.name().to_string())
            .collect(),
        estimate: stats
            .named
            .iter()
            .map(|(e, x, _)| (e.name().to_string(), *x))
            .collect(),
        sigma: stats
            .named
            .iter()
            .map(|(e, _, s)| (e.name().to_string(), *s))
            .collect(),
        located_in: stats.located_in,
        gap: report::GapBeforeAfter {
            before: stats.before,
            after,
        },
        set: set_lines,
        reason: stats.reason,
        split: report::SplitReport {
            seed: cfg.seed,
            fit: ids(&stats.fit),
            held_out: held_out_ids,
        },
        observability: stats.observability,
        groups: stats.groups,
        candidates: stats.candidates,
        covariate_tests: stats.covariate_tests,
        model_free: stats.model_free.map(|(m, _)| m),
        detectable: stats
            .detectable
            .iter()
            .map(|(e, d)| (e.name().to_string(), *d))
            .collect(),
        nuisance: learned.nuisance,
        rates: observed.rates,
        foreign: learned.screening,
        counts: observed.counts,
        plots: plot_files,
    };
    d.write(dir, &p.path)?;
    Ok(d)
}

/// The indices of reference ids `ids` in `set` (ids without observations there are skipped).
fn references_of(set: &model::ObservationSet, ids: &[String]) -> Vec<usize> {
    ids.iter()
        .filter_map(|id| set.reference_ids.iter().position(|r| r == id))
        .collect()
}

/// `values` of the observations on `refs`.
fn held_out_values(set: &model::ObservationSet, refs: &[usize], values: &[f64]) -> Vec<f64> {
    set.observations
        .iter()
        .zip(values)
        .filter(|(o, _)| refs.contains(&o.reference))
        .map(|(_, &v)| v)
        .collect()
}

/// Refuses outputs that would overwrite an input (or each other) before any work (`diagnose`
/// and `validate`).
pub fn check_collisions(p: &LoadedPipeline, req: &Request) -> Result<()> {
    let mut inputs = crate::pipeline::files::inputs(p);
    inputs.push(("--patches".into(), req.patches.clone()));
    if let Some(c) = &req.control_points {
        inputs.push(("--control-points".into(), c.clone()));
    }
    let names = output_names();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    crate::io::paths::check_collisions(&inputs, &crate::io::paths::in_out_dir(&req.out_dir, &names))
}

/// Every file a diagnosis may write into its folder (which plots depends on the covariates).
fn output_names() -> Vec<String> {
    let fixed = [
        report::DIAGNOSIS_JSON,
        report::SUMMARY_MD,
        reprocess::CORRECTED_PIPELINE,
        reprocess::CORRECTED_LAS,
        plots::BEFORE_AFTER,
    ];
    let covariates = model::Covariate::ALL
        .iter()
        .map(|c| plots::covariate_file(c.name()));
    fixed
        .into_iter()
        .map(String::from)
        .chain(covariates)
        .collect()
}

/// Runs the statistics on `set` ([`analysis::analyse`]) and keeps what the report needs.
fn statistics(set: &model::ObservationSet, cfg: &DiagnoseConfig) -> Result<Statistics> {
    let settings = analysis::Settings {
        seed: cfg.seed,
        alpha: cfg.alpha,
        bins: locate::DEFAULT_BINS,
    };
    let a = analysis::analyse(set, &settings)?;
    let sel = &a.selection;
    let model_free = a.model_free.as_ref().map(|m| {
        let r = report::ModelFreeReport {
            covariate: m.covariate.name().into(),
            bins: m.bins.iter().map(|b| bin_report(b, b.offset_m)).collect(),
            closed_fraction: m.closure.unwrap_or(0.0),
        };
        (r, gap_metrics(&m.after))
    });
    let obs = &sel.observability;
    let named = sel
        .effects
        .iter()
        .zip(sel.estimate.iter().zip(&sel.sigma))
        .map(|(&e, (&x, &s))| (e, x, s))
        .collect();
    let applied = sel.correction().map_or_else(Vec::new, |t| {
        t.effects
            .iter()
            .copied()
            .zip(t.values.iter().copied())
            .collect()
    });
    Ok(Statistics {
        fit: a.split.fit.clone(),
        held_out: a.split.held_out.clone(),
        verdict: match sel.verdict {
            select::Verdict::Effect => report::Verdict::Effect,
            select::Verdict::None => report::Verdict::None,
            select::Verdict::Unexplained => report::Verdict::Unexplained,
        },
        named,
        applied,
        reason: a.reason.clone(),
        before: gap_metrics(&a.before),
        observability: report::ObservabilityReport {
            condition_number: obs.condition_number,
            effects: obs
                .effects
                .iter()
                .zip(&obs.vif)
                .map(|(e, &vif)| report::ObservabilityRow {
                    effect: e.name().into(),
                    vif,
                })
                .collect(),
            unobservable: obs
                .unobservable
                .iter()
                .map(|e| e.name().to_string())
                .collect(),
        },
        groups: obs
            .groups
            .iter()
            .filter(|g| g.members.len() > 1)
            .map(|g| report::GroupReport {
                members: g.members.iter().map(|e| e.name().to_string()).collect(),
                hint: g.separating_data.join("; "),
            })
            .collect(),
        candidates: sel
            .candidates
            .iter()
            .map(|c| report::CandidateReport {
                effects: c.fit.effects.iter().map(|e| e.name().to_string()).collect(),
                estimate: c.fit.estimate.clone(),
                sigma: c.fit.sigma.clone(),
                held_out_chi2_reduction: c.held_out_reduction,
                p_value: c.p_value,
                held_out_p_value: c.held_out_p_value,
                significant: c.significant,
            })
            .collect(),
        covariate_tests: a
            .covariate_tests
            .iter()
            .map(|t| report::CovariateReport {
                covariate: t.covariate.name().into(),
                p_value: t.p_value,
                bins: t
                    .bins
                    .iter()
                    .map(|b| bin_report(b, b.mean_normalised))
                    .collect(),
            })
            .collect(),
        located_in: a.located_in.iter().map(|c| c.name().to_string()).collect(),
        model_free,
        normalised: locate::normalised_residuals(set, None),
        detectable: {
            let (fit_n, held_n) = (
                fit::Normals::of(set, &a.split.fit)?,
                fit::Normals::of(set, &a.split.held_out)?,
            );
            let g = obs.groups.len();
            power::detectable(&fit_n, &held_n, cfg.alpha, g + g * (g - 1) / 2)
        },
    })
}

/// The held-out gap of a re-processed set and its normalised residuals there.
fn gap_of(set: &model::ObservationSet, refs: &[usize]) -> Result<(report::GapMetrics, Vec<f64>)> {
    let g = metrics::gap(set, refs, None)?;
    let z = locate::normalised_residuals(set, None);
    Ok((gap_metrics(&g), held_out_values(set, refs, &z)))
}

fn gap_metrics(g: &metrics::Gap) -> report::GapMetrics {
    report::GapMetrics {
        chi2_per_dof: g.chi2_per_dof,
        rms_m: g.rms_m,
        mean_m: g.mean_m,
        coverage_95: g.coverage_95,
        n: g.n,
    }
}

fn bin_report(b: &locate::Bin, value: f64) -> report::BinReport {
    report::BinReport {
        range: [b.lower, b.upper],
        n: b.n,
        mean: value,
    }
}
