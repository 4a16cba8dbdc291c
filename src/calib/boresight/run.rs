//! `kinescan calibrate boresight`: config and files in, `boresight.json` and
//! `boresight_sites.csv` out.

use super::config::BoresightConfig;
use super::estimate::{estimate_boresight, BoresightReport, TripodSite};
use super::inputs::{read_scan_sites, read_sites};
use crate::calib::ellipse::LegScanModel;
use crate::calib::tripod::BoresightSetup;
use crate::io::atomic::{write_atomic, write_json};
use crate::io::config_file;
use crate::io::paths::{check_collisions, in_out_dir};
use crate::io::publish::publish_folder;
use crate::{Error, Result};
use std::path::Path;

/// The files a boresight calibration writes into its output folder: the report
/// (`boresight.json`, published last) and the per-site table.
pub const OUTPUT_FILES: [&str; 2] = ["boresight.json", "boresight_sites.csv"];

/// The sites of a config: from `centres`, or fitted from `scans` (exactly one must be given).
fn config_sites(
    cfg: &BoresightConfig,
    config_path: &Path,
    setup: &BoresightSetup,
) -> Result<Vec<TripodSite>> {
    let src = config_path.display().to_string();
    let attitudes = &cfg.files.sites;
    match (&cfg.files.centres, &cfg.files.scans) {
        (Some(c), None) => read_sites(c, attitudes),
        (None, Some(s)) => {
            let model = LegScanModel {
                leg_radius_m: cfg
                    .tripod
                    .leg_radius_m
                    .filter(|r| crate::calib::positive(*r))
                    .ok_or_else(|| {
                        Error::config(&src, "tripod.leg_radius_m", "needed (> 0) with files.scans")
                    })?,
                sigma_range_m: cfg
                    .scanner
                    .sigma_range_m
                    .filter(|r| crate::calib::positive(*r))
                    .ok_or_else(|| {
                        Error::config(
                            &src,
                            "scanner.sigma_range_m",
                            "needed (> 0) with files.scans",
                        )
                    })?,
                range_zero_error_m: cfg.scanner.range_zero_error_m,
            };
            read_scan_sites(s, attitudes, &model, setup)
        }
        _ => Err(Error::config(
            &src,
            "files",
            "give exactly one of centres and scans",
        )),
    }
}

/// `kinescan calibrate boresight`: reads the TOML config at `config_path` (a
/// [`BoresightConfig`]; unknown keys refused, errors name the key and the file) and the CSV files
/// it names (paths relative to the config: ellipse centres in the scan plane, m; IMU attitudes,
/// convention angles in deg), estimates the boresight ([`estimate_boresight`]) and writes
/// `boresight.json` (the serialisable [`BoresightReport`]: convention boresight angles
/// `R_s^b = Rz(bz) Ry(by) Rx(bx)` in deg, the matrix, the misalignment about body x, y, z on top
/// of the nominal, covariances in deg^2) and `boresight_sites.csv` (per-site apex and leg
/// residuals) atomically into `out_dir`.
pub fn run_boresight_calibration(config_path: &Path, out_dir: &Path) -> Result<BoresightReport> {
    let cfg: BoresightConfig = config_file::load(config_path, &[])?.value;
    let setup = cfg.setup(&config_path.display().to_string())?;
    let mut inputs = vec![
        ("config file".to_string(), config_path.to_path_buf()),
        ("files.sites".into(), cfg.files.sites.to_path_buf()),
    ];
    for (key, f) in [
        ("files.centres", &cfg.files.centres),
        ("files.scans", &cfg.files.scans),
    ] {
        if let Some(f) = f {
            inputs.push((key.into(), f.to_path_buf()));
        }
    }
    check_collisions(&inputs, &in_out_dir(out_dir, &OUTPUT_FILES))?;
    let sites = config_sites(&cfg, config_path, &setup)?;
    let report = estimate_boresight(&sites, &setup)?;
    let mut csv = String::from("site,apex_x_s_m,apex_y_s_m,apex_z_s_m,d1_m,d2_m,d3_m,res_leg1_deg,res_leg2_deg,res_leg3_deg\n");
    for s in &report.sites {
        let [x, y, z] = s.apex_s_m;
        let [d1, d2, d3] = s.apex_distances_m;
        let [r1, r2, r3] = s.leg_residual_deg;
        csv += &format!(
            "{},{x:.6},{y:.6},{z:.6},{d1:.6},{d2:.6},{d3:.6},{r1:.5},{r2:.5},{r3:.5}\n",
            s.site
        );
    }
    publish_folder(
        out_dir,
        "boresight",
        OUTPUT_FILES[0],
        &OUTPUT_FILES,
        |dir| {
            write_atomic(&dir.join(OUTPUT_FILES[1]), csv.as_bytes())?;
            write_json(&dir.join(OUTPUT_FILES[0]), &report)
        },
    )?;
    Ok(report)
}
