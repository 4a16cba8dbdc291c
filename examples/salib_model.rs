//! Export of the uncertainty model for the SALib oracle (tests/salib/check_sobol.py).
//!
//! `salib_model export DIR`: writes `problem.json` (inputs, sigmas, case), our Sobol indices
//! from our own Saltelli design (`ours.json`), and that design in SALib's row order with the
//! model outputs (`design_x.f64`, `design_y.f64`: little-endian f64, row-major).
//! `salib_model eval IN OUT`: reads rows of 18 input errors (little-endian f64) and writes the
//! E, N, U displacement (m) of the exact model for each row.
//!
//! The case: paper 003's "expected" sigmas plus INS sigmas and timing terms, a van turning at
//! 20 deg/s and rolling at 10 deg/s, a return at 30 m.
#![allow(clippy::disallowed_methods)] // clippy.toml's NaN rule is for tests/suite

use kinescan::app::sensitivity::{
    enu_error_model, flat_ground_point, load_sensitivity, study_sigmas,
};
use kinescan::uncertainty::model::{Input, PointGeometry, N_INPUTS};
use kinescan::uncertainty::sobol::{Row, SaltelliDesign};
use std::io::Write;
use std::path::Path;

const CASE: &str = r#"
sigma_set = "expected"
[ins]
sigma_position_ned_m = [0.02, 0.02, 0.025]
sigma_attitude_rph_deg = [0.005, 0.005, 0.015]
[timing]
sigma_clock_time_s = 0.0002
sigma_attitude_latency_s = 0.0005
[platform]
lat_deg = 43.8
lon_deg = -79.5
h_m = 200.0
rph_deg = [1.0, -2.0, 30.0]
speed_mps = 8.0
body_rate_deg_s = [10.0, 0.0, 20.0]
[sensor]
lever_arm_b_m = [-0.6, 0.3, -1.2]
boresight_deg = [0.5, -0.3, 0.8]
[points]
scanner_height_m = 2.5
range_m = [30.0, 30.0]
count = 1
"#;

/// Base rows of our own design (independent of SALib's sample).
const N_OURS: usize = 1 << 15;
/// Base rows of the design exported for the same-sample estimator check.
const N_SHARED: usize = 1 << 12;

fn case() -> (PointGeometry, [f64; N_INPUTS]) {
    let dir = std::env::temp_dir().join(format!("salib_case_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("case.toml");
    std::fs::write(&path, CASE).expect("write case");
    let c = load_sensitivity(&path).expect("valid case");
    std::fs::remove_dir_all(&dir).ok();
    let (platform, sensor, points) = (c.platform.as_ref(), c.sensor.as_ref(), c.points.as_ref());
    let height = points.expect("[points]").scanner_height_m;
    let geom = flat_ground_point(
        platform.expect("[platform]"),
        sensor.expect("[sensor]"),
        height,
        30.0,
    );
    (geom, study_sigmas(&c, None).expect("sigmas"))
}

fn write_f64(path: &Path, values: impl Iterator<Item = f64>) {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path).expect("create"));
    for v in values {
        w.write_all(&v.to_le_bytes()).expect("write");
    }
}

fn export(dir: &Path) {
    std::fs::create_dir_all(dir).expect("out dir");
    let (geom, sigmas) = case();
    let model = enu_error_model(&geom);
    let singles: Vec<Vec<usize>> = (0..N_INPUTS).map(|i| vec![i]).collect();
    let names: Vec<&str> = Input::ALL.iter().map(|i| i.name()).collect();

    let ours = SaltelliDesign::new(&sigmas, singles.clone(), N_OURS, 1)
        .evaluate(&model)
        .analyze(200, 2);
    let problem = serde_json::json!({ "names": names, "sigmas": sigmas });
    std::fs::write(dir.join("problem.json"), problem.to_string()).expect("problem");

    // SALib row order per base row: A, AB_1..AB_D, B.
    let shared = SaltelliDesign::new(&sigmas, singles, N_SHARED, 3);
    let rows: Vec<Vec<f64>> = (0..N_SHARED)
        .flat_map(|j| {
            let mut r = vec![shared.row(j, Row::A)];
            r.extend((0..N_INPUTS).map(|f| shared.row(j, Row::Ab(f))));
            r.push(shared.row(j, Row::B));
            r
        })
        .collect();
    write_f64(&dir.join("design_x.f64"), rows.iter().flatten().copied());
    write_f64(
        &dir.join("design_y.f64"),
        rows.iter().flat_map(|x| model(x)),
    );
    let same = shared.evaluate(&model).analyze(0, 0);
    let out = serde_json::json!({ "independent": ours.per_output, "same_sample": same.per_output });
    std::fs::write(dir.join("ours.json"), out.to_string()).expect("ours");
}

fn eval(input: &Path, output: &Path) {
    let bytes = std::fs::read(input).expect("read inputs");
    let x: Vec<f64> = bytes
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
        .collect();
    let (geom, _) = case();
    let model = enu_error_model(&geom);
    write_f64(output, x.chunks_exact(N_INPUTS).flat_map(&model));
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    match args.get(1).map(String::as_str) {
        Some("export") if args.len() == 3 => export(Path::new(&args[2])),
        Some("eval") if args.len() == 4 => eval(Path::new(&args[2]), Path::new(&args[3])),
        _ => {
            eprintln!("usage: salib_model export DIR | salib_model eval IN.f64 OUT.f64");
            std::process::exit(2);
        }
    }
}
