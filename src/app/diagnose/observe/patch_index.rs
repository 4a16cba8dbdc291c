//! The reference patches on an ECEF grid: which patch (if any) a georeferenced point lies on.

use crate::geo::ellipsoid::r_n_to_e;
use crate::io::patches::PlanarPatch;
use crate::pipeline::config::DiagnoseConfig;
use nalgebra::{Matrix3, Vector3};
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// Returns beyond `diagnose.plane_tolerance_m` but within this distance (m) of a
/// patch plane, inside its rectangle, are counted as `off_plane` (clutter in front of or behind
/// the patch); further ones as `off_patches`.
pub(super) const NEAR_PLANE_M: f64 = 1.0;
/// Cell size (m) of the ECEF grid that finds the patches near a point.
const GRID_CELL_M: f64 = 8.0;
/// A patch in ECEF: centre, rows (length axis, height axis, normal), shrunk half sizes.
pub(super) struct PatchFrame {
    pub(super) centre_e: Vector3<f64>,
    pub(super) axes_e: Matrix3<f64>,
    pub(super) half_m: (f64, f64),
    /// Normal in NED at the patch centre (for the survey sigma in the visit covariance).
    pub(super) normal_n: Vector3<f64>,
    pub(super) sigma_m: f64,
}

/// Where a point lies relative to the patches.
pub(super) enum Place {
    Off,
    /// Inside patch `.0`'s rectangle, within [`NEAR_PLANE_M`] of its plane but beyond its
    /// tolerance.
    OffPlane(usize),
    /// On patch `.0`, at signed distance `.1` (m, along its normal) from its plane.
    On(usize, f32),
}

/// The patches on an ECEF grid: a point is tested only against the patches of its cell.
pub(super) struct PatchIndex {
    pub(super) frames: Vec<PatchFrame>,
    cells: Cells,
    /// Per patch, how far (m) from its plane a return is on it: `diagnose.plane_tolerance_m`,
    /// or [`NEAR_PLANE_M`] for a patch whose returns lie off its plane as a whole (its visits
    /// are then centred on their own median return, [`super::visits`]).
    tolerance_m: Vec<f64>,
}

impl PatchIndex {
    pub(super) fn new(patches: &[PlanarPatch], opts: &DiagnoseConfig) -> Self {
        let mut cells = Cells::default();
        let frames: Vec<PatchFrame> = patches
            .iter()
            .map(|p| {
                let r_enu_e = crate::geo::ellipsoid::r_enu_to_e(p.lat_rad, p.lon_rad);
                let (l, h) = p.axes_enu();
                let n = p.normal_enu();
                let axes_e = Matrix3::from_rows(&[
                    (r_enu_e * l).transpose(),
                    (r_enu_e * h).transpose(),
                    (r_enu_e * n).transpose(),
                ]);
                let n_e = r_enu_e * n;
                PatchFrame {
                    centre_e: p.centre_ecef(),
                    axes_e,
                    half_m: (
                        p.half_length_m - opts.edge_margin_m,
                        p.half_height_m - opts.edge_margin_m,
                    ),
                    normal_n: r_n_to_e(p.lat_rad, p.lon_rad).transpose() * n_e,
                    sigma_m: p.sigma_m.unwrap_or(0.0),
                }
            })
            .collect();
        for (k, f) in frames.iter().enumerate() {
            let (hl, hh) = (f.half_m.0.max(0.0), f.half_m.1.max(0.0));
            let extent = Vector3::new(hl, hh, NEAR_PLANE_M);
            // Bounding box of the patch box in ECEF: |R^T| * extent about the centre.
            let half_box = f.axes_e.transpose().abs() * extent;
            let lo = cell_of(&(f.centre_e - half_box));
            let hi = cell_of(&(f.centre_e + half_box));
            for i in lo[0]..=hi[0] {
                for j in lo[1]..=hi[1] {
                    for m in lo[2]..=hi[2] {
                        cells.entry([i, j, m]).or_default().push(k);
                    }
                }
            }
        }
        PatchIndex {
            tolerance_m: vec![opts.plane_tolerance_m; frames.len()],
            frames,
            cells,
        }
    }

    /// Takes every return within [`NEAR_PLANE_M`] of the plane of each patch `displaced`
    /// names as on it.
    pub(super) fn widen(&mut self, displaced: &[bool]) {
        for (tolerance, &off) in self.tolerance_m.iter_mut().zip(displaced) {
            if off {
                *tolerance = NEAR_PLANE_M;
            }
        }
    }

    /// The patch a point lies on (nearest plane when rectangles overlap).
    pub(super) fn place(&self, x_e: &Vector3<f64>) -> Place {
        let Some(list) = self.cells.get(&cell_of(x_e)) else {
            return Place::Off;
        };
        let mut best: Option<(usize, f64)> = None;
        let mut near: Option<(usize, f64)> = None;
        for &k in list {
            let f = &self.frames[k];
            let c = f.axes_e * (x_e - f.centre_e);
            if c.x.abs() > f.half_m.0 || c.y.abs() > f.half_m.1 || c.z.abs() > NEAR_PLANE_M {
                continue;
            }
            if near.is_none_or(|(_, d)| c.z.abs() < d.abs()) {
                near = Some((k, c.z));
            }
            if c.z.abs() <= self.tolerance_m[k] && best.is_none_or(|(_, d)| c.z.abs() < d.abs()) {
                best = Some((k, c.z));
            }
        }
        match (best, near) {
            (Some((k, d)), _) => Place::On(k, d as f32),
            (None, Some((k, _))) => Place::OffPlane(k),
            (None, None) => Place::Off,
        }
    }
}

/// The patches of each grid cell that has any.
type Cells = HashMap<[i64; 3], Vec<usize>, BuildHasherDefault<CellHasher>>;

/// Hashes a grid cell by multiplying and rotating its 8-byte words. Every return of the survey
/// is looked up; the standard library's SipHash, which resists keys chosen by an attacker
/// (no one chooses these), had been 3% of a diagnosis' CPU.
#[derive(Default)]
struct CellHasher(u64);

impl CellHasher {
    fn add(&mut self, word: u64) {
        self.0 = (self.0.rotate_left(5) ^ word).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
}

impl Hasher for CellHasher {
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.add(u64::from_le_bytes(word));
        }
    }

    fn write_u64(&mut self, i: u64) {
        self.add(i);
    }

    fn write_usize(&mut self, i: usize) {
        self.add(i as u64);
    }

    fn finish(&self) -> u64 {
        self.0
    }
}

fn cell_of(x: &Vector3<f64>) -> [i64; 3] {
    [0, 1, 2].map(|i| (x[i] / GRID_CELL_M).floor() as i64)
}
