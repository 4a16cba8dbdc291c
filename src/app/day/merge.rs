//! The day's outputs merged from the unit outputs, in plan order (so the bytes do not depend
//! on the order units finished): one LAS per pass, or one per tile of the output frame, staged
//! in an [`OutputSet`]. A pass whose units wrote their records into its file, one after
//! another, gets its header there ([`SinkSettings::finish_parts`]); a pass that is one unit in
//! its own file is that file, byte for byte. Both are staged without a copy
//! ([`OutputSet::stage_file`]); every other file goes through a [`LasSink`]. The sigma
//! statistics per pass come from the units' journalled histograms, per tile from the records
//! as they are split.

use super::config::{Layout, LoadedDay};
use super::journal::Entry;
use super::plan::{pass_pipeline, Plan};
use super::quality::{SigmaHistograms, SigmaOffsets, SigmaStats};
use super::units::{pass_file, unit_path};
use crate::io::las::{stats_of_records, LasSummary, PointLayout};
use crate::io::laz::map_las;
use crate::io::publish::OutputSet;
use crate::pipeline::prepare::{map_frame, open_geoid, open_trajectory};
use crate::pipeline::schema::OutputSchema;
use crate::pipeline::write::{into_format, LasSink, SinkSettings};
use crate::{Error, Result};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Writes the day's LAS files into `set`'s staging folders (compressed when the template's
/// `output.format` says so) from the unit outputs `done` (the one standing for each unit of
/// `plan`: its own, or its corrected re-run's), leaving out the passes `failed` names; gives
/// their
/// summaries (staged paths), in file-name order, and the sigma statistics.
pub fn merge(
    day: &LoadedDay,
    plan: &Plan,
    done: &BTreeMap<String, Entry>,
    failed: &[Option<String>],
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
    let mut frame = None;
    let per_pass = day.config.day.layout == Layout::PerPass;
    // Plan order: the passes in day-file order, each pass's units in order.
    for (pass, p) in day.config.passes.iter().enumerate() {
        if failed[pass].is_some() {
            continue;
        }
        let units: Vec<&Entry> = plan
            .units
            .iter()
            .filter(|u| u.pass == pass)
            .map(|u| &done[&u.id])
            .collect();
        let pass_las = out.join(format!("{}.las", p.name));
        let in_pass_file = !units.is_empty() && units.iter().all(|e| e.range.is_some());
        if per_pass && in_pass_file {
            // Its units' records are in its file, one after another: the header completes it.
            let file = pass_file(out, &p.name);
            let parts: Vec<LasSummary> = units.iter().map(|e| e.las.clone()).collect();
            let las = settings(day, pass, &file, &mut frame)?.finish_parts(&parts)?;
            let staged = set.stage_file(&pass_las, &file)?;
            summaries.push(LasSummary {
                path: staged,
                ..las
            });
            continue;
        }
        if let (true, [e]) = (per_pass, &units[..]) {
            // The pass is this unit's own file, byte for byte.
            let staged = set.stage_file(&pass_las, &unit_path(out, &e.unit))?;
            summaries.push(LasSummary {
                path: staged,
                ..e.las.clone()
            });
            continue;
        }
        let layout = settings(day, pass, &pass_las, &mut frame)?.layout().clone();
        for e in units {
            let (map, at) = records_of(out, e, &p.name)?;
            let records = &map[at];
            let groups: Vec<(String, Cow<[u8]>)> = match day.config.day.layout {
                Layout::PerPass => vec![(format!("{}.las", p.name), Cow::Borrowed(records))],
                Layout::Tiles { size_m } => by_tile(records, &layout, size_m),
            };
            for (name, part) in groups {
                let part = &*part;
                let staged = set.stage(&out.join(&name))?;
                if !sinks.contains_key(&staged) {
                    let settings = settings(day, pass, &staged, &mut frame)?;
                    sinks.insert(staged.clone(), LasSink::new(settings));
                }
                if let (Some(at), Layout::Tiles { .. }) = (offsets, &day.config.day.layout) {
                    let stem = name.trim_end_matches(".las").to_string();
                    let h = tile_sigma.entry(stem).or_default();
                    h.add_records(part, layout.record_len(), at);
                }
                let sink = sinks.get_mut(&staged).expect("inserted above");
                sink.write(part, &stats_of_records(part, sink.layout()))?;
            }
        }
    }
    for (_, sink) in sinks {
        summaries.extend(sink.finish()?);
    }
    summaries.sort_by(|a, b| a.path.cmp(&b.path));
    let passes = day.config.passes.iter().zip(&by_pass).zip(failed);
    let mut sigma: Vec<SigmaStats> = passes
        .filter(|(_, failed)| failed.is_none())
        .map(|(p, _)| p)
        .map(|(p, h)| h.stats(&format!("pass {}", p.name)))
        .collect();
    sigma.extend(tile_sigma.iter().map(|(tile, h)| h.stats(tile)));
    if offsets.is_none() {
        sigma.clear();
    }
    let summaries = into_format(day.template.config.output.format, summaries)?;
    Ok((summaries, sigma))
}

/// The settings of a LAS file `las` of pass `pass` (the frame opened on first use).
fn settings(
    day: &LoadedDay,
    pass: usize,
    las: &Path,
    frame: &mut Option<SinkFrame>,
) -> Result<SinkSettings> {
    let f = match frame {
        Some(f) => f,
        slot => slot.insert(SinkFrame::open(day)?),
    };
    let c = pass_pipeline(day, pass, las).config;
    let schema = OutputSchema::new(&c);
    SinkSettings::new(&c, &schema, &f.frame, f.geoid.as_ref(), &f.traj)
}

/// The unit output `e` (a unit of the pass named `pass`) mapped, and where its records are.
fn records_of(out: &Path, e: &Entry, pass: &str) -> Result<(memmap2::Mmap, Range<usize>)> {
    let Some([start, end]) = e.range else {
        let (map, layout) = map_las(&unit_path(out, &e.unit))?;
        let len = map.len();
        return Ok((map, layout.offset_to_points..len));
    };
    let file = pass_file(out, pass);
    let opened = std::fs::File::open(&file).map_err(|e| Error::io(&file, e))?;
    // SAFETY: read-only; pass files are written only by a process running the day in plan
    // order, which holds the output stem's lock, as the merge does.
    let map = unsafe { memmap2::Mmap::map(&opened) }.map_err(|e| Error::io(&file, e))?;
    let at = start as usize..end as usize;
    if map.len() < at.end {
        let problem = format!(
            "ends before the records of unit {} (bytes {start} to {end})",
            e.unit
        );
        return Err(Error::bad_file(file, problem));
    }
    Ok((map, at))
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

/// The records (of `layout`) of a unit grouped by tile (`tile_<E>_<N>.las`, lower-left corner
/// in m, tiles in (E, N) order), each group in record order.
fn by_tile<'a>(records: &[u8], layout: &PointLayout, size_m: f64) -> Vec<(String, Cow<'a, [u8]>)> {
    let mut tiles: BTreeMap<(i64, i64), Vec<u8>> = BTreeMap::new();
    for r in records.chunks_exact(layout.record_len()) {
        let coord = |axis: usize| {
            let raw = i32::from_le_bytes(r[4 * axis..4 * axis + 4].try_into().expect("4 bytes"));
            layout.coordinate_m(axis, raw)
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
