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
