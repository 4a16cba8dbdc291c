//! Every reader refuses bad input with a message naming the file and the record or line.

use kinescan::io::info::describe;
use kinescan::io::profiles::{ProfileColumns, ProfileFile, ProfileWriter, RawReturn};
use kinescan::io::profiles_csv::{import_csv, ProfileCsvReader};
use kinescan::io::sbet::{SbetFile, SBET_RECORD_BYTES};
use kinescan::io::smrmsg::SmrmsgFile;
use std::path::Path;

fn sbet_bytes(recs: &[[f64; 17]]) -> Vec<u8> {
    recs.iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

fn good_sbet(t: f64) -> [f64; 17] {
    let mut a = [0.1; 17];
    a[0] = t;
    a
}

fn assert_err_contains(e: impl std::fmt::Display, wants: &[&str]) {
    let e = e.to_string();
    for w in wants {
        assert!(e.contains(w), "`{e}` lacks `{w}`");
    }
}

#[test]
fn sbet_truncated_and_bad_records() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.sbet");
    let mut bytes = sbet_bytes(&[good_sbet(1.0), good_sbet(2.0)]);
    bytes.truncate(SBET_RECORD_BYTES + 100);
    std::fs::write(&p, &bytes).unwrap();
    let e = SbetFile::open(&p).unwrap_err();
    assert_err_contains(
        e,
        &[
            "t.sbet",
            "not a whole number of 136-byte records",
            "1 whole",
        ],
    );

    std::fs::write(&p, b"").unwrap();
    assert_err_contains(SbetFile::open(&p).unwrap_err(), &["t.sbet", "no records"]);

    let cases: [(usize, usize, f64, &str); 4] = [
        (1, 3, f64::NAN, "altitude is NaN (not finite)"),
        (2, 16, f64::INFINITY, "z angular rate is inf"),
        (1, 0, 0.5, "time 0.5 s does not increase"),
        (2, 0, 2.0, "time going backwards or repeating"),
    ];
    for (rec, field, value, want) in cases {
        let mut recs = [good_sbet(1.0), good_sbet(2.0), good_sbet(3.0)];
        recs[rec][field] = value;
        std::fs::write(&p, sbet_bytes(&recs)).unwrap();
        let at = format!("record {rec}");
        assert_err_contains(SbetFile::open(&p).unwrap_err(), &["t.sbet", &at, want]);
    }
    let mut recs = [good_sbet(1.0)];
    recs[0][1] = 2.0;
    std::fs::write(&p, sbet_bytes(&recs)).unwrap();
    assert_err_contains(
        SbetFile::open(&p).unwrap_err(),
        &["t.sbet", "record 0", "latitude 2 rad"],
    );
}

#[test]
fn smrmsg_truncated_and_bad_records() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("s.smrmsg");
    let rec = |t: f64| {
        let mut a = [0.05; 10];
        a[0] = t;
        a
    };
    let bytes = |recs: &[[f64; 10]]| -> Vec<u8> {
        recs.iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect()
    };
    std::fs::write(&p, &bytes(&[rec(1.0)])[..79]).unwrap();
    let e = SmrmsgFile::open(&p).unwrap_err();
    assert_err_contains(e, &["s.smrmsg", "not a whole number of 80-byte records"]);
    let cases: [(usize, usize, f64, &str); 4] = [
        (1, 9, f64::NAN, "heading RMS is NaN"),
        (0, 2, f64::NEG_INFINITY, "east RMS is -inf"),
        (1, 4, -0.1, "north velocity RMS is negative"),
        (2, 0, 2.0, "time 2 s does not increase"),
    ];
    for (i, field, value, want) in cases {
        let mut recs = [rec(1.0), rec(2.0), rec(3.0)];
        recs[i][field] = value;
        std::fs::write(&p, bytes(&recs)).unwrap();
        let at = format!("record {i}");
        assert_err_contains(SmrmsgFile::open(&p).unwrap_err(), &["s.smrmsg", &at, want]);
    }
}

fn csv_err(path: &Path, body: &str) -> String {
    std::fs::write(path, body).unwrap();
    match ProfileCsvReader::open(path) {
        Err(e) => e.to_string(),
        Ok(mut r) => r
            .find_map(Result::err)
            .map(|e| e.to_string())
            .expect("reader accepted bad input"),
    }
}

#[test]
fn csv_profiles_bad_lines() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("prof.csv");
    let head = "profile,beta_rad,range_m,intensity,time_s\n";
    let cases = [
        ("1,0.1,5,10\n", "line 2: 4 fields where the header has 5"),
        (
            "1,0.1,5,10,1,2\n",
            "line 2: 6 fields where the header has 5",
        ),
        (
            "1,0.1,5,10,1\n1,abc,5,10,1\n",
            "line 3: beta_rad `abc` is not a number",
        ),
        ("1,NaN,5,10,1\n", "line 2: beta_rad is NaN (not finite)"),
        ("1,0.1,inf,10,1\n", "line 2: range_m is inf (not finite)"),
        ("1,0.1,5,10,-inf\n", "line 2: time_s is -inf (not finite)"),
        ("1,0.1,-2,10,1\n", "line 2: range_m -2 is negative"),
        (
            "1,0.1,5,65536,1\n",
            "line 2: intensity `65536` is not an integer in 0..=65535",
        ),
        ("1,0.1,5,-1,1\n", "intensity `-1`"),
        ("1,0.1,5,,1\n", "intensity ``"),
        (
            "-1,0.1,5,10,1\n",
            "line 2: profile counter `-1` is not an unsigned integer",
        ),
        ("1.5,0.1,5,10,1\n", "profile counter `1.5`"),
        ("4294967296,0.1,5,10,1\n", "profile counter `4294967296`"),
        (
            "7,0.1,5,10,1\n7,0.2,5,10,1\n\n6,0.1,5,10,1\n",
            "line 5: profile counter decreases from 7 to 6: wrap or reordered file",
        ),
    ];
    for (body, want) in cases {
        let e = csv_err(&p, &format!("{head}{body}"));
        assert!(
            e.contains("prof.csv") && e.contains(want),
            "`{e}` lacks `{want}`"
        );
    }
    let e = csv_err(&p, "profile,beta_rad,range_m,intensity,quality\n");
    assert_err_contains(e, &["prof.csv", "unknown or misplaced column `quality`"]);
    let e = csv_err(&p, "");
    assert_err_contains(e, &["prof.csv", "empty file"]);
    // A failed import leaves no binary behind.
    std::fs::write(&p, format!("{head}1,0.1,5,10,1\n0,0.1,5,10,1\n")).unwrap();
    let bin = dir.path().join("prof.bin");
    assert_err_contains(import_csv(&p, &bin).unwrap_err(), &["prof.csv", "line 3"]);
    assert!(!bin.exists());
}

#[test]
fn binary_profiles_bad_magic_and_count() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("prof.bin");
    let mut w = ProfileWriter::create(&p, ProfileColumns::default()).unwrap();
    for k in 0..3 {
        w.push(&RawReturn {
            profile: k,
            range_m: 1.0,
            ..Default::default()
        })
        .unwrap();
    }
    w.finish().unwrap();
    let good = std::fs::read(&p).unwrap();

    let mut bad = good.clone();
    bad[0] = b'X';
    std::fs::write(&p, &bad).unwrap();
    assert_err_contains(
        ProfileFile::open(&p).unwrap_err(),
        &["prof.bin", "bad magic"],
    );

    let mut bad = good.clone();
    bad[24] = 5; // header count 5, body holds 3
    std::fs::write(&p, &bad).unwrap();
    let e = ProfileFile::open(&p).unwrap_err();
    assert_err_contains(
        e,
        &["prof.bin", "header says 5 records but the file holds 3"],
    );

    std::fs::write(&p, &good[..good.len() - 1]).unwrap();
    let e = ProfileFile::open(&p).unwrap_err();
    assert_err_contains(e, &["prof.bin", "not a whole number of 40-byte records"]);

    // NaN range in record 2 (bytes 64 + 2 * 40 + 16 ..): refused on checked access.
    let mut bad = good.clone();
    bad[64 + 80 + 16..64 + 80 + 24].copy_from_slice(&f64::NAN.to_le_bytes());
    std::fs::write(&p, &bad).unwrap();
    let f = ProfileFile::open(&p).unwrap();
    assert!(f.get_checked(1).is_ok());
    assert_err_contains(
        f.get_checked(2).unwrap_err(),
        &["prof.bin", "record 2", "range_m is NaN"],
    );
    // `info` counts it as `run` does (rejected, named) instead of refusing the file.
    let info = describe(&p).unwrap();
    let prof = info.profiles.unwrap();
    assert_eq!(prof.invalid_returns, 1);
    assert_err_contains(prof.first_invalid.unwrap(), &["record 2", "range_m is NaN"]);

    std::fs::write(&p, &good[..10]).unwrap();
    let e = ProfileFile::open(&p).unwrap_err();
    assert_err_contains(e, &["prof.bin", "shorter than the 64-byte header"]);
}

#[test]
fn describe_refuses_unknown_and_ambiguous_files() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("mystery.dat");
    std::fs::write(&p, [0u8; 7]).unwrap();
    assert_err_contains(
        describe(&p).unwrap_err(),
        &["mystery.dat", "not recognised"],
    );
    // 680 B = 5 x 136 = 8.5 x 80: only SBET by size, plausible first records.
    let recs: Vec<[f64; 17]> = (0..5).map(|k| good_sbet(1.0 + 0.005 * k as f64)).collect();
    std::fs::write(&p, sbet_bytes(&recs)).unwrap();
    let info = describe(&p).unwrap();
    assert_eq!(info.records, 5);
    // 2720 B = 20 x 136 = 34 x 80, whose bytes read as plausible in both layouts (all
    // fields small and positive, times increasing both ways): refused as ambiguous.
    let amb: Vec<u8> = (0..340)
        .flat_map(|k| (k as f64 * 1e-3).to_le_bytes())
        .collect();
    std::fs::write(&p, amb).unwrap();
    assert_err_contains(describe(&p).unwrap_err(), &["mystery.dat", "ambiguous"]);
}
