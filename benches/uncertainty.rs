//! Per-return cost of the uncertainty propagation against the georeferencing it rides on:
//! `ReturnTerms` + ECEF point (what every return costs), the run's [`Propagator`] (what the
//! `[uncertainty]` table adds per return), and the reference Jacobian + `J Q J^T` (the tested
//! model, for comparison). 1024 returns of a 40 m street section seen from a moving van.
#![allow(clippy::disallowed_methods)] // clippy.toml's NaN rule is for tests/suite

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use kinescan::geo::ellipsoid::r_n_to_e;
use kinescan::geo::rotations::{q_b_to_n, r_zyx};
use kinescan::georef::ReturnTerms;
use kinescan::trajectory::NavSigma;
use kinescan::uncertainty::model::{LocalLevel, PointGeometry};
use kinescan::uncertainty::propagate::{covariance_of, Propagator};
use kinescan::uncertainty::UncertaintyInputs;
use nalgebra::{Matrix2, Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

struct Case {
    geom: PointGeometry,
    terms: ReturnTerms,
}

fn cases(n: usize) -> Vec<Case> {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (lat, lon) = (48.1f64.to_radians(), 11.6f64.to_radians());
    let lever = Vector3::new(0.5, 0.0, -1.5);
    let r_s_b = r_zyx(0.01, -0.02, 1.5);
    (0..n)
        .map(|_| {
            let q = q_b_to_n(
                rng.random_range(-0.05..0.05),
                rng.random_range(-0.05..0.05),
                rng.random_range(0.0..std::f64::consts::TAU),
            );
            let geom = PointGeometry {
                r_e_m: Vector3::new(4.17e6, 0.86e6, 4.73e6),
                lat_rad: lat,
                lon_rad: lon,
                h_m: 520.0,
                r_b_to_n: *q.to_rotation_matrix().matrix(),
                v_n_mps: Vector3::new(12.0, 3.0, 0.1),
                omega_b_radps: Vector3::new(0.01, -0.02, 0.15),
                lever_arm_b_m: lever,
                r_s_to_b: r_s_b,
                alpha_rad: 0.0,
                beta_rad: rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
                range_m: rng.random_range(2.0..40.0),
                range_zero_m: 0.0,
            };
            let terms = geom.terms(r_n_to_e(lat, lon));
            Case { geom, terms }
        })
        .collect()
}

fn inputs() -> UncertaintyInputs {
    UncertaintyInputs {
        sigma_lever_arm_b_m: Vector3::repeat(0.01),
        sigma_boresight_rad: Vector3::repeat(1.7e-4),
        sigma_alpha_rad: 8.7e-5,
        sigma_beta_rad: 8.7e-5,
        sigma_range_m: 0.005,
        sigma_range_zero_m: 0.005,
        clock_covariance_s2: Matrix2::new(1e-8, 0.0, 0.0, 1e-16),
        sigma_attitude_latency_s: 2e-4,
    }
}

fn bench(c: &mut Criterion) {
    let cases = cases(1024);
    let nav = NavSigma {
        pos_ned_m: Vector3::new(0.02, 0.02, 0.03),
        att_rph_rad: Vector3::new(8.7e-5, 8.7e-5, 2.9e-4),
    };
    let g0 = &cases[0].geom;
    let local = LocalLevel::at(g0.lat_rad, g0.lon_rad, g0.h_m);
    // UTM-like map axes: a small rotation and scale (grid convergence, k = 0.9996).
    let out = r_zyx(0.0, 0.0, 0.02) * 0.9996 * local.r_n_to_e.transpose();
    let r_n_out: Matrix3<f64> = out * local.r_n_to_e;
    let (lever, r_s_b) = (g0.lever_arm_b_m, g0.r_s_to_b);
    let mut g = c.benchmark_group("per_return");
    g.throughput(Throughput::Elements(cases.len() as u64));
    g.bench_function("georeference_terms", |b| {
        b.iter(|| {
            cases
                .iter()
                .map(|k| {
                    let t = black_box(&k.geom).terms(local.r_n_to_e);
                    t.point_e(&k.geom.r_e_m).x
                })
                .sum::<f64>()
        })
    });
    for (name, with_groups) in [
        ("propagator_sigmas", false),
        ("propagator_sigmas_and_shares", true),
    ] {
        let prop = black_box(Propagator::new(inputs(), with_groups, lever, r_s_b));
        g.bench_function(name, |b| {
            b.iter(|| {
                cases
                    .iter()
                    .map(|k| {
                        let v = prop.variances(
                            &r_n_out,
                            &local.dtheta_per_m,
                            black_box(&k.terms),
                            &k.geom.omega_b_radps,
                            &k.geom.v_n_mps,
                            black_box(&nav),
                            black_box([1.0, k.geom.beta_rad]),
                        );
                        v.var_m2.sum() + v.group_variance_m2.iter().sum::<f64>()
                    })
                    .sum::<f64>()
            })
        });
    }
    g.bench_function("reference_jacobian", |b| {
        let sigmas = inputs().sigmas(&nav, [1.0, 1234.5]);
        b.iter(|| {
            cases
                .iter()
                .map(|k| {
                    let j = k
                        .geom
                        .jacobian_in_axes(&out, &local.dtheta_per_m, black_box(&k.terms));
                    let v = covariance_of(&j, black_box(&sigmas)).axes();
                    v.var_m2.sum() + v.group_variance_m2.iter().sum::<f64>()
                })
                .sum::<f64>()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
