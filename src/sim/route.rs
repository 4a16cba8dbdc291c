//! The route: a closed loop of straights joined by circular arcs (scene frame, metres), and a
//! speed profile along it (limited by top speed, lateral acceleration in corners, acceleration
//! and braking limits, standing still at stops) giving distance, speed and acceleration as
//! functions of time. Laps repeat identically; every lap starts and ends standing still.

use super::scenario::RouteCfg;
use crate::geo::rotations::wrap_pi;
use crate::{Error, Result};

/// Arc-length step of the speed profile (m).
const DS_M: f64 = 0.25;

/// Arc length (m) over which the body's heading is the path direction averaged: the yaw rate
/// ramps into and out of an arc instead of stepping (a vehicle steers continuously; a step
/// would be a kink no 200 Hz sampling reproduces, e.g. once shifted by a latency).
const HEADING_WINDOW_M: f64 = 1.0;

#[derive(Debug, Clone, Copy)]
enum Element {
    Line {
        p: [f64; 2],
        u: [f64; 2],
    },
    Arc {
        c: [f64; 2],
        r: f64,
        a0: f64,
        /// +1 counter-clockwise (left turn), -1 clockwise.
        sense: f64,
    },
}

/// Position, direction and curvature of the path at an arc length.
#[derive(Debug, Clone, Copy)]
pub struct PathPoint {
    /// East, north (m).
    pub xy: [f64; 2],
    /// Unit tangent (east, north).
    pub dir: [f64; 2],
    /// Signed curvature (1/m), > 0 turning left.
    pub curvature: f64,
}

/// Motion state along the path at an instant.
#[derive(Debug, Clone, Copy)]
pub struct Motion {
    /// Distance along the lap (m).
    pub s_m: f64,
    /// Speed (m/s).
    pub v_mps: f64,
    /// Longitudinal acceleration (m/s^2).
    pub a_mps2: f64,
}

/// The loop and its timing.
#[derive(Debug, Clone)]
pub struct Route {
    elements: Vec<(f64, f64, Element)>,
    length_m: f64,
    v: Vec<f64>,
    /// Departure time from grid point i (after any dwell), and arrival time at i.
    depart: Vec<f64>,
    arrive: Vec<f64>,
    lap_s: f64,
}

impl Route {
    /// Builds the loop through `cfg.waypoints_m`, offset `lane_offset_m` to the right of
    /// the waypoint line, corners rounded with `cfg.corner_radius_m`.
    pub fn new(cfg: &RouteCfg, lane_offset_m: f64, source: &str) -> Result<Route> {
        let corners = offset_polygon(&cfg.waypoints_m, lane_offset_m);
        let elements = build_elements(&corners, cfg.corner_radius_m)
            .map_err(|p| Error::config(source, "route.waypoints_m", p))?;
        let length_m = elements.last().map_or(0.0, |e| e.1);
        let mut route = Route {
            elements,
            length_m,
            v: Vec::new(),
            depart: Vec::new(),
            arrive: Vec::new(),
            lap_s: 0.0,
        };
        for (i, s) in cfg.stops.iter().enumerate() {
            if s.at_m >= length_m {
                let msg = format!("at {} m is beyond the lap length {length_m:.1} m", s.at_m);
                return Err(Error::config(source, format!("route.stops[{i}].at_m"), msg));
            }
        }
        route.speed_profile(cfg);
        Ok(route)
    }

    /// Length of one lap (m).
    pub fn length_m(&self) -> f64 {
        self.length_m
    }

    /// Duration of one lap (s).
    pub fn lap_s(&self) -> f64 {
        self.lap_s
    }

    /// Path geometry at arc length `s` (wrapped into the lap).
    pub fn at(&self, s: f64) -> PathPoint {
        let s = s.rem_euclid(self.length_m);
        let i = self
            .elements
            .partition_point(|e| e.1 <= s)
            .min(self.elements.len() - 1);
        let (s0, _, el) = self.elements[i];
        let ds = s - s0;
        match el {
            Element::Line { p, u } => PathPoint {
                xy: [p[0] + u[0] * ds, p[1] + u[1] * ds],
                dir: u,
                curvature: 0.0,
            },
            Element::Arc { c, r, a0, sense } => {
                let a = a0 + sense * ds / r;
                let (sa, ca) = a.sin_cos();
                PathPoint {
                    xy: [c[0] + r * ca, c[1] + r * sa],
                    dir: [-sense * sa, sense * ca],
                    curvature: sense / r,
                }
            }
        }
    }

    /// The body's heading at arc length `s`: the path direction angle (rad, counter-clockwise
    /// from east) averaged over [`HEADING_WINDOW_M`] centred on `s`, and its rate along the
    /// path (1/m, the smoothed curvature). Equal to the path's on straights and inside arcs
    /// longer than the window.
    pub fn steered(&self, s: f64) -> (f64, f64) {
        let angle = |s: f64| {
            let d = self.at(s).dir;
            d[1].atan2(d[0])
        };
        let (a, half) = (angle(s), HEADING_WINDOW_M / 2.0);
        // The direction angle is linear in s on each element: the mean over a piece is the
        // value at its middle.
        let (mut lo, hi, mut sum) = (s - half, s + half, 0.0);
        while lo < hi {
            let wrapped = lo.rem_euclid(self.length_m);
            let i = self.elements.partition_point(|e| e.1 <= wrapped);
            let end = self.elements.get(i).map_or(self.length_m, |e| e.1);
            let piece_end = hi.min(lo + (end - wrapped).max(1e-9));
            sum += (piece_end - lo) * wrap_pi(angle((lo + piece_end) / 2.0) - a);
            lo = piece_end;
        }
        let curvature = wrap_pi(angle(s + half) - angle(s - half)) / HEADING_WINDOW_M;
        (a + sum / HEADING_WINDOW_M, curvature)
    }

    /// Motion at time `t` since the start of the first lap (s).
    pub fn motion(&self, t: f64) -> Motion {
        let t = t.rem_euclid(self.lap_s);
        let n = self.v.len();
        // Last grid point departed at or before t.
        let i = self
            .depart
            .partition_point(|&d| d <= t)
            .saturating_sub(1)
            .min(n - 2);
        if t < self.depart[i] {
            return Motion {
                s_m: i as f64 * DS_M,
                v_mps: 0.0,
                a_mps2: 0.0,
            };
        }
        if t >= self.arrive[i + 1] {
            // Standing at a stop, waiting to depart.
            return Motion {
                s_m: ((i + 1) as f64 * DS_M).min(self.length_m),
                v_mps: self.v[i + 1],
                a_mps2: 0.0,
            };
        }
        let (v0, v1) = (self.v[i], self.v[i + 1]);
        let ds = self.step(i);
        let a = (v1 * v1 - v0 * v0) / (2.0 * ds);
        let tau = t - self.depart[i];
        Motion {
            s_m: (i as f64 * DS_M + v0 * tau + 0.5 * a * tau * tau).min(self.length_m),
            v_mps: (v0 + a * tau).max(0.0),
            a_mps2: a,
        }
    }

    fn step(&self, i: usize) -> f64 {
        ((i + 1) as f64 * DS_M).min(self.length_m) - i as f64 * DS_M
    }

    fn speed_profile(&mut self, cfg: &RouteCfg) {
        let n = (self.length_m / DS_M).ceil() as usize + 1;
        let mut v: Vec<f64> = (0..n)
            .map(|i| {
                // Largest curvature on the steps either side: speed is limited before an arc
                // starts within the next step.
                let k = [-1.0, 0.0, 1.0]
                    .map(|d| {
                        let s = ((i as f64 + d) * DS_M).clamp(0.0, self.length_m - 1e-9);
                        self.at(s).curvature.abs()
                    })
                    .into_iter()
                    .fold(0.0, f64::max);
                let corner = if k > 0.0 {
                    (cfg.max_lateral_acc_mps2 / k).sqrt()
                } else {
                    f64::INFINITY
                };
                cfg.max_speed_mps.min(corner)
            })
            .collect();
        let mut dwell = vec![0.0; n];
        v[0] = 0.0;
        v[n - 1] = 0.0;
        dwell[0] = cfg.lap_start_dwell_s;
        for s in &cfg.stops {
            // Never next to the lap ends or another stop: two standing grid points in a row
            // would take forever to drive between. Such stops merge.
            let mut i = ((s.at_m / DS_M).round() as usize).clamp(2, n - 3);
            if let Some(j) = [i - 1, i + 1].into_iter().find(|&j| v[j] == 0.0) {
                i = j;
            }
            v[i] = 0.0;
            dwell[i] += s.dwell_s;
        }
        for i in 0..n - 1 {
            let ds = ((i + 1) as f64 * DS_M).min(self.length_m) - i as f64 * DS_M;
            v[i + 1] = v[i + 1].min((v[i] * v[i] + 2.0 * cfg.max_acc_mps2 * ds).sqrt());
        }
        for i in (0..n - 1).rev() {
            let ds = ((i + 1) as f64 * DS_M).min(self.length_m) - i as f64 * DS_M;
            v[i] = v[i].min((v[i + 1] * v[i + 1] + 2.0 * cfg.max_decel_mps2 * ds).sqrt());
        }
        let mut arrive = vec![0.0; n];
        let mut depart = vec![0.0; n];
        let mut t = 0.0;
        for i in 0..n {
            if i > 0 {
                let ds = (i as f64 * DS_M).min(self.length_m) - (i - 1) as f64 * DS_M;
                t += 2.0 * ds / (v[i - 1] + v[i]);
            }
            arrive[i] = t;
            t += dwell[i];
            depart[i] = t;
        }
        self.v = v;
        self.arrive = arrive;
        self.depart = depart;
        self.lap_s = t;
    }
}

/// Corners of the loop shifted `offset` to the right of travel (intersections of the offset
/// edge lines).
fn offset_polygon(w: &[[f64; 2]], offset: f64) -> Vec<[f64; 2]> {
    let n = w.len();
    let unit = |a: [f64; 2], b: [f64; 2]| {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let l = dx.hypot(dy);
        [dx / l, dy / l]
    };
    (0..n)
        .map(|i| {
            let (p, c, q) = (w[(i + n - 1) % n], w[i], w[(i + 1) % n]);
            let (u0, u1) = (unit(p, c), unit(c, q));
            // Right normals.
            let (n0, n1) = ([u0[1], -u0[0]], [u1[1], -u1[0]]);
            let m = [n0[0] + n1[0], n0[1] + n1[1]];
            let k = offset / (1.0 + n0[0] * n1[0] + n0[1] * n1[1]).max(1e-9);
            [c[0] + m[0] * k, c[1] + m[1] * k]
        })
        .collect()
}

/// Straights and arcs of the loop, each with its start and end arc length; the loop starts
/// in the middle of the first edge.
fn build_elements(c: &[[f64; 2]], r: f64) -> std::result::Result<Vec<(f64, f64, Element)>, String> {
    let n = c.len();
    let sub = |a: [f64; 2], b: [f64; 2]| [b[0] - a[0], b[1] - a[1]];
    let len = |v: [f64; 2]| v[0].hypot(v[1]);
    let mut tangent = vec![0.0; n];
    let mut turn = vec![0.0; n];
    for i in 0..n {
        let (a, b) = (sub(c[(i + n - 1) % n], c[i]), sub(c[i], c[(i + 1) % n]));
        if len(a) < 1e-6 || len(b) < 1e-6 {
            return Err(format!("waypoints {} and {} coincide", i, (i + 1) % n));
        }
        let ang = (a[0] * b[1] - a[1] * b[0]).atan2(a[0] * b[0] + a[1] * b[1]);
        if ang.abs() > 170f64.to_radians() {
            return Err(format!("turn at waypoint {i} is sharper than 170 deg"));
        }
        turn[i] = ang;
        tangent[i] = r * (ang.abs() / 2.0).tan();
    }
    let mut out = Vec::new();
    let mut s = 0.0;
    let mut push = |out: &mut Vec<(f64, f64, Element)>, l: f64, e: Element| {
        if l > 1e-9 {
            out.push((s, s + l, e));
            s += l;
        }
    };
    for k in 0..=n {
        let i = k % n;
        let j = (i + 1) % n;
        let e = sub(c[i], c[j]);
        let l = len(e);
        let u = [e[0] / l, e[1] / l];
        let free = l - tangent[i] - tangent[j];
        if free < 0.0 {
            return Err(format!(
                "edge {i}->{j} ({l:.1} m) is too short for route.corner_radius_m {r}"
            ));
        }
        // Straight part of edge i->j: first lap starts at its middle, last one ends there.
        let (from, to) = match k {
            0 => (tangent[i] + free / 2.0, l - tangent[j]),
            _ if k == n => (tangent[i], tangent[i] + free / 2.0),
            _ => (tangent[i], l - tangent[j]),
        };
        let p = [c[i][0] + u[0] * from, c[i][1] + u[1] * from];
        push(&mut out, to - from, Element::Line { p, u });
        if k == n {
            break;
        }
        // Arc at corner j.
        let sense = turn[j].signum();
        if turn[j].abs() > 1e-12 {
            let start = [c[j][0] - u[0] * tangent[j], c[j][1] - u[1] * tangent[j]];
            let normal = [-u[1] * sense, u[0] * sense];
            let centre = [start[0] + normal[0] * r, start[1] + normal[1] * r];
            let a0 = (start[1] - centre[1]).atan2(start[0] - centre[0]);
            push(
                &mut out,
                r * turn[j].abs(),
                Element::Arc {
                    c: centre,
                    r,
                    a0,
                    sense,
                },
            );
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> RouteCfg {
        RouteCfg {
            waypoints_m: vec![[0.0, 0.0], [100.0, 0.0], [100.0, 60.0], [0.0, 60.0]],
            ..RouteCfg::default()
        }
    }

    #[test]
    fn loop_is_continuous_and_closed() {
        let r = Route::new(&square(), 0.0, "t").unwrap();
        let expect = 2.0 * (100.0 + 60.0) - 4.0 * (2.0 - std::f64::consts::FRAC_PI_2) * 8.0;
        assert!((r.length_m() - expect).abs() < 1e-9, "{}", r.length_m());
        let mut prev = r.at(0.0);
        for k in 1..=4000 {
            let p = r.at(k as f64 * r.length_m() / 4000.0);
            let step = (p.xy[0] - prev.xy[0]).hypot(p.xy[1] - prev.xy[1]);
            assert!(step < r.length_m() / 4000.0 + 1e-9, "jump at {k}");
            prev = p;
        }
        let (a, b) = (r.at(0.0).xy, r.at(r.length_m() - 1e-9).xy);
        assert!((a[0] - b[0]).hypot(a[1] - b[1]) < 1e-6);
    }

    #[test]
    fn speed_respects_limits_and_stops() {
        let mut cfg = square();
        cfg.stops.push(super::super::scenario::StopCfg {
            at_m: 150.0,
            dwell_s: 3.0,
        });
        let r = Route::new(&cfg, 0.0, "t").unwrap();
        let mut prev = r.motion(0.0);
        let dt = 0.01;
        let mut stood = 0.0;
        for k in 1..(r.lap_s() / dt) as usize {
            let m = r.motion(k as f64 * dt);
            assert!(m.v_mps <= cfg.max_speed_mps + 1e-9);
            let k_abs = r.at(m.s_m).curvature.abs();
            assert!(m.v_mps * m.v_mps * k_abs <= cfg.max_lateral_acc_mps2 + 0.05);
            assert!(m.s_m >= prev.s_m - 1e-9, "moving backwards at {k}");
            if m.v_mps == 0.0 && (m.s_m - 150.0).abs() < 1.0 {
                stood += dt;
            }
            prev = m;
        }
        assert!((stood - 3.0).abs() < 0.05, "stood {stood} s");
    }
}
