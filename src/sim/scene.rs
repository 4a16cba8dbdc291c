//! The scene: analytic primitives in the local East-North-Up frame (metres, z up) about the
//! scenario origin, and a ray caster behind a uniform 2D grid so the cost per ray stays flat
//! as the scene grows.
//!
//! The ground is the plane `z = gx * east + gy * north` (height 0 at the origin); every other
//! object is an oriented box, a vertical cylinder or a sphere, indexed by its horizontal
//! footprint.

use nalgebra::{Matrix3, Vector3};

/// What an object is (drives reflectance and which reference files list it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Class {
    /// Raised sidewalk slab (kerbs are its edges).
    Sidewalk,
    /// Building.
    Building,
    /// Pole (lamp post).
    Pole,
    /// Spherical target.
    Sphere,
    /// Flat retro-reflective sync target.
    SyncTarget,
    /// Tree trunk or crown.
    Tree,
    /// Parked car.
    Car,
    /// A foreign thing on a reference patch (`scene.foreign_share`, `sim::foreign`).
    Foreign,
}

/// Geometry of one object.
#[derive(Debug, Clone, Copy)]
pub enum Shape {
    /// Oriented box: centre, rotation local-to-ENU (columns = local axes), half extents.
    Box {
        /// Centre (ENU, m).
        centre: Vector3<f64>,
        /// Local-to-ENU rotation.
        r_l_to_enu: Matrix3<f64>,
        /// Half extents along the local axes (m).
        half_m: Vector3<f64>,
    },
    /// Vertical cylinder with a top cap.
    Cylinder {
        /// Axis position east, north (m).
        centre_xy: [f64; 2],
        /// Bottom and top heights (m).
        z_m: [f64; 2],
        /// Radius (m).
        radius_m: f64,
    },
    /// Sphere.
    Sphere {
        /// Centre (ENU, m).
        centre: Vector3<f64>,
        /// Radius (m).
        radius_m: f64,
    },
}

/// One scene object.
#[derive(Debug, Clone, Copy)]
pub struct Object {
    /// Geometry.
    pub shape: Shape,
    /// Kind.
    pub class: Class,
    /// Reflectance (diffuse 0..1; retro-reflectors far above 1).
    pub reflectance: f64,
    /// Probability that a ray passes through (vegetation), else 0.
    pub porosity: f64,
}

/// A ray hit.
#[derive(Debug, Clone, Copy)]
pub struct Hit {
    /// Distance along the (unit) ray (m).
    pub t_m: f64,
    /// Object index; [`GROUND`] for the ground plane.
    pub object: u32,
    /// Face of a box (0..6: -x,+x,-y,+y,-z,+z), 0 otherwise.
    pub face: u8,
    /// Unit surface normal (ENU), facing the ray origin's side.
    pub normal: Vector3<f64>,
}

/// Object index reported for ground hits.
pub const GROUND: u32 = u32::MAX;

/// Scene with its spatial index.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Ground slope dz/dEast, dz/dNorth.
    pub ground_slope: [f64; 2],
    /// Ground reflectance.
    pub ground_reflectance: f64,
    /// All objects but the ground.
    pub objects: Vec<Object>,
    grid: Grid,
    z_max_m: f64,
}

#[derive(Debug, Clone)]
struct Grid {
    min: [f64; 2],
    cell_m: f64,
    n: [usize; 2],
    /// CSR: objects of cell `c` are `items[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Scene {
    /// Builds the index over `objects` with square cells of `cell_m` metres.
    pub fn new(
        ground_slope: [f64; 2],
        ground_reflectance: f64,
        objects: Vec<Object>,
        cell_m: f64,
    ) -> Scene {
        let boxes: Vec<[f64; 5]> = objects.iter().map(|o| footprint(&o.shape)).collect();
        let z_max_m = boxes.iter().map(|b| b[4]).fold(0.0, f64::max);
        let grid = Grid::build(&boxes, cell_m);
        Scene {
            ground_slope,
            ground_reflectance,
            objects,
            grid,
            z_max_m,
        }
    }

    /// Ground height at (east, north) (m).
    #[inline]
    pub fn ground_z(&self, e: f64, n: f64) -> f64 {
        self.ground_slope[0] * e + self.ground_slope[1] * n
    }

    /// Unit upward ground normal (ENU).
    pub fn ground_normal(&self) -> Vector3<f64> {
        Vector3::new(-self.ground_slope[0], -self.ground_slope[1], 1.0).normalize()
    }

    /// Nearest hit of the ray `o + t d` (d unit, ENU) with `t` in `(t_min, t_max]`.
    /// `ray_key` seeds the pass-through draw of porous objects (deterministic per ray).
    pub fn cast(
        &self,
        o: &Vector3<f64>,
        d: &Vector3<f64>,
        t_min: f64,
        t_max: f64,
        ray_key: u64,
    ) -> Option<Hit> {
        let mut best = self.cast_ground(o, d, t_min, t_max);
        let mut t_best = best.map_or(t_max, |h| h.t_m);
        let g = &self.grid;
        let Some((t_in, t_out)) = g.clip(o, d, t_min, t_best) else {
            return best;
        };
        let cell = |t: f64, k: usize| {
            let p = [o.x + d.x * t, o.y + d.y * t][k];
            (((p - g.min[k]) / g.cell_m).floor().max(0.0) as usize).min(g.n[k] - 1)
        };
        let mut c = [cell(t_in, 0), cell(t_in, 1)];
        let dir = [d.x, d.y];
        let step: [isize; 2] = [dir[0].signum() as isize, dir[1].signum() as isize];
        let mut t_next = [0.0; 2];
        let mut t_delta = [f64::INFINITY; 2];
        for k in 0..2 {
            if dir[k].abs() > 1e-15 {
                let edge = g.min[k] + (c[k] as f64 + (step[k] > 0) as u8 as f64) * g.cell_m;
                let origin = [o.x, o.y][k];
                t_next[k] = (edge - origin) / dir[k];
                t_delta[k] = g.cell_m / dir[k].abs();
            } else {
                t_next[k] = f64::INFINITY;
            }
        }
        let mut t_cell_in = t_in;
        loop {
            if d.z > 0.0 && o.z + d.z * t_cell_in > self.z_max_m {
                break;
            }
            let ci = c[1] * g.n[0] + c[0];
            for &id in &g.items[g.start[ci] as usize..g.start[ci + 1] as usize] {
                let obj = &self.objects[id as usize];
                if let Some(h) = intersect(&obj.shape, o, d, t_min, t_best) {
                    if obj.porosity > 0.0 && unit_hash(ray_key, id) < obj.porosity {
                        continue;
                    }
                    t_best = h.t_m;
                    best = Some(Hit { object: id, ..h });
                }
            }
            let k = if t_next[0] < t_next[1] { 0 } else { 1 };
            let t_cell_out = t_next[k];
            if t_cell_out >= t_best || t_cell_out >= t_out {
                break;
            }
            let nk = c[k] as isize + step[k];
            if nk < 0 || nk as usize >= g.n[k] {
                break;
            }
            c[k] = nk as usize;
            t_next[k] += t_delta[k];
            t_cell_in = t_cell_out;
        }
        best
    }

    fn cast_ground(
        &self,
        o: &Vector3<f64>,
        d: &Vector3<f64>,
        t_min: f64,
        t_max: f64,
    ) -> Option<Hit> {
        let [gx, gy] = self.ground_slope;
        // Plane f(p) = z - gx e - gy n = 0.
        let f0 = o.z - gx * o.x - gy * o.y;
        let df = d.z - gx * d.x - gy * d.y;
        if df.abs() < 1e-15 {
            return None;
        }
        let t = -f0 / df;
        (t > t_min && t <= t_max).then(|| {
            let n = self.ground_normal();
            Hit {
                t_m: t,
                object: GROUND,
                face: 0,
                normal: if f0 >= 0.0 { n } else { -n },
            }
        })
    }
}

/// Horizontal bounding box [x0, y0, x1, y1] and top height of a shape.
fn footprint(s: &Shape) -> [f64; 5] {
    match *s {
        Shape::Box {
            centre,
            r_l_to_enu,
            half_m,
        } => {
            let ext = r_l_to_enu.abs() * half_m;
            [
                centre.x - ext.x,
                centre.y - ext.y,
                centre.x + ext.x,
                centre.y + ext.y,
                centre.z + ext.z,
            ]
        }
        Shape::Cylinder {
            centre_xy: [x, y],
            z_m,
            radius_m: r,
        } => [x - r, y - r, x + r, y + r, z_m[1]],
        Shape::Sphere {
            centre: c,
            radius_m: r,
        } => [c.x - r, c.y - r, c.x + r, c.y + r, c.z + r],
    }
}

impl Grid {
    fn build(boxes: &[[f64; 5]], cell_m: f64) -> Grid {
        let mut min = [f64::INFINITY; 2];
        let mut max = [f64::NEG_INFINITY; 2];
        for b in boxes {
            for k in 0..2 {
                min[k] = min[k].min(b[k]);
                max[k] = max[k].max(b[k + 2]);
            }
        }
        if boxes.is_empty() {
            min = [0.0; 2];
            max = [cell_m; 2];
        }
        let n = [0, 1].map(|k| (((max[k] - min[k]) / cell_m).ceil() as usize).max(1));
        let cell_of =
            |v: f64, k: usize| (((v - min[k]) / cell_m).floor().max(0.0) as usize).min(n[k] - 1);
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); n[0] * n[1]];
        for (id, b) in boxes.iter().enumerate() {
            for cy in cell_of(b[1], 1)..=cell_of(b[3], 1) {
                for cx in cell_of(b[0], 0)..=cell_of(b[2], 0) {
                    lists[cy * n[0] + cx].push(id as u32);
                }
            }
        }
        let mut start = Vec::with_capacity(lists.len() + 1);
        let mut items = Vec::new();
        for l in &lists {
            start.push(items.len() as u32);
            items.extend_from_slice(l);
        }
        start.push(items.len() as u32);
        Grid {
            min,
            cell_m,
            n,
            start,
            items,
        }
    }

    /// Parameter interval of the ray inside the grid's horizontal rectangle.
    fn clip(&self, o: &Vector3<f64>, d: &Vector3<f64>, t0: f64, t1: f64) -> Option<(f64, f64)> {
        let (mut lo, mut hi) = (t0, t1);
        for (k, (ok, dk)) in [(o.x, d.x), (o.y, d.y)].into_iter().enumerate() {
            let a = self.min[k];
            let b = a + self.n[k] as f64 * self.cell_m;
            if dk.abs() < 1e-15 {
                if ok < a || ok > b {
                    return None;
                }
            } else {
                let (ta, tb) = ((a - ok) / dk, (b - ok) / dk);
                lo = lo.max(ta.min(tb));
                hi = hi.min(ta.max(tb));
            }
        }
        (lo <= hi).then_some((lo, hi))
    }
}

/// Nearest intersection of a shape with `o + t d`, `t` in `(t_min, t_max)`; face and outward
/// normal at the entry point. Rays starting inside a shape see no hit.
#[inline]
fn intersect(s: &Shape, o: &Vector3<f64>, d: &Vector3<f64>, t_min: f64, t_max: f64) -> Option<Hit> {
    match *s {
        Shape::Box {
            centre,
            r_l_to_enu,
            half_m,
        } => {
            let ol = r_l_to_enu.tr_mul(&(o - centre));
            let dl = r_l_to_enu.tr_mul(d);
            let (mut t_near, mut t_far, mut axis) = (f64::NEG_INFINITY, f64::INFINITY, 0);
            for k in 0..3 {
                if dl[k].abs() < 1e-15 {
                    if ol[k].abs() > half_m[k] {
                        return None;
                    }
                    continue;
                }
                let inv = 1.0 / dl[k];
                let (ta, tb) = ((-half_m[k] - ol[k]) * inv, (half_m[k] - ol[k]) * inv);
                let (t_enter, t_exit) = if ta < tb { (ta, tb) } else { (tb, ta) };
                if t_enter > t_near {
                    t_near = t_enter;
                    axis = k;
                }
                t_far = t_far.min(t_exit);
            }
            if t_near > t_far || t_near <= t_min || t_near >= t_max {
                return None;
            }
            let sign = if dl[axis] > 0.0 { -1.0 } else { 1.0 };
            let mut nl = Vector3::zeros();
            nl[axis] = sign;
            Some(Hit {
                t_m: t_near,
                object: 0,
                face: (2 * axis + (sign > 0.0) as usize) as u8,
                normal: r_l_to_enu * nl,
            })
        }
        Shape::Cylinder {
            centre_xy: [cx, cy],
            z_m: [z0, z1],
            radius_m: r,
        } => {
            let (ox, oy) = (o.x - cx, o.y - cy);
            let a = d.x * d.x + d.y * d.y;
            let mut best: Option<Hit> = None;
            if a > 1e-18 {
                let b = ox * d.x + oy * d.y;
                let disc = b * b - a * (ox * ox + oy * oy - r * r);
                if disc >= 0.0 {
                    let t = (-b - disc.sqrt()) / a;
                    let z = o.z + d.z * t;
                    if t > t_min && t < t_max && z >= z0 && z <= z1 {
                        let n = Vector3::new(ox + d.x * t, oy + d.y * t, 0.0) / r;
                        best = Some(Hit {
                            t_m: t,
                            object: 0,
                            face: 0,
                            normal: n,
                        });
                    }
                }
            }
            if d.z < 0.0 && o.z > z1 {
                let t = (z1 - o.z) / d.z;
                let (px, py) = (ox + d.x * t, oy + d.y * t);
                if t > t_min
                    && t < t_max
                    && px * px + py * py <= r * r
                    && best.is_none_or(|h| t < h.t_m)
                {
                    best = Some(Hit {
                        t_m: t,
                        object: 0,
                        face: 1,
                        normal: Vector3::z(),
                    });
                }
            }
            best
        }
        Shape::Sphere {
            centre,
            radius_m: r,
        } => {
            let oc = o - centre;
            let b = oc.dot(d);
            let disc = b * b - (oc.norm_squared() - r * r);
            if disc < 0.0 {
                return None;
            }
            let t = -b - disc.sqrt();
            (t > t_min && t < t_max).then(|| Hit {
                t_m: t,
                object: 0,
                face: 0,
                normal: (oc + d * t) / r,
            })
        }
    }
}

/// Uniform [0, 1) from a ray key and an object id (splitmix64 finaliser).
#[inline]
pub(crate) fn unit_hash(key: u64, id: u32) -> f64 {
    let mut z = key ^ (id as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box(c: Vector3<f64>) -> Object {
        Object {
            shape: Shape::Box {
                centre: c,
                r_l_to_enu: Matrix3::identity(),
                half_m: Vector3::new(1.0, 1.0, 1.0),
            },
            class: Class::Building,
            reflectance: 0.5,
            porosity: 0.0,
        }
    }

    #[test]
    fn grid_cast_matches_brute_force() {
        let mut objs = Vec::new();
        for i in 0..20 {
            for j in 0..20 {
                let c = Vector3::new(i as f64 * 7.0, j as f64 * 5.0, 1.5 + (i % 3) as f64);
                objs.push(unit_box(c));
                objs.push(Object {
                    shape: Shape::Sphere {
                        centre: c + Vector3::new(3.0, 2.0, 0.0),
                        radius_m: 0.5,
                    },
                    class: Class::Sphere,
                    reflectance: 0.8,
                    porosity: 0.0,
                });
                objs.push(Object {
                    shape: Shape::Cylinder {
                        centre_xy: [c.x - 2.5, c.y],
                        z_m: [-1.0, 5.0],
                        radius_m: 0.2,
                    },
                    class: Class::Pole,
                    reflectance: 0.4,
                    porosity: 0.0,
                });
            }
        }
        let scene = Scene::new([0.01, -0.02], 0.2, objs.clone(), 4.0);
        let o = Vector3::new(60.0, 48.0, 2.0);
        for k in 0..5000 {
            let a = k as f64 * 0.7345;
            let b = (k as f64 * 0.1234).sin() * 1.2;
            let d = Vector3::new(a.cos() * b.cos(), a.sin() * b.cos(), b.sin());
            let fast = scene.cast(&o, &d, 0.0, 80.0, k);
            let mut slow = scene.cast_ground(&o, &d, 0.0, 80.0).map(|h| h.t_m);
            for obj in &objs {
                if let Some(h) = intersect(&obj.shape, &o, &d, 0.0, slow.unwrap_or(80.0)) {
                    slow = Some(h.t_m);
                }
            }
            assert_eq!(fast.map(|h| h.t_m), slow, "ray {k}");
        }
    }

    #[test]
    fn shapes_hit_where_expected() {
        let o = Vector3::new(0.0, 0.0, 0.0);
        let d = Vector3::x();
        let bx = unit_box(Vector3::new(5.0, 0.0, 0.0)).shape;
        let h = intersect(&bx, &o, &d, 0.0, 100.0).unwrap();
        assert!((h.t_m - 4.0).abs() < 1e-12 && (h.normal + Vector3::x()).norm() < 1e-12);
        let cyl = Shape::Cylinder {
            centre_xy: [5.0, 0.0],
            z_m: [-1.0, 1.0],
            radius_m: 0.5,
        };
        assert!((intersect(&cyl, &o, &d, 0.0, 100.0).unwrap().t_m - 4.5).abs() < 1e-12);
        let sph = Shape::Sphere {
            centre: Vector3::new(5.0, 0.0, 0.0),
            radius_m: 2.0,
        };
        assert!((intersect(&sph, &o, &d, 0.0, 100.0).unwrap().t_m - 3.0).abs() < 1e-12);
        let scene = Scene::new([0.1, 0.0], 0.2, vec![], 4.0);
        let down = Vector3::new(0.0, 0.0, -1.0);
        let g = scene
            .cast(&Vector3::new(10.0, 0.0, 3.0), &down, 0.0, 100.0, 0)
            .unwrap();
        assert!((g.t_m - 2.0).abs() < 1e-12 && g.object == GROUND);
    }
}
