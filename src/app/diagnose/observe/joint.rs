//! Several pipelines of one mount observed as one survey (a day's passes): each observed on its
//! own, the observations joined ([`ObservationSet::join`]) and every return accounted for.

use super::{observe, ObserveCounts, Observed, References};
use crate::app::diagnose::model::ObservationSet;
use crate::pipeline::config::{DiagnoseConfig, LoadedPipeline};
use crate::{Error, Result};

/// Observes every pipeline of `ps` (in order) on `refs` and joins their observations; the
/// counts add up over the pipelines, the rate and velocity checks are the first's (they read
/// one trajectory).
pub fn observe_joint(
    ps: &[LoadedPipeline],
    refs: &References,
    opts: &DiagnoseConfig,
) -> Result<Observed> {
    let mut sets = Vec::with_capacity(ps.len());
    let mut summed: Option<(ObserveCounts, _)> = None;
    for p in ps {
        let Observed {
            set,
            counts,
            motion,
        } = observe(p, refs, opts)?;
        sets.push(set);
        match &mut summed {
            Some((all, _)) => all.add(&counts),
            None => summed = Some((counts, motion)),
        }
    }
    let Some((mut counts, motion)) = summed else {
        return Err(Error::Invalid("diagnosis: no pipeline to observe".into()));
    };
    let set = ObservationSet::join(sets)?;
    let unobserved = |id: &String| !set.reference_ids.contains(id);
    counts.patches_without_observations.retain(unobserved);
    counts
        .control_points_without_observations
        .retain(unobserved);
    Ok(Observed {
        set,
        counts,
        motion,
    })
}

impl ObserveCounts {
    /// Adds the returns of another survey of the same references (the references read are
    /// the same; those without observations are left to the caller).
    fn add(&mut self, other: &ObserveCounts) {
        // Every field named: a new count must be added here too.
        let ObserveCounts {
            returns_read,
            rejected,
            off_patches,
            off_plane,
            on_patches,
            in_short_visits,
            thinned,
            observations,
            patches_read: _,
            patches_without_observations: _,
            displaced_patches,
            on_targets,
            target_returns_unused,
            target_returns_used,
            target_visits,
            target_visits_not_flat,
            target_observations,
            control_points_read: _,
            control_points_without_observations: _,
        } = other;
        self.returns_read += returns_read;
        for (reason, n) in rejected {
            *self.rejected.entry(*reason).or_default() += n;
        }
        self.off_patches += off_patches;
        self.off_plane += off_plane;
        self.on_patches += on_patches;
        self.in_short_visits += in_short_visits;
        self.thinned += thinned;
        self.observations += observations;
        // A patch off its plane in several surveys is listed once per survey.
        self.displaced_patches
            .extend(displaced_patches.iter().cloned());
        self.on_targets += on_targets;
        self.target_returns_unused += target_returns_unused;
        self.target_returns_used += target_returns_used;
        self.target_visits += target_visits;
        self.target_visits_not_flat += target_visits_not_flat;
        self.target_observations += target_observations;
    }
}
