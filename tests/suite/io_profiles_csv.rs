//! CSV profiles: round trips CSV -> binary -> CSV, import summaries, and header rules.

use kinescan::io::profiles::{ProfileColumns, ProfileFile, RawReturn};
use kinescan::io::profiles_csv::{
    export_csv, import_csv, CounterJump, ProfileCsvReader, ProfileCsvWriter,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;

/// Seeded returns with awkward values (tiny, huge, negative zero, full-precision mantissas).
fn random_returns(n: usize, columns: ProfileColumns) -> Vec<RawReturn> {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut profile = 0u32;
    (0..n)
        .map(|i| {
            profile += (rng.random::<f64>() < 0.1) as u32 + 3 * (i == n / 2) as u32;
            let range_m = if rng.random::<f64>() < 0.05 {
                0.0
            } else {
                rng.random::<f64>() * 300.0
            };
            RawReturn {
                profile,
                intensity: rng.random(),
                // Every scale of a mirror angle up to 2 pi (the reader refuses beyond: degrees).
                beta_rad: (rng.random::<f64>() - 0.5) * 12.5 * 10f64.powi(rng.random_range(-20..1)),
                range_m,
                alpha_rad: if columns.alpha { -0.0 } else { 0.0 },
                time_s: if columns.time {
                    5e5 + rng.random::<f64>() * 1e4
                } else {
                    0.0
                },
            }
        })
        .collect()
}

fn write_csv(path: &Path, columns: ProfileColumns, returns: &[RawReturn]) {
    let mut w = ProfileCsvWriter::create(path, columns).unwrap();
    for r in returns {
        w.push(r).unwrap();
    }
    assert_eq!(w.finish().unwrap(), returns.len() as u64);
}

fn bits(r: &RawReturn) -> (u32, u16, [u64; 4]) {
    let f = [r.beta_rad, r.range_m, r.alpha_rad, r.time_s].map(f64::to_bits);
    (r.profile, r.intensity, f)
}

#[test]
fn csv_binary_csv_round_trip_is_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    for (alpha, time) in [(false, false), (true, false), (false, true), (true, true)] {
        let columns = ProfileColumns { alpha, time };
        let returns = random_returns(5000, columns);
        let (csv, bin, csv2) = (
            dir.path().join("a.csv"),
            dir.path().join("a.bin"),
            dir.path().join("b.csv"),
        );
        write_csv(&csv, columns, &returns);
        let summary = import_csv(&csv, &bin).unwrap();
        assert_eq!(summary.columns, columns);
        let file = ProfileFile::open(&bin).unwrap();
        assert_eq!(file.len(), returns.len());
        assert_eq!(file.columns(), columns);
        for (i, r) in returns.iter().enumerate() {
            assert_eq!(bits(&file.get(i)), bits(r), "return {i}");
        }
        assert_eq!(export_csv(&bin, &csv2).unwrap(), returns.len() as u64);
        // Same bytes both ways: formatting is a pure function of the f64 bits.
        assert_eq!(std::fs::read(&csv).unwrap(), std::fs::read(&csv2).unwrap());
        let back: Vec<RawReturn> = ProfileCsvReader::open(&csv2)
            .unwrap()
            .map(Result::unwrap)
            .collect();
        assert_eq!(
            back.iter().map(bits).collect::<Vec<_>>(),
            returns.iter().map(bits).collect::<Vec<_>>()
        );
    }
}

#[test]
fn import_summary_counts_missing_returns_and_jumps() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("p.csv");
    let body = "profile,beta_rad,range_m,intensity,time_s\n\
                10,0.1,5.5,100,1.0\n\
                10,0.2,,,1.1\n\
                11,0.1,0,0,2.0\n\
                \n\
                15,-0.3,7.25,65535,3.0\n\
                16,0.4,8,1,4.0\n\
                20,0.5,9,2,5.0\n";
    std::fs::write(&csv, body).unwrap();
    let s = import_csv(&csv, &dir.path().join("p.bin")).unwrap();
    let t = &s.tally;
    assert_eq!(
        (t.returns, t.missing_returns, t.counters.profiles),
        (6, 2, 5)
    );
    let c = &t.counters;
    assert_eq!((c.first_profile, c.last_profile), (Some(10), Some(20)));
    assert_eq!(c.jump_count, 2);
    // Line 6 (the blank line 5 still counts as a line).
    let want = [
        CounterJump {
            at: 6,
            from: 11,
            to: 15,
        },
        CounterJump {
            at: 8,
            from: 16,
            to: 20,
        },
    ];
    assert_eq!(c.jumps, want);
    assert_eq!(t.beta_range_rad, Some((-0.3, 0.5)));
    assert!(s.columns.time && !s.columns.alpha);
    let text = s.to_string();
    assert!(
        text.contains("6 returns (2 missing) in 5 profiles"),
        "{text}"
    );
    assert!(text.contains("line 6: 11 -> 15"), "{text}");
    let f = ProfileFile::open(&dir.path().join("p.bin")).unwrap();
    assert_eq!(f.get(1).range_m, 0.0);
    assert_eq!(f.get(3).intensity, 65535);
}

#[test]
fn header_allows_only_the_spec_columns_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("h.csv");
    let ok = [
        "profile,beta_rad,range_m,intensity",
        "profile,beta_rad,range_m,intensity,alpha_rad",
        "profile,beta_rad,range_m,intensity,time_s",
        "profile,beta_rad,range_m,intensity,alpha_rad,time_s",
    ];
    for h in ok {
        std::fs::write(&csv, format!("{h}\n")).unwrap();
        ProfileCsvReader::open(&csv).unwrap();
    }
    let bad = [
        (
            "profile,beta_rad,range_m,intensity,time_s,alpha_rad",
            "`alpha_rad`",
        ),
        ("profile,beta_rad,range_m,intensity,gps_time", "`gps_time`"),
        ("profile,beta,range_m,intensity", "`beta`"),
        ("profile,beta_rad,range_m", "lacks column `intensity`"),
    ];
    for (h, want) in bad {
        std::fs::write(&csv, format!("{h}\n")).unwrap();
        let e = ProfileCsvReader::open(&csv).err().unwrap().to_string();
        assert!(e.contains(want) && e.contains("h.csv"), "{e}");
    }
}

#[test]
fn writer_refuses_what_the_reader_would_refuse() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("w.csv");
    let mut w = ProfileCsvWriter::create(&path, ProfileColumns::default()).unwrap();
    w.push(&RawReturn {
        profile: 5,
        ..Default::default()
    })
    .unwrap();
    let e = w
        .push(&RawReturn {
            profile: 4,
            ..Default::default()
        })
        .unwrap_err();
    assert!(e.to_string().contains("return 1"), "{e}");
    let nan = RawReturn {
        profile: 6,
        range_m: f64::NAN,
        ..Default::default()
    };
    assert!(w.push(&nan).is_err());
    drop(w);
    assert!(!path.exists(), "an unfinished writer must leave no file");
}

#[test]
fn describe_summarises_csv_and_binary_profiles_alike() {
    use kinescan::io::info::{describe, FileKind};
    let dir = tempfile::tempdir().unwrap();
    let (csv, bin) = (dir.path().join("p.csv"), dir.path().join("p.bin"));
    let body = "profile,beta_rad,range_m,intensity,alpha_rad,time_s\n\
                3,-1.5,10,1,0,100.5\n3,1.5,,,0,100.6\n4,0,12,3,0,101\n9,0.2,5,4,0,102\n";
    std::fs::write(&csv, body).unwrap();
    import_csv(&csv, &bin).unwrap();
    let (c, b) = (describe(&csv).unwrap(), describe(&bin).unwrap());
    assert_eq!(
        (c.kind, b.kind),
        (FileKind::ProfilesCsv, FileKind::ProfilesBinary)
    );
    for info in [&c, &b] {
        let p = info.profiles.as_ref().unwrap();
        assert_eq!(
            (
                p.tally.returns,
                p.tally.missing_returns,
                p.tally.counters.profiles
            ),
            (4, 1, 3)
        );
        assert_eq!(
            (p.tally.profile_range, p.tally.counters.jump_count),
            (Some((3, 9)), 1)
        );
        assert_eq!(p.tally.beta_range_rad, Some((-1.5, 1.5)));
        assert_eq!(p.time_range_s, Some((100.5, 102.0)));
        assert!(p.columns.alpha && p.columns.time);
    }
    // Jump positions: CSV line 5, binary record 3.
    assert_eq!(
        (
            c.profiles.unwrap().tally.counters.jumps[0].at,
            b.profiles.unwrap().tally.counters.jumps[0].at
        ),
        (5, 3)
    );
}

proptest::proptest! {
    // Any finite f64 (subnormals, -0, extremes) survives the CSV text bit-exactly.
    #[test]
    fn any_finite_values_round_trip(
        values in proptest::collection::vec((proptest::num::f64::ANY, 0.0..1e300f64, proptest::num::f64::ANY, proptest::num::f64::ANY), 1..40),
        intensity in proptest::num::u16::ANY,
    ) {
        let columns = ProfileColumns { alpha: true, time: true };
        let returns: Vec<RawReturn> = values
            .iter()
            .enumerate()
            // Mirror angles beyond 2 pi are refused (degrees, issue #23).
            .filter(|(_, (b, _, a, t))| {
                b.is_finite() && b.abs() <= std::f64::consts::TAU && a.is_finite() && t.is_finite()
            })
            .map(|(i, &(beta_rad, range_m, alpha_rad, time_s))| RawReturn {
                profile: i as u32, intensity, beta_rad, range_m, alpha_rad, time_s,
            })
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("p.csv");
        write_csv(&csv, columns, &returns);
        let back: Vec<RawReturn> = ProfileCsvReader::open(&csv).unwrap().map(Result::unwrap).collect();
        proptest::prop_assert_eq!(back.iter().map(bits).collect::<Vec<_>>(), returns.iter().map(bits).collect::<Vec<_>>());
    }
}
