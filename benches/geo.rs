//! Per-point cost of the geodesy used on every LAS point: ECEF -> geodetic, ECEF -> UTM, and a
//! 1e6-point ECEF -> UTM batch (a 2 km x 2 km mobile-mapping block in zone 32N).
#![allow(clippy::disallowed_methods)] // clippy.toml's NaN rule is for tests/suite

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use kinescan::geo::ellipsoid::{ecef_to_geodetic, geodetic_to_ecef, Geodetic};
use kinescan::geo::projection::MapFrame;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

/// `n` ECEF points spread over about 2 km x 2 km x 50 m around 48.1 N, 11.6 E (seeded).
fn block(n: usize) -> Vec<Vector3<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    (0..n)
        .map(|_| {
            geodetic_to_ecef(Geodetic {
                lat_rad: (48.1 + 0.018 * rng.random::<f64>()).to_radians(),
                lon_rad: (11.6 + 0.027 * rng.random::<f64>()).to_radians(),
                h_m: 500.0 + 50.0 * rng.random::<f64>(),
            })
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let utm = MapFrame::utm(32, true).expect("zone 32N");
    let pts = block(1024);
    let mut g = c.benchmark_group("per_point");
    g.throughput(Throughput::Elements(pts.len() as u64));
    g.bench_function("ecef_to_geodetic", |b| {
        b.iter(|| {
            pts.iter()
                .map(|p| ecef_to_geodetic(black_box(p)).h_m)
                .sum::<f64>()
        })
    });
    g.bench_function("ecef_to_utm", |b| {
        b.iter(|| {
            pts.iter()
                .map(|p| utm.ecef_to_map(black_box(p)).x)
                .sum::<f64>()
        })
    });
    g.bench_function("utm_to_ecef", |b| {
        let m: Vec<_> = pts.iter().map(|p| utm.ecef_to_map(p)).collect();
        b.iter(|| {
            m.iter()
                .map(|p| utm.map_to_ecef(black_box(p)).x)
                .sum::<f64>()
        })
    });
    g.bench_function("r_enu_to_map_axes_utm", |b| {
        b.iter(|| {
            pts.iter()
                .map(|p| utm.r_enu_to_map_axes(black_box(p))[(0, 1)])
                .sum::<f64>()
        })
    });
    g.finish();

    let big = block(1_000_000);
    let mut out = vec![Vector3::zeros(); big.len()];
    let mut g = c.benchmark_group("batch");
    g.sample_size(10);
    g.throughput(Throughput::Elements(big.len() as u64));
    g.bench_function("ecef_to_utm_1e6", |b| {
        b.iter(|| {
            for (o, p) in out.iter_mut().zip(&big) {
                *o = utm.ecef_to_map(p);
            }
            black_box(&out);
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
