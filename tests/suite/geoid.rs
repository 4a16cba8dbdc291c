//! Geoid grids against PROJ: the committed synthetic test grid, as GTX and as GeoTIFF, gives
//! the orthometric heights pyproj's vgridshift gives with the same files
//! (tests/oracle/geoid_oracle.csv, checked in CI by make_geoid_oracle.py) to <= 1 mm.

use std::path::Path;

use kinescan::geo::geoid::GeoidGrid;

fn grid(name: &str) -> GeoidGrid {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name);
    GeoidGrid::open(&path).unwrap()
}

#[test]
fn geoid_heights_match_pyproj_for_gtx_and_geotiff() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/oracle/geoid_oracle.csv");
    let text = std::fs::read_to_string(path).unwrap();
    let (gtx, tif) = (grid("geoid_test.gtx"), grid("geoid_test.tif"));
    assert_eq!(gtx.extent(), tif.extent());
    let (mut worst, mut n) = (0.0, 0);
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        let (lat, lon, h) = (v[0].to_radians(), v[1].to_radians(), v[2]);
        for (g, oracle) in [(&gtx, v[3]), (&tif, v[4])] {
            let big_h = h - g.undulation_m(lat, lon).expect("inside the grid");
            crate::common::raise_max(&mut worst, (big_h - oracle).abs());
        }
        n += 1;
    }
    println!("{n} points, worst |H - H_pyproj| = {worst:.2e} m");
    assert!(n >= 300);
    // 1 mm is the acceptance bound; the oracle prints 0.1 um.
    assert!(worst <= 1e-3, "worst {worst} m");
}

#[test]
fn outside_the_grid_has_no_undulation() {
    let g = grid("geoid_test.gtx");
    let e = g.extent();
    let inside = (e.south_deg + 0.1, e.west_deg + 0.1);
    let n = |lat: f64, lon: f64| g.undulation_m(lat.to_radians(), lon.to_radians());
    assert!(n(inside.0, inside.1).is_some());
    assert!(n(e.south_deg - 0.01, inside.1).is_none());
    assert!(n(e.north_deg + 0.01, inside.1).is_none());
    assert!(n(inside.0, e.west_deg - 0.01).is_none());
    assert!(n(inside.0, e.east_deg + 0.01).is_none());
    let err = GeoidGrid::open(Path::new("no/such/grid.gtx")).unwrap_err();
    assert!(err.to_string().contains("no/such/grid.gtx"), "{err}");
}
