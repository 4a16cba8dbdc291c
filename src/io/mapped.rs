//! Read-only memory maps of fixed-size-record files.

use crate::{Error, Result};
use memmap2::Mmap;
use std::fs::File;
use std::path::{Path, PathBuf};

/// A memory-mapped file of `header_bytes` followed by whole records of `record_bytes` each.
#[derive(Debug)]
pub struct MappedRecords {
    path: PathBuf,
    map: Option<Mmap>,
    header_bytes: usize,
    record_bytes: usize,
    len: usize,
}

impl MappedRecords {
    /// Maps `path`; refuses a file whose body is not a whole number of records.
    pub fn open(path: &Path, header_bytes: usize, record_bytes: usize, kind: &str) -> Result<Self> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let meta = file.metadata().map_err(|e| Error::io(path, e))?;
        if meta.is_dir() {
            return Err(Error::bad_file(
                path,
                format!("is a directory, not a {kind} file"),
            ));
        }
        let size = meta.len() as usize;
        if size < header_bytes {
            return Err(Error::bad_file(
                path,
                format!("{kind}: {size} bytes is shorter than the {header_bytes}-byte header"),
            ));
        }
        let body = size - header_bytes;
        if !body.is_multiple_of(record_bytes) {
            return Err(Error::bad_file(
                path,
                format!(
                    "{kind}: size {size} B is not a whole number of {record_bytes}-byte records \
                     ({} whole records and {} stray bytes: truncated or not a {kind} file)",
                    body / record_bytes,
                    body % record_bytes
                ),
            ));
        }
        // An empty file cannot be mapped on every platform; it simply has no records.
        let map = if size == 0 {
            None
        } else {
            // SAFETY: the map is read-only; kinescan never writes its inputs. As with any mmap,
            // another process truncating the file while it is mapped is outside our control.
            Some(unsafe { Mmap::map(&file) }.map_err(|e| Error::io(path, e))?)
        };
        Ok(MappedRecords {
            path: path.to_path_buf(),
            map,
            header_bytes,
            record_bytes,
            len: body / record_bytes,
        })
    }

    /// File path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Number of records.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when there are no records.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Header bytes.
    pub fn header(&self) -> &[u8] {
        self.map.as_deref().map_or(&[], |m| &m[..self.header_bytes])
    }

    /// Bytes of record `i` (panics when out of range: an internal invariant).
    #[inline]
    pub fn record(&self, i: usize) -> &[u8] {
        let start = self.header_bytes + i * self.record_bytes;
        &self.map.as_deref().expect("record of an empty file")[start..start + self.record_bytes]
    }

    /// Bytes of records `range`.
    pub fn records(&self, range: std::ops::Range<usize>) -> &[u8] {
        let start = self.header_bytes + range.start * self.record_bytes;
        let end = self.header_bytes + range.end * self.record_bytes;
        self.map.as_deref().map_or(&[], |m| &m[start..end])
    }
}

/// How far before a released range to release too: the largest page-cache folio mapped at
/// once on x86-64 (a PMD, 2 MiB), which covers the default 64 KiB fault-around window.
const RELEASE_BEHIND_BYTES: usize = 2 << 20;

impl MappedRecords {
    /// Tells the kernel the pages of records `range` are no longer needed by this process, so
    /// resident memory stays flat however large the file (they are re-read if touched again).
    ///
    /// Also releases the [`RELEASE_BEHIND_BYTES`] before the range: a page fault maps the
    /// already-cached neighbours of the faulting page (Linux "fault-around": a 64 KiB window,
    /// or a whole large folio of the page cache, up to 2 MiB), which can bring back the tail of
    /// the range released just before; without this, every chunk boundary kept up to that much
    /// resident (74 MB over 1,220 chunks of a 0.8 GB file).
    pub fn release(&self, range: std::ops::Range<usize>) {
        self.release_bytes(range, 0);
    }

    /// [`MappedRecords::release`], and the [`RELEASE_BEHIND_BYTES`] after the range too: for
    /// reads that jump about the file (a visit's returns, then another visit's elsewhere),
    /// where no later release behind would take the neighbours a fault mapped after the range.
    pub fn release_around(&self, range: std::ops::Range<usize>) {
        self.release_bytes(range, RELEASE_BEHIND_BYTES);
    }

    fn release_bytes(&self, range: std::ops::Range<usize>, ahead: usize) {
        let Some(map) = self.map.as_ref() else { return };
        const PAGE: usize = 4096;
        let first = self.header_bytes + range.start * self.record_bytes;
        let start = first.saturating_sub(RELEASE_BEHIND_BYTES) / PAGE * PAGE;
        let end = (self.header_bytes + range.end * self.record_bytes + ahead).min(map.len());
        if end > start {
            // SAFETY: the map is private and read-only; dropping its pages only makes later
            // reads fault them in again from the unchanged file.
            let _ = unsafe {
                map.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, start, end - start)
            };
        }
    }
}

/// Little-endian f64 at byte offset `at` of `bytes`.
#[inline]
pub fn f64_le(bytes: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"))
}
