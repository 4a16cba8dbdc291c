//! The account of every return the diagnosis reads, and the observations it keeps.

use crate::app::diagnose::model::ObservationSet;
use crate::pipeline::report::RejectReason;
use std::collections::BTreeMap;

/// What happened to every return read: `returns_read` = sum of `rejected` + `off_patches` +
/// `off_plane` + `on_patches` + `on_targets`; `on_patches` = `in_short_visits` + `thinned` +
/// `observations`; `on_targets` = `target_returns_unused` + `target_returns_used`.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct ObserveCounts {
    /// Returns read from every profile file.
    pub returns_read: u64,
    /// Returns that cannot be georeferenced, by reason (as in `kinescan run`).
    pub rejected: BTreeMap<RejectReason, u64>,
    /// Georeferenced, not inside any patch rectangle (less its edge margin) near its plane.
    pub off_patches: u64,
    /// Inside a patch rectangle, within 1 m of its plane but beyond the plane tolerance (of a
    /// displaced patch: from its visit's median).
    pub off_plane: u64,
    /// On a patch (inside its rectangle, within the plane tolerance).
    pub on_patches: u64,
    /// On a patch, in a visit with fewer than `min_per_visit` returns: left out.
    pub in_short_visits: u64,
    /// On a patch, left out by the even thinning of long visits.
    pub thinned: u64,
    /// Kept as observations.
    pub observations: u64,
    /// Patches read from the patch file.
    pub patches_read: usize,
    /// Patch ids without any observation.
    pub patches_without_observations: Vec<String>,
    /// Patches whose returns lay off their plane as a whole, observed about each visit's
    /// median distance from it (their returns further than `plane_tolerance_m` from that
    /// median are in `off_plane`).
    pub displaced_patches: Vec<super::DisplacedPatch>,
    /// On a control point's target (bright, near the point; taken before the patches).
    pub on_targets: u64,
    /// On a target, in a visit left out (fewer than `target_min_returns`, or not flat).
    pub target_returns_unused: u64,
    /// On a target, in an observed visit (their centroid is the observation).
    pub target_returns_used: u64,
    /// Target visits observed.
    pub target_visits: u64,
    /// Target visits left out as not flat (`target_flatness_m`).
    pub target_visits_not_flat: u64,
    /// Centroid observations of the target visits (one to three per visit).
    pub target_observations: u64,
    /// Control points read (0 without a control-point file).
    pub control_points_read: usize,
    /// Control point ids without any observation.
    pub control_points_without_observations: Vec<String>,
}

/// The observations of a survey and the account of every return.
#[derive(Debug, Clone)]
pub struct Observed {
    /// The observations.
    pub set: ObservationSet,
    /// What happened to every return.
    pub counts: ObserveCounts,
    /// The SBET's rate and velocity fields against its attitude and positions, and which the
    /// signatures used.
    pub motion: crate::trajectory::MotionChecks,
}
