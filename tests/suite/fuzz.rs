//! Fuzzing on the stable toolchain: property tests feed mutated bytes (bit flips, truncations,
//! insertions, deletions, splices between samples, CSV/TOML tokens, special f64 values) of valid
//! files (simulator output, test fixtures, the repository's pipeline and scenario files) and of
//! real files (`../shared/realdata`) to every parser. Each case must end, within a time bound,
//! in a value or in an error naming the file; a panic or a hang fails.
//!
//! The normal suite runs [`QUICK_CASES`] cases per parser; the long run (docs/robustness.md,
//! its own `.ci/run` step) runs `PROPTEST_CASES` (default 100,000) per parser:
//! `PROPTEST_CASES=100000 cargo test --release --test suite -- --ignored fuzz --nocapture`.

use crate::common;

use kinescan::io::csd::{CsdFile, CSD_HEADER_BYTES, CSD_PULSE_BYTES};
use kinescan::io::gnss::{GnssFile, GNSS_RECORD_BYTES};
use kinescan::io::imu::{ImuFile, IMU_RECORD_BYTES};
use kinescan::io::info::describe;
use kinescan::io::patches::read_patches;
use kinescan::io::points::read_control_points;
use kinescan::io::profiles::ProfileFile;
use kinescan::io::profiles_csv::ProfileCsvReader;
use kinescan::io::sbet::{SbetFile, SBET_RECORD_BYTES};
use kinescan::io::smrmsg::{SmrmsgFile, SMRMSG_RECORD_BYTES};
use kinescan::sim::scenario::Scenario;
use kinescan::sim::{self, SimOptions};
use proptest::prelude::*;
use proptest::test_runner::{Config, FileFailurePersistence, TestCaseError, TestRunner};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// Cases per parser in the normal suite.
const QUICK_CASES: u32 = 2000;
/// Cases per parser in the long run when `PROPTEST_CASES` is not set.
const LONG_CASES: u32 = 100_000;
/// A parse taking longer than this is a hang (the largest sample parses in well under 1 ms).
const HANG_LIMIT: Duration = Duration::from_secs(10);

/// Every parser under test.
#[derive(Debug, Clone, Copy)]
enum Parser {
    Sbet,
    Smrmsg,
    ProfilesBinary,
    ProfilesCsv,
    ControlPoints,
    Patches,
    PipelineToml,
    ScenarioToml,
    DayToml,
    Csd,
    Imu,
    Gnss,
}

impl Parser {
    const ALL: [Parser; 12] = [
        Parser::Sbet,
        Parser::Smrmsg,
        Parser::ProfilesBinary,
        Parser::ProfilesCsv,
        Parser::ControlPoints,
        Parser::Patches,
        Parser::PipelineToml,
        Parser::ScenarioToml,
        Parser::DayToml,
        Parser::Csd,
        Parser::Imu,
        Parser::Gnss,
    ];

    fn file_name(self) -> &'static str {
        match self {
            Parser::Sbet => "fuzz.sbet",
            Parser::Smrmsg => "fuzz.smrmsg",
            Parser::ProfilesBinary => "fuzz.ksprof",
            Parser::ProfilesCsv => "fuzz_profiles.csv",
            Parser::ControlPoints => "fuzz_points.csv",
            Parser::Patches => "fuzz_patches.csv",
            Parser::PipelineToml => "fuzz_pipeline.toml",
            Parser::ScenarioToml => "fuzz_scenario.toml",
            Parser::DayToml => "fuzz_day.toml",
            Parser::Csd => "fuzz.csd",
            // `info` recognises raw records by name (imu*, gnss*).
            Parser::Imu => "imu_fuzz.bin",
            Parser::Gnss => "gnss_fuzz.bin",
        }
    }

    /// Parses `path` completely: `Ok` for a value, `Err(message)` for a refusal.
    fn parse(self, path: &Path) -> Result<(), String> {
        let e = |e: kinescan::Error| e.to_string();
        match self {
            Parser::Sbet => SbetFile::open(path).map(|_| ()).map_err(e)?,
            Parser::Smrmsg => SmrmsgFile::open(path).map(|_| ()).map_err(e)?,
            Parser::ProfilesBinary => {
                let f = ProfileFile::open(path).map_err(e)?;
                // Per-record problems are counted by run; each must still name the file.
                for i in 0..f.len() {
                    if let Err(err) = f.get_checked(i) {
                        names_file(&err.to_string(), path).map_err(|m| m.to_string())?;
                    }
                }
            }
            Parser::ProfilesCsv => {
                for item in ProfileCsvReader::open(path).map_err(e)? {
                    item.map_err(e)?;
                }
            }
            Parser::ControlPoints => read_control_points(path).map(|_| ()).map_err(e)?,
            Parser::Patches => read_patches(path).map(|_| ()).map_err(e)?,
            Parser::PipelineToml => kinescan::pipeline::config::load(path, &[])
                .map(|_| ())
                .map_err(e)?,
            Parser::ScenarioToml => Scenario::load(path).map(|_| ()).map_err(e)?,
            // The day file with its template and profile files beside it (`day_folder`).
            Parser::DayToml => kinescan::app::day::config::load(path)
                .map(|_| ())
                .map_err(e)?,
            Parser::Csd => {
                let f = CsdFile::open(path).map_err(e)?;
                for pulse in f.pulses() {
                    pulse.map_err(e)?;
                }
            }
            Parser::Imu => ImuFile::open(path).map(|_| ()).map_err(e)?,
            Parser::Gnss => GnssFile::open(path).map(|_| ()).map_err(e)?,
        }
        Ok(())
    }

    /// `info` reads the data files too (kind detection, then the kind's reader).
    fn has_info(self) -> bool {
        !matches!(
            self,
            Parser::PipelineToml | Parser::ScenarioToml | Parser::DayToml
        )
    }
}

fn names_file(message: &str, path: &Path) -> Result<(), TestCaseError> {
    let name = path.file_name().unwrap().to_string_lossy();
    if message.contains(&*name) {
        Ok(())
    } else {
        Err(TestCaseError::fail(format!(
            "error without the file name: {message}"
        )))
    }
}

/// Valid samples of every format, made once: a short simulation of the city-block scenario
/// (SBET, SMRMSG, binary and CSV profiles, control points, patches), the test trajectory
/// fixture, the repository's pipeline and scenario files, and the real files.
struct Samples {
    dir: PathBuf,
    by_parser: Vec<Vec<Vec<u8>>>,
}

fn samples() -> &'static Samples {
    static SAMPLES: OnceLock<Samples> = OnceLock::new();
    SAMPLES.get_or_init(make_samples)
}

fn head_records(bytes: &[u8], record: usize, n: usize) -> Vec<u8> {
    bytes[..bytes.len().min(record * n)].to_vec()
}

fn head_lines(bytes: &[u8], n: usize) -> Vec<u8> {
    let mut end = 0;
    for _ in 0..n {
        match bytes[end..].iter().position(|&b| b == b'\n') {
            Some(p) => end += p + 1,
            None => return bytes.to_vec(),
        }
    }
    bytes[..end].to_vec()
}

fn make_samples() -> Samples {
    let dir = tempfile::tempdir().unwrap().keep();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let sim_dir = dir.join("sim");
    let opts = SimOptions {
        profiles_csv: true,
        duration_s: Some(3.0),
        ..SimOptions::default()
    };
    let scenario = root.join("pipelines/scenario_city_block.toml");
    sim::simulate(&scenario, &sim_dir, &opts).unwrap();
    let read = |p: PathBuf| std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let sim_file = |name: &str| read(sim_dir.join(name));
    let fixture_dir = dir.join("fixture");
    std::fs::create_dir(&fixture_dir).unwrap();
    let (traj_sbet, traj_smrmsg) = common::write_trajectory(&fixture_dir);

    let mut sbet = vec![
        head_records(&sim_file(sim::files::SBET), SBET_RECORD_BYTES, 12),
        head_records(&read(traj_sbet), SBET_RECORD_BYTES, 12),
    ];
    let mut smrmsg = vec![
        head_records(&sim_file(sim::files::SMRMSG), SMRMSG_RECORD_BYTES, 12),
        read(traj_smrmsg),
    ];
    if let Some(real) = common::realdata("fuzz samples") {
        sbet.push(read(real.join("pdal/2-points.sbet")));
        sbet.push(read(real.join("pdal/badfile.sbet")));
        sbet.push(head_records(
            &read(real.join("leeward/sbet.out")),
            SBET_RECORD_BYTES,
            12,
        ));
        smrmsg.push(head_records(
            &read(real.join("pdal/smrmsg.smrmsg")),
            SMRMSG_RECORD_BYTES,
            12,
        ));
    }
    let profiles_bin = sim_file(sim::files::PROFILES);
    let profiles = vec![
        fixed_count_profiles(&profiles_bin, 30),
        fixed_count_profiles(&profiles_bin, 3),
    ];
    let csv = vec![head_lines(&sim_file(sim::files::PROFILES_CSV), 40)];
    let points = vec![head_lines(&sim_file(sim::files::CONTROL_POINTS), 12)];
    let patches = vec![head_lines(&sim_file(sim::files::PATCHES), 12)];
    let pipelines = vec![
        read(root.join("pipelines/demo_city_block.toml")),
        sync_pipeline().into_bytes(),
    ];
    let scenarios = ["city_block", "parking_lot", "survey_day", "sync_paper"]
        .iter()
        .map(|s| read(root.join(format!("pipelines/scenario_{s}.toml"))))
        .collect();
    let days = day_folder(&dir.join(format!("{:?}", Parser::DayToml)));
    let mut csd = vec![synthetic_csd(8)];
    if let Some(real) = common::realdata("fuzz samples") {
        csd.push(csd_head(&read(real.join("pdal/sample.csd")), 12));
    }
    // Raw IMU and GNSS records: 3 s of the raw city block (600 IMU records, 30 fixes).
    let raw_dir = dir.join("raw");
    std::fs::create_dir(&raw_dir).unwrap();
    let raw_sc = std::fs::read_to_string(root.join("pipelines/scenario_raw_city_block.toml"))
        .unwrap()
        .replace("duration_s = 120.0", "duration_s = 3.0");
    let raw_sc = Scenario::parse(&raw_sc, "raw fuzz samples").unwrap();
    assert_eq!(raw_sc.duration_s, 3.0);
    sim::raw::write_raw(&raw_sc, &raw_dir).unwrap();
    let raw_file = |name: &str| read(raw_dir.join(name));
    let imu = vec![head_records(
        &raw_file(sim::raw::files::IMU),
        IMU_RECORD_BYTES,
        12,
    )];
    let gnss = vec![head_records(
        &raw_file(sim::raw::files::GNSS),
        GNSS_RECORD_BYTES,
        12,
    )];
    let by_parser = vec![
        sbet, smrmsg, profiles, csv, points, patches, pipelines, scenarios, days, csd, imu, gnss,
    ];
    Samples { dir, by_parser }
}

/// The header and first `n` pulses of a CSD file, the header's count set to `n`.
fn csd_head(bytes: &[u8], n: usize) -> Vec<u8> {
    let mut out = bytes[..CSD_HEADER_BYTES + n * CSD_PULSE_BYTES].to_vec();
    out[124..128].copy_from_slice(&(n as u32).to_le_bytes());
    out
}

/// A valid CSD file of `n` pulses (header fields at their offsets, docs/formats.md).
fn synthetic_csd(n: usize) -> Vec<u8> {
    let mut b = vec![0u8; CSD_HEADER_BYTES];
    b[..4].copy_from_slice(b"CSD\0");
    b[4..23].copy_from_slice(b"Optech Incorporated");
    b[104..106].copy_from_slice(&(CSD_HEADER_BYTES as u16).to_le_bytes());
    b[106..108].copy_from_slice(&1660u16.to_le_bytes());
    b[124..128].copy_from_slice(&(n as u32).to_le_bytes());
    b[1154..1162].copy_from_slice(&0.028f64.to_le_bytes());
    for i in 0..n {
        let mut p = vec![0u8; CSD_PULSE_BYTES];
        p[0..8].copy_from_slice(&(575644.7 + i as f64 * 1e-5).to_le_bytes());
        p[8] = 2;
        p[9..13].copy_from_slice(&(820.0f32 + i as f32).to_le_bytes());
        p[13..17].copy_from_slice(&(821.5f32 + i as f32).to_le_bytes());
        p[33..37].copy_from_slice(&(-0.2f32 + 0.05 * i as f32).to_le_bytes());
        p[49..57].copy_from_slice(&0.6376f64.to_le_bytes());
        p[57..65].copy_from_slice(&(-1.44 - std::f64::consts::TAU).to_le_bytes());
        p[65..69].copy_from_slice(&1140.0f32.to_le_bytes());
        b.extend(p);
    }
    b
}

/// The first `n` records of a binary profile file with the header's record count set to `n`
/// (a valid file, unlike a plain cut).
fn fixed_count_profiles(bytes: &[u8], n: usize) -> Vec<u8> {
    let mut out = bytes[..64 + 40 * n].to_vec();
    out[24..32].copy_from_slice(&(n as u64).to_le_bytes());
    out
}

/// The day files' folder (`dir`): a template (the sync pipeline) and three profile files; the
/// samples are day files over them, per pass and in tiles, with a night's options.
fn day_folder(dir: &Path) -> Vec<Vec<u8>> {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("template.toml"), sync_pipeline()).unwrap();
    for name in ["p01.ksprof", "p02.ksprof", "p03.csv"] {
        std::fs::write(dir.join(name), b"only its existence is checked").unwrap();
    }
    let per_pass = "[day]\ntemplate = \"template.toml\"\nout = \"night\"\nunit_s = 30.0\n\n\
                    [[passes]]\nname = \"p01\"\nprofiles = [\"p01.ksprof\"]\n\n\
                    [[passes]]\nname = \"p-02_b\"\nprofiles = [\"p02.ksprof\", \"p03.csv\"]\n";
    let tiles = "[day]\ntemplate = \"template.toml\"\nout = \"night\"\n\
                 layout = { kind = \"tiles\", size_m = 50.0 }\n\n\
                 [day.night]\nsync = false\ndiagnose = true\nauto_correct = true\n\n\
                 [[passes]]\nname = \"a\"\nprofiles = [\"p01.ksprof\"]\n";
    vec![per_pass.into(), tiles.into()]
}

fn sync_pipeline() -> String {
    "[inputs]\nsbet = \"t.sbet\"\nsmrmsg = \"t.smrmsg\"\nprofiles = [\"a.ksprof\", \"b.csv\"]\n\
     gps_week = 2394\n\n[trajectory]\nmax_gap_s = 0.1\n\n\
     [sensor]\nlever_arm_b_m = [0.5, 0.0, -1.5]\nboresight_deg = [0.1, 0, 0]\n\n\
     [time]\nmodel = \"software\"\nt0_s = 300000.0\nperiod_s = 0.01\n\n\
     [latency]\nattitude_s = 0.002\n\n[sync]\npoints = \"p.csv\"\ntargets = \"q.csv\"\n\
     method = \"refined\"\nestimate_latency = true\n\n\
     [output]\nlas = \"out/day.las\"\nsplit = \"max_points\"\nmax_points_per_file = 1000\n\
     frame = { kind = \"enu\", lat_deg = 48.1, lon_deg = 11.5, h_m = 500 }\n"
        .into()
}

/// One change to a file's bytes; positions are taken modulo the current length.
#[derive(Debug, Clone)]
enum Mutation {
    Flip {
        at: usize,
        bit: u8,
    },
    Truncate {
        at: usize,
    },
    Insert {
        at: usize,
        bytes: Vec<u8>,
    },
    Delete {
        at: usize,
        len: usize,
    },
    Splice {
        at: usize,
        sample: usize,
        from: usize,
        len: usize,
    },
    Token {
        at: usize,
        token: usize,
    },
    Float {
        at: usize,
        value: usize,
    },
}

const TOKENS: [&[u8]; 24] = [
    b"nan",
    b"inf",
    b"-1",
    b"1e400",
    b"1e-300",
    b"0",
    b",",
    b"\n",
    b"\r\n",
    b"\"",
    b"=",
    b"[",
    b"]",
    b"{",
    b"}",
    b"\xef\xbb\xbf",
    b"-",
    b".",
    b"4294967296",
    b"\0",
    b"#",
    b"[output]",
    b"kind",
    b"\xff",
];

const FLOATS: [f64; 10] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    -0.0,
    1e308,
    -1.0,
    0.0,
    f64::MIN_POSITIVE,
    604_800.5,
    4.0e9,
];

fn mutation() -> impl Strategy<Value = Mutation> {
    let at = any::<usize>();
    prop_oneof![
        (at, 0u8..8).prop_map(|(at, bit)| Mutation::Flip { at, bit }),
        at.prop_map(|at| Mutation::Truncate { at }),
        (at, proptest::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(at, bytes)| Mutation::Insert { at, bytes }),
        (at, 1usize..64).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (at, any::<usize>(), any::<usize>(), 1usize..256).prop_map(|(at, sample, from, len)| {
            Mutation::Splice {
                at,
                sample,
                from,
                len,
            }
        }),
        (at, 0..TOKENS.len()).prop_map(|(at, token)| Mutation::Token { at, token }),
        (at, 0..FLOATS.len()).prop_map(|(at, value)| Mutation::Float { at, value }),
    ]
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation, others: &[Vec<u8>]) {
    let pos = |at: usize, len: usize| at % (len + 1);
    match m {
        Mutation::Flip { at, bit } => {
            if !bytes.is_empty() {
                let i = at % bytes.len();
                bytes[i] ^= 1 << bit;
            }
        }
        Mutation::Truncate { at } => bytes.truncate(pos(*at, bytes.len())),
        Mutation::Insert { at, bytes: new } => {
            let i = pos(*at, bytes.len());
            bytes.splice(i..i, new.iter().copied());
        }
        Mutation::Delete { at, len } => {
            let i = pos(*at, bytes.len());
            let end = (i + len).min(bytes.len());
            bytes.drain(i..end);
        }
        Mutation::Splice {
            at,
            sample,
            from,
            len,
        } => {
            let src = &others[sample % others.len()];
            let s = pos(*from, src.len());
            let piece = &src[s..(s + len).min(src.len())];
            let i = pos(*at, bytes.len());
            let end = (i + piece.len()).min(bytes.len());
            bytes.splice(i..end, piece.iter().copied());
        }
        Mutation::Token { at, token } => {
            let i = pos(*at, bytes.len());
            bytes.splice(i..i, TOKENS[*token].iter().copied());
        }
        Mutation::Float { at, value } => {
            let i = pos(*at, bytes.len().saturating_sub(8));
            let end = (i + 8).min(bytes.len());
            bytes.splice(i..end, FLOATS[*value].to_le_bytes());
        }
    }
}

/// Runs `parser` (and `info`) on the mutated bytes under the [`Watchdog`]; returns whether the
/// parser gave a value. A panic fails the case (proptest catches it).
fn check_case(
    parser: Parser,
    path: &Path,
    bytes: &[u8],
    watchdog: &Watchdog,
) -> Result<bool, TestCaseError> {
    // A new file each case: truncating a file in place makes ext4 flush it (auto_da_alloc),
    // which costs milliseconds a case.
    let _ = std::fs::remove_file(path);
    std::fs::write(path, bytes).unwrap();
    watchdog.start(bytes);
    let parsed = parser.parse(path);
    let info = parser
        .has_info()
        .then(|| describe(path).map(|_| ()).map_err(|e| e.to_string()));
    watchdog.stop();
    let accepted = parsed.is_ok();
    for r in [Some(parsed), info].into_iter().flatten() {
        if let Err(message) = r {
            names_file(&message, path)?;
        }
    }
    Ok(accepted)
}

/// Fails the whole test process when one case runs longer than [`HANG_LIMIT`] (a hang cannot
/// be caught in-thread): prints the case's bytes and aborts.
struct Watchdog {
    state: Arc<Mutex<RunningCase>>,
}

/// When the running case started, and its bytes (`None` between cases).
type RunningCase = Option<(Instant, Vec<u8>)>;

impl Watchdog {
    fn new(parser: Parser) -> Watchdog {
        let state: Arc<Mutex<RunningCase>> = Arc::new(Mutex::new(None));
        let watched = Arc::downgrade(&state);
        std::thread::spawn(move || {
            while let Some(state) = watched.upgrade() {
                if let Some((started, bytes)) = &*state.lock().unwrap() {
                    if started.elapsed() > HANG_LIMIT {
                        eprintln!("fuzz {parser:?}: hang (> {HANG_LIMIT:?}) on bytes {bytes:?}");
                        std::process::abort();
                    }
                }
                drop(state);
                std::thread::sleep(Duration::from_millis(200));
            }
        });
        Watchdog { state }
    }

    fn start(&self, bytes: &[u8]) {
        *self.state.lock().unwrap() = Some((Instant::now(), bytes.to_vec()));
    }

    fn stop(&self) {
        *self.state.lock().unwrap() = None;
    }
}

/// Fuzzes one parser with `cases` cases; returns (cases, accepted, seconds).
fn fuzz(parser: Parser, cases: u32) -> (u32, u64, f64) {
    let s = samples();
    let pool = &s.by_parser[parser as usize];
    let dir = s.dir.join(format!("{parser:?}"));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(parser.file_name());
    // Every sample is valid as given (else the mutations start from a refusal). The real
    // `badfile.sbet` is the one deliberate exception.
    let accepted = std::cell::Cell::new(0u64);
    for (k, sample) in pool.iter().enumerate() {
        std::fs::write(&path, sample).unwrap();
        let bad_real = matches!(parser, Parser::Sbet) && sample.len() % SBET_RECORD_BYTES != 0;
        let r = parser.parse(&path);
        assert!(
            r.is_ok() || bad_real,
            "{parser:?} sample {k} refused: {r:?}"
        );
    }
    // The seed: PROPTEST_RNG_SEED (CI fixes it), else a new one each run. A failing case is
    // recorded in tests/suite/fuzz.proptest-regressions (path from the crate root, the test's
    // working folder) and replayed first by every later run.
    let config = Config {
        cases,
        failure_persistence: Some(Box::new(FileFailurePersistence::Direct(
            "tests/suite/fuzz.proptest-regressions",
        ))),
        max_shrink_iters: 2000,
        ..Config::default()
    };
    let mut runner = TestRunner::new(config);
    let watchdog = Watchdog::new(parser);
    let strategy = (0..pool.len(), proptest::collection::vec(mutation(), 1..5));
    let started = Instant::now();
    let result = runner.run(&strategy, |(k, mutations)| {
        let mut bytes = pool[k].clone();
        for m in &mutations {
            apply(&mut bytes, m, pool);
        }
        if check_case(parser, &path, &bytes, &watchdog)? {
            accepted.set(accepted.get() + 1);
        }
        Ok(())
    });
    let seconds = started.elapsed().as_secs_f64();
    if let Err(e) = result {
        panic!("{parser:?}: {e}");
    }
    (cases, accepted.get(), seconds)
}

/// Fuzzes every parser, or those `KINESCAN_FUZZ_ONLY` names (a comma list of the names
/// printed, e.g. `DayToml,Patches`: to measure one); a list naming none fails.
fn fuzz_all(cases: u32) {
    let only = std::env::var("KINESCAN_FUZZ_ONLY").ok();
    let chosen: Vec<Parser> = Parser::ALL
        .into_iter()
        .filter(|p| {
            only.as_deref()
                .is_none_or(|o| o.split(',').any(|n| n.trim() == format!("{p:?}")))
        })
        .collect();
    assert!(
        !chosen.is_empty(),
        "KINESCAN_FUZZ_ONLY={only:?} names no parser"
    );
    for parser in chosen {
        // The raw IMU and GNSS records are read by the SBET's and SMRMSG's generic reader
        // (`io::timed`, fuzzed at full length there): the long run gives them a fifth of
        // the cases each (about 4 s each in CI).
        let raw = matches!(parser, Parser::Imu | Parser::Gnss);
        let cases = if raw && cases > QUICK_CASES {
            (cases / 5).max(QUICK_CASES)
        } else {
            cases
        };
        let (n, accepted, seconds) = fuzz(parser, cases);
        eprintln!(
            "fuzz {parser:?}: {n} cases in {seconds:.1} s ({accepted} parsed to a value), \
             no panic, no hang, every error names the file"
        );
    }
}

#[test]
fn fuzz_quick_every_parser() {
    fuzz_all(QUICK_CASES);
}

/// The long run (docs/robustness.md): `PROPTEST_CASES` cases per parser (default 100,000).
#[test]
#[ignore = "long (CI): PROPTEST_CASES=100000 cargo test --test suite -- --ignored fuzz_long; the test profile is optimised (opt-level 3), so no --release"]
fn fuzz_long_every_parser() {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(LONG_CASES);
    fuzz_all(cases);
}
