//! Simulated IMU: the exact increments of the true motion ([`crate::ins::mechanisation::increments`])
//! plus the errors of a named grade ([`crate::ins::imu_model`]): scale factor and turn-on bias
//! drawn once per run, bias instability as a first-order Gauss-Markov process sampled exactly,
//! white noise of the random-walk density. Per axis, each triad from its own random stream.

use crate::ins::imu_model::{ImuGrade, TriadErrors};
use crate::io::imu::ImuRecord;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The constant errors drawn for one run (what a perfect filter would estimate).
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct DrawnErrors {
    /// Turn-on bias per axis (rad/s or m/s^2).
    pub bias: [f64; 3],
    /// Scale factor error per axis (dimensionless).
    pub scale_factor: [f64; 3],
}

/// One triad's error generator.
#[derive(Debug, Clone)]
struct TriadGen {
    drawn: DrawnErrors,
    gm: [f64; 3],
    phi: f64,
    drive: f64,
    white: f64,
    rng: ChaCha8Rng,
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

impl TriadGen {
    fn new(model: TriadErrors, dt: f64, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let drawn = DrawnErrors {
            bias: [0; 3].map(|_| model.bias * normal(&mut rng)),
            scale_factor: [0; 3].map(|_| model.scale_factor * normal(&mut rng)),
        };
        let gm = [0; 3].map(|_| model.instability * normal(&mut rng));
        let phi = (-dt / model.instability_tau_s).exp();
        TriadGen {
            drawn,
            gm,
            phi,
            drive: model.instability * (1.0 - phi * phi).sqrt(),
            white: model.random_walk / dt.sqrt(),
            rng,
        }
    }

    /// The measured mean over one interval of the true mean `x`; advances the bias process.
    fn measure(&mut self, x: &Vector3<f64>) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (i, o) in out.iter_mut().enumerate() {
            let n = self.white * normal(&mut self.rng);
            *o = (1.0 + self.drawn.scale_factor[i]) * x[i] + self.drawn.bias[i] + self.gm[i] + n;
            self.gm[i] = self.phi * self.gm[i] + self.drive * normal(&mut self.rng);
        }
        out
    }
}

/// IMU error generator of a grade at a rate.
#[derive(Debug, Clone)]
pub struct ImuGen {
    gyro: TriadGen,
    accel: TriadGen,
    /// The grade.
    pub grade: ImuGrade,
}

impl ImuGen {
    /// Generator for `grade` with records every `dt` (s), streams from `seed`.
    pub fn new(grade: ImuGrade, dt: f64, seed: u64) -> Self {
        ImuGen {
            gyro: TriadGen::new(grade.gyro, dt, seed ^ 0x6F0_0001),
            accel: TriadGen::new(grade.accel, dt, seed ^ 0xACC_0002),
            grade,
        }
    }

    /// Drawn gyro and accelerometer constants.
    pub fn drawn(&self) -> (DrawnErrors, DrawnErrors) {
        (self.gyro.drawn, self.accel.drawn)
    }

    /// The record ending at `time_s` for true increments `dtheta`, `dv` over `dt`.
    pub fn record(
        &mut self,
        time_s: f64,
        dtheta: &Vector3<f64>,
        dv: &Vector3<f64>,
        dt: f64,
    ) -> ImuRecord {
        ImuRecord {
            time_s,
            w_b: self.gyro.measure(&(dtheta / dt)),
            f_b: self.accel.measure(&(dv / dt)),
        }
    }
}
