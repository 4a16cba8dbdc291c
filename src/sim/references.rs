//! The candidate reference rectangles of a scene, one definition for the patch file
//! (`outputs`) and for the foreign things placed on them (`foreign`): every building's street
//! face and the ground squares along the driving line, and the patch record of a rectangle.

use super::dynamics::Frame;
use super::route::Route;
use super::scenario::{Scenario, SceneKind};
use super::scene::{Scene, Shape};
use crate::geo::ellipsoid::{ecef_to_geodetic, r_enu_to_e};
use crate::io::patches::PlanarPatch;
use nalgebra::Vector3;

/// Nominal survey sigma written for control points and patches (m); the truth is exact.
pub(crate) const SURVEY_SIGMA_M: f64 = 0.001;

/// A candidate facade reference: the street face (local -y) of a building box, from the walk
/// (the higher end's ground plus the kerb) to the roof.
pub(crate) struct FacadeRect {
    /// Building object index.
    pub object: u32,
    /// Rectangle centre (scene ENU, m).
    pub centre: Vector3<f64>,
    /// Unit normal, towards the street.
    pub normal: Vector3<f64>,
    /// Unit horizontal axis along the face.
    pub along: Vector3<f64>,
    /// Half length along `along`, half height (m).
    pub half: [f64; 2],
}

/// Every building's street face as a reference rectangle, in object order.
pub(crate) fn facade_rects(sc: &Scenario, scene: &Scene) -> Vec<FacadeRect> {
    let curb = if sc.scene.kind == SceneKind::Streets {
        sc.scene.curb_height_m
    } else {
        0.0
    };
    let mut out = Vec::new();
    for (id, obj) in scene.objects.iter().enumerate() {
        let Shape::Box {
            centre,
            r_l_to_enu,
            half_m,
        } = obj.shape
        else {
            continue;
        };
        if obj.class != super::scene::Class::Building {
            continue;
        }
        let normal = -r_l_to_enu.column(1).into_owned();
        let along = r_l_to_enu.column(0).into_owned();
        let half_len = half_m[0];
        let c = centre + normal * half_m[1];
        let ends = [c + along * half_len, c - along * half_len];
        let low = ends
            .iter()
            .map(|e| scene.ground_z(e.x, e.y))
            .fold(f64::MIN, f64::max)
            + curb;
        let top = centre.z + half_m.z;
        out.push(FacadeRect {
            object: id as u32,
            centre: Vector3::new(c.x, c.y, (low + top) / 2.0),
            normal,
            along,
            half: [half_len, (top - low) / 2.0],
        });
    }
    out
}

/// Half size of the ground reference squares (m).
pub(crate) const GROUND_SQUARE_HALF_M: f64 = 1.5;

/// Centres (scene ENU) of the ground reference squares: every 20 m along the driving line of
/// the part of the route driven while scanning.
pub(crate) fn ground_squares(sc: &Scenario, route: &Route, scene: &Scene) -> Vec<Vector3<f64>> {
    let scan_end_s = sc.duration_s - sc.scanner.end_margin_s;
    let driven = if scan_end_s >= route.lap_s() {
        route.length_m()
    } else {
        route.motion(scan_end_s).s_m
    };
    let mut out = Vec::new();
    let mut s = 10.0;
    while s < driven.min(route.length_m()) - 10.0 {
        let p = route.at(s);
        let off = sc.vehicle.lane_offset_m;
        let (x, y) = (p.xy[0] - p.dir[1] * off, p.xy[1] + p.dir[0] * off);
        out.push(Vector3::new(x, y, scene.ground_z(x, y)));
        s += 20.0;
    }
    out
}

/// The reference patch file's record of a rectangle (scene ENU centre and normal).
pub(crate) fn patch(
    id: String,
    frame: &Frame,
    c: Vector3<f64>,
    n: Vector3<f64>,
    hl: f64,
    hh: f64,
) -> PlanarPatch {
    let g = ecef_to_geodetic(&frame.to_ecef(&c));
    let n_local = r_enu_to_e(g.lat_rad, g.lon_rad).transpose() * (frame.r_enu_to_e * n);
    let n_local = n_local.normalize();
    PlanarPatch {
        id,
        lat_rad: g.lat_rad,
        lon_rad: g.lon_rad,
        h_m: g.h_m,
        normal_enu: [n_local.x, n_local.y, n_local.z],
        half_length_m: hl,
        half_height_m: hh,
        sigma_m: Some(SURVEY_SIGMA_M),
    }
}
