//! The day's outputs merged from the unit outputs, in plan order (so the bytes do not depend
//! on the order units finished): one LAS per pass, or one per tile of the output frame. Every
//! file goes through a [`LasSink`] into a staging folder ([`OutputSet`]).

use super::config::{Layout, LoadedDay};
use super::plan::{pass_pipeline, Plan};
use super::quality::{SigmaHistograms, SigmaOffsets, SigmaStats};
use super::units::unit_path;
use crate::io::las::{stats_of_records, LasSummary};
use crate::io::laz::LasLayout;
use crate::io::publish::OutputSet;
use crate::pipeline::prepare::{map_frame, open_geoid, open_trajectory};
use crate::pipeline::schema::OutputSchema;
use crate::pipeline::write::{into_format, LasSink, SinkSettings};
use crate::{Error, Result};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Writes the day's LAS files into `set`'s staging folders (compressed when the template's
/// `output.format` says so); gives their summaries (staged paths), in file-name order.
pub fn merge(
    day: &LoadedDay,
    plan: &Plan,
    set: &mut OutputSet,
) -> Result<(Vec<LasSummary>, Vec<SigmaStats>)> {
    let out = &day.config.day.out;
    let mut sinks: BTreeMap<PathBuf, LasSink> = BTreeMap::new();
    let mut by_pass = vec![SigmaHistograms::default(); day.config.passes.len()];
    let mut tile_sigma: BTreeMap<String, SigmaHistograms> = BTreeMap::new();
    let offsets = SigmaOffsets::of(&OutputSchema::new(&day.template.config));
    let first = pass_pipeline(day, 0, &out.join("x.las"));
    let traj = open_trajectory(&first.config)?;
    let frame = map_frame(&first.config.output.frame, &traj)?;
    let geoid = open_geoid(&first, &traj)?;
    for unit in &plan.units {
        let path = unit_path(out, &unit.id);
        let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
        let layout = LasLayout::of(&bytes).map_err(|p| Error::bad_file(&path, p))?;
        let records = &bytes[layout.offset_to_points..];
        let pass = &day.config.passes[unit.pass].name;
        if let Some(at) = offsets {
            by_pass[unit.pass].add_records(records, layout.record_len, at);
        }
        let groups: Vec<(String, Cow<[u8]>)> = match day.config.day.layout {
            Layout::PerPass => vec![(format!("{pass}.las"), Cow::Borrowed(records))],
            Layout::Tiles { size_m } => by_tile(records, &bytes, layout.record_len, size_m),
        };
        for (name, part) in groups {
            let part = &*part;
            let staged = set.stage(&out.join(&name))?;
            if !sinks.contains_key(&staged) {
                let c = pass_pipeline(day, unit.pass, &staged).config;
                let schema = OutputSchema::new(&c);
                let settings = SinkSettings::new(&c, &schema, &frame, geoid.as_ref(), &traj)?;
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
    let mut summaries = Vec::new();
    for (_, sink) in sinks {
        summaries.extend(sink.finish()?);
    }
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
