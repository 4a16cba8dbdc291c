//! COPC output read back by an independent reader, the `las` crate's `CopcReader` (its
//! hierarchy parser and LASzip decompression; not our code): every record of the LAS is in
//! exactly one octree node, byte for byte, and every node's points lie inside its cube. Set
//! `KINESCAN_COPC_OUT=/dir` to keep `cloud.las` and `cloud.copc.laz` (and the pipeline's pair)
//! for `python3 tests/laz_check.py --copc` (laspy's CopcReader, run in CI).

use std::path::Path;

use kinescan::io::copc::write_copc;
use las::copc::CopcReader;

/// Reads `copc` with the las crate and checks it against the LAS file `las`: the records of all
/// nodes are the LAS's records (as multisets of bytes), each node's points inside its bounds.
/// Returns the number of nodes and the deepest level.
fn check_against_las(las_path: &Path, copc_path: &Path) -> (usize, i32) {
    let las = std::fs::read(las_path).unwrap();
    let at = u32::from_le_bytes(las[96..100].try_into().unwrap()) as usize;
    let len = usize::from(u16::from_le_bytes([las[105], las[106]]));
    let mut expected: Vec<&[u8]> = las[at..].chunks(len).collect();
    let mut reader = CopcReader::from_path(copc_path).unwrap();
    let info = reader.header().copc_info_vlr().expect("copc info VLR");
    let entries: Vec<_> = reader.hierarchy_entries().collect();
    let mut got: Vec<Vec<u8>> = Vec::new();
    let mut deepest = 0;
    for e in &entries {
        let data = reader.read_entry(e).unwrap();
        assert_eq!(data.len(), e.point_count as usize, "{:?}", e.key);
        let b = e.key.bounds(&info);
        for p in data.points() {
            let p = p.unwrap();
            let inside = |v: f64, lo: f64, hi: f64| v >= lo - 1e-6 && v <= hi + 1e-6;
            assert!(
                inside(p.x, b.min.x, b.max.x)
                    && inside(p.y, b.min.y, b.max.y)
                    && inside(p.z, b.min.z, b.max.z),
                "point ({}, {}, {}) outside node {:?} {b:?}",
                p.x,
                p.y,
                p.z,
                e.key
            );
        }
        got.extend(data.raw_bytes().chunks(len).map(<[u8]>::to_vec));
        deepest = deepest.max(e.key.l);
    }
    assert_eq!(got.len(), expected.len(), "points in the hierarchy");
    got.sort();
    expected.sort();
    assert!(
        got.iter().zip(&expected).all(|(a, b)| a.as_slice() == *b),
        "the nodes' records are not the LAS's"
    );
    (entries.len(), deepest)
}

/// 150,000 points of a 30 m wide, 1.5 km long strip, leaves of at most 2,000 points: an
/// octree of several levels.
#[test]
fn copc_holds_every_las_record_once_in_its_node() {
    let dir = tempfile::tempdir().unwrap();
    let (las, copc) = (
        dir.path().join("cloud.las"),
        dir.path().join("cloud.copc.laz"),
    );
    crate::laz_output::write_las(&las, 150_000);
    let summary = write_copc(&las, &copc, 2_000).unwrap();
    assert_eq!(summary.point_count, 150_000);
    let (nodes, deepest) = check_against_las(&las, &copc);
    eprintln!("{nodes} nodes, deepest level {deepest}");
    assert!(
        nodes > 8 && deepest >= 3,
        "{nodes} nodes, deepest level {deepest}"
    );
    let again = dir.path().join("again.copc.laz");
    write_copc(&las, &again, 2_000).unwrap();
    assert_eq!(
        std::fs::read(&copc).unwrap(),
        std::fs::read(&again).unwrap()
    );
    if let Some(keep) = std::env::var_os("KINESCAN_COPC_OUT") {
        std::fs::copy(&las, Path::new(&keep).join("cloud.las")).unwrap();
        std::fs::copy(&copc, Path::new(&keep).join("cloud.copc.laz")).unwrap();
    }
}

/// `output.format = "copc"`: the run publishes `<stem>.copc.laz` (no LAS beside it) holding
/// the LAS the same run writes with `format = "las"`.
#[test]
fn pipeline_writes_copc_holding_the_same_las() {
    let (f, report) = crate::laz_output::run_las_and(60_000, "copc", "octree");
    let out = f.dir.path().join("out");
    assert!(!out.join("octree.las").exists(), "the LAS is not published");
    let (las, copc) = (out.join("cloud.las"), out.join("octree.copc.laz"));
    assert_eq!(report.outputs.len(), 1);
    assert_eq!(report.outputs[0].path, copc);
    assert_eq!(
        report.outputs[0].bytes,
        std::fs::metadata(&copc).unwrap().len()
    );
    check_against_las(&las, &copc);
    if let Some(keep) = std::env::var_os("KINESCAN_COPC_OUT") {
        std::fs::copy(&las, Path::new(&keep).join("pipeline.las")).unwrap();
        std::fs::copy(&copc, Path::new(&keep).join("pipeline.copc.laz")).unwrap();
    }
}
