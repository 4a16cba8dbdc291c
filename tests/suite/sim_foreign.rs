//! Foreign returns on the reference patches (`scene.foreign_share`, docs/simulator.md
//! "Foreign returns"): the share of the listed patches' returns that come from foreign things
//! is the configured one within a factor 1.5, the foreign returns sit where the things are
//! (0.1-1 m in front of a facade, at most 0.15 m above a ground square, nearer at their
//! mixed edges), and the default adds nothing. The foreign returns are found twice: by the
//! simulator (`truth.json` `foreign`) and here from the truth points alone (inside a patch's
//! rectangle, off its plane by more than 1 mm and at most 1.05 m): the two counts agree.
//!
//! Tolerance: the factor 1.5 asked of the simulator. At 2e-3 the base survey's 15,761 patch
//! returns take about 44 foreign ones (measured: 44, ratio 1.40), so the factor there is
//! about 2 Poisson sds and the case checks mostly placement and the count; at 1e-2 (207,
//! ratio 1.31) it is about 4 sds. Both ratios sit above 1: the measured share runs high on
//! this small survey (docs/simulator.md gives 0.59-2.35 on single seeds of larger ones).

use crate::sim_support;
use kinescan::io::patches::read_patches;
use kinescan::sim::read_truth_points;
use nalgebra::Vector3;
use sim_support::*;
use std::path::Path;

/// Margin inside a patch's edges (m), the diagnosis' default `edge_margin_m`.
const EDGE_M: f64 = 0.1;

/// Returns on the listed patches, seen from the truth points: (on patches, off-plane
/// distances of the foreign ones on facades, those on ground squares).
fn classify(dir: &Path) -> (usize, Vec<f64>, Vec<f64>) {
    let patches = read_patches(&dir.join("patches.csv")).unwrap();
    let centres: Vec<Vector3<f64>> = patches.iter().map(|p| p.centre_ecef()).collect();
    let (mut on, mut facade, mut ground) = (0, vec![], vec![]);
    for x in read_truth_points(&dir.join("truth_points.bin")).unwrap() {
        if x[0].is_nan() {
            continue;
        }
        let x = Vector3::from(x);
        for (p, c) in patches.iter().zip(&centres) {
            let reach = p.half_length_m.hypot(p.half_height_m) + 1.1;
            if (x - c).norm() > reach {
                continue;
            }
            let q = p.patch_coords_m(&x);
            // Inside the rectangle shrunk by the diagnosis' edge margin (0.1 m): at a sloped
            // facade's bottom edge the walk in front rises a centimetre into the rectangle.
            let (hl, hh) = (p.half_length_m - EDGE_M, p.half_height_m - EDGE_M);
            if q.x.abs() > hl || q.y.abs() > hh || q.z.abs() > 1.05 {
                continue;
            }
            on += 1;
            if q.z.abs() > 1e-3 {
                if p.id.starts_with("GND") {
                    ground.push(q.z);
                } else {
                    facade.push(q.z);
                }
            }
            break;
        }
    }
    (on, facade, ground)
}

#[test]
fn foreign_returns_take_their_share_of_the_patches_where_the_things_stand() {
    for share in [0.0, 2e-3, 1e-2] {
        let mut sc = base();
        sc.scene.foreign_share = share;
        // Tree crowns reach within 0.5 m of the facades: foreign too, but not the things.
        sc.scene.trees_per_side = 0;
        let dir = tempfile::tempdir().unwrap();
        run(&sc, dir.path(), 2);
        let (on, facade, ground) = classify(dir.path());
        let text = std::fs::read_to_string(dir.path().join("truth.json")).unwrap();
        let truth: serde_json::Value = serde_json::from_str(&text).unwrap();
        let found = facade.len() + ground.len();
        println!(
            "foreign_share {share}: {found} foreign of {on} on patches ({} facade, {} ground)",
            facade.len(),
            ground.len()
        );
        if share == 0.0 {
            assert_eq!(found, 0, "foreign returns without foreign_share");
            assert!(truth.get("foreign").is_none(), "truth.json has `foreign`");
            continue;
        }
        let f = &truth["foreign"];
        let counted = f["summary"]["foreign_returns"].as_u64().unwrap() as usize;
        let measured = f["measured_share"].as_f64().unwrap();
        println!(
            "  truth.json: {counted} foreign, measured share {measured:.5}, mixed {}",
            f["summary"]["mixed_returns"]
        );
        // The simulator counts every hit on a thing; from the truth points, a hit on a
        // stone's side within 1 mm of the ground looks like the ground's own, and a mixed
        // return at an oblique beam may project into the edge margin: a few percent at most.
        assert!(
            found.abs_diff(counted) <= 2 + counted / 10,
            "foreign returns: {found} found from the truth points, {counted} counted"
        );
        let ratio = found as f64 / on as f64 / share;
        assert!(
            ratio > 1.0 / 1.5 && ratio < 1.5,
            "share {share}: measured {} (ratio {ratio})",
            found as f64 / on as f64
        );
        assert!(
            (measured / share - ratio).abs() < 0.1 * ratio,
            "truth.json share {measured}"
        );
        // Facade things' street faces stand 0.1-1 m off the wall, their sides and mixed
        // edges nearer; stones 0.05-0.15 m high on the ground. Exact truth points: no noise.
        let front = facade
            .iter()
            .filter(|z| (0.1 - 1e-9..=1.0 + 1e-9).contains(*z))
            .count();
        assert!(
            facade.iter().all(|z| *z > 0.0 && *z <= 1.0 + 1e-9),
            "facade foreign off the plane outside (0, 1] m"
        );
        assert!(
            front * 2 > facade.len(),
            "only {front} of {} facade foreign returns 0.1-1 m off the wall",
            facade.len()
        );
        assert!(
            ground.iter().all(|z| *z > 0.0 && *z <= 0.15 + 1e-9),
            "ground foreign off the plane outside (0, 0.15] m"
        );
    }
}
