//! The raw records of the van's INS/GNSS unit (`[raw]`, docs/simulator.md): IMU records at
//! the nav rate from the true motion, GNSS fixes at the GNSS rate, and the truth they came
//! from, sample by sample (memory flat in duration).
//!
//! The true states are the simulator's true samples (position, attitude) with the velocity
//! the central difference of the ECEF positions, so that position, velocity and attitude are
//! one consistent motion; the IMU record ending at sample k carries the exact increments from
//! state k-1 to state k ([`crate::ins::mechanisation::increments`]) plus the grade's errors.

use super::dynamics::{Frame, TruthGen};
use super::gnss::GnssGen;
use super::imu::{DrawnErrors, ImuGen};
use super::route::Route;
use super::scenario::{RawCfg, Scenario};
use crate::geo::ellipsoid::r_n_to_e;
use crate::geo::rotations::q_b_to_n;
use crate::ins::imu_model::{self, ImuGrade};
use crate::ins::mechanisation::{increments, NavState};
use crate::io::gnss::{GnssRecord, GnssWriter};
use crate::io::imu::{ImuRecord, ImuWriter};
use crate::io::sbet::SbetRecord;
use crate::{Error, Result};
use nalgebra::Vector3;
use std::collections::VecDeque;
use std::path::Path;

/// File names of the raw records inside a simulation's output folder.
pub mod files {
    /// IMU records (docs/formats.md).
    pub const IMU: &str = "imu.bin";
    /// GNSS fixes (docs/formats.md).
    pub const GNSS: &str = "gnss.bin";
    /// The drawn IMU constants, outages and outliers (JSON).
    pub const RAW_TRUTH: &str = "raw_truth.json";
}

/// One sample of the raw stream.
#[derive(Debug, Clone, Copy)]
pub struct RawSample {
    /// The true state at the sample time.
    pub truth: NavState,
    /// The IMU record ending here (None for the first sample).
    pub imu: Option<ImuRecord>,
    /// A GNSS fix at this time, if any.
    pub gnss: Option<GnssRecord>,
}

/// What was drawn for a run: the truth of the raw records.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RawTruth {
    /// The IMU grade and its error model.
    pub grade: ImuGrade,
    /// Gyro turn-on biases (rad/s) and scale factors.
    pub gyro: DrawnErrors,
    /// Accelerometer turn-on biases (m/s^2) and scale factors.
    pub accel: DrawnErrors,
    /// GNSS outages [start, end] (s from the start).
    pub outages_s: Vec<[f64; 2]>,
    /// Times of the outlier fixes (GPS s).
    pub outlier_times_s: Vec<f64>,
    /// The `[raw]` table.
    pub config: RawCfg,
}

/// Sequential generator of the raw stream of a scenario with a `[raw]` table.
pub struct RawGen {
    gen: TruthGen,
    recs: VecDeque<SbetRecord>,
    prev: Option<NavState>,
    imu: ImuGen,
    gnss: GnssGen,
    cfg: RawCfg,
    k: u64,
    n: u64,
    dt: f64,
    gnss_every: u64,
    start_s: f64,
}

impl RawGen {
    /// Generator for `sc` (which must have a `[raw]` table).
    pub fn new(sc: &Scenario) -> Result<RawGen> {
        let cfg = sc
            .raw
            .clone()
            .ok_or_else(|| Error::config(&sc.name, "raw", "the scenario has no [raw] table"))?;
        let grade = imu_model::grade(&cfg.imu_grade)
            .ok_or_else(|| Error::config(&sc.name, "raw.imu_grade", "unknown grade"))?;
        let o = &sc.origin;
        let frame = Frame::new(o.lat_deg.to_radians(), o.lon_deg.to_radians(), o.h_m);
        let route = Route::new(&sc.route, sc.vehicle.lane_offset_m, &sc.name)?;
        let rate = sc.vehicle.nav_rate_hz;
        Ok(RawGen {
            gen: TruthGen::new(sc, route, frame),
            recs: VecDeque::new(),
            prev: None,
            imu: ImuGen::new(grade, 1.0 / rate, sc.seed ^ 0x1A0_0000_0000_0004),
            gnss: GnssGen::new(&cfg, sc.duration_s, sc.seed ^ 0x6A0_0000_0000_0005),
            gnss_every: (rate / cfg.gnss_rate_hz).round() as u64,
            cfg,
            k: 0,
            n: (sc.duration_s * rate).floor() as u64 + 1,
            dt: 1.0 / rate,
            start_s: sc.start_time_s,
        })
    }

    /// Number of samples in the run.
    pub fn len(&self) -> u64 {
        self.n
    }

    /// True when the run has no sample (never: a scenario lasts > 0 s).
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The truth of the records generated so far (outliers up to now).
    pub fn raw_truth(&self) -> RawTruth {
        let (gyro, accel) = self.imu.drawn();
        RawTruth {
            grade: self.imu.grade,
            gyro,
            accel,
            outages_s: self.gnss.outages().to_vec(),
            outlier_times_s: self.gnss.outlier_times.clone(),
            config: self.cfg.clone(),
        }
    }

    fn record(&mut self, k: u64) -> SbetRecord {
        while self.gen.next_index() <= k {
            self.recs.push_back(self.gen.next_sample());
        }
        let base = self.gen.next_index() - self.recs.len() as u64;
        self.recs[(k - base) as usize]
    }

    fn truth_state(&mut self, k: u64) -> NavState {
        let r = self.record(k);
        let e = |r: &SbetRecord| {
            crate::geo::ellipsoid::geodetic_to_ecef(crate::geo::ellipsoid::Geodetic {
                lat_rad: r.lat_rad,
                lon_rad: r.lon_rad,
                h_m: r.alt_m,
            })
        };
        let next = self.record(k + 1);
        let v_e: Vector3<f64> = if k == 0 {
            (e(&next) - e(&r)) / self.dt
        } else {
            let before = self.record(k - 1);
            (e(&next) - e(&before)) / (2.0 * self.dt)
        };
        while self.recs.len() > 3 {
            self.recs.pop_front();
        }
        NavState {
            time_s: r.time_s,
            lat_rad: r.lat_rad,
            lon_rad: r.lon_rad,
            h_m: r.alt_m,
            v_n: r_n_to_e(r.lat_rad, r.lon_rad).transpose() * v_e,
            q_b_n: q_b_to_n(r.roll_rad, r.pitch_rad, r.true_heading_rad()),
        }
    }
}

impl Iterator for RawGen {
    type Item = RawSample;

    fn next(&mut self) -> Option<RawSample> {
        if self.k >= self.n {
            return None;
        }
        let k = self.k;
        let truth = self.truth_state(k);
        let imu = self.prev.map(|p| {
            let (dth, dv) = increments(&p, &truth, self.dt);
            self.imu.record(truth.time_s, &dth, &dv, self.dt)
        });
        let rel = truth.time_s - self.start_s;
        let gnss = if k.is_multiple_of(self.gnss_every) {
            self.gnss.fix(&truth, rel)
        } else {
            None
        };
        self.prev = Some(truth);
        self.k += 1;
        Some(RawSample { truth, imu, gnss })
    }
}

/// Counts of raw records written.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct RawCounts {
    /// IMU records.
    pub imu_records: u64,
    /// GNSS fixes.
    pub gnss_records: u64,
}

/// Writes `imu.bin`, `gnss.bin` and `raw_truth.json` of `sc` into `dir`.
pub fn write_raw(sc: &Scenario, dir: &Path) -> Result<RawCounts> {
    let mut gen = RawGen::new(sc)?;
    let mut imu = ImuWriter::create(&dir.join(files::IMU))?;
    let mut gnss = GnssWriter::create(&dir.join(files::GNSS))?;
    for s in gen.by_ref() {
        if let Some(r) = &s.imu {
            imu.push(r)?;
        }
        if let Some(g) = &s.gnss {
            gnss.push(g)?;
        }
    }
    let counts = RawCounts {
        imu_records: imu.finish()?,
        gnss_records: gnss.finish()?,
    };
    crate::io::atomic::write_json(&dir.join(files::RAW_TRUTH), &gen.raw_truth())?;
    Ok(counts)
}
