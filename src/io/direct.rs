//! [`DirectWriter`]: the temporary of a large sequential output (a LAS file) written with
//! direct I/O (`O_DIRECT`), from an aligned buffer straight to the device: no copy into the
//! page cache (the kernel's write copy cost as much CPU as encoding the records) and no
//! gigabyte of dirty pages left for the final fsync. Where the filesystem refuses direct I/O
//! (at open, or on an unaligned write) it falls back to ordinary writes of the same bytes.
//! [`PartWriter`]: the same writes into a file made of parts, each written in place after the
//! previous one (a day's pass file, one work unit after another).

use super::atomic::{create_in_place, open_in_place, parent_dir, sync_dir, TempWriter};
use crate::{Error, Result};
use std::fs::File;
use std::io;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// Alignment of direct writes (memory address, file offset, length): the page size, a
/// multiple of every common logical block size.
const ALIGN: usize = 4096;

/// An aligned buffer of whole blocks in front of a file written with direct I/O.
pub struct DirectWriter {
    /// The temporary as created (ordinary I/O): the fallback, and what is fsynced.
    file: File,
    /// The same file opened with `O_DIRECT`; `None` once direct I/O was refused.
    direct: Option<File>,
    /// Storage of the buffer: `ALIGN` more bytes than used, so an aligned start exists.
    storage: Vec<u8>,
    /// Start of the aligned buffer in `storage`.
    start: usize,
    /// Buffer capacity (a multiple of `ALIGN`).
    capacity: usize,
    /// Bytes in the buffer.
    len: usize,
    /// File offset of the buffer's first byte (a multiple of `ALIGN` while direct).
    flushed: u64,
}

impl DirectWriter {
    /// A writer of `file` (at `path`) whose first byte goes to byte `offset` of the file. The
    /// bytes of the block before `offset` are read into the buffer (zeros beyond the end of the
    /// file) and written back unchanged with the first block, so every write stays aligned.
    fn at(file: File, path: &Path, buffer_bytes: usize, offset: u64) -> io::Result<Self> {
        let mut w = Self::wrap(file, path, buffer_bytes)?;
        let first = offset / ALIGN as u64 * ALIGN as u64;
        let before = (offset - first) as usize;
        let block = &mut w.storage[w.start..w.start + before];
        let mut read = 0;
        while read < before {
            match w.file.read_at(&mut block[read..], first + read as u64) {
                Ok(0) => break, // the end of the file: the buffer's zeros stand for the rest
                Ok(n) => read += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        w.flushed = first;
        w.len = before;
        Ok(w)
    }

    fn buffer(&mut self) -> &mut [u8] {
        &mut self.storage[self.start..self.start + self.capacity]
    }

    /// Writes the buffer's first `len` bytes (`len` a multiple of `ALIGN` while direct) at
    /// `flushed` and empties it.
    fn flush_blocks(&mut self, len: usize) -> io::Result<()> {
        let at = self.flushed;
        let (start, end) = (self.start, self.start + len);
        write_all_at(&self.file, &mut self.direct, &self.storage[start..end], at)?;
        self.flushed += len as u64;
        self.len = 0;
        Ok(())
    }

    /// Patches `bytes` at `offset` of what was written before the buffer: the aligned blocks
    /// holding them are read, patched and written back, direct I/O throughout.
    fn patch_written(&mut self, offset: u64, bytes: &[u8]) -> io::Result<()> {
        let first = offset / ALIGN as u64 * ALIGN as u64;
        let end = (offset + bytes.len() as u64).div_ceil(ALIGN as u64) * ALIGN as u64;
        let mut blocks = AlignedBlocks::new((end - first) as usize);
        let span = blocks.as_mut();
        let reader = self.direct.as_ref().unwrap_or(&self.file);
        reader.read_exact_at(span, first)?;
        let at = (offset - first) as usize;
        span[at..at + bytes.len()].copy_from_slice(bytes);
        write_all_at(&self.file, &mut self.direct, span, first)
    }
}

/// Writes `bytes` at `at`, with direct I/O while `direct` is open and the write aligned, else
/// (from then on) ordinary writes of `file`.
fn write_all_at(file: &File, direct: &mut Option<File>, bytes: &[u8], at: u64) -> io::Result<()> {
    let mut done = 0;
    while done < bytes.len() {
        let rest = &bytes[done..];
        let aligned = done.is_multiple_of(ALIGN) && rest.len().is_multiple_of(ALIGN);
        let target = direct.as_ref().filter(|_| aligned).unwrap_or(file);
        match target.write_at(rest, at + done as u64) {
            Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
            Ok(n) => done += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            // Direct I/O refused for this file or these blocks: ordinary writes from here on.
            Err(e) if direct.is_some() && e.kind() == io::ErrorKind::InvalidInput => {
                *direct = None;
            }
            Err(e) => return Err(e),
        }
        if !done.is_multiple_of(ALIGN) {
            *direct = None; // a short write: the rest cannot be aligned
        }
    }
    Ok(())
}

impl TempWriter for DirectWriter {
    fn wrap(file: File, temp_path: &Path, buffer_bytes: usize) -> io::Result<Self> {
        use std::os::unix::fs::OpenOptionsExt;
        let direct = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_DIRECT)
            .open(temp_path)
            .ok();
        let capacity = buffer_bytes.max(1).div_ceil(ALIGN) * ALIGN;
        let storage = vec![0u8; capacity + ALIGN];
        let start = storage.as_ptr().align_offset(ALIGN);
        Ok(DirectWriter {
            file,
            direct,
            storage,
            start,
            capacity,
            len: 0,
            flushed: 0,
        })
    }

    fn write_all(&mut self, mut bytes: &[u8]) -> io::Result<()> {
        while !bytes.is_empty() {
            let n = bytes.len().min(self.capacity - self.len);
            let len = self.len;
            self.buffer()[len..len + n].copy_from_slice(&bytes[..n]);
            self.len += n;
            bytes = &bytes[n..];
            if self.len == self.capacity {
                self.flush_blocks(self.capacity)?;
            }
        }
        Ok(())
    }

    fn write_at(&mut self, offset: u64, bytes: &[u8]) -> io::Result<()> {
        let end = offset + bytes.len() as u64;
        let buffered_end = self.flushed + self.len as u64;
        if end > buffered_end {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "write_at beyond the end of the file",
            ));
        }
        // The part still in the buffer is patched there, the rest on the file.
        let split = (self.flushed.clamp(offset, end) - offset) as usize;
        let (on_file, in_buffer) = bytes.split_at(split);
        if !in_buffer.is_empty() {
            let at = (offset + split as u64 - self.flushed) as usize;
            self.buffer()[at..at + in_buffer.len()].copy_from_slice(in_buffer);
        }
        if !on_file.is_empty() {
            self.patch_written(offset, on_file)?;
        }
        Ok(())
    }

    fn into_file(mut self) -> io::Result<File> {
        let len = self.flushed + self.len as u64;
        // The last partial block goes out padded with zeros, then the file is cut to length
        // (a part written in place also drops what an earlier, longer file held beyond it).
        let padded = self.len.div_ceil(ALIGN) * ALIGN;
        let tail = self.len;
        self.buffer()[tail..padded].fill(0);
        self.flush_blocks(padded)?;
        if self.file.metadata()?.len() != len {
            self.file.set_len(len)?;
        }
        Ok(self.file)
    }
}

/// One part of a file made of parts written in place, one after another (possibly by
/// different processes), each after the bytes of the parts before it: the records of a day's
/// work unit in its pass's file. A part is written with direct I/O like a [`DirectWriter`]
/// temporary; [`commit`](PartWriter::commit) cuts the file at the part's end and makes it
/// durable. Nothing makes a part atomic: the caller records which parts are complete (a
/// journal) and publishes the whole file once it is (`OutputSet::stage_file`).
pub struct PartWriter {
    path: PathBuf,
    writer: DirectWriter,
    fresh: bool,
}

impl PartWriter {
    /// Starts a part of the file `path` at byte `at`, with a buffer of about `buffer_bytes`.
    /// `first`: the file is created anew (an earlier file of that name is unlinked, other
    /// names of it keep their bytes) and the bytes before `at` are zeros until written by the
    /// caller; otherwise the existing file is written in place (copied first when other names
    /// link it: `io::atomic::open_in_place`), its bytes before `at` kept.
    pub fn open(path: &Path, at: u64, first: bool, buffer_bytes: usize) -> Result<Self> {
        let file = if first {
            create_in_place(path)?
        } else {
            open_in_place(path)?
        };
        let writer =
            DirectWriter::at(file, path, buffer_bytes, at).map_err(|e| Error::io(path, e))?;
        Ok(PartWriter {
            path: path.to_path_buf(),
            writer,
            fresh: first,
        })
    }

    /// Appends all of `bytes` to the part.
    pub fn write_all(&mut self, bytes: &[u8]) -> Result<()> {
        crate::interrupt::check()?;
        let result = self.writer.write_all(bytes);
        result.map_err(|e| Error::io(&self.path, e))
    }

    /// Writes what is buffered, cuts the file at the part's end, fsyncs it (and its folder for
    /// a file created anew).
    pub fn commit(self) -> Result<()> {
        let io = |e| Error::io(&self.path, e);
        let file = self.writer.into_file().map_err(io)?;
        file.sync_all().map_err(io)?;
        if self.fresh {
            sync_dir(parent_dir(&self.path)).map_err(io)?;
        }
        Ok(())
    }
}

/// A zeroed, `ALIGN`-aligned scratch of whole blocks (reads with direct I/O need one).
struct AlignedBlocks {
    storage: Vec<u8>,
    start: usize,
    len: usize,
}

impl AlignedBlocks {
    fn new(len: usize) -> Self {
        let storage = vec![0u8; len + ALIGN];
        let start = storage.as_ptr().align_offset(ALIGN);
        AlignedBlocks {
            storage,
            start,
            len,
        }
    }

    fn as_mut(&mut self) -> &mut [u8] {
        &mut self.storage[self.start..self.start + self.len]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The direct half of a test ran the fallback: the filesystem of the temporary folder
    /// refused `O_DIRECT` (tmpfs does). A failure under `KINESCAN_REQUIRE_ODIRECT=1` (CI).
    fn refused(test: &str) {
        let reason = "the temporary folder's filesystem refused O_DIRECT: only the fallback ran";
        crate::testing::skip("KINESCAN_REQUIRE_ODIRECT", test, reason);
    }

    /// Whatever the split of writes, buffer size and patches, the file holds the same bytes
    /// as with ordinary writes, its length exact (the padded last block cut off).
    #[test]
    fn direct_writes_give_the_bytes_written() {
        let dir = tempfile::tempdir().unwrap();
        let data: Vec<u8> = (0..3 * ALIGN as u32 + 1234)
            .map(|k| (k * 7 % 251) as u8)
            .collect();
        let cases = [(ALIGN, 1000), (3 * ALIGN, 5000), (1, 17), (1 << 20, 4096)];
        // With direct I/O, and as on a filesystem that refuses it.
        let mut fallback_only = false;
        for ((buffer, piece), direct) in cases.into_iter().flat_map(|c| [(c, true), (c, false)]) {
            let path = dir.path().join(format!("f{buffer}_{piece}_{direct}"));
            let file = File::create_new(&path).unwrap();
            let mut w = DirectWriter::wrap(file, &path, buffer).unwrap();
            if !direct {
                w.direct = None;
            }
            for part in data.chunks(piece) {
                w.write_all(part).unwrap();
            }
            // Patches in flushed blocks, across the buffer's start and in the buffer.
            let patches = [
                (0u64, 700usize),
                (ALIGN as u64 - 3, 9),
                (data.len() as u64 - 5, 5),
            ];
            let mut expect = data.clone();
            for (at, n) in patches {
                let patch: Vec<u8> = (0..n).map(|k| 255 - k as u8).collect();
                w.write_at(at, &patch).unwrap();
                expect[at as usize..at as usize + n].copy_from_slice(&patch);
            }
            assert!(w.write_at(data.len() as u64 - 1, &[0, 0]).is_err());
            fallback_only |= direct && w.direct.is_none();
            drop(w.into_file().unwrap());
            assert_eq!(std::fs::read(&path).unwrap(), expect, "buffer {buffer}");
        }
        if fallback_only {
            refused("direct_writes_give_the_bytes_written");
        }
    }

    /// A file written in parts, each by a writer of its own starting where the previous part
    /// ended (unaligned, empty parts too), holds the bytes written; a part written again cuts
    /// the file at its end; a first part makes the file anew and a later part copies a linked
    /// file first, so another name of the file keeps its bytes.
    #[test]
    fn parts_written_in_place_give_the_bytes_written() {
        let dir = tempfile::tempdir().unwrap();
        let data: Vec<u8> = (0..5 * ALIGN as u32 + 777)
            .map(|k| (k * 13 % 253) as u8)
            .collect();
        let cuts = [1272, 1272, 5000, 8192, 8193, 15000, data.len()];
        // The bytes before the first part are the caller's (a LAS header): zeros until then.
        let expect = |end: usize| {
            let mut e = data[..end].to_vec();
            e[..cuts[0]].fill(0);
            e
        };
        let path = dir.path().join("pass.las");
        let fallback_only = std::cell::Cell::new(false);
        // With direct I/O (a buffer of a block, then of several), and as on a filesystem that
        // refuses it.
        let write = |from: usize, to: usize, buffer: usize| {
            let first = from == cuts[0];
            let mut w = PartWriter::open(&path, from as u64, first, buffer.max(ALIGN)).unwrap();
            if buffer == 0 {
                w.writer.direct = None;
            }
            for piece in data[from..to].chunks(999) {
                w.write_all(piece).unwrap();
            }
            if buffer != 0 && w.writer.direct.is_none() {
                fallback_only.set(true);
            }
            w.commit().unwrap();
        };
        for buffer in [ALIGN, 3 * ALIGN, 1 << 20, 0] {
            for pair in cuts.windows(2) {
                write(pair[0], pair[1], buffer);
            }
            assert_eq!(
                std::fs::read(&path).unwrap(),
                expect(data.len()),
                "{buffer}"
            );
            write(cuts[2], cuts[3], buffer);
            assert_eq!(std::fs::read(&path).unwrap(), expect(cuts[3]), "{buffer}");
        }
        let published = dir.path().join("published.las");
        std::fs::hard_link(&path, &published).unwrap();
        write(cuts[3], cuts[4], ALIGN);
        assert_eq!(std::fs::read(&path).unwrap(), expect(cuts[4]));
        assert_eq!(
            std::fs::read(&published).unwrap(),
            expect(cuts[3]),
            "link written"
        );
        std::fs::remove_file(&published).unwrap();
        std::fs::hard_link(&path, &published).unwrap();
        write(cuts[0], cuts[2], ALIGN);
        assert_eq!(std::fs::read(&path).unwrap(), expect(cuts[2]));
        assert_eq!(
            std::fs::read(&published).unwrap(),
            expect(cuts[4]),
            "link written"
        );
        if fallback_only.get() {
            refused("parts_written_in_place_give_the_bytes_written");
        }
    }
}
