//! Fixed-width records of f64 kept in memory or spilled to a temporary file: what a
//! computation stores for a later pass when the whole of it would not fit in memory (the RTS
//! smoother's epochs over a day, docs/trajectory.md). Records are read and written by index;
//! the file lives in a folder made by [`crate::io::atomic::create_temp_dir`] (removed when
//! the store is dropped, and by `remove_stale_temps` after a crash) and is never an output.

use crate::{Error, Result};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

enum Backing {
    Memory(Vec<f64>),
    File {
        file: File,
        path: PathBuf,
        _dir: tempfile::TempDir,
    },
}

/// A store of records of `width` f64 each.
pub struct Spill {
    width: usize,
    len: usize,
    backing: Backing,
}

impl Spill {
    /// A store held in memory.
    pub fn memory(width: usize) -> Self {
        Spill {
            width,
            len: 0,
            backing: Backing::Memory(Vec::new()),
        }
    }

    /// A store in a temporary file in a new temporary folder inside `parent`; `label` names
    /// the folder (and the computation in errors).
    pub fn file_in(parent: &Path, label: &str, width: usize) -> Result<Self> {
        let dir = crate::io::atomic::create_temp_dir(parent, label)?;
        let path = dir.path().join(format!("{label}.f64"));
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&path)
            .map_err(|e| Error::io(&path, e))?;
        Ok(Spill {
            width,
            len: 0,
            backing: Backing::File {
                file,
                path,
                _dir: dir,
            },
        })
    }

    /// Number of records.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Bytes held in memory.
    pub fn memory_bytes(&self) -> usize {
        match &self.backing {
            Backing::Memory(v) => v.capacity() * 8,
            Backing::File { .. } => 0,
        }
    }

    /// Bytes stored in the file.
    pub fn file_bytes(&self) -> usize {
        match &self.backing {
            Backing::Memory(_) => 0,
            Backing::File { .. } => self.len * self.width * 8,
        }
    }

    /// Appends a record.
    pub fn push(&mut self, rec: &[f64]) -> Result<()> {
        self.put(self.len, rec)
    }

    /// Writes record `i` (`i <= len`; `i == len` appends; a record skipped over reads as zeros
    /// in a file, and is refused in memory).
    pub fn put(&mut self, i: usize, rec: &[f64]) -> Result<()> {
        assert_eq!(rec.len(), self.width, "spill record width");
        let w = self.width;
        match &mut self.backing {
            Backing::Memory(v) => {
                assert!(i <= self.len, "spill record {i} beyond {}", self.len);
                if i == self.len {
                    v.extend_from_slice(rec);
                } else {
                    v[i * w..(i + 1) * w].copy_from_slice(rec);
                }
            }
            Backing::File { file, path, .. } => {
                let bytes: Vec<u8> = rec.iter().flat_map(|x| x.to_le_bytes()).collect();
                file.seek(SeekFrom::Start((i * w * 8) as u64))
                    .and_then(|_| file.write_all(&bytes))
                    .map_err(|e| Error::io(&*path, e))?;
            }
        }
        self.len = self.len.max(i + 1);
        Ok(())
    }

    /// Reads record `i` into `out`.
    pub fn get(&self, i: usize, out: &mut [f64]) -> Result<()> {
        assert!(i < self.len, "spill record {i} of {}", self.len);
        assert_eq!(out.len(), self.width, "spill record width");
        let w = self.width;
        match &self.backing {
            Backing::Memory(v) => out.copy_from_slice(&v[i * w..(i + 1) * w]),
            Backing::File { file, path, .. } => {
                let mut bytes = vec![0u8; w * 8];
                let mut f: &File = file;
                f.seek(SeekFrom::Start((i * w * 8) as u64))
                    .and_then(|_| f.read_exact(&mut bytes))
                    .map_err(|e| Error::io(path, e))?;
                for (x, b) in out.iter_mut().zip(bytes.chunks_exact(8)) {
                    *x = f64::from_le_bytes(b.try_into().expect("8 bytes"));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Memory and file stores return what was written, bit for bit, in any order.
    #[test]
    fn memory_and_file_stores_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        for mut s in [
            Spill::memory(3),
            Spill::file_in(dir.path(), "spill-test", 3).unwrap(),
        ] {
            for i in 0..5 {
                let x = i as f64;
                s.push(&[x, -x / 3.0, f64::MIN_POSITIVE * x]).unwrap();
            }
            s.put(2, &[7.0, 8.0, 9.0]).unwrap();
            assert_eq!(s.len(), 5);
            let mut out = [0.0; 3];
            for i in (0..5).rev() {
                s.get(i, &mut out).unwrap();
                let x = i as f64;
                let want = if i == 2 {
                    [7.0, 8.0, 9.0]
                } else {
                    [x, -x / 3.0, f64::MIN_POSITIVE * x]
                };
                assert_eq!(out.map(f64::to_bits), want.map(f64::to_bits));
            }
        }
        // The file store's folder is removed with it.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
