//! Files identified by size and SHA-256 (for run reports).

use crate::{Error, Result};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::io::Read;
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
