//! Files identified by size and SHA-256 (for run reports).

use super::profiles::ProfileFile;
use crate::{Error, Result};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::io::Read;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// A file read or written, identified by size and SHA-256.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FileRecord {
    /// Role: "pipeline", "sbet", "smrmsg", "profiles", "las".
    pub role: String,
    /// Path as used.
    pub path: PathBuf,
    /// Size (bytes).
    pub bytes: u64,
    /// SHA-256 of the content, hex.
    pub sha256: String,
}

impl FileRecord {
    /// Hashes `path` by streaming it.
    pub fn of(role: &str, path: &Path) -> Result<Self> {
        let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut h = Sha256::new();
        let mut buf = vec![0u8; 1 << 20];
        let mut bytes = 0u64;
        loop {
            let n = f.read(&mut buf).map_err(|e| Error::io(path, e))?;
            if n == 0 {
                break;
            }
            h.update(&buf[..n]);
            bytes += n as u64;
        }
        Ok(FileRecord {
            role: role.into(),
            path: path.into(),
            bytes,
            sha256: hex(&h.finalize()),
        })
    }
}

/// Lower-case hex of `bytes`.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 (hex) of a profile file's header and of the record ranges received, in order (the
/// run's writer sends each chunk once written, so the hash runs beside the work); releases
/// each range's pages once hashed (all of the file when every chunk was written).
pub(crate) fn profile_sha256(
    file: &ProfileFile,
    ranges: std::sync::mpsc::Receiver<Range<usize>>,
) -> String {
    let mut hasher = Sha256::new();
    hasher.update(file.header_bytes());
    for r in ranges {
        hasher.update(file.record_bytes(r.clone()));
        file.release(r);
    }
    hex(&hasher.finalize())
}
