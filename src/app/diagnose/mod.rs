//! `kinescan diagnose`: where a survey departs from its model, which catalogue effect causes
//! it, and how far the gap shrinks once that effect is added (docs/diagnosis.md).
//!
//! The stages, in the order the data flows through them (docs/diagnosis.md, "Method"):
//! [`observe`] (returns on reference patches -> observations) -> [`model`] (the observation
//! set, validated once) -> [`nuisance`] (foreign returns set aside, the navigation error model
//! learned) -> [`select`] (which effect) -> [`locate`] (where the gap lies) -> [`confirm`] (the
//! explanation applied and the survey observed again) -> [`report`]. [`run`] calls them in
//! that order. `model` holds what every stage shares (the observation types, the residual
//! model's GLS algebra, the tests' tail probabilities); otherwise a stage imports only stages
//! before it.

/// 1. Returns on the references -> observations.
pub mod observe;

/// 2. The observation set, validated once, with its residual model, GLS algebra and tests.
pub mod model;

/// 3. What the null model needs, learned from the survey: foreign returns, navigation errors.
pub mod nuisance;

/// 4. Which catalogue effect explains the gap: observability, candidates, verdict, power.
pub mod select;

/// 5. Where the gap lies: covariate tests and the model-free correction.
pub mod locate;

/// 4 and 5 on one observation set in one call.
pub mod analysis;

/// 6. The explanation judged on the survey observed again with it.
pub mod confirm;

/// 7. diagnosis.json, summary.md, PNGs, corrected.toml.
pub mod report;

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
    /// The effects re-processed with (one member of a group, or a combination).
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
    /// Everything the statistics concluded (for the verdict on the re-observed gap).
    analysis: analysis::Analysis,
}

/// What the statistics learned from the survey before testing it: the returns set aside as
/// foreign, and the navigation error model.
struct Learned {
    screening: nuisance::screen::Screening,
    nuisance: nuisance::Nuisance,
    /// The fit references' normals under the models at the ends of the attitude correlation
    /// time's profile interval (`nuisance::interval_ends`) and the slow process's model the
    /// survey cannot reject (`nuisance::slow_alternative`).
    others: Vec<select::OtherModel>,
    /// Those other models themselves, in the same order.
    alternatives: Vec<nuisance::Nuisance>,
    /// The fit references' normals under the nodes of the quadrature over the learned
    /// model's sampling distribution (`nuisance::sampling_nodes`), which the sigmas average over.
    nodes: Vec<select::Node>,
    /// What the model's sampling error adds to the variance of the held-out `r^T C^-1 r`.
    held_out_chi2_var: f64,
}

impl Learned {
    /// Screens `set` for foreign returns and estimates the navigation error model on its fit
    /// references; returns the set the statistics run on (screened, model applied).
    fn from(
        set: model::ObservationSet,
        cfg: &DiagnoseConfig,
    ) -> Result<(Self, model::ObservationSet)> {
        let (mut screened, screening) = nuisance::screen::screen(set, cfg.max_foreign_share);
        let split = model::fit::split(&screened, cfg.seed)?;
        let held = nuisance::Held {
            position_tau_s: cfg.nav_position_tau_s,
            attitude_tau_s: cfg.nav_attitude_tau_s,
            position_scale: cfg.nav_position_scale,
            attitude_scale: cfg.nav_attitude_scale,
            position_white_share: cfg.nav_position_white_share,
            attitude_white_share: cfg.nav_attitude_white_share,
            position_slow_share: cfg.nav_position_slow_share,
            attitude_slow_share: cfg.nav_attitude_slow_share,
            position_slow_tau_s: cfg.nav_position_slow_tau_s,
            attitude_slow_tau_s: cfg.nav_attitude_slow_tau_s,
        };
        let start = screened
            .nav_tau_s
            .unwrap_or(crate::pipeline::config::START_NAV_TAU_S);
        let nuisance = nuisance::estimate(&screened, &split.fit, &held, start)?;
        let held_out_chi2_var = nuisance::chi2_variance(&screened, &split.held_out, &nuisance);
        let ends = nuisance::interval_ends(&nuisance);
        let widens_sigma = std::iter::repeat_n(false, ends.len()).chain([true]);
        let alternatives: Vec<_> = ends
            .into_iter()
            .chain(nuisance::slow_alternative(&nuisance))
            .collect();
        let others: Vec<select::OtherModel> = alternatives
            .iter()
            .zip(widens_sigma)
            .map(|(n, widens_sigma)| {
                Ok(select::OtherModel {
                    normals: nuisance::normals_under(&mut screened, n, &split.fit)?,
                    widens_sigma,
                })
            })
            .collect::<Result<_>>()?;
        // A node that is one of the tests' models (the profile interval's ends) reuses its
        // normals.
        let nodes = nuisance::sampling_nodes(&nuisance)
            .into_iter()
            .map(|(n, weight)| {
                let normals = match alternatives.iter().position(|a| *a == n) {
                    Some(k) => others[k].normals.clone(),
                    None => nuisance::normals_under(&mut screened, &n, &split.fit)?,
                };
                Ok(select::Node { normals, weight })
            })
            .collect::<Result<_>>()?;
        let applied = nuisance::apply(screened, &nuisance);
        Ok((
            Learned {
                screening,
                nuisance,
                others,
                alternatives,
                nodes,
                held_out_chi2_var,
            },
            applied,
        ))
    }

    /// The same screening and navigation model on a survey observed again, and what the
    /// model's sampling error adds to the variance of `r^T C^-1 r` on references `held_out`.
    fn apply(
        &self,
        set: model::ObservationSet,
        held_out: &[String],
    ) -> (model::ObservationSet, f64) {
        let (screened, _) = nuisance::screen::screen(set, self.screening.max_foreign_share);
        let refs = confirm::references_of(&screened, held_out);
        let var = nuisance::chi2_variance(&screened, &refs, &self.nuisance);
        (nuisance::apply(screened, &self.nuisance), var)
    }
}

/// Covariates shown in plots (the leading ones of the tests).
const PLOTTED_COVARIATES: usize = 3;

/// Stages of a diagnosis shown by its progress bar: observe, learn, test, at most
/// [`confirm::MAX_ROUNDS`] rounds of re-observation, write.
const STAGES: u64 = 4 + confirm::MAX_ROUNDS as u64;

/// Diagnoses pipeline `p` against the reference patches (and control points) of `req`;
/// writes the report files into `req.out_dir` and returns the report.
pub fn run(p: &LoadedPipeline, req: &Request) -> Result<report::Diagnosis> {
    run_with_progress(p, req, &indicatif::ProgressBar::hidden())
}

/// [`run`], showing its stages on `bar` (e.g. [`crate::progress::stages`] of [`STAGES`]).
pub fn run_with_progress(
    p: &LoadedPipeline,
    req: &Request,
    bar: &indicatif::ProgressBar,
) -> Result<report::Diagnosis> {
    run_joint(std::slice::from_ref(p), req, bar)
}

/// [`run_with_progress`] of the surveys of one mount (a day's passes, docs/nightly.md):
/// every pipeline of `ps` observed, the observations joined (one set of catalogue effects,
/// each survey its own visits), the nuisance learned and the effect selected once, the
/// correction applied to every pipeline and all observed again. The `[diagnose]` settings are
/// the first pipeline's. With more than one pipeline no `corrected.toml` is written: each
/// pipeline's `--set` lines are in `pipeline_sets`, those all share in `set`.
pub fn run_joint(
    ps: &[LoadedPipeline],
    req: &Request,
    bar: &indicatif::ProgressBar,
) -> Result<report::Diagnosis> {
    let Some(p) = ps.first() else {
        return Err(crate::Error::Invalid("diagnosis: no pipeline".into()));
    };
    for q in ps {
        observe::check_pipeline(q)?;
        check_collisions(q, req)?;
    }
    let cfg = p.config.diagnose.clone().unwrap_or_default();
    let refs = observe::References::read(&req.patches, req.control_points.as_deref())?;
    bar.set_length(STAGES);
    bar.set_message("observing the returns on the references");
    let mut observed = observe::observe_joint(ps, &refs, &cfg)?;
    bar.inc(1);
    bar.set_message("screening foreign returns, learning the navigation error model");
    let (learned, set) = Learned::from(std::mem::take(&mut observed.set), &cfg)?;
    observed.set = set;
    bar.inc(1);
    bar.set_message("testing the catalogue");
    let mut stats = statistics(&observed.set, &cfg, &learned)?;
    confirm_agreement(&mut observed.set, &learned, &mut stats)?;
    bar.inc(1);
    bar.set_message("observing again with the proposed correction");
    let confirmation =
        confirm_explanation(ps, req, &refs, &learned, &observed.set, &mut stats, bar)?;
    bar.set_position(STAGES - 1);
    bar.set_message("writing the report");
    let names = output_names();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let d = publish_folder(
        &req.out_dir,
        "diagnosis",
        report::DIAGNOSIS_JSON,
        &names,
        |dir| write_outputs(ps, (observed, learned), stats, confirmation.as_ref(), dir),
    )?;
    bar.finish_and_clear();
    Ok(d)
}

/// Judges the selection's `none` on the held-out references: where the fit references
/// located structure (`located_in`), the same binned offsets are tested on the held-out
/// references, under the learned navigation model and every other the survey cannot reject
/// ([`analysis::structure_left`] of no effect). Structure confirmed there makes the verdict
/// `unexplained`, with the model-free correction along the leading covariate: a departure the
/// held-out chi-square over every return is too blunt to see. The covariates are chosen on
/// the fit references, so the held-out test keeps its level. Updates `stats` (verdict,
/// reason, model-free correction); `set` is left as it was.
fn confirm_agreement(
    set: &mut model::ObservationSet,
    learned: &Learned,
    stats: &mut Statistics,
) -> Result<()> {
    let a = &stats.analysis;
    if a.selection.verdict != select::Verdict::None || a.located_in.is_empty() {
        return Ok(());
    }
    let held_out = a.split.held_out.clone();
    let located = a.located_in.clone();
    let alpha = a.selection.alpha;
    let Some(left) = analysis::structure_left(
        set,
        &held_out,
        &located,
        &[],
        Some((&learned.nuisance, &learned.alternatives)),
        (alpha, locate::DEFAULT_BINS),
    )?
    else {
        return Ok(());
    };
    let a = &stats.analysis;
    let m = analysis::model_free_correction(
        set,
        &a.split,
        &a.covariate_tests,
        &a.located_in,
        locate::DEFAULT_BINS,
    )?;
    stats.model_free = Some((model_free_report(&m), gap_metrics(&m.after)));
    stats.reason = analysis::structure_confirmed_reason(&a.selection, &a.located_in, &left, &m);
    stats.analysis.model_free = Some(m);
    stats.verdict = report_verdict(select::Verdict::Unexplained);
    Ok(())
}

/// Judges the selection's proposed explanation on the survey observed again with it
/// ([`confirm`]): the verdict becomes `effect` when the model without it holds on the held-out
/// references, or the re-observed held-out gap passes the same test, and its effects, refitted
/// on the re-observed held-out references, leave no structure along the covariates the gap was
/// located in ([`analysis::structure_left`]); else `unexplained`, with the model-free
/// correction. Updates `stats` (verdict, named, applied, reason).
fn confirm_explanation(
    ps: &[LoadedPipeline],
    req: &Request,
    refs: &observe::References,
    learned: &Learned,
    set: &model::ObservationSet,
    stats: &mut Statistics,
    bar: &indicatif::ProgressBar,
) -> Result<Option<confirm::Confirmation>> {
    let sel = &stats.analysis.selection;
    let (Some(chosen), Some(proposed)) = (sel.chosen.clone(), sel.proposed.clone()) else {
        return Ok(None);
    };
    let (null_rejected, alpha) = (sel.null.rejected, sel.alpha);
    let cfg = ps[0].config.diagnose.clone().unwrap_or_default();
    let ids =
        |r: &[usize]| -> Vec<String> { r.iter().map(|&i| set.reference_ids[i].clone()).collect() };
    let split = stats.analysis.split.clone();
    let (fit_ids, held_out_ids) = (ids(&split.fit), ids(&split.held_out));
    let proposal = confirm::Proposal {
        applied: chosen
            .effects
            .iter()
            .copied()
            .zip(chosen.estimate.iter().copied())
            .collect(),
        covariance: &chosen.cov,
        fit_ids: &fit_ids,
        held_out_ids: &held_out_ids,
    };
    let prepare = |s: model::ObservationSet, held_out: &[String]| {
        bar.inc(1);
        learned.apply(s, held_out)
    };
    let mut c = confirm::confirm(ps, refs, &cfg, &req.out_dir, &proposal, &prepare)?;
    let left = analysis::structure_left(
        &mut c.set,
        &c.held_out,
        &stats.analysis.located_in,
        &proposed.effects,
        Some((&learned.nuisance, &learned.alternatives)),
        (alpha, locate::DEFAULT_BINS),
    )?;
    let holds = (!null_rejected || c.p_value >= alpha) && left.is_none();
    let verdict = if holds {
        select::Verdict::Effect
    } else {
        select::Verdict::Unexplained
    };
    if verdict == select::Verdict::Unexplained && stats.analysis.model_free.is_none() {
        let a = &stats.analysis;
        let m = analysis::model_free_correction(
            set,
            &split,
            &a.covariate_tests,
            &a.located_in,
            locate::DEFAULT_BINS,
        )?;
        stats.model_free = Some((model_free_report(&m), gap_metrics(&m.after)));
        stats.analysis.model_free = Some(m);
    }
    let a = &stats.analysis;
    let reobserved = analysis::Reobserved {
        chi2: c.after.chi2_per_dof * c.after.n as f64,
        chi2_given_estimate: c.after_chi2_given_estimate,
        n: c.after.n,
        p_value: c.p_value,
        rounds: c.rounds,
        left,
    };
    stats.reason = analysis::reason(
        &a.selection,
        verdict,
        &a.located_in,
        a.model_free.as_ref(),
        Some(&reobserved),
    );
    stats.verdict = report_verdict(verdict);
    if holds {
        // The corrected members carry the settled correction; the others keep their
        // first-round estimates (each is what it would be were it alone the cause).
        stats.named = proposed
            .effects
            .iter()
            .zip(proposed.estimate.iter().zip(&proposed.sigma))
            .map(|(&e, (&x, &s))| {
                let settled = c.applied.iter().find(|(f, _)| *f == e).map(|(_, v)| *v);
                (e, settled.unwrap_or(x), s)
            })
            .collect();
        stats.applied = c.applied.clone();
        Ok(Some(c))
    } else {
        stats.named.clear();
        stats.applied.clear();
        Ok(None)
    }
}

/// Everything after the statistics, written into the staging folder `dir` (published by
/// [`run`] as one set): the re-processing, the plots, the report.
fn write_outputs(
    ps: &[LoadedPipeline],
    (observed, learned): (observe::Observed, Learned),
    stats: Statistics,
    confirmation: Option<&confirm::Confirmation>,
    dir: &Path,
) -> Result<report::Diagnosis> {
    let p = &ps[0];
    let cfg = p.config.diagnose.clone().unwrap_or_default();
    let set = &observed.set;
    let ids = |refs: &[usize]| -> Vec<String> {
        refs.iter().map(|&r| set.reference_ids[r].clone()).collect()
    };
    let held_out_ids = ids(&stats.held_out);
    let before_normalised = held_out_values(set, &stats.held_out, &stats.normalised);
    let (mut before, mut same_returns) = (stats.before, true);
    let n_held = stats.before.n;
    let after_var = confirmation.map_or((learned.held_out_chi2_var, n_held), |c| {
        (c.after_chi2_var, c.after.n)
    });
    let (set_lines, after, after_normalised) = match (confirmation, &stats.model_free) {
        (Some(c), _) => {
            let z = locate::normalised_residuals(&c.set, None);
            let matched = confirm::matched_gaps((set, &stats.held_out), (&c.set, &c.held_out))?;
            let after = match matched {
                Some((b, a)) => {
                    before = gap_metrics(&b);
                    gap_metrics(&a)
                }
                None => {
                    same_returns = false;
                    gap_metrics(&c.after)
                }
            };
            if let ([corrected], [lines]) = (&c.corrected[..], &c.set_lines[..]) {
                confirm::reprocess::write_pipeline(
                    &corrected.config,
                    &p.path,
                    lines,
                    &dir.join(confirm::reprocess::CORRECTED_PIPELINE),
                )?;
            }
            (
                c.set_lines.clone(),
                after,
                held_out_values(&c.set, &c.held_out, &z),
            )
        }
        (_, Some((_, after))) => (vec![Vec::new(); ps.len()], *after, Vec::new()),
        _ => (vec![Vec::new(); ps.len()], stats.before, Vec::new()),
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
        let plot = report::plots::covariate_plot(&t.covariate, &points, &t.bins);
        let file = report::plots::covariate_file(&t.covariate);
        plot_files.push(report::plots::write_png(&plot, dir, &file)?);
    }
    if !after_normalised.is_empty() {
        let plot = report::plots::before_after_plot(&before_normalised, &after_normalised);
        plot_files.push(report::plots::write_png(
            &plot,
            dir,
            report::plots::BEFORE_AFTER,
        )?);
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
            before_chi2_per_dof_sd: chi2_per_dof_sd(&before, learned.held_out_chi2_var, n_held),
            after_chi2_per_dof_sd: chi2_per_dof_sd(&after, after_var.0, after_var.1),
            after_chi2_per_dof_given_estimate: confirmation.map_or(after.chi2_per_dof, |c| {
                c.after_chi2_given_estimate / c.after.n.max(1) as f64
            }),
            before,
            after,
            same_returns,
        },
        set: shared_lines(&set_lines),
        pipeline_sets: if ps.len() > 1 { set_lines } else { Vec::new() },
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
        motion: observed.motion,
        foreign: learned.screening,
        counts: observed.counts,
        plots: plot_files,
    };
    d.write(dir, &p.path)?;
    Ok(d)
}

/// The `--set` lines every pipeline's `set_lines` has (all of them for one pipeline).
fn shared_lines(set_lines: &[Vec<String>]) -> Vec<String> {
    let Some((first, rest)) = set_lines.split_first() else {
        return Vec::new();
    };
    let shared = |l: &&String| rest.iter().all(|r| r.contains(l));
    first.iter().filter(shared).cloned().collect()
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
        confirm::reprocess::CORRECTED_PIPELINE,
        confirm::reprocess::CORRECTED_LAS,
        report::plots::BEFORE_AFTER,
    ];
    let covariates = model::Covariate::ALL
        .iter()
        .map(|c| report::plots::covariate_file(c.name()));
    fixed
        .into_iter()
        .map(String::from)
        .chain(covariates)
        .collect()
}

/// Runs the statistics on `set` ([`analysis::analyse`]) and keeps what the report needs.
fn statistics(
    set: &model::ObservationSet,
    cfg: &DiagnoseConfig,
    learned: &Learned,
) -> Result<Statistics> {
    let settings = analysis::Settings {
        held_out_chi2_var: learned.held_out_chi2_var,
        seed: cfg.seed,
        alpha: cfg.alpha,
        bins: locate::DEFAULT_BINS,
    };
    let a = analysis::analyse(set, &settings, (&learned.others, &learned.nodes))?;
    let sel = &a.selection;
    let model_free = a
        .model_free
        .as_ref()
        .map(|m| (model_free_report(m), gap_metrics(&m.after)));
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
        verdict: report_verdict(sel.verdict),
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
        groups: group_reports(&sel.named_groups, &obs.groups),
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
                model::fit::Normals::of(set, &a.split.fit)?,
                model::fit::Normals::of(set, &a.split.held_out)?,
            );
            select::power::detectable(
                &model::Effect::ALL,
                (&fit_n, &held_n),
                &learned.others,
                &obs.groups,
                cfg.alpha,
                cfg.seed,
            )
        },
        analysis: a,
    })
}

/// The groups of more than one member: the named explanation's (with their rivals), then the
/// geometry's others.
fn group_reports(
    named: &[select::observability::Group],
    geometry: &[select::observability::Group],
) -> Vec<report::GroupReport> {
    let names = |e: &[model::Effect]| e.iter().map(|e| e.name().to_string()).collect();
    let in_named =
        |g: &select::observability::Group| named.iter().any(|n| n.members.contains(&g.members[0]));
    named
        .iter()
        .chain(geometry.iter().filter(|g| !in_named(g)))
        .filter(|g| g.members.len() > 1)
        .map(|g| report::GroupReport {
            members: names(&g.members),
            hint: g.separating_data.join("; "),
            rivals: names(&g.rivals),
            max_abs_correlation: g.max_abs_correlation,
            first_is_preferred: g.members.iter().all(|&m| {
                select::observability::preference_rank(g.members[0])
                    <= select::observability::preference_rank(m)
            }),
        })
        .collect()
}

fn report_verdict(v: select::Verdict) -> report::Verdict {
    match v {
        select::Verdict::Effect => report::Verdict::Effect,
        select::Verdict::None => report::Verdict::None,
        select::Verdict::Unexplained => report::Verdict::Unexplained,
    }
}

fn model_free_report(m: &locate::Correction) -> report::ModelFreeReport {
    report::ModelFreeReport {
        covariate: m.covariate.name().into(),
        bins: m.bins.iter().map(|b| bin_report(b, b.offset_m)).collect(),
        // The share of the held-out excess closed, bounded to [0, 1] (an after-gap below the
        // model's own noise closes all of it).
        closed_fraction: m.closure.unwrap_or(0.0).clamp(0.0, 1.0),
    }
}

/// The sd of `g.chi2_per_dof` under the null model: `sqrt(2 / n)` with the model known, and
/// the learned model's sampling error, `extra_var` on the chi-square of `n_full` returns (a
/// systematic shift: the same per return on a subset of them).
fn chi2_per_dof_sd(g: &report::GapMetrics, extra_var: f64, n_full: usize) -> f64 {
    let n_full = n_full.max(1) as f64;
    (2.0 / g.n.max(1) as f64 + extra_var / (n_full * n_full)).sqrt()
}

fn gap_metrics(g: &model::metrics::Gap) -> report::GapMetrics {
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

#[cfg(test)]
mod tests {
    use super::shared_lines;

    /// Pipelines with their own clocks: a clock correction gives each its own `time.t0_s`
    /// line, the mounting line is the same for all and is the one shared.
    #[test]
    fn shared_lines_are_those_of_every_pipeline() {
        let lines = |t0: &str| {
            vec![
                "sensor.boresight_deg=[0.1, 0.0, 0.0]".to_string(),
                format!("time.t0_s={t0}"),
            ]
        };
        let (a, b) = (lines("100.5"), lines("200.5"));
        assert_eq!(shared_lines(&[a.clone(), b]), &a[..1]);
        assert_eq!(shared_lines(std::slice::from_ref(&a)), a);
        assert!(shared_lines(&[]).is_empty());
    }
}
