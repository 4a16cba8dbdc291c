//! Statistical acceptance of object-space synchronisation at the paper's geometry
//! (pipelines/scenario_sync_paper.toml: 33 rps, 2-9 m/s, a 5-minute route of two laps, four
//! sync plates each passed twice): the paper's method, the refined estimator against its
//! Cramer-Rao bound, normalised errors, and the georeferenced sync targets after sync.

use crate::sync_support;

use kinescan::georef::{georeference, point_s};
use kinescan::sync::{cramer_rao_bound, estimate, SightingStatus};
use kinescan::trajectory::PoseCursor;
use sync_support::{options, scenario, survey, PAPER};

/// Seeds: 50, as the acceptance asks. Relative sampling error of a standard deviation from
/// n = 50 samples is 1 / sqrt(2 (n - 1)) = 10%: the 25% bands below are 2.5 of those.
const SEEDS: u64 = 50;

fn std(v: &[f64]) -> f64 {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}
fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

#[test]
fn paper_and_refined_estimators_at_the_paper_geometry() {
    let dir = tempfile::tempdir().unwrap();
    let (mut pe0, mut pe1, mut ps0, mut ps1) = (vec![], vec![], vec![], vec![]);
    let (mut re0, mut re1, mut rs0, mut rs1) = (vec![], vec![], vec![], vec![]);
    let (mut crb0, mut crb1, mut z0, mut z1) = (vec![], vec![], vec![], vec![]);
    let (mut within, mut total, mut sightings) = (0usize, 0usize, 0usize);
    for seed in 1..=SEEDS {
        let sc = scenario(PAPER, seed);
        let s = survey(&sc, dir.path());
        // The user's t0 is 0.3 s off, the period the nominal 1/33 s (66 ppm off).
        let o = options(&s, 0.3);
        let r = estimate(&s.traj, &s.sensor, &s.file, &s.targets, &o).unwrap();
        let refined = r.refined.as_ref().unwrap().clock;
        let (t0, t) = (s.true_t0_s, s.true_period_s);
        pe0.push(r.paper.t0_s - t0);
        pe1.push(r.paper.period_s - t);
        ps0.push(r.paper.sigma_t0_s);
        ps1.push(r.paper.sigma_period_s);
        re0.push(refined.t0_s - t0);
        re1.push(refined.period_s - t);
        rs0.push(refined.sigma_t0_s);
        rs1.push(refined.sigma_period_s);
        z0.push((refined.t0_s - t0) / refined.sigma_t0_s);
        z1.push((refined.period_s - t) / refined.sigma_period_s);
        let crb = cramer_rao_bound(&s.traj, &s.sensor, &s.targets, &r, &o, (t0, t), None).unwrap();
        crb0.push(crb[(0, 0)]);
        crb1.push(crb[(1, 1)]);
        // Georeferenced target returns after sync: their mean distance to the surveyed plane
        // against 2 sigma of the trajectory's stated accuracy (SMRMSG) and the survey.
        for sg in r
            .sightings
            .iter()
            .filter(|g| g.status == SightingStatus::Accepted)
        {
            sightings += 1;
            let tg = s.targets.iter().find(|t| t.id == sg.target).unwrap();
            let n = tg.normal_e.unwrap();
            let mut cur = PoseCursor::new(&s.traj, 0.0, 0.0);
            let mut sum = 0.0;
            for ret in &sg.returns {
                let time = refined.t0_s
                    + refined.period_s * (ret.profile as f64 + o.mirror.fraction(ret.beta_rad));
                let pose = cur.at(time).unwrap();
                let x = georeference(
                    &pose,
                    &s.sensor,
                    &point_s(&s.sensor, ret.range_m, ret.alpha_rad, ret.beta_rad),
                );
                sum += n.dot(&(x - tg.centre_e_m));
            }
            let mean = sum / sg.returns.len() as f64;
            let mut sc_ = s.traj.sigma_cursor().unwrap();
            let sig = sc_.at(sg.crossing_time_s).unwrap();
            let horiz = crate::common::max_of([sig.pos_ned_m.x, sig.pos_ned_m.y]);
            let bound = 2.0 * (horiz * horiz + tg.sigma_m * tg.sigma_m).sqrt();
            total += 1;
            within += (mean.abs() <= bound) as usize;
        }
    }
    let crb_s0 = (crb0.iter().sum::<f64>() / crb0.len() as f64).sqrt();
    let crb_s1 = (crb1.iter().sum::<f64>() / crb1.len() as f64).sqrt();
    eprintln!(
        "paper: t0 err rms {:.3e} s (pred {:.3e}), T err rms {:.3e} s (pred {:.3e}), max |T err| {:.3e}",
        rms(&pe0), rms(&ps0), rms(&pe1), rms(&ps1), crate::common::max_abs(pe1.iter().copied())
    );
    eprintln!(
        "refined: t0 err std {:.3e} (pred {:.3e}, CRB {:.3e}), T err std {:.3e} (pred {:.3e}, CRB {:.3e})",
        std(&re0), rms(&rs0), crb_s0, std(&re1), rms(&rs1), crb_s1
    );
    eprintln!(
        "ratio paper/refined: t0 {:.2}, T {:.2}; z std t0 {:.3}, T {:.3}; plane within 2 sigma {within}/{total} ({sightings} sightings)",
        rms(&pe0) / rms(&re0), rms(&pe1) / rms(&re1), std(&z0), std(&z1)
    );
    // Paper's class: the paper's period differed from the laboratory's by 2e-6 s.
    assert!(rms(&pe1) < 2e-6, "paper T error rms {:.3e}", rms(&pe1));
    // Its predicted sigma (uniform profile quantisation + navigation) is honest within 2x both
    // ways (error rms / predicted: measured 1.19 for t0, 1.03 for T); one-sided, a sigma 100x
    // too large would pass.
    for (err, pred) in [(rms(&pe0), rms(&ps0)), (rms(&pe1), rms(&ps1))] {
        let ratio = err / pred;
        assert!(
            (0.5..=2.0).contains(&ratio),
            "error rms / predicted sigma {ratio}"
        );
    }
    // Refined at least 5x more precise than the paper's method on the same data.
    assert!(rms(&pe0) / rms(&re0) >= 5.0 && rms(&pe1) / rms(&re1) >= 5.0);
    // Empirical std within 25% of the Cramer-Rao bound (2.5 sampling sigmas, see SEEDS).
    for (e, b) in [(std(&re0), crb_s0), (std(&re1), crb_s1)] {
        assert!(
            (e / b - 1.0).abs() <= 0.25,
            "empirical {e:.3e} vs CRB {b:.3e}"
        );
    }
    for z in [std(&z0), std(&z1)] {
        assert!((0.8..=1.25).contains(&z), "normalised error std {z:.3}");
    }
    // Every plate passage of every seed is a sighting: 4 plates x 2 passes x SEEDS = 400
    // (measured 400); at least 380 (a sighting rejected now and then), so the rate below is
    // not one of nothing.
    assert!(total >= 380, "{total} accepted sightings of 400");
    // 2 sigma holds for 95.45% of Gaussian samples: >= 90% is >= 360 of 400, failed by an
    // honest sigma with probability 1.5e-6 (binomial); measured 384/400.
    assert!(
        within as f64 >= 0.9 * total as f64,
        "{within}/{total} within 2 sigma"
    );
}
