//! Applanix SBET trajectory files (conventions §6): 17 little-endian f64 per 136-byte record, no header.

use super::timed::{TimedFile, TimedRecord, TimedWriter};

/// Bytes per SBET record.
pub const SBET_RECORD_BYTES: usize = 136;

/// One SBET record, fields in file order.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct SbetRecord {
    /// GPS seconds of the week (s).
    pub time_s: f64,
    /// Geodetic latitude, WGS84 (rad).
    pub lat_rad: f64,
    /// Longitude (rad).
    pub lon_rad: f64,
    /// Ellipsoidal height (m).
    pub alt_m: f64,
    /// Velocity along wander-frame x (m/s).
    pub vel_x_mps: f64,
    /// Velocity along wander-frame y (m/s).
    pub vel_y_mps: f64,
    /// Velocity along wander-frame z, down (m/s).
    pub vel_z_mps: f64,
    /// Roll (rad).
    pub roll_rad: f64,
    /// Pitch (rad).
    pub pitch_rad: f64,
    /// Platform heading in the wander frame (rad); true heading = this - wander.
    pub platform_heading_rad: f64,
    /// Wander angle (rad).
    pub wander_rad: f64,
    /// Body x acceleration (m/s^2).
    pub acc_x_mps2: f64,
    /// Body y acceleration (m/s^2).
    pub acc_y_mps2: f64,
    /// Body z acceleration (m/s^2).
    pub acc_z_mps2: f64,
    /// Body x angular rate (rad/s).
    pub rate_x_radps: f64,
    /// Body y angular rate (rad/s).
    pub rate_y_radps: f64,
    /// Body z angular rate (rad/s).
    pub rate_z_radps: f64,
}

impl SbetRecord {
    /// True heading (rad), clockwise from north: platform heading minus wander angle.
    #[inline]
    pub fn true_heading_rad(&self) -> f64 {
        self.platform_heading_rad - self.wander_rad
    }

    /// All 17 fields in file order.
    pub fn to_array(&self) -> [f64; 17] {
        [
            self.time_s,
            self.lat_rad,
            self.lon_rad,
            self.alt_m,
            self.vel_x_mps,
            self.vel_y_mps,
            self.vel_z_mps,
            self.roll_rad,
            self.pitch_rad,
            self.platform_heading_rad,
            self.wander_rad,
            self.acc_x_mps2,
            self.acc_y_mps2,
            self.acc_z_mps2,
            self.rate_x_radps,
            self.rate_y_radps,
            self.rate_z_radps,
        ]
    }

    /// Record from 17 fields in file order.
    pub fn from_array(a: [f64; 17]) -> Self {
        SbetRecord {
            time_s: a[0],
            lat_rad: a[1],
            lon_rad: a[2],
            alt_m: a[3],
            vel_x_mps: a[4],
            vel_y_mps: a[5],
            vel_z_mps: a[6],
            roll_rad: a[7],
            pitch_rad: a[8],
            platform_heading_rad: a[9],
            wander_rad: a[10],
            acc_x_mps2: a[11],
            acc_y_mps2: a[12],
            acc_z_mps2: a[13],
            rate_x_radps: a[14],
            rate_y_radps: a[15],
            rate_z_radps: a[16],
        }
    }
}

const FIELD_NAMES: [&str; 17] = [
    "time",
    "latitude",
    "longitude",
    "altitude",
    "x velocity",
    "y velocity",
    "z velocity",
    "roll",
    "pitch",
    "platform heading",
    "wander angle",
    "x acceleration",
    "y acceleration",
    "z acceleration",
    "x angular rate",
    "y angular rate",
    "z angular rate",
];

impl TimedRecord for SbetRecord {
    const FIELDS: usize = 17;
    const KIND: &'static str = "SBET";

    fn field_names() -> &'static [&'static str] {
        &FIELD_NAMES
    }

    fn from_fields(fields: &[f64]) -> Self {
        Self::from_array(fields.try_into().expect("17 fields"))
    }

    fn to_fields(&self, out: &mut [f64]) {
        out.copy_from_slice(&self.to_array());
    }

    fn problem(fields: &[f64]) -> Option<String> {
        use std::f64::consts::{FRAC_PI_2, PI, TAU};
        // A hair over each bound: values written from wrapped f64 angles may round over it.
        let over = |v: f64, bound: f64| v.abs() > bound * (1.0 + 1e-9);
        let degrees = "SBET angles are radians: degrees, or not an SBET file";
        if over(fields[1], FRAC_PI_2) {
            return Some(format!(
                "latitude {} rad is outside [-pi/2, pi/2]",
                fields[1]
            ));
        }
        if over(fields[2], TAU) {
            return Some(format!(
                "longitude {} rad is outside [-2 pi, 2 pi]: {degrees}",
                fields[2]
            ));
        }
        if !(MIN_ALTITUDE_M..=MAX_ALTITUDE_M).contains(&fields[3]) {
            return Some(format!(
                "altitude {} m is not near the Earth's surface ({MIN_ALTITUDE_M} to \
                 {MAX_ALTITUDE_M} m): a corrupt record, or not an SBET file",
                fields[3]
            ));
        }
        let angles = [(7, PI), (8, PI), (9, TAU), (10, TAU)];
        let bad = angles.iter().find(|(k, bound)| over(fields[*k], *bound))?;
        Some(format!(
            "{} {} is beyond {} rad: {degrees}",
            FIELD_NAMES[bad.0],
            fields[bad.0],
            if bad.1 == PI { "pi" } else { "2 pi" }
        ))
    }

    /// A move or turn between two records that no vehicle can make: a corrupt record (its
    /// neighbour named), not a trajectory to georeference with.
    fn step_problem(prev: &[f64], next: &[f64]) -> Option<String> {
        use std::f64::consts::{PI, TAU};
        let dt = next[0] - prev[0];
        let wrap = |d: f64| (d + PI).rem_euclid(TAU) - PI;
        const EARTH_RADIUS_M: f64 = 6_371_000.0;
        let north = (next[1] - prev[1]) * EARTH_RADIUS_M;
        let east = wrap(next[2] - prev[2]) * EARTH_RADIUS_M * next[1].cos();
        let up = next[3] - prev[3];
        let speed = (north * north + east * east + up * up).sqrt() / dt;
        if speed > MAX_SPEED_MPS {
            return Some(format!(
                "position jumps {:.1} m in {dt} s from the previous record ({speed:.0} m/s; no \
                 survey vehicle exceeds {MAX_SPEED_MPS} m/s): a corrupt record (latitude, \
                 longitude or altitude)",
                speed * dt
            ));
        }
        for k in [7, 8, 9] {
            let rate = wrap(next[k] - prev[k]).abs() / dt;
            if rate > MAX_TURN_RATE_RADPS {
                return Some(format!(
                    "{} turns {:.3} rad in {dt} s from the previous record ({rate:.0} rad/s; no \
                     survey vehicle exceeds {MAX_TURN_RATE_RADPS} rad/s): a corrupt record, or \
                     angles in degrees",
                    FIELD_NAMES[k],
                    rate * dt
                ));
            }
        }
        None
    }
}

/// Lowest plausible SBET altitude (m; the Dead Sea shore is at -430 m).
pub const MIN_ALTITUDE_M: f64 = -1_000.0;
/// Highest plausible SBET altitude (m; airborne surveys fly below 15 km).
pub const MAX_ALTITUDE_M: f64 = 100_000.0;
/// Fastest plausible survey platform (m/s; airborne surveys fly below 150 m/s).
pub const MAX_SPEED_MPS: f64 = 1_000.0;
/// Fastest plausible turn of a survey platform (rad/s, about 1,100 deg/s).
pub const MAX_TURN_RATE_RADPS: f64 = 20.0;

/// A validated, memory-mapped SBET file.
pub type SbetFile = TimedFile<SbetRecord>;

/// Streaming, atomic SBET writer.
pub type SbetWriter = TimedWriter<SbetRecord>;
