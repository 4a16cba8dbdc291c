//! Throughput of the LAS point encoder: 1e6 format 6 points with 4 float32 extra dimensions.
#![allow(clippy::disallowed_methods)] // clippy.toml's NaN rule is for tests/suite

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use kinescan::io::las::{encode_points, ExtraDim, GpsTimeConvention, LasPoint, PointLayout};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const N: usize = 1_000_000;

fn bench_encode(c: &mut Criterion) {
    let offset_m = [691_000.0, 5_335_000.0, 500.0];
    let dims = ["sigma_x", "sigma_y", "sigma_z", "sigma_h95"]
        .map(|name| ExtraDim::f32(name, "1-sigma (m)"))
        .to_vec();
    let time = GpsTimeConvention::AdjustedStandard { gps_week: 2398 };
    let layout = PointLayout::new(offset_m, time, dims).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let points: Vec<LasPoint> = (0..N)
        .map(|i| {
            let mut p = LasPoint {
                x: offset_m[0] + rng.random_range(-500.0..500.0),
                y: offset_m[1] + rng.random_range(-500.0..500.0),
                z: offset_m[2] + rng.random_range(-30.0..30.0),
                intensity: rng.random(),
                scan_angle_deg: rng.random_range(-180.0..180.0),
                gps_time: 345_600.0 + i as f64 * 1e-6,
                ..Default::default()
            };
            p.extra[..4]
                .iter_mut()
                .for_each(|v| *v = rng.random_range(0.001..0.05));
            p
        })
        .collect();
    let mut out = Vec::with_capacity(N * layout.record_len());
    let mut group = c.benchmark_group("las");
    group.throughput(Throughput::Elements(N as u64));
    group.sample_size(20);
    group.bench_function("encode_points_1e6_4xf32", |b| {
        b.iter(|| {
            out.clear();
            encode_points(&points, &layout, &mut out).unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, bench_encode);
criterion_main!(benches);
