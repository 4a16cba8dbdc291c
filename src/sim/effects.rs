//! Injected systematic effects: each off by default, switched on by naming it with a magnitude
//! in the scenario's `[effects]` table. The pipeline is not told; `truth.json` records them.
//!
//! To add an effect: add an `Option` field here (key = name with its unit suffix), check it in
//! [`Effects::check`], list it in [`Effects::injected`], and apply it where it acts (true
//! sensor in `SensorTruth::new`, scanner clock in `ScanClock`, navigation solution in
//! `nav::NavSolution`). docs/simulator.md lists the catalogue.

use super::checker::Checker;
use serde::{Deserialize, Serialize};

/// The catalogue of systematic effects; `None` = off.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Effects {
    /// Attitude latency tau (s): SBET attitude stamped `s` is the true attitude at `s - tau`.
    pub attitude_latency_s: Option<f64>,
    /// Boresight error (bx, by, bz) (deg): true boresight angles = configured + this.
    pub boresight_error_deg: Option<[f64; 3]>,
    /// Lever-arm error, body frame (m): true lever arm = configured + this.
    pub lever_arm_error_m: Option<[f64; 3]>,
    /// Range zero error (m): true K = configured K + this.
    pub range_zero_error_m: Option<f64>,
    /// Range scale error (ppm): recorded range = true distance * (1 + ppm 1e-6) - K.
    pub range_scale_ppm: Option<f64>,
    /// Encoder offset (deg): recorded beta = true mirror angle + this.
    pub encoder_offset_deg: Option<f64>,
    /// Cone error (deg): true alpha = configured alpha0 + this.
    pub cone_error_deg: Option<f64>,
    /// Linear clock drift (ppm): true mirror period = configured period * (1 + ppm 1e-6).
    pub clock_drift_ppm: Option<f64>,
    /// Quadratic clock drift q (1/s): adds `q * tau^2` to the true time, `tau = T n`.
    pub clock_drift_quadratic_per_s: Option<f64>,
    /// Mirror-period wobble [amplitude (s), period (s)]: adds `A sin(2 pi tau / P)` to the
    /// true time, `tau = T n`.
    pub mirror_wobble_s: Option<[f64; 2]>,
    /// Trajectory drift in GNSS outages, north/east/down (m/s): SBET position error grows by
    /// this rate from each outage start and vanishes at its end.
    pub outage_drift_mps: Option<[f64; 3]>,
    /// Heading bias (deg): SBET heading = true heading + this.
    pub heading_bias_deg: Option<f64>,
    /// Position latency tau_p (s): SBET position stamped `s` is the true position at
    /// `s - tau_p`.
    pub position_latency_s: Option<f64>,
    /// Clock offset (s): true return time = configured clock's time + this (a t0 error).
    pub clock_offset_s: Option<f64>,
    /// Outside the catalogue: range error cyclic in range [amplitude (m), wavelength (m)]:
    /// recorded range += `A sin(2 pi d / L)`, `d` the true distance.
    pub range_cyclic_m: Option<[f64; 2]>,
    /// Outside the catalogue: incidence-dependent range error (m): recorded range +=
    /// `A sin^2(i)`, `i` the angle between the beam and the surface normal.
    pub range_incidence_m: Option<f64>,
}

/// The correction of the catalogue (docs/conventions.md §8) that models one injected effect:
/// the value to ADD to the configured pipeline value so that a re-run reproduces the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CatalogueCorrection {
    /// Catalogue name, e.g. `lever_arm_y_m`.
    pub name: &'static str,
    /// Value in the name's unit.
    pub value: f64,
}

/// One injected effect as recorded in the truth file.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct InjectedEffect {
    /// Catalogue key, e.g. `attitude_latency_s`.
    pub name: &'static str,
    /// Magnitude(s), in the key's unit.
    pub value: Vec<f64>,
    /// Unit of `value`.
    pub unit: &'static str,
}

impl Effects {
    pub(crate) fn check(&self, c: &mut Checker) {
        let lim = |c: &mut Checker, key: &str, v: Option<f64>, max: f64| {
            if let Some(v) = v {
                c.range(&format!("effects.{key}"), v, -max, max);
            }
        };
        lim(c, "attitude_latency_s", self.attitude_latency_s, 1.0);
        lim(c, "range_zero_error_m", self.range_zero_error_m, 10.0);
        lim(c, "range_scale_ppm", self.range_scale_ppm, 1e5);
        lim(c, "encoder_offset_deg", self.encoder_offset_deg, 10.0);
        lim(c, "cone_error_deg", self.cone_error_deg, 10.0);
        lim(c, "clock_drift_ppm", self.clock_drift_ppm, 1e4);
        lim(
            c,
            "clock_drift_quadratic_per_s",
            self.clock_drift_quadratic_per_s,
            1e-3,
        );
        lim(c, "heading_bias_deg", self.heading_bias_deg, 10.0);
        lim(c, "position_latency_s", self.position_latency_s, 1.0);
        lim(c, "clock_offset_s", self.clock_offset_s, 1.0);
        lim(c, "range_incidence_m", self.range_incidence_m, 1.0);
        if let Some([a, l]) = self.range_cyclic_m {
            c.range("effects.range_cyclic_m[0]", a, -1.0, 1.0);
            c.pos("effects.range_cyclic_m[1]", l);
        }
        let vec3 = |c: &mut Checker, key: &str, v: Option<[f64; 3]>, max: f64| {
            for (i, x) in v.iter().flatten().enumerate() {
                c.range(&format!("effects.{key}[{i}]"), *x, -max, max);
            }
        };
        vec3(c, "boresight_error_deg", self.boresight_error_deg, 10.0);
        vec3(c, "lever_arm_error_m", self.lever_arm_error_m, 5.0);
        vec3(c, "outage_drift_mps", self.outage_drift_mps, 10.0);
        if let Some([a, p]) = self.mirror_wobble_s {
            c.range("effects.mirror_wobble_s[0]", a, -0.1, 0.1);
            c.pos("effects.mirror_wobble_s[1]", p);
            c.test("effects.mirror_wobble_s", (std::f64::consts::TAU * a / p).abs() < 0.1, || {
                format!("amplitude {a} s over period {p} s would make the scanner clock run backwards")
            });
        }
    }

    /// The effects switched on, in catalogue order.
    pub fn injected(&self) -> Vec<InjectedEffect> {
        let mut out = Vec::new();
        let mut add = |name, v: Option<Vec<f64>>, unit| {
            if let Some(value) = v {
                out.push(InjectedEffect { name, value, unit });
            }
        };
        let one = |v: Option<f64>| v.map(|x| vec![x]);
        add("attitude_latency_s", one(self.attitude_latency_s), "s");
        add(
            "boresight_error_deg",
            self.boresight_error_deg.map(Vec::from),
            "deg",
        );
        add(
            "lever_arm_error_m",
            self.lever_arm_error_m.map(Vec::from),
            "m",
        );
        add("range_zero_error_m", one(self.range_zero_error_m), "m");
        add("range_scale_ppm", one(self.range_scale_ppm), "ppm");
        add("encoder_offset_deg", one(self.encoder_offset_deg), "deg");
        add("cone_error_deg", one(self.cone_error_deg), "deg");
        add("clock_drift_ppm", one(self.clock_drift_ppm), "ppm");
        add(
            "clock_drift_quadratic_per_s",
            one(self.clock_drift_quadratic_per_s),
            "1/s",
        );
        add(
            "mirror_wobble_s",
            self.mirror_wobble_s.map(Vec::from),
            "s, s",
        );
        add(
            "outage_drift_mps",
            self.outage_drift_mps.map(Vec::from),
            "m/s",
        );
        add("heading_bias_deg", one(self.heading_bias_deg), "deg");
        add("position_latency_s", one(self.position_latency_s), "s");
        add("clock_offset_s", one(self.clock_offset_s), "s");
        add("range_cyclic_m", self.range_cyclic_m.map(Vec::from), "m, m");
        add("range_incidence_m", one(self.range_incidence_m), "m");
        out
    }

    /// Whether an effect outside the catalogue is on (quadratic drift, mirror wobble, outage
    /// drift, cyclic or incidence range error): no catalogue correction models it.
    pub fn has_uncatalogued(&self) -> bool {
        self.clock_drift_quadratic_per_s.is_some()
            || self.mirror_wobble_s.is_some()
            || self.outage_drift_mps.is_some()
            || self.range_cyclic_m.is_some()
            || self.range_incidence_m.is_some()
    }

    /// The catalogue corrections (docs/conventions.md §8) that model the injected catalogue
    /// effects exactly, with their signs: what a perfect diagnosis estimates. Zero components
    /// of vector effects are left out. Effects outside the catalogue give none.
    pub fn catalogue_corrections(&self) -> Vec<CatalogueCorrection> {
        let mut out = Vec::new();
        let mut add = |name, value: Option<f64>| {
            if let Some(value) = value.filter(|v| *v != 0.0) {
                out.push(CatalogueCorrection { name, value });
            }
        };
        // Stamps lag the truth by tau: the pipeline reads the attitude (position) at t + tau.
        add("attitude_latency_s", self.attitude_latency_s);
        add("position_latency_s", self.position_latency_s);
        // True time = configured + offset; true period = T (1 + ppm 1e-6).
        add("clock_offset_s", self.clock_offset_s);
        add("clock_drift_ppm", self.clock_drift_ppm);
        let b = self.boresight_error_deg.unwrap_or([0.0; 3]);
        add("boresight_x_deg", Some(b[0]));
        add("boresight_y_deg", Some(b[1]));
        add("boresight_z_deg", Some(b[2]));
        let l = self.lever_arm_error_m.unwrap_or([0.0; 3]);
        add("lever_arm_x_m", Some(l[0]));
        add("lever_arm_y_m", Some(l[1]));
        add("lever_arm_z_m", Some(l[2]));
        add("range_zero_m", self.range_zero_error_m);
        // Recorded rho = d (1 + s) - K, so (1 + S)(rho + K) = d needs 1 + S = 1 / (1 + s).
        add(
            "range_scale_ppm",
            self.range_scale_ppm
                .map(|s| (1.0 / (1.0 + s * 1e-6) - 1.0) * 1e6),
        );
        // Recorded beta = true + offset: the pipeline adds dbeta = -offset.
        add("encoder_offset_deg", self.encoder_offset_deg.map(|o| -o));
        add("cone_deg", self.cone_error_deg);
        // SBET heading = true + bias: the pipeline adds -bias to the SBET heading.
        add("heading_offset_deg", self.heading_bias_deg.map(|b| -b));
        out
    }
}
