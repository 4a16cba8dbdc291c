//! Shared test fixtures: a synthetic trajectory that exercises every heading, roll and pitch to
//! +-30 deg and a wander angle, and helpers to invert the georeferencing equation.
#![allow(dead_code)]

use kinescan::geo::ellipsoid::{geodetic_to_ecef, r_n_to_e, Geodetic};
use kinescan::geo::rotations::wrap_pi;
use kinescan::io::sbet::{SbetRecord, SbetWriter};
use kinescan::io::smrmsg::{SmrmsgRecord, SmrmsgWriter};
use nalgebra::Vector3;
use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

/// Start of the synthetic trajectory (GPS seconds of week).
pub const T_START_S: f64 = 300_000.0;
/// Its length (s).
pub const DURATION_S: f64 = 20.0;
/// Origin of the synthetic drive (Munich, UTM zone 32N).
pub const LAT0_DEG: f64 = 48.137;
/// Origin longitude.
pub const LON0_DEG: f64 = 11.575;

/// Writes a 200 Hz SBET (and a 1 Hz SMRMSG): a 30 m circle at 15 m/s (heading through more
/// than 1.5 turns, so every heading and the 359 -> 1 deg wrap occur), roll and pitch
/// sinusoids of 30 deg amplitude, a slowly varying wander angle, platform heading wrapped to
/// (-pi, pi].
pub fn write_trajectory(dir: &Path) -> (PathBuf, PathBuf) {
    let sbet = dir.join("traj.sbet");
    let smrmsg = dir.join("traj.smrmsg");
    let mut w = SbetWriter::create(&sbet).unwrap();
    let n = (DURATION_S * 200.0) as usize;
    let (lat0, lon0) = (LAT0_DEG.to_radians(), LON0_DEG.to_radians());
    let (rad_m, speed) = (30.0, 15.0);
    for k in 0..=n {
        let t = k as f64 / 200.0;
        let ang = speed / rad_m * t;
        let (north, east) = (rad_m * ang.sin(), rad_m * (1.0 - ang.cos()));
        let heading = ang; // tangent of the circle
        let wander = 0.3 * (0.1 * t).sin();
        let r = SbetRecord {
            time_s: T_START_S + t,
            lat_rad: lat0 + north / 6_366_000.0,
            lon_rad: lon0 + east / (6_389_000.0 * lat0.cos()),
            alt_m: 520.0 + 0.5 * (0.3 * t).sin(),
            vel_x_mps: speed * (heading + wander).cos(),
            vel_y_mps: speed * (heading + wander).sin(),
            roll_rad: 30f64.to_radians() * (0.7 * t).sin(),
            pitch_rad: 30f64.to_radians() * (0.45 * t + 1.0).sin(),
            platform_heading_rad: wrap_pi(heading + wander),
            wander_rad: wander,
            rate_z_radps: speed / rad_m,
            ..SbetRecord::default()
        };
        w.push(&r).unwrap();
    }
    w.finish().unwrap();
    write_smrmsg(&smrmsg, T_START_S, DURATION_S, [0.3, 0.3, 1.0]);
    (sbet, smrmsg)
}

/// Writes an SMRMSG at 1 Hz over `[t0, t0 + span]`: position 0.02/0.02/0.04 m, velocity
/// 0.01 m/s, roll/pitch/heading `att_arcmin`.
pub fn write_smrmsg(path: &Path, t0: f64, span: f64, att_arcmin: [f64; 3]) {
    let mut s = SmrmsgWriter::create(path).unwrap();
    for k in 0..=(span as usize) {
        let r = SmrmsgRecord {
            time_s: t0 + k as f64,
            north_m: 0.02,
            east_m: 0.02,
            down_m: 0.04,
            vel_north_mps: 0.01,
            vel_east_mps: 0.01,
            vel_down_mps: 0.01,
            roll_arcmin: att_arcmin[0],
            pitch_arcmin: att_arcmin[1],
            heading_arcmin: att_arcmin[2],
        };
        s.push(&r).unwrap();
    }
    s.finish().unwrap();
}

/// A 64-bit linear congruential generator: deterministic test randomness without a seed
/// dependency on rand's stream stability.
pub struct Lcg(pub u64);

impl Lcg {
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [a, b).
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }
}

/// ECEF of a geodetic position in degrees.
pub fn ecef_deg(lat_deg: f64, lon_deg: f64, h_m: f64) -> Vector3<f64> {
    geodetic_to_ecef(Geodetic {
        lat_rad: lat_deg.to_radians(),
        lon_rad: lon_deg.to_radians(),
        h_m,
    })
}

/// `R_n^e` at the synthetic origin.
pub fn r_n_to_e_origin() -> nalgebra::Matrix3<f64> {
    r_n_to_e(LAT0_DEG.to_radians(), LON0_DEG.to_radians())
}

/// A full turn.
pub const FULL_TURN: f64 = TAU;

/// The shared real-data folder: `$KINESCAN_REALDATA`, else `../shared/realdata` beside the
/// crate. When absent, `None` after a skip of `test` that `KINESCAN_REQUIRE_REALDATA=1` (CI
/// sets it) makes a failure (`kinescan::testing::skip`).
pub fn realdata(test: &str) -> Option<PathBuf> {
    let candidates = [
        std::env::var_os("KINESCAN_REALDATA").map(PathBuf::from),
        Some(Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/realdata")),
    ];
    let found = candidates
        .into_iter()
        .flatten()
        .find(|p| p.join("PROVENANCE.md").exists());
    if found.is_none() {
        kinescan::testing::skip(
            "KINESCAN_REQUIRE_REALDATA",
            test,
            "../shared/realdata not found (set KINESCAN_REALDATA)",
        );
    }
    found
}

/// NaN-proof maxima (`f64::max` drops a NaN, so an error that came out NaN would pass a bound
/// checked against `fold(0.0, f64::max)`; clippy.toml refuses it in tests).
pub use kinescan::testing::{max_abs, max_of, min_of, raise_max};

/// The OGC WKT CRS record (VLR 2112) of the LAS file `path`.
pub fn las_wkt(path: &Path) -> String {
    las::Reader::from_path(path)
        .unwrap()
        .header()
        .vlrs()
        .iter()
        .find(|v| v.record_id == 2112)
        .map(|v| String::from_utf8_lossy(&v.data).into_owned())
        .unwrap()
}

/// Writes `path`: profiles `profiles` of 36 returns each at 10 m, every 10 deg of mirror angle.
pub fn write_ring_profiles(path: &Path, profiles: std::ops::Range<u32>) {
    use kinescan::io::profiles::{ProfileColumns, ProfileWriter, RawReturn};
    let mut w = ProfileWriter::create(path, ProfileColumns::default()).unwrap();
    for n in profiles {
        for k in 0..36 {
            w.push(&RawReturn {
                profile: n,
                beta_rad: (k as f64 * 10.0 - 180.0).to_radians(),
                range_m: 10.0,
                intensity: 7,
                ..Default::default()
            })
            .unwrap();
        }
    }
    w.finish().unwrap();
}

/// A one-pass survey in `dir` (the synthetic trajectory, `pass.ksprof` with `profiles`
/// profiles from 100) and its `pipeline.toml` writing `out/day.las`.
pub fn one_pass_survey(dir: &Path, profiles: u32) {
    write_trajectory(dir);
    write_ring_profiles(&dir.join("pass.ksprof"), 100..100 + profiles);
    let pipeline = format!(
        "[inputs]\nsbet = \"traj.sbet\"\nprofiles = [\"pass.ksprof\"]\n\n\
         [sensor]\nlever_arm_b_m = [0.5, 0.0, -1.5]\n\n[time]\nt0_s = {}\nperiod_s = 0.01\n\n\
         [output]\nlas = \"out/day.las\"\n",
        T_START_S
    );
    std::fs::write(dir.join("pipeline.toml"), pipeline).unwrap();
}

/// What a written plot shows: its size and how many pixels are in the first palette colour
/// (the first series' data and legend key) and black (text, frame).
pub struct PlotPixels {
    pub width: u32,
    pub height: u32,
    pub first_series: usize,
    pub black: usize,
}

/// Decodes the 8-bit RGB PNG plot at `path` and counts its pixels. Set `KINESCAN_PLOT_OUT=dir`
/// to keep a copy for a visual check.
pub fn plot_pixels(path: &Path) -> PlotPixels {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb, "{}", path.display());
    let count = |c: [u8; 3]| {
        buf[..info.buffer_size()]
            .chunks_exact(3)
            .filter(|px| *px == c)
            .count()
    };
    if let Some(keep) = std::env::var_os("KINESCAN_PLOT_OUT") {
        std::fs::copy(path, Path::new(&keep).join(path.file_name().unwrap())).unwrap();
    }
    PlotPixels {
        width: info.width,
        height: info.height,
        first_series: count(kinescan::plot::PALETTE[0]),
        black: count([0, 0, 0]),
    }
}

/// Unmounts a test's tmpfs when dropped.
#[cfg(target_os = "linux")]
pub struct Tmpfs<'a>(&'a Path);

#[cfg(target_os = "linux")]
impl Drop for Tmpfs<'_> {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount").arg(self.0).status();
    }
}

/// Mounts a tmpfs of `size_kib` KiB on the existing folder `dir`; None where the test cannot
/// mount one (not root, no `mount`): a skip of `test` that `KINESCAN_REQUIRE_TMPFS=1` (CI sets
/// it) makes a failure (`kinescan::testing::skip`).
#[cfg(target_os = "linux")]
pub fn mount_tmpfs<'a>(dir: &'a Path, size_kib: u64, test: &str) -> Option<Tmpfs<'a>> {
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", &format!("size={size_kib}k"), "tmpfs"])
        .arg(dir)
        .output();
    match mounted {
        Ok(o) if o.status.success() => Some(Tmpfs(dir)),
        other => {
            let reason = format!("cannot mount a tmpfs ({other:?})");
            kinescan::testing::skip("KINESCAN_REQUIRE_TMPFS", test, &reason);
            None
        }
    }
}

/// Pages (4 KiB, tmpfs's block) a file of `bytes` occupies.
pub fn pages(bytes: u64) -> u64 {
    bytes.div_ceil(4096)
}

/// SHA-256 of every file under `dir`, by relative path (sorted); the stem's lock file (empty,
/// kept) left out.
pub fn tree(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        let name = e.file_name().to_string_lossy().into_owned();
        if name.ends_with(".kinescan-lock") {
            continue;
        }
        if e.file_type().unwrap().is_dir() {
            for (n, h) in tree(&e.path()) {
                out.push((format!("{name}/{n}"), h));
            }
        } else {
            out.push((
                name,
                <sha2::Sha256 as sha2::Digest>::digest(std::fs::read(e.path()).unwrap()).to_vec(),
            ));
        }
    }
    out.sort();
    out
}

/// Runs the built `kinescan` binary with `args` in folder `dir`.
pub fn kinescan(dir: &Path, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_kinescan"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// Extra dimension names and per-point f32 values of a LAS file (see [`read_extra_f64`]).
pub fn read_extra(path: &Path) -> (Vec<String>, Vec<Vec<f32>>) {
    let (names, values) = read_extra_f64(path);
    let narrow = |row: Vec<f64>| row.into_iter().map(|v| v as f32).collect();
    (names, values.into_iter().map(narrow).collect())
}

/// Extra dimension names and per-point values of a LAS file: float32 (data_type 9) and float64
/// (10) as stored, a scaled fraction byte (1) times its scale.
pub fn read_extra_f64(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let mut reader = las::Reader::from_path(path).unwrap();
    // (name, data_type).
    let dims: Vec<(String, u8)> = reader
        .header()
        .all_vlrs()
        .find(|v| v.user_id == "LASF_Spec" && v.record_id == 4)
        .map(|v| {
            v.data
                .chunks(192)
                .map(|d| {
                    let name = String::from_utf8_lossy(&d[4..36]);
                    (name.trim_end_matches('\0').to_string(), d[2])
                })
                .collect()
        })
        .unwrap();
    let values = reader
        .read_all()
        .unwrap()
        .points()
        .map(|p| {
            let bytes = p.unwrap().extra_bytes;
            let mut at = 0;
            dims.iter()
                .map(|(_, data_type)| {
                    let b = &bytes[at..];
                    let (v, size) = match data_type {
                        1 => (f64::from(b[0]) * kinescan::io::las::FRACTION_SCALE, 1),
                        9 => (f64::from(f32::from_le_bytes(b[..4].try_into().unwrap())), 4),
                        10 => (f64::from_le_bytes(b[..8].try_into().unwrap()), 8),
                        t => panic!("data_type {t}"),
                    };
                    at += size;
                    v
                })
                .collect()
        })
        .collect();
    (dims.into_iter().map(|d| d.0).collect(), values)
}
