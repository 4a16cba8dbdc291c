//! `describe` on synthetic trajectories with known rate and gaps.

use kinescan::io::info::{describe, FileKind};
use kinescan::io::sbet::{SbetRecord, SbetWriter};

#[test]
fn sbet_rate_and_gaps_are_found() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("traj.sbet");
    let mut w = SbetWriter::create(&path).unwrap();
    // 100 Hz from t = 1000 s, 1001 records, with two holes: 0.5 s after record 300 and
    // 0.02 s (2 intervals, just over 1.5 x median) after record 700.
    let mut t = 1000.0;
    for i in 0..1001 {
        let mut a = [0.0; 17];
        a[0] = t;
        a[1] = 0.8;
        a[4] = 3.0;
        a[5] = 4.0; // |v| = 5 m/s
        w.push(&SbetRecord::from_array(a)).unwrap();
        t += match i {
            300 => 0.5,
            700 => 0.02,
            _ => 0.01,
        };
    }
    w.finish().unwrap();
    // Times accumulate 0.01 s steps: ~1e-13 s rounding per step, < 1e-10 s after 1000 steps.
    let info = describe(&path).unwrap();
    assert_eq!((info.kind, info.records), (FileKind::Sbet, 1001));
    let tm = info.time.unwrap();
    assert!(
        (tm.median_rate_hz - 100.0).abs() < 1e-6,
        "{}",
        tm.median_rate_hz
    );
    assert_eq!(tm.gap_count, 2);
    let g = &tm.largest_gaps;
    assert!((g[0].interval_s - 0.5).abs() < 1e-9 && (g[0].after_s - 1003.0).abs() < 1e-8);
    assert!((g[1].interval_s - 0.02).abs() < 1e-9);
    assert!((tm.span_s - (998.0 * 0.01 + 0.5 + 0.02)).abs() < 1e-8);
    let s = info.sbet.unwrap();
    assert_eq!(s.speed_mps, (5.0, 5.0));
    assert_eq!(s.lat_deg.0, 0.8f64.to_degrees());
}

/// Raw IMU and GNSS records (recognised by name): counts, rates, the outage as the GNSS gap,
/// ranges (gravity on the IMU's z axis, the fixes' sigmas as simulated), and the text.
#[test]
fn raw_imu_and_gnss_records_are_summarised() {
    let dir = tempfile::tempdir().unwrap();
    let base = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("pipelines/scenario_raw_city_block.toml"),
    )
    .unwrap()
    .replace("duration_s = 120.0", "duration_s = 20.0")
    .replace("outages_s = [[60.0, 90.0]]", "outages_s = [[5.0, 8.0]]")
    .replace("outlier_probability = 0.005", "outlier_probability = 0.0");
    assert!(base.contains("[[5.0, 8.0]]") && base.contains("duration_s = 20.0"));
    let sc = kinescan::sim::Scenario::parse(&base, "raw").unwrap();
    let counts = kinescan::sim::raw::write_raw(&sc, dir.path()).unwrap();
    let imu = describe(&dir.path().join("imu.bin")).unwrap();
    assert_eq!((imu.kind, imu.records), (FileKind::Imu, counts.imu_records));
    let t = imu.time.as_ref().unwrap();
    // 200 Hz from the simulator's sample times (rounding of 5 ms steps: < 1e-6 Hz).
    assert!(
        (t.median_rate_hz - 200.0).abs() < 1e-6,
        "{}",
        t.median_rate_hz
    );
    assert_eq!(t.gap_count, 0);
    let r = imu.imu.as_ref().unwrap();
    // Gravity on z (down): about -9.81 m/s^2 at rest, within the drive's +-3 m/s^2.
    let (lo, hi) = r.specific_force_mps2[2];
    assert!(lo > -13.0 && hi < -6.5 && lo < -9.7 && hi > -9.9, "{r:?}");
    let gnss = describe(&dir.path().join("gnss.bin")).unwrap();
    assert_eq!(gnss.kind, FileKind::Gnss);
    let t = gnss.time.as_ref().unwrap();
    assert!(
        (t.median_rate_hz - 10.0).abs() < 1e-6,
        "{}",
        t.median_rate_hz
    );
    // The 3 s outage is the one gap: 3.1 s between the fixes either side.
    assert_eq!(t.gap_count, 1, "{t:?}");
    assert!((t.largest_gaps[0].interval_s - 3.1).abs() < 1e-6, "{t:?}");
    let g = gnss.gnss.as_ref().unwrap();
    assert_eq!(g.sigma_m, [(0.02, 0.02); 3]);
    assert!(g.lat_deg.0 > 48.13 && g.lat_deg.1 < 48.15, "{g:?}");
    let text = format!("{imu}\n{gnss}");
    for want in [
        "raw IMU records",
        "raw GNSS positions",
        "specific force",
        "sigma north 20.0 .. 20.0 mm",
    ] {
        assert!(text.contains(want), "{want}: {text}");
    }
}
