//! The parallel executor of stages 4 and 5 (georeference, write): chunks of memory-mapped
//! returns are georeferenced with rayon and written in input order by a writer thread, so the
//! output bytes do not depend on the number of threads.

use super::config::Strictness;
use super::georeference::ReturnGeoreferencer;
use super::point_batch::PointBatch;
use super::prepare::PreparedInput;
use super::report::{FileRecord, InputReport, RejectReason, ReturnCounts};
use super::schema::PointFill;
use super::write::LasSink;
use crate::io::counters::CounterTracker;
use crate::io::digest::hex;
use crate::io::las::{ChunkStats, PointLayout};
use crate::io::profiles::ProfileFile;
use crate::{Error, Result};
use rayon::prelude::*;
use sha2::{Digest, Sha256};
use std::ops::Range;

/// The result of one chunk of returns: its LAS records, already encoded.
struct ChunkOut {
    records: Vec<u8>,
    stats: ChunkStats,
    counts: [u64; RejectReason::ALL.len()],
    first_reject: Option<(usize, RejectReason)>,
    counters: CounterTracker,
    time_span_s: Option<(f64, f64)>,
}

/// Georeferences the returns `range` of `file` into encoded records.
fn chunk(
    geo: &ReturnGeoreferencer,
    fill: &PointFill,
    file: &ProfileFile,
    range: Range<usize>,
    layout: &PointLayout,
    pool: &BufferPool,
) -> Result<ChunkOut> {
    let mut records = pool.take();
    records.reserve(range.len() * layout.record_len());
    let mut out = ChunkOut {
        records,
        stats: ChunkStats::empty(layout.record_len()),
        counts: [0; RejectReason::ALL.len()],
        first_reject: None,
        counters: CounterTracker::default(),
        time_span_s: None,
    };
    let mut cursors = geo.cursors();
    let mut batch = PointBatch::new(geo);
    let (mut t_min, mut t_max) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in range {
        let r = file.get(i);
        if out.counters.add(i as u64, r.profile) == crate::io::counters::CounterStep::Decrease {
            break;
        }
        match geo.georeference(&r, &mut cursors) {
            Ok(g) => {
                batch.push((&r, i, &g), fill, geo, &mut cursors);
                if batch.is_full() {
                    let stats = batch.flush(fill, geo, layout, file, &mut out.records)?;
                    out.stats.merge(&stats);
                }
                t_min = t_min.min(g.t_s);
                t_max = t_max.max(g.t_s);
            }
            Err(reason) => {
                out.counts[reason.index()] += 1;
                out.first_reject.get_or_insert((i, reason));
            }
        }
    }
    let stats = batch.flush(fill, geo, layout, file, &mut out.records)?;
    out.stats.merge(&stats);
    if t_min <= t_max {
        out.time_span_s = Some((t_min, t_max));
    }
    Ok(out)
}

/// Record buffers handed back by the writer for reuse: a fresh multi-megabyte buffer per chunk
/// costs a page fault and a page clear per 4 KiB, more than writing it.
#[derive(Default)]
struct BufferPool(std::sync::Mutex<Vec<Vec<u8>>>);

impl BufferPool {
    fn take(&self) -> Vec<u8> {
        self.0
            .lock()
            .map(|mut v| v.pop())
            .ok()
            .flatten()
            .unwrap_or_default()
    }

    fn give(&self, mut buf: Vec<u8>) {
        buf.clear();
        if let Ok(mut v) = self.0.lock() {
            v.push(buf);
        }
    }
}

/// A batch of chunk results, in input order.
type Batch = Vec<(Range<usize>, Result<ChunkOut>)>;

/// Chunks written but not yet tapped: bounds the mapped input pages still resident.
const TAP_QUEUE_CHUNKS: usize = 16;

/// What the third thread of a pass over a profile file does with each chunk once written.
pub enum Tap<'a> {
    /// Hashes the profile file as read (its header, then the records processed): the input's
    /// SHA-256 in the run report.
    HashInput,
    /// Hands each chunk's encoded LAS records, in output order, to this function (a day's work
    /// unit digests its output and fills its sigma histograms there); the input is not hashed.
    Records(&'a mut (dyn FnMut(&[u8]) + Send)),
}

/// Georeferences one profile file into `sink`, hashing it for the report.
pub fn process_input(
    geo: &ReturnGeoreferencer,
    fill: &PointFill,
    input: &PreparedInput,
    opts: &super::RunOptions,
    strictness: Strictness,
    sink: &mut LasSink,
    bar: &indicatif::ProgressBar,
) -> Result<InputReport> {
    let all = 0..input.file.len();
    let (acc, sha256) = execute(
        geo,
        fill,
        input,
        all,
        opts,
        strictness,
        sink,
        bar,
        Tap::HashInput,
    )?;
    acc.finish(input, sha256.unwrap_or_default())
}

/// Georeferences the records `records` of one profile file into `sink` (a day's work unit),
/// handing the encoded records to `on_records` as they are written; gives the returns' counts.
#[allow(clippy::too_many_arguments)]
pub fn process_records(
    geo: &ReturnGeoreferencer,
    fill: &PointFill,
    input: &PreparedInput,
    records: Range<usize>,
    opts: &super::RunOptions,
    strictness: Strictness,
    sink: &mut LasSink,
    on_records: &mut (dyn FnMut(&[u8]) + Send),
) -> Result<ReturnCounts> {
    let hidden = indicatif::ProgressBar::hidden();
    let tap = Tap::Records(on_records);
    let (acc, _) = execute(
        geo, fill, input, records, opts, strictness, sink, &hidden, tap,
    )?;
    Ok(acc.counts)
}

/// Georeferences the records `records` of one profile file into `sink`. Batches of chunks are
/// computed in parallel on the pool while a writer thread absorbs the previous batch (counts,
/// checks, LAS), so writing overlaps computing; results are absorbed strictly in input order.
/// A third thread does `tap`'s work on the written chunks (the input's SHA-256, or the
/// caller's use of the records) and releases their input pages, so it is off the writer's
/// path. Gives the writer's account and the input's SHA-256 (with [`Tap::HashInput`]).
#[allow(clippy::too_many_arguments)]
fn execute<'f>(
    geo: &ReturnGeoreferencer,
    fill: &PointFill,
    input: &'f PreparedInput,
    records: Range<usize>,
    opts: &super::RunOptions,
    strictness: Strictness,
    sink: &mut LasSink,
    bar: &indicatif::ProgressBar,
    tap: Tap,
) -> Result<(FileAccumulator<'f>, Option<String>)> {
    let file = &input.file;
    let n = records.end.min(file.len());
    let chunk_len = opts.chunk_returns.max(1);
    let batch = chunk_len * rayon::current_num_threads() * 8;
    let layout = sink.layout().clone();
    let (tx, rx) = std::sync::mpsc::sync_channel::<Batch>(1);
    let mut acc = FileAccumulator::new(file, strictness);
    let pool = BufferPool::default();
    let keep_records = matches!(tap, Tap::Records(_));
    let (tap_tx, tap_rx) = std::sync::mpsc::sync_channel::<Written>(TAP_QUEUE_CHUNKS);
    let sha256 = std::thread::scope(|scope| {
        let tapper = scope.spawn(|| run_tap(file, tap, tap_rx, &pool));
        let writer = scope.spawn(|| -> Result<()> {
            let tap_tx = tap_tx; // moved in: dropping it ends the tap
            for batch in rx {
                for (r, out) in batch {
                    let records = acc.absorb(r.clone(), out, sink, bar)?;
                    let records = if keep_records {
                        Some(records)
                    } else {
                        pool.give(records);
                        None
                    };
                    let _ = tap_tx.send((r, records)); // the tap stops only with the run
                }
            }
            Ok(())
        });
        for batch_start in (records.start..n).step_by(batch) {
            let batch_end = (batch_start + batch).min(n);
            let ranges: Vec<_> = (batch_start..batch_end)
                .step_by(chunk_len)
                .map(|s| s..(s + chunk_len).min(batch_end))
                .collect();
            let outs: Batch = ranges
                .into_par_iter()
                .map(|r| (r.clone(), chunk(geo, fill, file, r, &layout, &pool)))
                .collect();
            if tx.send(outs).is_err() {
                break; // the writer stopped on an error, reported below
            }
        }
        drop(tx);
        writer.join().expect("writer thread panicked")?;
        Ok::<_, Error>(tapper.join().expect("tap thread panicked"))
    })?;
    Ok((acc, sha256))
}

/// A chunk written: its input records, and its encoded LAS records when the tap takes them.
type Written = (Range<usize>, Option<Vec<u8>>);

/// The tap's thread: per written chunk, in order, `tap`'s work, then the chunk's input pages
/// released and its record buffer given back. Gives the input's SHA-256 (hex) with
/// [`Tap::HashInput`].
fn run_tap(
    file: &ProfileFile,
    mut tap: Tap,
    chunks: std::sync::mpsc::Receiver<Written>,
    pool: &BufferPool,
) -> Option<String> {
    let mut hasher = matches!(tap, Tap::HashInput).then(|| {
        let mut h = Sha256::new();
        h.update(file.header_bytes());
        h
    });
    for (r, records) in chunks {
        if let Some(h) = &mut hasher {
            h.update(file.record_bytes(r.clone()));
        }
        if let (Tap::Records(on_records), Some(records)) = (&mut tap, records) {
            on_records(&records);
            pool.give(records);
        }
        file.release(r);
    }
    hasher.map(|h| hex(&h.finalize()))
}

/// What the writer side learns about one profile file.
struct FileAccumulator<'f> {
    file: &'f ProfileFile,
    strictness: Strictness,
    counts: ReturnCounts,
    counters: CounterTracker,
    span: Option<(f64, f64)>,
}

impl<'f> FileAccumulator<'f> {
    fn new(file: &'f ProfileFile, strictness: Strictness) -> Self {
        FileAccumulator {
            file,
            strictness,
            counts: ReturnCounts::default(),
            counters: CounterTracker::default(),
            span: None,
        }
    }

    /// Takes one chunk's result in input order: checks, counts, writes its records; gives the
    /// emptied record buffer back for reuse.
    fn absorb(
        &mut self,
        r: Range<usize>,
        out: Result<ChunkOut>,
        sink: &mut LasSink,
        bar: &indicatif::ProgressBar,
    ) -> Result<Vec<u8>> {
        let path = self.file.path();
        // A chunk's error names the file and record already.
        let out = out?;
        self.counters.append(&out.counters);
        if let Some(d) = self.counters.first_decrease {
            let msg = format!(
                "profile counter decreases from {} to {}: counter wrap or reordered file",
                d.from, d.to
            );
            return Err(Error::bad_record(path, format!("record {}", d.at), msg));
        }
        if self.strictness == Strictness::Fail {
            if let Some((i, reason)) = out.first_reject {
                let msg = format!("{} (output.strictness = \"fail\")", reason.describe());
                return Err(Error::bad_record(path, format!("record {i}"), msg));
            }
        }
        self.counts
            .add_chunk(r.len() as u64, out.stats.count, &out.counts);
        if let Some((a, b)) = out.time_span_s {
            self.span = Some(self.span.map_or((a, b), |(x, y)| (x.min(a), y.max(b))));
        }
        sink.write(&out.records, &out.stats)?;
        bar.inc(r.len() as u64);
        Ok(out.records)
    }

    /// The input's report, `sha256` being the hex digest of the file as read.
    fn finish(self, input: &PreparedInput, sha256: String) -> Result<InputReport> {
        let c = self.counts;
        assert_eq!(
            c.read,
            c.written + c.rejected_total(),
            "every return read is written or rejected"
        );
        let path = self.file.path();
        let record = if input.original != path {
            FileRecord::of("profiles", &input.original)?
        } else {
            let bytes = std::fs::metadata(path)
                .map_err(|e| Error::io(path, e))?
                .len();
            FileRecord {
                role: "profiles".into(),
                path: path.into(),
                bytes,
                sha256,
            }
        };
        let t = self.counters;
        Ok(InputReport {
            file: record,
            point_source_id: input.point_source_id,
            counts: c,
            profile_range: t.first_profile.zip(t.last_profile),
            counter_jumps: t.jump_count,
            counter_jump_examples: t.jumps.iter().map(|j| (j.at, j.from, j.to)).collect(),
            time_span_s: self.span,
        })
    }
}
