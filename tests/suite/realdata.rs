//! Readers against real third-party files (see the realdata PROVENANCE.md). The expected values
//! are external truth: PDAL's `test/unit/io/SbetReaderTest.cpp` (testReadAsRadians) for the
//! SBET, the CSV published beside the SMRMSG for the SMRMSG.

use crate::common::realdata;
use kinescan::io::info::{describe, FileKind};
use kinescan::io::sbet::SbetFile;
use kinescan::io::smrmsg::SmrmsgFile;

/// PDAL's printed values (radians), 16 significant digits, both records, file field order.
/// Kept exactly as printed (hence more digits than an f64 always distinguishes).
#[allow(clippy::excessive_precision)]
const PDAL_2_POINTS: [[f64; 17]; 2] = [
    [
        1.516310028360710e+05,
        5.680211852972264e-01,
        -2.041654392303940e+00,
        1.077152953296560e+02,
        -2.332420866600025e+00,
        -3.335067504871401e-01,
        -3.093961631767838e-02,
        -2.813407149321339e-02,
        -2.429905393889139e-02,
        3.046773230278662e+00,
        -2.198414736922658e-02,
        7.859639737752390e-01,
        7.849084719295495e-01,
        -2.978807916450262e-01,
        6.226807982589819e-05,
        9.312162756440178e-03,
        7.217812320996525e-02,
    ],
    [
        1.516310078318641e+05,
        5.680211834722869e-01,
        -2.041654392034053e+00,
        1.077151424357507e+02,
        -2.336228229691271e+00,
        -3.324663118952635e-01,
        -3.022948961008987e-02,
        -2.813856631423094e-02,
        -2.425215669392169e-02,
        3.047131105236811e+00,
        -2.198416007932108e-02,
        8.397590491636475e-01,
        3.252165276637165e-01,
        -1.558883225990844e-01,
        8.379685112283802e-04,
        7.372886784718076e-03,
        7.179027672314571e-02,
    ],
];

#[test]
fn pdal_two_point_sbet_matches_pdal_to_printed_precision() {
    let Some(dir) = realdata("pdal_two_point_sbet") else {
        return;
    };
    let f = SbetFile::open(&dir.join("pdal/2-points.sbet")).unwrap();
    assert_eq!(f.len(), 2);
    for (i, want) in PDAL_2_POINTS.iter().enumerate() {
        let got = f.record(i).to_array();
        for k in 0..17 {
            // PDAL prints 16 significant digits, so the printed value is within 5e-16 relative
            // of the stored f64; 1e-12 relative leaves margin and still catches any decoding
            // slip (wrong field, byte order, f32).
            let rel = (got[k] - want[k]).abs() / want[k].abs();
            assert!(
                rel <= 1e-12,
                "record {i} field {k}: {} vs {}",
                got[k],
                want[k]
            );
        }
    }
    let r0 = f.record(0);
    // True heading = platform heading - wander (conventions §3): 3.0687574 rad = 175.8236 deg.
    assert!((r0.true_heading_rad() - (3.046773230278662 + 0.02198414736922658)).abs() < 1e-12);
}

#[test]
fn pdal_badfile_sbet_is_refused_as_not_whole_records() {
    let Some(dir) = realdata("pdal_badfile_sbet") else {
        return;
    };
    let e = SbetFile::open(&dir.join("pdal/badfile.sbet"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("badfile.sbet"), "{e}");
    assert!(e.contains("not a whole number of 136-byte records"), "{e}");
    let e = describe(&dir.join("pdal/badfile.sbet"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("badfile.sbet") && e.contains("not a whole number"),
        "{e}"
    );
}

#[test]
fn pdal_smrmsg_equals_its_csv_on_every_row() {
    let Some(dir) = realdata("pdal_smrmsg") else {
        return;
    };
    let f = SmrmsgFile::open(&dir.join("pdal/smrmsg.smrmsg")).unwrap();
    assert_eq!(f.len(), 21_902);
    let text = std::fs::read_to_string(dir.join("pdal/smrmsg.txt")).unwrap();
    let mut rows = 0;
    for (i, line) in text.lines().skip(1).enumerate() {
        let want: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        let got = f.record(i).to_array();
        assert_eq!(want.len(), 10);
        for k in 0..10 {
            // The CSV prints 6 decimals: |error| <= 5e-7 plus float noise, under 1e-6.
            assert!((got[k] - want[k]).abs() <= 1e-6, "row {i} field {k}");
        }
        rows += 1;
    }
    assert_eq!(rows, f.len());
    assert_eq!((f.time_s(0), f.time_s(f.len() - 1)), (536_258.0, 558_159.0));
}

#[test]
fn describe_reports_the_provenance_facts() {
    let Some(dir) = realdata("describe_realdata") else {
        return;
    };
    let sbet = describe(&dir.join("pdal/2-points.sbet")).unwrap();
    assert_eq!((sbet.kind, sbet.records), (FileKind::Sbet, 2));
    let t = sbet.time.as_ref().unwrap();
    // Two records 4.996 ms apart: 200 Hz nominal (PROVENANCE), 200.16 Hz measured.
    assert!(
        (t.median_rate_hz - 200.0).abs() < 0.5,
        "{}",
        t.median_rate_hz
    );
    let s = sbet.sbet.as_ref().unwrap();
    // Ranges over both records (record 1 is the southern one), from PDAL's radian values.
    let (lat0, lat1) = (
        PDAL_2_POINTS[0][1].to_degrees(),
        PDAL_2_POINTS[1][1].to_degrees(),
    );
    assert!((s.lat_deg.0 - lat1).abs() < 1e-9 && (s.lat_deg.1 - lat0).abs() < 1e-9);
    assert!((s.lon_deg.0 - PDAL_2_POINTS[0][2].to_degrees()).abs() < 1e-9);

    let sm = describe(&dir.join("pdal/smrmsg.smrmsg")).unwrap();
    assert_eq!((sm.kind, sm.records), (FileKind::Smrmsg, 21_902));
    let t = sm.time.as_ref().unwrap();
    assert_eq!(
        (t.start_s, t.end_s, t.span_s),
        (536_258.0, 558_159.0, 21_901.0)
    );
    // 21,902 records over 21,901 s at exactly 1 s: 1 Hz and no gaps.
    assert_eq!((t.median_rate_hz, t.gap_count), (1.0, 0));

    // leeward's sbet.out is 27,200 B: a multiple of both 136 and 80, recognised by name.
    let lw = describe(&dir.join("leeward/sbet.out")).unwrap();
    assert_eq!((lw.kind, lw.records), (FileKind::Sbet, 200));
    let t = lw.time.as_ref().unwrap();
    assert!((t.start_s - 400825.0013).abs() < 1e-3 && (t.end_s - 400825.9965).abs() < 1e-3);
    assert!(
        (t.median_rate_hz - 200.0).abs() < 1.0,
        "{}",
        t.median_rate_hz
    );
    let s = lw.sbet.as_ref().unwrap();
    // First record about 37.76475 N, -119.02382 E, 6991.6 m, about 110 m/s (PROVENANCE).
    assert!(
        s.lat_deg.0 <= 37.7648 && s.lat_deg.1 >= 37.7647,
        "{:?}",
        s.lat_deg
    );
    assert!(s.h_m.0 <= 6991.7 && s.h_m.1 >= 6991.5, "{:?}", s.h_m);
    assert!(
        s.speed_mps.0 > 100.0 && s.speed_mps.1 < 120.0,
        "{:?}",
        s.speed_mps
    );
    let text = lw.to_string();
    assert!(
        text.contains("Applanix SBET") && text.contains("records: 200"),
        "{text}"
    );
    let json = serde_json::to_string(&lw).unwrap();
    assert!(json.contains("\"kind\":\"sbet\""), "{json}");
}
