//! An outside check of the whole direct georeferencing equation: a forward model written out
//! from docs/conventions.md alone (§2 time model and latencies, §3 frames, §4 the equation),
//! sharing no code with the crate's `georef`, `trajectory`, `timing` or pose code. It reads the
//! SBET's bytes itself (§6: 17 little-endian f64 per record), interpolates the position
//! linearly in latitude, longitude and height and the attitude by its own quaternion slerp,
//! and builds `R_n^e`, `R_b^n`, `R_s^b` and `u_s` from the formulas of §3. `kinescan run` must
//! write the same points (and GPS times) for every return, with every term of the equation
//! non-zero: lever arm, boresight, alpha0 (cone), range zero and scale, encoder offset, heading
//! offset, attitude and position latency, a decreasing mirror and a non-trivial clock. The
//! pipeline's own round trip (`pipeline_roundtrip.rs`) builds its known points with the
//! pipeline's pose cursor and beam code, so a wrong sign or term shared by both would cancel
//! there; it cannot cancel here.
//!
//! Also a few returns whose coordinates are worked out by hand in the comments (heading 90 deg,
//! yaw rate 1 rad/s, attitude latency 10 ms, on the equator at the prime meridian).

use crate::common::{write_trajectory, Lcg, DURATION_S, T_START_S};
use kinescan::io::profiles::{ProfileColumns, ProfileWriter, RawReturn};
use kinescan::io::sbet::{SbetRecord, SbetWriter};
use nalgebra::{Matrix3, Vector3};
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::path::Path;

// ---------------------------------------------------------------------------------------------
// The forward model (docs/conventions.md), independent of the crate.

/// WGS84 (conventions §3).
const A_M: f64 = 6_378_137.0;
const INV_F: f64 = 298.257223563;

/// ECEF of a geodetic position (rad, rad, m) on WGS84.
fn ecef(lat: f64, lon: f64, h: f64) -> Vector3<f64> {
    let f = 1.0 / INV_F;
    let e2 = f * (2.0 - f);
    let n = A_M / (1.0 - e2 * lat.sin().powi(2)).sqrt();
    Vector3::new(
        (n + h) * lat.cos() * lon.cos(),
        (n + h) * lat.cos() * lon.sin(),
        (n * (1.0 - e2) + h) * lat.sin(),
    )
}

/// `R_n^e` as written in conventions §3 (NED to ECEF).
fn r_n_e(lat: f64, lon: f64) -> Matrix3<f64> {
    let (sl, cl) = lat.sin_cos();
    let (so, co) = lon.sin_cos();
    Matrix3::new(
        -sl * co,
        -so,
        -cl * co, //
        -sl * so,
        co,
        -cl * so, //
        cl,
        0.0,
        -sl,
    )
}

fn rx(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}

fn ry(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

fn rz(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// A unit quaternion (w, x, y, z) of `Rz(h) * Ry(p) * Rx(r)`: the product of the three axis
/// quaternions, so no matrix-to-quaternion branch is involved.
fn quat_zyx(h: f64, p: f64, r: f64) -> [f64; 4] {
    let mul = |a: [f64; 4], b: [f64; 4]| {
        [
            a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
        ]
    };
    let z = [(h / 2.0).cos(), 0.0, 0.0, (h / 2.0).sin()];
    let y = [(p / 2.0).cos(), 0.0, (p / 2.0).sin(), 0.0];
    let x = [(r / 2.0).cos(), (r / 2.0).sin(), 0.0, 0.0];
    mul(mul(z, y), x)
}

/// Rotation matrix of a unit quaternion (w, x, y, z).
fn quat_matrix(q: [f64; 4]) -> Matrix3<f64> {
    let [w, x, y, z] = q;
    Matrix3::new(
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y - w * z),
        2.0 * (x * z + w * y),
        2.0 * (x * y + w * z),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z - w * x),
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        1.0 - 2.0 * (x * x + y * y),
    )
}

/// Spherical linear interpolation on the shorter arc (conventions §4: attitude interpolated on
/// the rotation group, never Euler angles across a wrap).
fn slerp(a: [f64; 4], mut b: [f64; 4], w: f64) -> [f64; 4] {
    let mut dot: f64 = (0..4).map(|k| a[k] * b[k]).sum();
    if dot < 0.0 {
        b = b.map(|v| -v);
        dot = -dot;
    }
    let theta = crate::common::min_of([dot, 1.0]).acos();
    let (ka, kb) = if theta < 1e-12 {
        (1.0 - w, w)
    } else {
        (
            ((1.0 - w) * theta).sin() / theta.sin(),
            (w * theta).sin() / theta.sin(),
        )
    };
    let q: [f64; 4] = std::array::from_fn(|k| ka * a[k] + kb * b[k]);
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    q.map(|v| v / n)
}

/// An SBET read from its bytes (conventions §6): time, lat, lon, alt, 3 velocities, roll,
/// pitch, platform heading, wander, 6 more.
struct Sbet {
    records: Vec<[f64; 17]>,
}

impl Sbet {
    fn read(path: &Path) -> Sbet {
        let bytes = std::fs::read(path).unwrap();
        assert_eq!(bytes.len() % 136, 0, "{}", path.display());
        let records = bytes
            .chunks_exact(136)
            .map(|r| {
                std::array::from_fn(|k| f64::from_le_bytes(r[8 * k..8 * k + 8].try_into().unwrap()))
            })
            .collect();
        Sbet { records }
    }

    /// The records around `t` and the weight of the later one.
    fn bracket(&self, t: f64) -> (&[f64; 17], &[f64; 17], f64) {
        let k = self.records.partition_point(|r| r[0] <= t);
        assert!(k > 0 && k < self.records.len(), "{t} outside the SBET");
        let (a, b) = (&self.records[k - 1], &self.records[k]);
        (a, b, (t - a[0]) / (b[0] - a[0]))
    }

    /// ECEF position and (lat, lon) at `t`: latitude, longitude and height interpolated
    /// linearly (conventions §4: `r_e(t)`, `lat(t)`, `lon(t)` from the trajectory at `t`).
    fn position(&self, t: f64) -> (Vector3<f64>, f64, f64) {
        let (a, b, w) = self.bracket(t);
        let lerp = |k: usize| a[k] + w * (b[k] - a[k]);
        let (lat, lon, h) = (lerp(1), lerp(2), lerp(3));
        (ecef(lat, lon, h), lat, lon)
    }

    /// `R_b^n` at `t` (conventions §3): `Rz(heading) Ry(pitch) Rx(roll)`, true heading =
    /// platform heading - wander + the heading offset; slerp between the records.
    fn attitude(&self, t: f64, heading_offset: f64) -> Matrix3<f64> {
        let (a, b, w) = self.bracket(t);
        let q = |r: &[f64; 17]| quat_zyx(r[9] - r[10] + heading_offset, r[8], r[7]);
        quat_matrix(slerp(q(a), q(b), w))
    }
}

/// Every parameter of the equation (conventions §2-§4, §8's names).
struct Params {
    lever_arm_b_m: [f64; 3],
    boresight_deg: [f64; 3],
    alpha0_deg: f64,
    range_zero_m: f64,
    range_scale_ppm: f64,
    encoder_offset_deg: f64,
    heading_offset_deg: f64,
    attitude_latency_s: f64,
    position_latency_s: f64,
    t0_s: f64,
    period_s: f64,
    beta_start_deg: f64,
    /// +1 increasing, -1 decreasing.
    direction: f64,
}

impl Params {
    /// Return time (conventions §2), the encoder offset added to beta first (§3).
    fn time(&self, n: u32, beta: f64) -> f64 {
        let beta = beta + self.encoder_offset_deg.to_radians();
        let f = (self.direction * (beta - self.beta_start_deg.to_radians())).rem_euclid(TAU) / TAU;
        self.t0_s + self.period_s * (n as f64 + f)
    }

    /// The point (ECEF) and time of return (n, beta, rho) (conventions §4):
    /// `x_e = r_e(t + tau_p) + R_n^e R_b^n(t + tau) (l_b + R_s^b x_s)`,
    /// `x_s = (1 + S 1e-6) (rho + K) u_s(alpha0, beta + dbeta)`.
    fn forward(&self, sbet: &Sbet, n: u32, beta: f64, rho: f64) -> (Vector3<f64>, f64) {
        let t = self.time(n, beta);
        let beta = beta + self.encoder_offset_deg.to_radians();
        let alpha = self.alpha0_deg.to_radians();
        let u_s = Vector3::new(
            alpha.sin(),
            -alpha.cos() * beta.sin(),
            alpha.cos() * beta.cos(),
        );
        let x_s = (1.0 + self.range_scale_ppm * 1e-6) * (rho + self.range_zero_m) * u_s;
        let [bx, by, bz] = self.boresight_deg.map(f64::to_radians);
        let r_s_b = rz(bz) * ry(by) * rx(bx);
        let (r_e, lat, lon) = sbet.position(t + self.position_latency_s);
        let r_b_n = sbet.attitude(
            t + self.attitude_latency_s,
            self.heading_offset_deg.to_radians(),
        );
        let x_b = Vector3::from(self.lever_arm_b_m) + r_s_b * x_s;
        (r_e + r_n_e(lat, lon) * r_b_n * x_b, t)
    }

    /// The pipeline file of these parameters (output in ECEF, 0.1 mm steps).
    fn pipeline_toml(&self, sbet: &str, profiles: &str) -> String {
        let dir = if self.direction > 0.0 {
            "increasing"
        } else {
            "decreasing"
        };
        format!(
            r#"[inputs]
sbet = "{sbet}"
profiles = ["{profiles}"]

[trajectory]
heading_offset_deg = {}

[sensor]
lever_arm_b_m = {:?}
boresight_deg = {:?}
alpha0_deg = {}
range_zero_m = {}
range_scale_ppm = {}
encoder_offset_deg = {}
min_range_m = 0.5
max_range_m = 300.0

[time]
model = "software"
t0_s = {}
period_s = {}
beta_start_deg = {}
direction = "{dir}"

[latency]
attitude_s = {}
position_s = {}

[output]
las = "out/cloud.las"
scale_m = 0.0001
frame = {{ kind = "ecef" }}
"#,
            self.heading_offset_deg,
            self.lever_arm_b_m,
            self.boresight_deg,
            self.alpha0_deg,
            self.range_zero_m,
            self.range_scale_ppm,
            self.encoder_offset_deg,
            self.t0_s,
            self.period_s,
            self.beta_start_deg,
            self.attitude_latency_s,
            self.position_latency_s,
        )
    }
}

/// Runs `kinescan run` on the folder and returns the written points: ECEF and GPS time.
fn run_pipeline(dir: &Path) -> Vec<(Vector3<f64>, f64)> {
    let out = crate::common::kinescan(dir, &["run", "pipeline.toml"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut reader = las::Reader::from_path(dir.join("out/cloud.las")).unwrap();
    reader
        .read_all()
        .unwrap()
        .points()
        .map(|p| {
            let p = p.unwrap();
            (Vector3::new(p.x, p.y, p.z), p.gps_time.unwrap())
        })
        .collect()
}

fn write_profiles(path: &Path, returns: &[(u32, f64, f64)]) {
    let mut w = ProfileWriter::create(path, ProfileColumns::default()).unwrap();
    for &(profile, beta_rad, range_m) in returns {
        w.push(&RawReturn {
            profile,
            beta_rad,
            range_m,
            intensity: 100,
            ..Default::default()
        })
        .unwrap();
    }
    w.finish().unwrap();
}

// ---------------------------------------------------------------------------------------------
// Many returns: the pipeline against the forward model.

/// Every term non-zero and none small: a wrong sign or a missing term moves points by
/// centimetres to metres at these ranges (2-150 m; see the test's tolerance).
fn survey_params() -> Params {
    Params {
        lever_arm_b_m: [0.41, -0.27, -1.63],
        boresight_deg: [1.7, -2.3, 91.4],
        alpha0_deg: 0.8,
        range_zero_m: 0.021,
        range_scale_ppm: 150.0,
        encoder_offset_deg: 0.07,
        heading_offset_deg: 0.05,
        attitude_latency_s: 0.0037,
        position_latency_s: 0.002,
        t0_s: T_START_S + 0.013,
        period_s: 0.01,
        beta_start_deg: -135.0,
        direction: -1.0,
    }
}

/// 20,000 random returns over the synthetic drive (a 30 m circle at 15 m/s, every heading,
/// roll and pitch to +-30 deg, a wander angle): every point and time `kinescan run` writes is
/// the forward model's. Tolerance 0.5 mm: the LAS quantisation is 0.05 mm, and the two
/// position interpolations (linear in lat/lon/h here; the crate's own) differ by far less
/// (both interpolate 7.5 cm steps of a 30 m circle: their chord error, 2e-5 m, is the same to
/// 1e-9 m). What a defect would cost at 150 m: the attitude latency's sign 2 x 3.7 ms x 0.5
/// rad/s x 150 m = 0.55 m; the position latency 2 ms x 15 m/s = 3 cm; the heading offset
/// 0.05 deg = 13 cm; the range scale 150 ppm = 2.2 cm; the encoder offset 0.07 deg = 18 cm;
/// alpha0 0.8 deg = 2 m; the range zero 2.1 cm; a lever arm or boresight axis mixed up: > 10
/// cm. The GPS time agrees to 1 ns (the time model alone).
#[test]
fn the_pipeline_writes_the_forward_models_points() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (sbet_path, _) = write_trajectory(d);
    let sbet = Sbet::read(&sbet_path);
    let p = survey_params();
    let mut rng = Lcg(2027);
    // Profiles whose returns (and latencies) fall inside the trajectory.
    let first = ((T_START_S + 0.2 - p.t0_s) / p.period_s) as u32;
    let last = ((T_START_S + DURATION_S - 0.2 - p.t0_s) / p.period_s) as u32;
    let mut returns: Vec<(u32, f64, f64)> = (0..20_000)
        .map(|_| {
            let n = first + (rng.uniform() * f64::from(last - first)) as u32;
            (n, rng.range(-PI, PI), rng.range(2.0, 150.0))
        })
        .collect();
    returns.sort_by_key(|r| r.0);
    write_profiles(&d.join("pass.ksprof"), &returns);
    std::fs::write(
        d.join("pipeline.toml"),
        p.pipeline_toml("traj.sbet", "pass.ksprof"),
    )
    .unwrap();
    let points = run_pipeline(d);
    assert_eq!(points.len(), returns.len(), "every return written");
    let (mut worst_m, mut worst_t) = (0.0, 0.0);
    for (&(n, beta, rho), (x, t)) in returns.iter().zip(&points) {
        let (want, want_t) = p.forward(&sbet, n, beta, rho);
        crate::common::raise_max(&mut worst_m, (x - want).norm());
        crate::common::raise_max(&mut worst_t, (t - want_t).abs());
    }
    println!(
        "forward model vs kinescan run: worst {worst_m:.2e} m, {worst_t:.2e} s over {} returns",
        points.len()
    );
    assert!(worst_m <= 5e-4, "worst point difference {worst_m} m");
    assert!(worst_t <= 1e-9, "worst time difference {worst_t} s");
}

// ---------------------------------------------------------------------------------------------
// Returns worked out by hand.

/// The hand-computed survey: on the equator at the prime meridian (lat = lon = 0, h = 0), the
/// van turning in place at 1 rad/s, true heading 90 deg (east) at `T_C`, roll = pitch = 0,
/// wander 0.2 rad (platform heading = true heading + 0.2), 100 Hz. Scanner: identity
/// boresight, alpha0 = 0, lever arm (1, 0, 0) m, K = S = 0, attitude latency 10 ms; clock
/// t0 = 1000 s, T = 0.1 s, beta_start = -180 deg, increasing.
const T_C: f64 = 1000.55;

fn hand_params() -> Params {
    Params {
        lever_arm_b_m: [1.0, 0.0, 0.0],
        boresight_deg: [0.0; 3],
        alpha0_deg: 0.0,
        range_zero_m: 0.0,
        range_scale_ppm: 0.0,
        encoder_offset_deg: 0.0,
        heading_offset_deg: 0.0,
        attitude_latency_s: 0.010,
        position_latency_s: 0.0,
        t0_s: 1000.0,
        period_s: 0.1,
        beta_start_deg: -180.0,
        direction: 1.0,
    }
}

fn write_spinning_sbet(path: &Path) {
    let mut w = SbetWriter::create(path).unwrap();
    for k in 0..=300 {
        let t = 999.0 + k as f64 * 0.01;
        let heading = FRAC_PI_2 + (t - T_C);
        w.push(&SbetRecord {
            time_s: t,
            platform_heading_rad: heading + 0.2,
            wander_rad: 0.2,
            rate_z_radps: 1.0,
            ..SbetRecord::default()
        })
        .unwrap();
    }
    w.finish().unwrap();
}

/// The worked points (profile, beta, range, expected ECEF, expected time):
///
/// A: profile 5, beta = 0, rho = 10 m. Time: wrap(0 - (-pi)) / 2pi = 0.5, so
///    t = 1000 + 0.1 (5 + 0.5) = 1000.55 s = T_C; the attitude is taken at t + tau = 1000.56 s:
///    heading h = 90 deg + 0.01 rad (1 rad/s x 10 ms). u_s(0, 0) = (0, 0, 1): x_s = (0, 0, 10),
///    x_b = l_b + x_s = (1, 0, 10). R_b^n = Rz(h): x_n = (cos h, sin h, 10)
///    = (-sin 0.01, cos 0.01, 10) = (-0.0099998333, 0.9999500004, 10) (N, E, D).
///    At lat = lon = 0, R_n^e maps N -> +Z, E -> +Y, D -> -X and r_e = (a, 0, 0):
///    x_e = (6378137 - 10, 0.9999500004, -0.0099998333).
///    (With the latency's sign reversed, h = 90 deg - 0.01 rad and Z = +0.0099998: 2 cm off;
///    without the lever arm, Y = 0 and Z = 0: 1 m off.)
///
/// B: profile 5, beta = +90 deg, rho = 5 m. Time: wrap(pi/2 + pi) / 2pi = 0.75, so
///    t = 1000 + 0.1 x 5.75 = 1000.575 s, attitude at 1000.585 s: h = 90 deg + 0.035 rad.
///    u_s(0, 90 deg) = (0, -1, 0) (s-frame -y): x_s = (0, -5, 0), x_b = (1, -5, 0).
///    x_n = (cos h + 5 sin h, sin h - 5 cos h, 0) with cos h = -sin 0.035 = -0.0349928546,
///    sin h = cos 0.035 = 0.9993875625: x_n = (4.9619449580, 1.1743518355, 0).
///    x_e = (6378137, 1.1743518355, 4.9619449580).
///    (Without the latency, h = 90 deg + 0.025 rad: x_n = (4.9734402, 1.1246745), 5 cm off.)
///
/// C: profile 7, beta = -90 deg, rho = 2 m. Time: wrap(-pi/2 + pi) / 2pi = 0.25, so
///    t = 1000 + 0.1 x 7.25 = 1000.725 s, attitude at 1000.735 s: h = 90 deg + 0.185 rad.
///    u_s(0, -90 deg) = (0, 1, 0): x_s = (0, 2, 0), x_b = (1, 2, 0).
///    x_n = (cos h - 2 sin h, sin h + 2 cos h, 0) with cos h = -sin 0.185 = -0.1839465335,
///    sin h = cos 0.185 = 0.9829362506: x_n = (-2.1498190348, 0.6150431836, 0).
///    x_e = (6378137, 0.6150431836, -2.1498190348).
const HAND_POINTS: [(u32, f64, f64, [f64; 3], f64); 3] = [
    (
        5,
        0.0,
        10.0,
        [6_378_127.0, 0.999_950_000_4, -0.009_999_833_3],
        1000.55,
    ),
    (
        5,
        FRAC_PI_2,
        5.0,
        [6_378_137.0, 1.174_351_835_5, 4.961_944_958_0],
        1000.575,
    ),
    (
        7,
        -FRAC_PI_2,
        2.0,
        [6_378_137.0, 0.615_043_183_6, -2.149_819_034_8],
        1000.725,
    ),
];

/// The worked points come out of the forward model and out of `kinescan run` to 0.2 mm (the
/// LAS's 0.05 mm quantisation, the hand values' 1e-10 m rounding, and the slerp between 100 Hz
/// records of a constant-rate turn, which is exact).
#[test]
fn hand_computed_points_heading_90_latency_10_ms_yaw_rate_1() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_spinning_sbet(&d.join("spin.sbet"));
    let p = hand_params();
    let returns: Vec<(u32, f64, f64)> = HAND_POINTS.iter().map(|h| (h.0, h.1, h.2)).collect();
    write_profiles(&d.join("spin.ksprof"), &returns);
    std::fs::write(
        d.join("pipeline.toml"),
        p.pipeline_toml("spin.sbet", "spin.ksprof"),
    )
    .unwrap();
    let sbet = Sbet::read(&d.join("spin.sbet"));
    let points = run_pipeline(d);
    assert_eq!(points.len(), HAND_POINTS.len());
    for ((n, beta, rho, want, want_t), (x, t)) in HAND_POINTS.into_iter().zip(points) {
        let want = Vector3::from(want);
        let (model, model_t) = p.forward(&sbet, n, beta, rho);
        assert!(
            (model - want).norm() < 1e-6,
            "forward model {model} vs hand {want}"
        );
        assert!(
            (model_t - want_t).abs() < 1e-9,
            "forward model t {model_t} vs {want_t}"
        );
        assert!((x - want).norm() <= 2e-4, "kinescan {x} vs hand {want}");
        assert!((t - want_t).abs() < 1e-9, "kinescan t {t} vs {want_t}");
    }
}

/// The forward model's pieces against conventions §3 directly: `R_n^e` columns are north,
/// east and down in ECEF; `Rz(90 deg)` turns body x (forward) to east; the quaternion product
/// and slerp reproduce the matrices.
#[test]
fn the_forward_models_frames_match_the_conventions() {
    let (lat, lon) = (0.7f64, 0.2f64);
    let r = r_n_e(lat, lon);
    // North: d(ECEF)/d(lat) direction; east: d/d(lon); down: -d/d(h).
    let d = 1e-7;
    let north = (ecef(lat + d, lon, 0.0) - ecef(lat - d, lon, 0.0)).normalize();
    let east = (ecef(lat, lon + d, 0.0) - ecef(lat, lon - d, 0.0)).normalize();
    let down = (ecef(lat, lon, -1.0) - ecef(lat, lon, 1.0)).normalize();
    for (k, axis) in [north, east, down].iter().enumerate() {
        assert!((r.column(k) - axis).norm() < 1e-9, "column {k}");
    }
    let east_of_forward = rz(FRAC_PI_2) * Vector3::x();
    assert!((east_of_forward - Vector3::y()).norm() < 1e-15);
    let (h, p, ro) = (2.9, -0.4, 0.5);
    let q = quat_zyx(h, p, ro);
    assert!((quat_matrix(q) - rz(h) * ry(p) * rx(ro)).norm() < 1e-14);
    // Slerp across the +-pi heading wrap goes the short way: halfway between 179 and -179 deg
    // is 180 deg.
    let half = quat_matrix(slerp(
        quat_zyx(179f64.to_radians(), 0.0, 0.0),
        quat_zyx(-179f64.to_radians(), 0.0, 0.0),
        0.5,
    ));
    assert!((half - rz(PI)).norm() < 1e-12);
}
