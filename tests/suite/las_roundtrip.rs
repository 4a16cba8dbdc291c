//! LAS writer round trips, read back with the independent `las` crate reader.
//!
//! Set `KINESCAN_LASPY_OUT=/path/file.las` to also keep a representative file for
//! `python3 tests/laspy_check.py` (EPSG 32632, dims sigma_x,sigma_y,sigma_z,range_m).

use std::path::Path;

use kinescan::io::las::{
    encode_points, finish_parts, ChunkStats, ExtraDim, ExtraType, GpsTimeConvention, LasPoint,
    LasSummary, LasWriter, LasWriterConfig, PointLayout, FRACTION_SCALE, MAX_EXTRA_DIMS,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// WKT1 of EPSG:32632 (WGS 84 / UTM zone 32N), as PROJ writes it.
const WKT_32632: &str = r#"PROJCS["WGS 84 / UTM zone 32N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],PARAMETER["central_meridian",9],PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],PARAMETER["false_northing",0],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AXIS["Northing",NORTH],AUTHORITY["EPSG","32632"]]"#;

const GPS_WEEK: u32 = 2398;
const OFFSET_M: [f64; 3] = [691_000.0, 5_335_000.0, 500.0];

fn dims() -> Vec<ExtraDim> {
    vec![
        ExtraDim::f32("sigma_x", "1-sigma along X (m)"),
        ExtraDim::f32("sigma_y", "1-sigma along Y (m)"),
        ExtraDim::f32("sigma_z", "1-sigma along Z (m)"),
        ExtraDim::f64("range_m", "scanner range (m)"),
        ExtraDim::fraction("share", "a fraction 0-1"),
    ]
}

fn config(time: GpsTimeConvention) -> LasWriterConfig {
    LasWriterConfig {
        layout: PointLayout::new(OFFSET_M, time, dims()).unwrap(),
        wkt: WKT_32632.to_string(),
        system_identifier: "kinescan test".to_string(),
        file_source_id: 7,
        creation_day_of_year: 321,
        creation_year: 2026,
    }
}

/// Points spread over a few hundred metres around the offset, returns 1..=3.
fn points(n: usize, seed: u64) -> Vec<LasPoint> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|i| {
            let nr = rng.random_range(1..=3u8);
            let mut extra = [0.0; MAX_EXTRA_DIMS];
            extra[0] = rng.random_range(0.001..0.05);
            extra[1] = rng.random_range(0.001..0.05);
            extra[2] = rng.random_range(0.001..0.08);
            extra[3] = rng.random_range(1.0..120.0);
            extra[4] = rng.random_range(0.0..=1.0);
            LasPoint {
                x: OFFSET_M[0] + rng.random_range(-300.0..300.0),
                y: OFFSET_M[1] + rng.random_range(-300.0..300.0),
                z: OFFSET_M[2] + rng.random_range(-20.0..40.0),
                intensity: rng.random(),
                return_number: rng.random_range(1..=nr),
                number_of_returns: nr,
                scan_angle_deg: rng.random_range(-180.0..180.0),
                gps_time: 345_600.0 + i as f64 * 1e-5,
                point_source_id: rng.random(),
                // Below 12: the las crate reads class 12 (overlap) back as a flag.
                classification: rng.random_range(0..12),
                user_data: rng.random(),
                extra,
            }
        })
        .collect()
}

/// Encodes `chunk`-sized pieces in parallel and writes them in order.
fn write_file(path: &Path, cfg: LasWriterConfig, pts: &[LasPoint], chunk: usize) -> LasSummary {
    let layout = cfg.layout.clone();
    let encoded: Vec<(Vec<u8>, ChunkStats)> = pts
        .par_chunks(chunk)
        .map(|c| {
            let mut buf = Vec::new();
            let stats = encode_points(c, &layout, &mut buf).unwrap();
            (buf, stats)
        })
        .collect();
    let mut writer = LasWriter::create(path, cfg).unwrap();
    for (bytes, stats) in &encoded {
        writer.write_encoded(bytes, stats).unwrap();
    }
    writer.finish().unwrap()
}

/// (name, data_type, description, offset in the extra bytes) parsed from the Extra Bytes VLR
/// by hand; only the unsigned char type carries a scale (FRACTION_SCALE).
fn parse_extra_bytes_vlr(header: &las::Header) -> Vec<(String, u8, String, usize)> {
    let vlr = header
        .vlrs()
        .iter()
        .find(|v| v.user_id == "LASF_Spec" && v.record_id == 4)
        .expect("Extra Bytes VLR");
    assert_eq!(vlr.data.len() % 192, 0);
    let text = |b: &[u8]| String::from_utf8(b.iter().take_while(|c| **c != 0).copied().collect());
    let mut offset = 0;
    vlr.data
        .chunks_exact(192)
        .map(|d| {
            assert_eq!(&d[0..2], &[0, 0], "reserved");
            let scaled = d[2] == 1;
            let options = if scaled { 1 << 3 } else { 0 };
            assert_eq!(d[3], options, "options: scale only for the byte type");
            let scale = f64::from_le_bytes(d[112..120].try_into().unwrap());
            assert_eq!(scale, if scaled { FRACTION_SCALE } else { 0.0 });
            assert!(
                d[36..112].iter().chain(&d[120..160]).all(|b| *b == 0),
                "unused/no_data/min/max/other scales/offset"
            );
            let size = match d[2] {
                1 => 1,
                9 => 4,
                10 => 8,
                t => panic!("unexpected data_type {t}"),
            };
            let entry = (
                text(&d[4..36]).unwrap(),
                d[2],
                text(&d[160..192]).unwrap(),
                offset,
            );
            offset += size;
            entry
        })
        .collect()
}

fn extra_value(bytes: &[u8], data_type: u8, offset: usize) -> f64 {
    match data_type {
        1 => f64::from(bytes[offset]) * FRACTION_SCALE,
        9 => f64::from(f32::from_le_bytes(
            bytes[offset..offset + 4].try_into().unwrap(),
        )),
        _ => f64::from_le_bytes(bytes[offset..offset + 8].try_into().unwrap()),
    }
}

fn read_back(path: &Path) -> (las::Header, Vec<las::Point>) {
    let mut reader = las::Reader::from_path(path).unwrap();
    let header = reader.header().clone();
    let pts = reader
        .read_all()
        .unwrap()
        .points()
        .map(|p| p.unwrap())
        .collect();
    (header, pts)
}

fn check_roundtrip(time: GpsTimeConvention, path: &Path) {
    let pts = points(5_000, 11);
    let summary = write_file(path, config(time), &pts, 777);
    let (header, back) = read_back(path);
    assert_eq!(header.version(), las::Version::new(1, 4));
    assert_eq!(header.point_format().to_u8().unwrap(), 6);
    assert_eq!(header.point_format().extra_bytes, 4 + 4 + 4 + 8 + 1);
    assert_eq!(header.number_of_points(), pts.len() as u64);
    assert_eq!(back.len(), pts.len());
    assert_eq!(header.system_identifier(), "kinescan test");
    assert!(header.generating_software().starts_with("kinescan "));
    assert_eq!(header.file_source_id(), 7);

    // Global encoding: bit 0 per convention, bit 4 (WKT) always.
    let adjusted = matches!(time, GpsTimeConvention::AdjustedStandard { .. });
    assert!(header.has_wkt_crs());
    let expected_type = if adjusted {
        las::GpsTimeType::Standard
    } else {
        las::GpsTimeType::Week
    };
    assert_eq!(header.gps_time_type(), expected_type);
    // The header exactly as stored (las::Header::into_raw would recompute legacy fields).
    let raw = las::raw::Header::read_from(std::fs::File::open(path).unwrap()).unwrap();
    assert_eq!(
        raw.global_encoding,
        if adjusted { 0b1_0001 } else { 0b1_0000 }
    );
    // Legacy counts must be zero for format 6 (LAS 1.4 R15).
    assert_eq!(raw.number_of_point_records, 0);
    assert_eq!(raw.number_of_points_by_return, [0; 5]);
    assert_eq!(
        (raw.file_creation_day_of_year, raw.file_creation_year),
        (321, 2026)
    );

    let wkt = header
        .vlrs()
        .iter()
        .find(|v| v.user_id == "LASF_Projection" && v.record_id == 2112)
        .expect("WKT VLR");
    assert_eq!(wkt.data.last(), Some(&0), "WKT null-terminated");
    assert_eq!(&wkt.data[..wkt.data.len() - 1], WKT_32632.as_bytes());

    let eb = parse_extra_bytes_vlr(&header);
    let names: Vec<&str> = eb.iter().map(|e| e.0.as_str()).collect();
    assert_eq!(names, ["sigma_x", "sigma_y", "sigma_z", "range_m", "share"]);
    assert_eq!(eb[0].2, "1-sigma along X (m)");

    let shift = time.shift_s();
    let half_step = 0.5e-4 * (1.0 + 1e-9); // half the 0.1 mm scale, f64 slack
    let mut by_return = [0u64; 15];
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for (p, q) in pts.iter().zip(&back) {
        for (a, b) in [(p.x, q.x), (p.y, q.y), (p.z, q.z)] {
            assert!(
                (a - b).abs() <= half_step,
                "coordinate {a} read back as {b}"
            );
        }
        for (k, v) in [q.x, q.y, q.z].into_iter().enumerate() {
            // NaN-proof (min_of fails on NaN); the maximum as minus the minimum of negatives,
            // as max_of's fold starts at 0.
            lo[k] = crate::common::min_of([lo[k], v]);
            hi[k] = -crate::common::min_of([-hi[k], -v]);
        }
        // Adding an exact integer shift rounds once: exact to f64 resolution at 4.5e8 s.
        assert_eq!(q.gps_time.unwrap(), p.gps_time + shift);
        assert_eq!(q.intensity, p.intensity);
        assert_eq!(
            (q.return_number, q.number_of_returns),
            (p.return_number, p.number_of_returns)
        );
        by_return[usize::from(p.return_number) - 1] += 1;
        // Stored in 0.006 deg counts: at most half a count off.
        assert!((f64::from(q.scan_angle) - p.scan_angle_deg).abs() <= 0.003 + 1e-4);
        assert_eq!(q.point_source_id, p.point_source_id);
        assert_eq!(u8::from(q.classification), p.classification);
        assert_eq!(q.user_data, p.user_data);
        for (k, (_, ty, _, off)) in eb.iter().enumerate() {
            let v = extra_value(&q.extra_bytes, *ty, *off);
            let want = match *ty {
                9 => f64::from(p.extra[k] as f32),
                1 => (p.extra[k] / FRACTION_SCALE).round() * FRACTION_SCALE,
                _ => p.extra[k],
            };
            assert_eq!(v, want, "extra dimension {k}");
            if *ty == 1 {
                // Half a step of 0.004 at most, plus the scale's own rounding.
                assert!((v - p.extra[k]).abs() <= 0.002 + 1e-12);
            }
        }
    }
    let stored = las::raw::Header::read_from(std::fs::File::open(path).unwrap()).unwrap();
    assert_eq!(
        stored.large_file.unwrap().number_of_points_by_return,
        by_return
    );
    assert_eq!(summary.points_by_return, by_return);
    // Header bounds are exactly the extent of the stored coordinates.
    let bounds = header.bounds();
    assert_eq!([bounds.min.x, bounds.min.y, bounds.min.z], lo);
    assert_eq!([bounds.max.x, bounds.max.y, bounds.max.z], hi);
    assert_eq!(summary.min_m, lo);
    assert_eq!(summary.max_m, hi);
    let t_end = pts.last().unwrap().gps_time + shift;
    assert_eq!(
        summary.gps_time_range,
        Some((pts[0].gps_time + shift, t_end))
    );
    assert_eq!(summary.file_bytes, std::fs::metadata(path).unwrap().len());
}

#[test]
fn roundtrip_adjusted_standard_gps_time() {
    let dir = tempfile::tempdir().unwrap();
    let time = GpsTimeConvention::AdjustedStandard { gps_week: GPS_WEEK };
    check_roundtrip(time, &dir.path().join("adjusted.las"));
    if let Some(out) = std::env::var_os("KINESCAN_LASPY_OUT") {
        write_file(Path::new(&out), config(time), &points(5_000, 11), 1000);
        eprintln!("wrote {}", Path::new(&out).display());
    }
}

#[test]
fn roundtrip_gps_week_seconds() {
    let dir = tempfile::tempdir().unwrap();
    check_roundtrip(GpsTimeConvention::WeekSeconds, &dir.path().join("week.las"));
}

#[test]
fn adjusted_time_matches_definition() {
    // GPS week 2398, 345600 s of week: standard GPS time 2398 * 604800 + 345600 = 1 450 656 000 s.
    let shift = GpsTimeConvention::AdjustedStandard { gps_week: GPS_WEEK }.shift_s();
    assert_eq!(345_600.0 + shift, 1_450_656_000.0 - 1e9);
    assert_eq!(GpsTimeConvention::WeekSeconds.shift_s(), 0.0);
}

#[test]
fn empty_file_is_valid() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty.las");
    let summary = write_file(&path, config(GpsTimeConvention::WeekSeconds), &[], 10);
    assert_eq!(summary.point_count, 0);
    assert_eq!(summary.gps_time_range, None);
    let (header, back) = read_back(&path);
    assert_eq!(header.number_of_points(), 0);
    assert!(back.is_empty());
    assert_eq!(header.bounds().min.x, 0.0);
    assert_eq!(parse_extra_bytes_vlr(&header).len(), 5);
}

#[test]
fn no_extra_dims_means_no_extra_bytes_vlr() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plain.las");
    let time = GpsTimeConvention::WeekSeconds;
    let layout = PointLayout::new(OFFSET_M, time, vec![]).unwrap();
    let pts = points(50, 9);
    write_file(
        &path,
        LasWriterConfig {
            layout,
            ..config(time)
        },
        &pts,
        16,
    );
    let (header, back) = read_back(&path);
    assert_eq!(header.point_format().extra_bytes, 0);
    assert_eq!(header.vlrs().len(), 1);
    assert!(header.vlrs()[0].is_wkt_crs());
    assert_eq!(back.len(), 50);
    assert!((back[49].x - pts[49].x).abs() <= 0.5e-4 * (1.0 + 1e-9));
}

#[test]
fn coordinate_outside_i32_is_an_error() {
    let layout = config(GpsTimeConvention::WeekSeconds).layout;
    // 0.0001 m scale reaches +-214 748.3647 m about the offset; 250 km is 35.25 km too far.
    let ok = LasPoint {
        x: OFFSET_M[0],
        y: OFFSET_M[1],
        z: OFFSET_M[2],
        ..Default::default()
    };
    let mut p = LasPoint {
        y: OFFSET_M[1] + 250_000.0,
        ..ok
    };
    let err = encode_points(&[ok, p], &layout, &mut Vec::new()).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("point 1") && msg.contains(" Y "), "{msg}");
    assert!(msg.contains("35251.635 m beyond"), "{msg}");
    assert!(msg.contains("offset"), "{msg}");
    p.y = f64::NAN;
    assert!(encode_points(&[p], &layout, &mut Vec::new()).is_err());
    // Just inside the range is fine.
    p.y = OFFSET_M[1] + 214_748.0;
    p.x = OFFSET_M[0] - 214_748.0;
    assert!(encode_points(&[p], &layout, &mut Vec::new()).is_ok());
}

#[test]
fn invalid_point_fields_are_errors() {
    let layout = config(GpsTimeConvention::WeekSeconds).layout;
    let at_offset = LasPoint {
        x: OFFSET_M[0],
        y: OFFSET_M[1],
        z: OFFSET_M[2],
        ..Default::default()
    };
    for bad in [
        LasPoint {
            return_number: 0,
            ..at_offset
        },
        LasPoint {
            number_of_returns: 16,
            ..at_offset
        },
        LasPoint {
            scan_angle_deg: 180.01,
            ..at_offset
        },
    ] {
        assert!(
            encode_points(&[bad], &layout, &mut Vec::new()).is_err(),
            "{bad:?}"
        );
    }
}

#[test]
fn invalid_layouts_are_errors() {
    let time = GpsTimeConvention::WeekSeconds;
    let long = ExtraDim::f32(&"n".repeat(33), "");
    let dup = vec![ExtraDim::f32("a", ""), ExtraDim::f64("a", "")];
    let many = (0..=MAX_EXTRA_DIMS)
        .map(|i| ExtraDim::f32(&format!("d{i}"), ""))
        .collect();
    for dims in [vec![long], dup, many, vec![ExtraDim::f32("", "")]] {
        assert!(PointLayout::new(OFFSET_M, time, dims).is_err());
    }
    assert!(PointLayout::with_scale([0.0, 1.0, 1.0], OFFSET_M, time, vec![]).is_err());
    let layout = PointLayout::new(OFFSET_M, time, dims()).unwrap();
    assert_eq!(layout.record_len(), 30 + 21);
    assert_eq!(layout.extra_dims()[3].data_type, ExtraType::F64);
    let dir = tempfile::tempdir().unwrap();
    let bad_wkt = LasWriterConfig {
        wkt: String::new(),
        ..config(time)
    };
    assert!(LasWriter::create(dir.path().join("x.las"), bad_wkt).is_err());
}

#[test]
fn mismatched_chunk_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(GpsTimeConvention::WeekSeconds);
    let other = PointLayout::new(OFFSET_M, GpsTimeConvention::WeekSeconds, vec![]).unwrap();
    let mut buf = Vec::new();
    let stats = encode_points(&points(3, 1), &other, &mut buf).unwrap();
    let mut writer = LasWriter::create(dir.path().join("m.las"), cfg).unwrap();
    assert!(writer.write_encoded(&buf, &stats).is_err());
    assert!(writer.write_encoded(&buf[..30], &stats).is_err());
}

#[test]
fn unfinished_writer_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.las");
    let cfg = config(GpsTimeConvention::WeekSeconds);
    let mut writer = LasWriter::create(&path, cfg.clone()).unwrap();
    writer.write_points(&points(100, 2)).unwrap();
    assert!(!path.exists(), "destination appears only on finish");
    drop(writer);
    assert!(!path.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "temporary file removed"
    );

    // An existing file is untouched by an abandoned rewrite.
    write_file(&path, cfg.clone(), &points(10, 3), 4);
    let before = std::fs::read(&path).unwrap();
    let mut writer = LasWriter::create(&path, cfg).unwrap();
    writer.write_points(&points(50, 4)).unwrap();
    drop(writer);
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn output_independent_of_chunking() {
    let dir = tempfile::tempdir().unwrap();
    let time = GpsTimeConvention::AdjustedStandard { gps_week: GPS_WEEK };
    let pts = points(3_001, 5);
    let files: Vec<Vec<u8>> = [1usize, 7, 1000, 5000]
        .iter()
        .map(|&chunk| {
            let path = dir.path().join(format!("c{chunk}.las"));
            write_file(&path, config(time), &pts, chunk);
            std::fs::read(path).unwrap()
        })
        .collect();
    // Also the single-threaded convenience path.
    let path = dir.path().join("direct.las");
    let mut writer = LasWriter::create(&path, config(time)).unwrap();
    for c in pts.chunks(333) {
        writer.write_points(c).unwrap();
    }
    writer.finish().unwrap();
    let direct = std::fs::read(path).unwrap();
    for f in &files {
        assert!(f == &files[0] && f == &direct, "chunking changed the bytes");
    }
}

/// A file written in parts (empty parts too, each by a writer of its own right after the
/// previous part) and completed by `finish_parts` from the parts' summaries has the bytes and
/// the summary of the file written whole. Completing it again writes nothing; a part written
/// again after the file was published through a hard link leaves the published file as it
/// was; a file whose size is not that of its parts is refused.
#[test]
fn a_file_written_in_parts_is_the_file_written_whole() {
    let dir = tempfile::tempdir().unwrap();
    let time = GpsTimeConvention::AdjustedStandard { gps_week: GPS_WEEK };
    let pts = points(3_001, 6);
    let whole_path = dir.path().join("whole.las");
    let whole = write_file(&whole_path, config(time), &pts, 1000);
    let path = dir.path().join("parts.las");
    let cuts = [0, 0, 1, 700, 700, 2048, 3_001, 3_001];
    let mut parts: Vec<LasSummary> = Vec::new();
    for pair in cuts.windows(2) {
        let previous_end = parts.last().map(|p| p.file_bytes);
        let mut w = LasWriter::part(&path, config(time), previous_end).unwrap();
        w.write_points(&pts[pair[0]..pair[1]]).unwrap();
        parts.push(w.finish().unwrap());
    }
    let summary = finish_parts(&path, &config(time), &parts).unwrap();
    assert_eq!(
        summary,
        LasSummary {
            path: path.clone(),
            ..whole.clone()
        }
    );
    let whole_bytes = std::fs::read(&whole_path).unwrap();
    assert!(std::fs::read(&path).unwrap() == whole_bytes, "bytes differ");

    let modified = || std::fs::metadata(&path).unwrap().modified().unwrap();
    let before = modified();
    std::thread::sleep(std::time::Duration::from_millis(20));
    finish_parts(&path, &config(time), &parts).unwrap();
    assert_eq!(modified(), before, "a complete file written again");

    let published = dir.path().join("published.las");
    std::fs::hard_link(&path, &published).unwrap();
    let mut w = LasWriter::part(&path, config(time), Some(parts[3].file_bytes)).unwrap();
    w.write_points(&pts[700..701]).unwrap();
    let short = w.finish().unwrap();
    assert!(
        std::fs::read(&published).unwrap() == whole_bytes,
        "published file changed"
    );
    let mut cut = parts[..4].to_vec();
    let err = finish_parts(&path, &config(time), &parts)
        .unwrap_err()
        .to_string();
    assert!(err.contains("parts.las") && err.contains("bytes"), "{err}");
    cut.push(short);
    let summary = finish_parts(&path, &config(time), &cut).unwrap();
    assert_eq!(summary.point_count, 701);
    assert!(
        std::fs::read(&published).unwrap() == whole_bytes,
        "published file changed"
    );
}
