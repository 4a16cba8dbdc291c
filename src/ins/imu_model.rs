//! IMU error models by grade: what the simulator injects and what the filter assumes
//! (docs/trajectory.md cites the datasheets). All values 1 sigma, per axis, SI.
//!
//! A sensor's error is `s * x + b0 + b_gm(t) + n(t)`: scale factor `s` (constant per run),
//! turn-on bias `b0` (constant per run), bias instability `b_gm` (first-order Gauss-Markov,
//! correlation time `tau`) and white noise `n` of power spectral density `rw^2` (angle or
//! velocity random walk).

use serde::Serialize;

const DEG_PER_H: f64 = std::f64::consts::PI / 180.0 / 3600.0;
const DEG_PER_SQRT_H: f64 = std::f64::consts::PI / 180.0 / 60.0;
const MICRO_G: f64 = 9.806_65e-6;
const PPM: f64 = 1e-6;

/// One sensor triad's error model (gyros in rad, rad/s; accelerometers in m/s, m/s^2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TriadErrors {
    /// Turn-on bias (rad/s or m/s^2).
    pub bias: f64,
    /// Bias instability: stationary sigma of the Gauss-Markov part (rad/s or m/s^2).
    pub instability: f64,
    /// Its correlation time (s).
    pub instability_tau_s: f64,
    /// Random walk: white-noise density (rad/sqrt(s) or m/s/sqrt(s)).
    pub random_walk: f64,
    /// Scale factor error (dimensionless, 1e-6 = 1 ppm).
    pub scale_factor: f64,
}

/// A named IMU grade.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ImuGrade {
    /// Grade name as configured.
    pub name: &'static str,
    /// Gyroscopes.
    pub gyro: TriadErrors,
    /// Accelerometers.
    pub accel: TriadErrors,
}

/// Names accepted by [`grade`].
pub const GRADES: [&str; 3] = ["tactical", "navigation", "perfect"];

/// The grade called `name`: `tactical` (fibre-optic gyro IMU of the LN-200 class),
/// `navigation` (ring-laser gyro IMU of the HG9900 class) or `perfect` (no error at all; tests
/// and mechanisation checks).
pub fn grade(name: &str) -> Option<ImuGrade> {
    let g = match name {
        "tactical" => ImuGrade {
            name: "tactical",
            gyro: TriadErrors {
                bias: 1.0 * DEG_PER_H,
                instability: 0.35 * DEG_PER_H,
                instability_tau_s: 300.0,
                random_walk: 0.07 * DEG_PER_SQRT_H,
                scale_factor: 100.0 * PPM,
            },
            accel: TriadErrors {
                bias: 300.0 * MICRO_G,
                instability: 50.0 * MICRO_G,
                instability_tau_s: 300.0,
                random_walk: 50.0 * MICRO_G,
                scale_factor: 300.0 * PPM,
            },
        },
        "navigation" => ImuGrade {
            name: "navigation",
            gyro: TriadErrors {
                bias: 0.003 * DEG_PER_H,
                instability: 0.0015 * DEG_PER_H,
                instability_tau_s: 3600.0,
                random_walk: 0.002 * DEG_PER_SQRT_H,
                scale_factor: 5.0 * PPM,
            },
            accel: TriadErrors {
                bias: 25.0 * MICRO_G,
                instability: 10.0 * MICRO_G,
                instability_tau_s: 3600.0,
                random_walk: 8.0 * MICRO_G,
                scale_factor: 100.0 * PPM,
            },
        },
        "perfect" => {
            let zero = TriadErrors {
                bias: 0.0,
                instability: 0.0,
                instability_tau_s: 1.0,
                random_walk: 0.0,
                scale_factor: 0.0,
            };
            ImuGrade {
                name: "perfect",
                gyro: zero,
                accel: zero,
            }
        }
        _ => return None,
    };
    Some(g)
}
