//! The journal of a day: `<out>/journal.jsonl`, one JSON line per finished work unit (the
//! digest and summary of its points, where they are, the unit's return counts and sigma
//! histograms), appended and fsynced once the unit's points are durable: its own file renamed
//! into place, or its records written into its pass's file. A restart trusts a line only when
//! the unit's points are there with the same digest; anything else is done again.

use super::quality::SigmaHistograms;
use crate::io::atomic::append_line_durably;
use crate::io::digest::hex;
use crate::io::las::LasSummary;
use crate::io::laz::map_las;
use crate::pipeline::report::ReturnCounts;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::os::unix::fs::FileExt;
use std::path::Path;

/// One finished unit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// Unit id (plan).
    pub unit: String,
    /// [`UnitDigest`] of its points, hex: of its own file (`units/<id>.las`), or of its
    /// records in its pass's file.
    pub sha256: String,
    /// Where its point records are in its pass's file (`units/<pass>.pass.las`, written in
    /// parts): first and one-past-last byte. None when they are in its own file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range: Option<[u64; 2]>,
    /// Its returns read, written and rejected by reason.
    pub counts: ReturnCounts,
    /// Seconds it took.
    pub seconds: f64,
    /// Its points (count, bounds) and its file: its own (`file_bytes` its size), or its
    /// pass's (`file_bytes` where its records end).
    pub las: LasSummary,
    /// Histograms of its points' sigmas (empty without `[uncertainty]`).
    pub sigma: SigmaHistograms,
}

/// Appends `entry` to the journal at `path`.
pub fn append(path: &Path, entry: &Entry) -> Result<()> {
    let line = serde_json::to_string(entry)
        .map_err(|e| Error::Invalid(format!("{}: JSON encoding: {e}", path.display())))?;
    append_line_durably(path, &line)
}

/// The journal's entries by unit (the last line of a unit wins); none without a journal. A
/// torn last line (a writer killed mid-line) is ignored; any other bad line is refused.
pub fn read(path: &Path) -> Result<BTreeMap<String, Entry>> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(BTreeMap::new()),
        Err(e) => return Err(Error::io(path, e)),
    };
    let whole = text.rfind('\n').map_or(0, |k| k + 1);
    let mut entries = BTreeMap::new();
    for (k, line) in text[..whole].lines().enumerate() {
        let entry: Entry = serde_json::from_str(line)
            .map_err(|e| Error::bad_record(path, format!("line {}", k + 1), e.to_string()))?;
        entries.insert(entry.unit.clone(), entry);
    }
    Ok(entries)
}

/// The SHA-256 of a unit's points that the journal holds: its point records, then (in its own
/// file) the file's header and VLRs. A unit hashes the records as they are written (off the
/// writer's path) and the header once the file is complete, so the file is not read again.
#[derive(Default)]
pub struct UnitDigest(Sha256);

impl UnitDigest {
    /// Adds point records, in file order.
    pub fn records(&mut self, bytes: &[u8]) {
        self.0.update(bytes);
    }

    /// The digest (hex), `head` being the file's bytes before its first point record (none
    /// for records in a pass's file).
    pub fn finish(mut self, head: &[u8]) -> String {
        self.0.update(head);
        hex(&self.0.finalize())
    }
}

/// [`UnitDigest`] of the unit file at `path`; none when it cannot be read as a LAS file.
pub fn file_digest(path: &Path) -> Option<String> {
    let (map, layout) = map_las(path).ok()?;
    let mut digest = UnitDigest::default();
    digest.records(&map[layout.offset_to_points..]);
    Some(digest.finish(&map[..layout.offset_to_points]))
}

/// [`UnitDigest`] of the records at bytes `range` of the pass file at `path`; none when the
/// file cannot be read or ends before. Read, not mapped: a `--unit` process verifies while
/// the process running the day in order may be writing the pass file.
pub fn part_digest(path: &Path, range: [u64; 2]) -> Option<String> {
    let file = std::fs::File::open(path).ok()?;
    let mut digest = UnitDigest::default();
    let mut buffer = vec![0u8; 4 << 20];
    let mut at = range[0];
    while at < range[1] {
        let n = buffer.len().min(usize::try_from(range[1] - at).ok()?);
        file.read_exact_at(&mut buffer[..n], at).ok()?;
        digest.records(&buffer[..n]);
        at += n as u64;
    }
    Some(digest.finish(&[]))
}
