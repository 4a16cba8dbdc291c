//! Truth and reference outputs: the per-return truth sidecar, control points, reference
//! patches and `truth.json`.
//!
//! Truth sidecar layout (little-endian): header 64 bytes: magic `KSTRUTH1`, u32 version (1),
//! u32 record bytes (24), u32 flags (0), u32 reserved, u64 record count, 32 reserved bytes.
//! Then one record per return of `profiles.bin`, same order: f64 x, y, z, the true point in
//! ECEF (m); NaN in all three for a missing return.

use super::dynamics::Frame;
use super::foreign::Foreign;
use super::nav::NavCounts;
use super::references::{
    facade_rects, ground_squares, patch, GROUND_SQUARE_HALF_M, SURVEY_SIGMA_M,
};
use super::route::Route;
use super::scanner::ScannerModel;
use super::scenario::Scenario;
use super::world::World;
use super::{files, SimSummary};
use crate::geo::ellipsoid::ecef_to_geodetic;
use crate::io::atomic::{write_json, AtomicFile};
use crate::io::patches::write_patches;
use crate::io::points::{write_control_points, ControlPoint};
use crate::{Error, Result};
use std::path::Path;

/// Magic bytes of the truth sidecar.
pub const TRUTH_MAGIC: &[u8; 8] = b"KSTRUTH1";
/// Header size of the truth sidecar (bytes).
pub const TRUTH_HEADER_BYTES: usize = 64;
/// Record size of the truth sidecar (bytes).
pub const TRUTH_RECORD_BYTES: usize = 24;

/// Streaming writer of the truth sidecar.
pub(crate) struct TruthPointsWriter {
    out: AtomicFile,
    count: u64,
}

impl TruthPointsWriter {
    pub(crate) fn create(path: &Path) -> Result<Self> {
        let mut out = AtomicFile::create(path)?;
        out.write_all(&header(0))?;
        Ok(TruthPointsWriter { out, count: 0 })
    }
    pub(crate) fn push_encoded(&mut self, bytes: &[u8]) -> Result<()> {
        self.count += (bytes.len() / TRUTH_RECORD_BYTES) as u64;
        self.out.write_all(bytes)
    }
    pub(crate) fn finish(mut self) -> Result<u64> {
        self.out.write_at(0, &header(self.count))?;
        self.out.commit()?;
        Ok(self.count)
    }
}

fn header(count: u64) -> [u8; TRUTH_HEADER_BYTES] {
    let mut h = [0u8; TRUTH_HEADER_BYTES];
    h[0..8].copy_from_slice(TRUTH_MAGIC);
    h[8..12].copy_from_slice(&1u32.to_le_bytes());
    h[12..16].copy_from_slice(&(TRUTH_RECORD_BYTES as u32).to_le_bytes());
    h[24..32].copy_from_slice(&count.to_le_bytes());
    h
}

/// Reads a truth sidecar whole (for tests and small surveys): one `[x, y, z]` per return.
pub fn read_truth_points(path: &Path) -> Result<Vec<[f64; 3]>> {
    let b = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if b.len() < TRUTH_HEADER_BYTES || &b[0..8] != TRUTH_MAGIC {
        return Err(Error::bad_file(
            path,
            "not a kinescan truth sidecar (bad magic)",
        ));
    }
    let count = u64::from_le_bytes(b[24..32].try_into().expect("8 bytes")) as usize;
    let body = &b[TRUTH_HEADER_BYTES..];
    if body.len() != count * TRUTH_RECORD_BYTES {
        return Err(Error::bad_file(
            path,
            format!("header says {count} records, size disagrees"),
        ));
    }
    let f = |c: &[u8]| f64::from_le_bytes(c.try_into().expect("8 bytes"));
    Ok(body
        .chunks_exact(TRUTH_RECORD_BYTES)
        .map(|r| [f(&r[0..8]), f(&r[8..16]), f(&r[16..24])])
        .collect())
}

/// Writes control points (every landmark) and reference patches (street facades with at least
/// `output.patch_min_returns` returns, ground squares along the part of the route driven
/// while scanning).
pub(crate) fn write_references(
    sc: &Scenario,
    world: &World,
    route: &Route,
    frame: Frame,
    surface_hits: &[u32],
    foreign: Option<&Foreign>,
    out_dir: &Path,
) -> Result<ForeignCounts> {
    let points: Vec<ControlPoint> = world
        .landmarks
        .iter()
        .map(|l| {
            let g = ecef_to_geodetic(&frame.to_ecef(&l.enu));
            ControlPoint {
                id: l.id.clone(),
                lat_rad: g.lat_rad,
                lon_rad: g.lon_rad,
                h_m: g.h_m,
                sigma_m: SURVEY_SIGMA_M,
            }
        })
        .collect();
    write_control_points(&out_dir.join(files::CONTROL_POINTS), &points)?;
    let mut patches = Vec::new();
    let scene = &world.scene;
    let mut counts = ForeignCounts::default();
    for r in facade_rects(sc, scene) {
        let id = r.object as usize;
        // Street-facing facades only (local -y, face 2): building ends may hide behind a
        // neighbour a few decimetres away and make poor references.
        let face = 2usize;
        if surface_hits[id * 8 + face] < sc.output.patch_min_returns {
            continue;
        }
        let key = format!("FAC{id}_{face}");
        if let Some(f) = foreign {
            counts.add(
                &key,
                surface_hits[id * 8 + face],
                f.hits_of(r.object, surface_hits),
            );
        }
        patches.push(patch(key, &frame, r.centre, r.normal, r.half[0], r.half[1]));
    }
    for (i, c) in ground_squares(sc, route, scene).into_iter().enumerate() {
        let key = format!("GND{}", patches.len());
        if let Some(f) = foreign {
            let own = surface_hits[f.square_key(i) as usize];
            counts.add(&key, own, f.hits_of(f.square_owner(i), surface_hits));
        }
        let h = GROUND_SQUARE_HALF_M;
        patches.push(patch(key, &frame, c, scene.ground_normal(), h, h));
    }
    write_patches(&out_dir.join(files::PATCHES), &patches)?;
    Ok(counts)
}

/// `truth.json` `foreign`: the foreign things and their returns.
#[derive(Debug, Clone, serde::Serialize)]
pub(crate) struct ForeignSummary {
    /// Things placed.
    pub things: usize,
    /// Mixed returns at their edges (all of them, on listed patches or not).
    pub mixed_returns: u64,
    /// Returns on the listed patches.
    #[serde(flatten)]
    pub counts: ForeignCounts,
}

/// Foreign returns on the listed reference patches (`truth.json` `foreign`).
#[derive(Debug, Default, Clone, serde::Serialize)]
pub(crate) struct ForeignCounts {
    /// Returns on the listed patches: their own surface's plus the foreign ones.
    pub patch_returns: u64,
    /// Returns from foreign things on them.
    pub foreign_returns: u64,
    /// Per patch: id, returns, foreign returns.
    pub by_patch: Vec<(String, u64, u64)>,
}

impl ForeignCounts {
    fn add(&mut self, id: &str, own: u32, foreign: u64) {
        self.patch_returns += own as u64 + foreign;
        self.foreign_returns += foreign;
        self.by_patch
            .push((id.to_string(), own as u64 + foreign, foreign));
    }
}

/// Writes `truth.json`: configured sensor (what to give the pipeline), true sensor, clock,
/// injected effects, navigation error statistics, the sync targets' faces, files and counts.
#[allow(clippy::too_many_arguments)]
pub(crate) fn write_truth_json(
    sc: &Scenario,
    world: &World,
    m: &ScannerModel,
    route: &Route,
    nav: &NavCounts,
    summary: &SimSummary,
    foreign: Option<&ForeignSummary>,
    out_dir: &Path,
) -> Result<()> {
    let sensor = |s: &crate::georef::Sensor| {
        serde_json::json!({
            "lever_arm_b_m": [s.lever_arm_b_m.x, s.lever_arm_b_m.y, s.lever_arm_b_m.z],
            "boresight_rad": [s.boresight_rad.x, s.boresight_rad.y, s.boresight_rad.z],
            "boresight_deg": [s.boresight_rad.x.to_degrees(), s.boresight_rad.y.to_degrees(), s.boresight_rad.z.to_degrees()],
            "alpha0_rad": s.alpha0_rad,
            "range_zero_m": s.range_zero_m,
        })
    };
    let mirror = &m.clock.mirror;
    let fx = &sc.effects;
    let e = &sc.nav_errors;
    let mut doc = serde_json::json!({
        "format": "kinescan-sim-truth/1",
        "scenario": sc.name,
        "seed": sc.seed,
        "gps_week": sc.gps_week,
        "origin": sc.origin,
        "start_time_s": sc.start_time_s,
        "duration_s": sc.duration_s,
        "configured_sensor": sensor(&m.configured),
        "true_sensor": sensor(&m.truth),
        "scanner": {
            "beta_start_rad": mirror.beta_start_rad,
            "direction": mirror.direction.sign(),
            "points_per_profile": m.points_per_profile(),
            "nominal_period_s": sc.scanner.period_s,
            "true_period_s": m.true_period_s,
            "t0_s": m.clock.t0_s,
            "pps_time_tags": sc.scanner.pps_time_tags,
            "max_range_m": sc.scanner.max_range_m,
            "min_range_m": sc.scanner.min_range_m,
            "sigma_range_m": sc.scanner.sigma_range_m,
            "sigma_angle_rad": sc.scanner.sigma_angle_deg.to_radians(),
            "clock_quadratic_per_s": fx.clock_drift_quadratic_per_s.unwrap_or(0.0),
            "mirror_wobble_s": fx.mirror_wobble_s.unwrap_or([0.0, 1.0]),
            "encoder_offset_rad": fx.encoder_offset_deg.unwrap_or(0.0).to_radians(),
            "range_scale_ppm": fx.range_scale_ppm.unwrap_or(0.0),
        },
        "latency": {
            "configured_attitude_latency_s": 0.0,
            "true_attitude_latency_s": fx.attitude_latency_s.unwrap_or(0.0),
            "position_latency_s": 0.0,
        },
        "effects": fx.injected(),
        "nav_errors": {
            "position_sigma_m": e.position_sigma_m,
            "position_tau_s": e.position_tau_s,
            "attitude_sigma_rad": e.attitude_sigma_deg.map(f64::to_radians),
            "attitude_tau_s": e.attitude_tau_s,
            "outages_s": e.outages_s,
            "outage_sigma_factor": e.outage_sigma_factor,
            "heading_bias_rad": fx.heading_bias_deg.unwrap_or(0.0).to_radians(),
            "outage_drift_mps": fx.outage_drift_mps,
        },
        "route": { "lap_length_m": route.length_m(), "lap_duration_s": route.lap_s() },
        "sync_targets": world.sync_faces(),
        "counts": {
            "sbet_records": nav.sbet_records,
            "smrmsg_records": nav.smrmsg_records,
            "profiles": summary.profiles,
            "returns": summary.returns,
            "valid_returns": summary.valid_returns,
        },
        "files": {
            "sbet": files::SBET, "smrmsg": files::SMRMSG,
            "truth_sbet": sc.output.truth_sbet.then_some(files::TRUTH_SBET),
            "profiles": files::PROFILES,
            "truth_points": sc.output.truth_points.then_some(files::TRUTH_POINTS),
            "control_points": files::CONTROL_POINTS, "patches": files::PATCHES,
        },
        "truth_points_layout": "64-byte header (magic KSTRUTH1, u32 version 1, u32 record bytes 24, u32 flags, u32 reserved, u64 count, 32 reserved); per return in profiles.bin order: f64 x, y, z ECEF (m), NaN when missing",
    });
    if let Some(f) = foreign {
        let share = f.counts.foreign_returns as f64 / f.counts.patch_returns.max(1) as f64;
        doc["foreign"] = serde_json::json!({
            "foreign_share": sc.scene.foreign_share,
            "measured_share": share,
            "summary": f,
        });
    }
    if !e.is_plain() {
        // Written only off the defaults, so that a default survey's truth.json is today's.
        let extra = serde_json::json!({
            "model": e.model,
            "white_share": e.white_share,
            "position_tau2_s": e.position_tau2_s,
            "attitude_tau2_s": e.attitude_tau2_s,
            "second_share": e.second_share,
            "smrmsg_factor": e.smrmsg_factor,
            "zero_rate_fields": e.zero_rate_fields,
        });
        if let (Some(n), Some(x)) = (doc["nav_errors"].as_object_mut(), extra.as_object()) {
            n.extend(x.clone());
        }
    }
    write_json(&out_dir.join(files::TRUTH_JSON), &doc)
}
