//! Procedural scenes from the scenario's `[scene]` table: a street grid or a parking lot, with
//! buildings (some facades skewed), sidewalks with kerbs, poles, spherical targets, flat
//! retro-reflective sync targets and optional trees. Scene frame: local ENU about the origin.

use super::scenario::{SceneCfg, SceneKind};
use super::scene::{Class, Object, Scene, Shape};
use crate::geo::rotations::rot_z;
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A surveyed point of the scene (sync target face centre or sphere centre).
#[derive(Debug, Clone)]
pub struct Landmark {
    /// Identifier written to the control-point file.
    pub id: String,
    /// Position (scene ENU, m).
    pub enu: Vector3<f64>,
}

/// The generated world: scene plus its surveyed landmarks.
#[derive(Debug, Clone)]
pub struct World {
    /// Ray-castable scene.
    pub scene: Scene,
    /// Sync targets and spheres, in generation order.
    pub landmarks: Vec<Landmark>,
}

struct Builder<'a> {
    cfg: &'a SceneCfg,
    rng: ChaCha8Rng,
    objects: Vec<Object>,
    landmarks: Vec<Landmark>,
}

/// A sync target's plate as a surveyor would measure it (`truth.json` `sync_targets`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SyncFace {
    /// Landmark id (as in the control-point file).
    pub id: String,
    /// Unit face normal (scene ENU), the plate's local y axis.
    pub normal_enu: [f64; 3],
    /// Half width and half height of the face (m).
    pub half_size_m: [f64; 2],
}

impl World {
    /// The plate of every sync-target landmark (the box whose face centre is the landmark).
    pub fn sync_faces(&self) -> Vec<SyncFace> {
        let plate_of = |l: &Landmark| {
            self.scene.objects.iter().find_map(|ob| match ob.shape {
                Shape::Box {
                    centre,
                    r_l_to_enu,
                    half_m,
                } if ob.class == Class::SyncTarget && (centre - l.enu).norm() < 0.05 => {
                    let n = r_l_to_enu.column(1);
                    Some(SyncFace {
                        id: l.id.clone(),
                        normal_enu: [n.x, n.y, n.z],
                        half_size_m: [half_m.x, half_m.z],
                    })
                }
                _ => None,
            })
        };
        self.landmarks.iter().filter_map(plate_of).collect()
    }
}

/// Generates the world of `cfg`, deterministically from `seed`.
pub fn build(cfg: &SceneCfg, seed: u64) -> World {
    let mut b = Builder {
        cfg,
        rng: ChaCha8Rng::seed_from_u64(seed ^ 0x5CE7_E000_0000_0001),
        objects: Vec::new(),
        landmarks: Vec::new(),
    };
    match cfg.kind {
        SceneKind::Streets => b.streets(),
        SceneKind::ParkingLot => b.parking_lot(),
    }
    let scene = Scene::new(
        cfg.ground_slope,
        cfg.reflectance[0],
        b.objects,
        cfg.grid_cell_m,
    );
    World {
        scene,
        landmarks: b.landmarks,
    }
}

impl Builder<'_> {
    fn ground(&self, e: f64, n: f64) -> f64 {
        self.cfg.ground_slope[0] * e + self.cfg.ground_slope[1] * n
    }

    fn push(&mut self, shape: Shape, class: Class) {
        let r = &self.cfg.reflectance;
        let (reflectance, porosity) = match class {
            Class::Sidewalk => (r[0], 0.0),
            Class::Building | Class::Car | Class::Foreign => (r[1], 0.0),
            Class::Pole => (r[2], 0.0),
            Class::Sphere => (r[3], 0.0),
            Class::SyncTarget => (self.cfg.sync_reflectance, 0.0),
            Class::Tree => (r[4], 0.0),
        };
        self.objects.push(Object {
            shape,
            class,
            reflectance,
            porosity,
        });
    }

    /// Street grid: street centre lines at east = i * (block + street), same for north.
    fn streets(&mut self) {
        let c = self.cfg;
        let pitch = [0, 1].map(|k| c.block_size_m[k] + c.street_width_m);
        let half_w = c.street_width_m / 2.0;
        for i in 0..c.blocks[0] {
            for j in 0..c.blocks[1] {
                let x0 = i as f64 * pitch[0] + half_w;
                let y0 = j as f64 * pitch[1] + half_w;
                let (x1, y1) = (x0 + c.block_size_m[0], y0 + c.block_size_m[1]);
                self.slab([x0, y0], [x1, y1]);
                // Sides counter-clockwise; inward = left of the side's direction.
                let corners = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]];
                for s in 0..4 {
                    let (a, b) = (corners[s], corners[(s + 1) % 4]);
                    self.side(a, b, c.curb_height_m, c.sidewalk_width_m);
                }
            }
        }
    }

    /// Parking lot: open area [0, L_e] x [0, L_n], buildings facing it from outside, lamp
    /// posts along its middle, two rows of parked cars, targets on stands.
    fn parking_lot(&mut self) {
        let c = self.cfg;
        let [lx, ly] = c.block_size_m;
        // Sides clockwise so that "inward" (left) points away from the lot.
        let corners = [[0.0, 0.0], [0.0, ly], [lx, ly], [lx, 0.0]];
        for s in 0..4 {
            self.side(corners[s], corners[(s + 1) % 4], 0.0, c.sidewalk_width_m);
        }
        let mid = ly / 2.0;
        if c.pole_spacing_m > 0.0 {
            let mut x = 30.0;
            while x < lx - 30.0 {
                self.pole([x, mid], 0.0);
                x += c.pole_spacing_m;
            }
        }
        for row in [-1.0, 1.0] {
            for k in 0..c.cars_per_row {
                let x = 40.0 + (lx - 80.0) * (k as f64 + 0.5) / c.cars_per_row.max(1) as f64;
                let y = mid + row * 5.0;
                let g = self.ground(x, y);
                let centre = Vector3::new(x, y, g + 0.75);
                self.push(
                    Shape::Box {
                        centre,
                        r_l_to_enu: Matrix3::identity(),
                        half_m: Vector3::new(0.9, 2.25, 0.75),
                    },
                    Class::Car,
                );
            }
        }
        for (k, x) in [0.3, 0.7].into_iter().enumerate() {
            let y = if k == 0 { mid - 12.0 } else { mid + 12.0 };
            let facing = if k == 0 { 1.0 } else { -1.0 };
            self.sync_target([x * lx, y], [1.0, 0.0], [0.0, facing], 0.0);
            self.sphere([x * lx + 3.0, y], 0.0);
        }
    }

    /// Raised sidewalk slab over a block, following the ground slope.
    fn slab(&mut self, lo: [f64; 2], hi: [f64; 2]) {
        let c = self.cfg;
        let n = Vector3::new(-c.ground_slope[0], -c.ground_slope[1], 1.0).normalize();
        let ex = (Vector3::x() - n * n.x).normalize();
        let ey = n.cross(&ex);
        let (cx, cy) = ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
        let top = Vector3::new(cx, cy, self.ground(cx, cy)) + n * c.curb_height_m;
        let half = Vector3::new(
            (hi[0] - lo[0]) / 2.0 * (1.0 + c.ground_slope[0].powi(2)).sqrt(),
            (hi[1] - lo[1]) / 2.0 * (1.0 + c.ground_slope[1].powi(2)).sqrt(),
            0.5,
        );
        let r = Matrix3::from_columns(&[ex, ey, n]);
        self.push(
            Shape::Box {
                centre: top - n * 0.5,
                r_l_to_enu: r,
                half_m: half,
            },
            Class::Sidewalk,
        );
    }

    /// Populates one side from kerb point `a` to `b`, objects to the left of a->b.
    fn side(&mut self, a: [f64; 2], b: [f64; 2], curb: f64, walk: f64) {
        let c = self.cfg;
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let u = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
        let inward = [-u[1], u[0]];
        let at = |s: f64, d: f64| {
            [
                a[0] + u[0] * s + inward[0] * d,
                a[1] + u[1] * s + inward[1] * d,
            ]
        };
        // Buildings, leaving the corners free.
        let margin = 15.0;
        let mut s = margin;
        loop {
            let l = self
                .rng
                .random_range(c.building_length_m[0]..=c.building_length_m[1]);
            if s + l > len - margin {
                break;
            }
            let depth = self.rng.random_range(8.0..15.0);
            let height = self
                .rng
                .random_range(c.building_height_m[0]..=c.building_height_m[1]);
            let skew = self.rng.random_range(-1.0..=1.0) * c.facade_max_skew_deg.to_radians();
            let front = at(s + l / 2.0, walk + 0.2 + l / 2.0 * skew.sin().abs());
            self.building(front, u, skew, [l, depth, height], curb);
            s += l + self.rng.random_range(0.0..4.0);
        }
        if c.pole_spacing_m > 0.0 {
            let mut p = c.pole_spacing_m / 2.0;
            while p < len {
                self.pole(at(p, 0.5), curb);
                p += c.pole_spacing_m;
            }
        }
        let n_s = c.spheres_per_side;
        for k in 0..n_s {
            self.sphere(at(len * (k as f64 + 0.5) / n_s as f64 + 2.0, 1.2), curb);
        }
        let n_t = c.sync_targets_per_side;
        for k in 0..n_t {
            let s_k = len * (k as f64 + 0.3) / n_t as f64;
            let first = self.landmarks.iter().all(|l| !l.id.starts_with("SYNC"));
            self.sync_target(at(s_k, 1.0), u, [-inward[0], -inward[1]], curb);
            if c.decoy_offset_m > 0.0 && first {
                let p = at(s_k + c.decoy_offset_m, 1.0);
                self.plate(p, u, [-inward[0], -inward[1]], curb);
            }
        }
        let n_v = c.trees_per_side;
        for k in 0..n_v {
            self.tree(at(len * (k as f64 + 0.75) / n_v as f64, 1.2), curb);
        }
    }

    /// A building whose front face centre is `front`; `u` = street direction, `skew` = yaw of
    /// the facade away from it (rad); size [length, depth, height] (m).
    fn building(&mut self, front: [f64; 2], u: [f64; 2], skew: f64, size: [f64; 3], curb: f64) {
        let yaw = u[1].atan2(u[0]) + skew;
        let r = rot_z(yaw);
        let depth_dir = r * Vector3::y();
        let g = self.ground(front[0], front[1]);
        let (bottom, top) = (g - 5.0, g + curb + size[2]);
        let centre =
            Vector3::new(front[0], front[1], (bottom + top) / 2.0) + depth_dir * (size[1] / 2.0);
        self.push(
            Shape::Box {
                centre,
                r_l_to_enu: r,
                half_m: Vector3::new(size[0] / 2.0, size[1] / 2.0, (top - bottom) / 2.0),
            },
            Class::Building,
        );
    }

    fn pole(&mut self, p: [f64; 2], curb: f64) {
        let g = self.ground(p[0], p[1]);
        let c = self.cfg;
        self.push(
            Shape::Cylinder {
                centre_xy: p,
                z_m: [g - 0.5, g + curb + c.pole_height_m],
                radius_m: c.pole_radius_m,
            },
            Class::Pole,
        );
    }

    fn sphere(&mut self, p: [f64; 2], curb: f64) {
        let centre = Vector3::new(p[0], p[1], self.ground(p[0], p[1]) + curb + 1.5);
        let id = format!("SPH{:03}", self.landmarks.len());
        self.push(
            Shape::Sphere {
                centre,
                radius_m: self.cfg.sphere_radius_m,
            },
            Class::Sphere,
        );
        self.landmarks.push(Landmark { id, enu: centre });
    }

    /// Flat 0.5 x 0.5 m retro-reflective target, face centre 1.2 m above the walk, its face
    /// normal `facing` yawed by `scene.sync_target_yaw_deg`; `u` its horizontal in-plane
    /// direction. Listed as a landmark.
    fn sync_target(&mut self, p: [f64; 2], u: [f64; 2], facing: [f64; 2], curb: f64) {
        let face = self.plate(p, u, facing, curb);
        let id = format!("SYNC{:03}", self.landmarks.len());
        self.landmarks.push(Landmark { id, enu: face });
    }

    /// The retro-reflective plate of [`Self::sync_target`], unlisted; returns its face centre.
    fn plate(&mut self, p: [f64; 2], u: [f64; 2], facing: [f64; 2], curb: f64) -> Vector3<f64> {
        let face = Vector3::new(p[0], p[1], self.ground(p[0], p[1]) + curb + 1.2);
        let yaw = rot_z(self.cfg.sync_target_yaw_deg.to_radians());
        let f = yaw * Vector3::new(facing[0], facing[1], 0.0);
        let r = Matrix3::from_columns(&[yaw * Vector3::new(u[0], u[1], 0.0), -f, Vector3::z()]);
        self.push(
            Shape::Box {
                centre: face - f * 0.01,
                r_l_to_enu: r,
                half_m: Vector3::new(0.25, 0.01, 0.25),
            },
            Class::SyncTarget,
        );
        face
    }

    fn tree(&mut self, p: [f64; 2], curb: f64) {
        let g = self.ground(p[0], p[1]) + curb;
        self.push(
            Shape::Cylinder {
                centre_xy: p,
                z_m: [g - 0.5, g + 3.0],
                radius_m: 0.15,
            },
            Class::Tree,
        );
        self.push(
            Shape::Sphere {
                centre: Vector3::new(p[0], p[1], g + 4.0),
                radius_m: 1.5,
            },
            Class::Tree,
        );
        self.objects.last_mut().expect("just pushed").porosity = self.cfg.tree_porosity;
    }
}
