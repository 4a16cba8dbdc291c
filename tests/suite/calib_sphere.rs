//! Sphere fit acceptance: predicted vs empirical centre covariance, iteration
//! count from the barycentre, robustness to 10 % returns off the sphere, bad input.

use kinescan::calib::sphere::{fit_sphere, fit_sphere_robust, ray_sphere_range, SphereRadius};
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const RADIUS: f64 = 0.1;
const SIGMA_RANGE: f64 = 0.002;

fn centre() -> Vector3<f64> {
    Vector3::new(0.0, 1.5, 0.0)
}

/// Unit ray from the origin with angles (a, b) (rad) about the +y axis (sphere direction).
fn ray(a: f64, b: f64) -> Vector3<f64> {
    Vector3::new(a.tan(), 1.0, b.tan()).normalize()
}

/// A 20 cm sphere at 1.5 m scanned on a 0.15 deg grid (~2000 returns, one paper pass at
/// 6 deg/s) with Gaussian range noise. Returns the sphere points and the rays that missed.
fn scan(rng: &mut ChaCha8Rng) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
    let noise = Normal::new(0.0, SIGMA_RANGE).unwrap();
    let step = 0.15f64.to_radians();
    let (mut hits, mut misses) = (Vec::new(), Vec::new());
    for i in -32..=32 {
        for j in -32..=32 {
            let d = ray(i as f64 * step, j as f64 * step);
            match ray_sphere_range(&Vector3::zeros(), &d, &centre(), RADIUS) {
                Some(r) => hits.push(d * (r + noise.sample(rng))),
                None => misses.push(d),
            }
        }
    }
    (hits, misses)
}

/// Ratios sqrt(e' C_emp e / e' C_pred e) along the eigenvectors of the predicted covariance;
/// `C_emp` is the scatter about the sample mean.
fn sigma_ratios(errors: &[Vector3<f64>], pred: &Matrix3<f64>) -> [f64; 3] {
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<Vector3<f64>>() / n;
    let emp = errors
        .iter()
        .map(|e| (e - mean) * (e - mean).transpose())
        .sum::<Matrix3<f64>>()
        / (n - 1.0);
    let eig = SymmetricEigen::new(*pred);
    [0, 1, 2].map(|k| {
        let e = eig.eigenvectors.column(k);
        ((e.transpose() * emp * e)[0] / eig.eigenvalues[k]).sqrt()
    })
}

fn check_covariance(radius: SphereRadius) {
    // 800 trials: the standard error of a sample sigma over N trials is sigma / sqrt(2N), i.e.
    // 2.5 % here, so the 10 % acceptance band is 4 standard errors on each principal axis.
    const TRIALS: usize = 800;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (mut errors, mut pred, mut max_it) = (Vec::new(), Matrix3::zeros(), 0);
    for _ in 0..TRIALS {
        let (pts, _) = scan(&mut rng);
        let f = fit_sphere(&pts, radius).unwrap();
        errors.push(f.centre_m - centre());
        pred += f.cov_centre_m2 / TRIALS as f64;
        max_it = max_it.max(f.iterations);
    }
    let ratios = sigma_ratios(&errors, &pred);
    let sig: Vec<f64> = SymmetricEigen::new(pred)
        .eigenvalues
        .iter()
        .map(|v| v.sqrt() * 1e6)
        .collect();
    let mean = errors.iter().sum::<Vector3<f64>>() / TRIALS as f64;
    println!("mean error {:?} um", mean * 1e6);
    println!("{radius:?}: predicted sigmas {sig:.1?} um, empirical/predicted {ratios:.3?}, max iterations {max_it}");
    assert!(ratios.iter().all(|r| (r - 1.0).abs() < 0.10), "{ratios:?}");
    assert!(max_it <= 10, "max iterations {max_it}");
    // Unbiased across the line of sight (x, z): mean error within 4 standard errors
    // (sigma / sqrt(N)). Along the line of sight (y) range noise on grazing rim returns biases
    // the fit towards the scanner (second order, sigma^2 / 2R at the rim): printed, not tested;
    // it is the same for both table directions and cancels in the latency.
    for k in [0, 2] {
        assert!(
            mean[k].abs() < 4.0 * (pred[(k, k)] / TRIALS as f64).sqrt(),
            "bias {mean:?}"
        );
    }
}

#[test]
fn known_radius_covariance_matches_scatter() {
    check_covariance(SphereRadius::Known(RADIUS));
}

#[test]
fn free_radius_covariance_matches_scatter() {
    check_covariance(SphereRadius::Free);
}

/// 10 % of the returns off the sphere: half on a 3 cm stand under it (NED-like, z down), half
/// on a wall 25 cm behind the sphere seen around its silhouette.
fn outliers(rng: &mut ChaCha8Rng, misses: &[Vector3<f64>], n: usize) -> Vec<Vector3<f64>> {
    let noise = Normal::new(0.0, SIGMA_RANGE).unwrap();
    let c = centre();
    let mut stand = Vec::new();
    let mut wall = Vec::new();
    for d in misses {
        // Stand: cylinder of radius 1.5 cm about the vertical through the centre, below it.
        let t = (c.y - 0.015) / d.y;
        let p = d * t;
        if (p.x - c.x).abs() < 0.015 && p.z > c.z + 0.05 {
            stand.push(p + d * noise.sample(rng));
        } else {
            wall.push(d * ((c.y + 0.25) / d.y + noise.sample(rng)));
        }
    }
    let pick =
        |v: Vec<Vector3<f64>>, k: usize| v.into_iter().step_by(2).take(k).collect::<Vec<_>>();
    let mut out = pick(stand, n / 2);
    let k = n - out.len();
    out.extend(pick(wall, k));
    out
}

#[test]
fn robust_fit_with_ten_percent_outliers_stays_within_two_sigma() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let (mut worst_robust, mut worst_plain) = (0.0f64, f64::INFINITY);
    for _ in 0..50 {
        let (pts, misses) = scan(&mut rng);
        let clean = fit_sphere(&pts, SphereRadius::Known(RADIUS)).unwrap();
        let n_out = pts.len() / 9; // 10 % of all returns
        let mut all = pts.clone();
        all.extend(outliers(&mut rng, &misses, n_out));
        assert!((all.len() - pts.len()) as f64 >= 0.099 * all.len() as f64);
        let inv = clean.cov_centre_m2.try_inverse().unwrap();
        let maha = |c: Vector3<f64>| {
            ((c - clean.centre_m).transpose() * inv * (c - clean.centre_m))[0].sqrt()
        };
        let robust = fit_sphere_robust(&all, SphereRadius::Known(RADIUS)).unwrap();
        crate::common::raise_max(&mut worst_robust, maha(robust.centre_m));
        // A plain fit that does not converge counts as infinitely far.
        let plain = fit_sphere(&all, SphereRadius::Known(RADIUS))
            .map_or(f64::INFINITY, |f| maha(f.centre_m));
        worst_plain = crate::common::min_of([worst_plain, plain]);
    }
    println!("Mahalanobis distance to the clean fit: robust worst {worst_robust:.2}, plain best {worst_plain:.1}");
    // "Within 2 sigma of the clean fit" as a Mahalanobis distance, worst of 50 trials.
    assert!(worst_robust < 2.0);
    // The outliers matter: without the robust scheme every fit is far off or fails to converge
    // (so this test can fail).
    assert!(worst_plain > 10.0);
}

#[test]
fn too_few_returns_is_a_clear_error() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (pts, _) = scan(&mut rng);
    let e = fit_sphere(&pts[..19], SphereRadius::Known(RADIUS))
        .unwrap_err()
        .to_string();
    assert!(e.contains("19 returns") && e.contains("at least 20"), "{e}");
    assert!(fit_sphere(&pts[..20], SphereRadius::Known(RADIUS)).is_ok());
}
