//! The day's outputs merged from the unit outputs, in plan order (so the bytes do not depend
//! on the order units finished): one LAS per pass, or one per tile of the output frame, staged
//! in an [`OutputSet`]. A pass that is one unit is its unit's file, staged without a copy
//! ([`OutputSet::stage_file`]); every other file goes through a [`LasSink`]. The sigma
//! statistics per pass come from the units' journalled histograms, per tile from the records
//! as they are split.

use super::config::{Layout, LoadedDay};
use super::journal::Entry;
use super::plan::{pass_pipeline, Plan};
use super::quality::{SigmaHistograms, SigmaOffsets, SigmaStats};
use super::units::unit_path;
use crate::io::las::{stats_of_records, LasSummary};
use crate::io::laz::map_las;
use crate::io::publish::OutputSet;
use crate::pipeline::prepare::{map_frame, open_geoid, open_trajectory};
use crate::pipeline::schema::OutputSchema;
use crate::pipeline::write::{into_format, LasSink, SinkSettings};
use crate::Result;
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Writes the day's LAS files into `set`'s staging folders (compressed when the template's
/// `output.format` says so) from the unit files `done` (the one standing for each unit of
/// `plan`: its own, or its corrected re-run's); gives their
/// summaries (staged paths), in file-name order, and the sigma statistics.
pub fn merge(
    day: &LoadedDay,
    plan: &Plan,
    done: &BTreeMap<String, Entry>,
    set: &mut OutputSet,
) -> Result<(Vec<LasSummary>, Vec<SigmaStats>)> {
    let out = &day.config.day.out;
    let mut by_pass = vec![SigmaHistograms::default(); day.config.passes.len()];
    for unit in &plan.units {
        by_pass[unit.pass].merge(&done[&unit.id].sigma);
    }
    let mut summaries = Vec::new();
    let mut sinks: BTreeMap<PathBuf, LasSink> = BTreeMap::new();
    let mut tile_sigma: BTreeMap<String, SigmaHistograms> = BTreeMap::new();
    let offsets = SigmaOffsets::of(&OutputSchema::new(&day.template.config));
    let units_of = |pass: usize| plan.units.iter().filter(|u| u.pass == pass).count();
    let mut sink_settings = None;
    for unit in &plan.units {
        let path = unit_path(out, &done[&unit.id].unit);
        let pass = &day.config.passes[unit.pass].name;
        if day.config.day.layout == Layout::PerPass && units_of(unit.pass) == 1 {
            // The pass is this unit's file, byte for byte: staged by a hard link.
            let staged = set.stage_file(&out.join(format!("{pass}.las")), &path)?;
            let las = done[&unit.id].las.clone();
            summaries.push(LasSummary {
                path: staged,
                ..las
            });
            continue;
        }
        let (map, layout) = map_las(&path)?;
        let records = &map[layout.offset_to_points..];
        let groups: Vec<(String, Cow<[u8]>)> = match day.config.day.layout {
            Layout::PerPass => vec![(format!("{pass}.las"), Cow::Borrowed(records))],
            Layout::Tiles { size_m } => by_tile(records, &map, layout.record_len, size_m),
        };
        for (name, part) in groups {
            let part = &*part;
            let staged = set.stage(&out.join(&name))?;
            if !sinks.contains_key(&staged) {
                if sink_settings.is_none() {
                    sink_settings = Some(SinkFrame::open(day)?);
                }
                let f = sink_settings.as_ref().expect("opened above");
                let c = pass_pipeline(day, unit.pass, &staged).config;
                let schema = OutputSchema::new(&c);
                let settings = SinkSettings::new(&c, &schema, &f.frame, f.geoid.as_ref(), &f.traj)?;
                sinks.insert(staged.clone(), LasSink::new(settings));
            }
            if let (Some(at), Layout::Tiles { .. }) = (offsets, &day.config.day.layout) {
                let stem = name.trim_end_matches(".las").to_string();
                let h = tile_sigma.entry(stem).or_default();
                h.add_records(part, layout.record_len, at);
            }
            let sink = sinks.get_mut(&staged).expect("inserted above");
            sink.write(part, &stats_of_records(part, sink.layout()))?;
        }
    }
    for (_, sink) in sinks {
        summaries.extend(sink.finish()?);
    }
    summaries.sort_by(|a, b| a.path.cmp(&b.path));
    let passes = day.config.passes.iter().zip(&by_pass);
    let mut sigma: Vec<SigmaStats> = passes
        .map(|(p, h)| h.stats(&format!("pass {}", p.name)))
        .collect();
    sigma.extend(tile_sigma.iter().map(|(tile, h)| h.stats(tile)));
    if offsets.is_none() {
        sigma.clear();
    }
    let summaries = into_format(day.template.config.output.format, summaries)?;
    Ok((summaries, sigma))
}

/// What a merged file's header is made from (the frame and offset of `kinescan run`'s).
struct SinkFrame {
    traj: crate::trajectory::Trajectory,
    frame: crate::geo::projection::MapFrame,
    geoid: Option<crate::geo::geoid::GeoidGrid>,
}

impl SinkFrame {
    fn open(day: &LoadedDay) -> Result<Self> {
        let first = pass_pipeline(day, 0, &day.config.day.out.join("x.las"));
        let traj = open_trajectory(&first.config)?;
        let frame = map_frame(&first.config.output.frame, &traj)?;
        let geoid = open_geoid(&first, &traj)?;
        Ok(SinkFrame { traj, frame, geoid })
    }
}

/// The records of a unit grouped by tile (`tile_<E>_<N>.las`, lower-left corner in m, tiles
/// in (E, N) order), each group in record order.
fn by_tile<'a>(
    records: &[u8],
    las: &[u8],
    record_len: usize,
    size_m: f64,
) -> Vec<(String, Cow<'a, [u8]>)> {
    let (scale, offset) = scale_offset(las);
    let mut tiles: BTreeMap<(i64, i64), Vec<u8>> = BTreeMap::new();
    for r in records.chunks_exact(record_len) {
        let coord = |axis: usize| {
            let raw = i32::from_le_bytes(r[4 * axis..4 * axis + 4].try_into().expect("4 bytes"));
            f64::from(raw) * scale[axis] + offset[axis]
        };
        let key = (
            (coord(0) / size_m).floor() as i64,
            (coord(1) / size_m).floor() as i64,
        );
        tiles.entry(key).or_default().extend_from_slice(r);
    }
    let corner = |k: i64| k as f64 * size_m;
    tiles
        .into_iter()
        .map(|((e, n), part)| {
            (
                format!("tile_{}_{}.las", corner(e), corner(n)),
                Cow::Owned(part),
            )
        })
        .collect()
}

/// Point scale and offset (m) of a LAS 1.4 file's header (bytes 131 to 179).
fn scale_offset(las: &[u8]) -> ([f64; 3], [f64; 3]) {
    let f = |i: usize| f64::from_le_bytes(las[i..i + 8].try_into().expect("8 bytes"));
    ([f(131), f(139), f(147)], [f(155), f(163), f(171)])
}
