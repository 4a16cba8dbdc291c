//! Why no observation is left, named by its cause before the fit can only say "0 reference
//! patch(es) have returns" or the patch file is blamed: every return rejected by the run's own
//! checks, or every visit cut shorter than `diagnose.min_per_visit` returns (issue #23).

use super::ObserveCounts;
use crate::pipeline::config::{DiagnoseConfig, LoadedPipeline};
use crate::pipeline::report::ReturnCounts;
use crate::{Error, Result};

/// Refuses a survey whose returns are rejected by the run's own checks in a share above
/// `output.max_rejected_share` (as `kinescan run` refuses it), naming the main reason and the
/// key to check: no return on a patch is then no fault of the patches.
pub(super) fn check_rejected(p: &LoadedPipeline, counts: &ObserveCounts) -> Result<()> {
    let returns = ReturnCounts {
        read: counts.returns_read,
        written: 0,
        rejected: counts.rejected.clone(),
    };
    let max = p.config.output.max_rejected_share;
    let Some(excess) = returns.excess_rejected(max) else {
        return Ok(());
    };
    let (key, cause) = excess.reason.likely_cause();
    let problem = format!(
        "by the run's own checks, {}; so too few can fall on a reference patch (not a fault \
         of the patch file): {cause}",
        excess.describe("the survey", max)
    );
    Err(Error::config(p.path.display().to_string(), key, problem))
}

/// Refuses a survey whose returns on the references all fell in visits too short to keep
/// (`any_visit`: whether any patch or target visit is left), naming the visit key that cut
/// them: `diagnose.max_visit_s` when it is below the gap that ends a visit, else
/// `diagnose.min_per_visit`.
pub(super) fn check_visits(
    p: &LoadedPipeline,
    opts: &DiagnoseConfig,
    counts: &ObserveCounts,
    any_visit: bool,
) -> Result<()> {
    if any_visit || counts.in_short_visits == 0 {
        return Ok(());
    }
    let n = counts.in_short_visits + counts.target_returns_unused;
    let why = format!(
        "every one of the {n} returns on the references is in a visit of fewer than \
         diagnose.min_per_visit = {} returns (a visit ends at a gap over \
         diagnose.visit_gap_s = {} s and is cut after diagnose.max_visit_s = {} s), so no \
         visit is left to fit",
        opts.min_per_visit, opts.visit_gap_s, opts.max_visit_s
    );
    let (key, fix) = if opts.max_visit_s < opts.visit_gap_s {
        (
            "diagnose.max_visit_s",
            format!(
                "diagnose.max_visit_s = {} s cuts every visit into pieces too short to keep: \
                 raise it (default 5 s)",
                opts.max_visit_s
            ),
        )
    } else {
        (
            "diagnose.min_per_visit",
            "lower diagnose.min_per_visit or raise diagnose.visit_gap_s".to_string(),
        )
    };
    let problem = format!("{why}: {fix}");
    Err(Error::config(p.path.display().to_string(), key, problem))
}
