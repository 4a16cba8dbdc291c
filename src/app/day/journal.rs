//! The journal of a day: `<out>/journal.jsonl`, one JSON line per finished work unit (its
//! output file, that file's SHA-256 and the unit's return counts), appended and fsynced after
//! the unit's output was renamed into place. A restart trusts a line only when the unit's file
//! is there with the same hash; anything else is done again.

use crate::io::atomic::append_line_durably;
use crate::pipeline::report::ReturnCounts;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::Path;

/// One finished unit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// Unit id (plan).
    pub unit: String,
    /// SHA-256 of its output file, hex.
    pub sha256: String,
    /// Its returns read, written and rejected by reason.
    pub counts: ReturnCounts,
    /// Seconds it took.
    pub seconds: f64,
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

/// SHA-256 of the file at `path`, hex; none when it cannot be read.
pub fn file_sha256(path: &Path) -> Option<String> {
    let bytes = std::fs::read(path).ok()?;
    Some(crate::io::digest::hex(&Sha256::digest(&bytes)))
}
