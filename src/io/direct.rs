//! [`DirectWriter`]: the temporary of a large sequential output (a LAS file) written with
//! direct I/O (`O_DIRECT`), from an aligned buffer straight to the device: no copy into the
//! page cache (the kernel's write copy cost as much CPU as encoding the records) and no
//! gigabyte of dirty pages left for the final fsync. Where the filesystem refuses direct I/O
//! (at open, or on an unaligned write) it falls back to ordinary writes of the same bytes.

use super::atomic::TempWriter;
use std::fs::File;
use std::io;
use std::os::unix::fs::FileExt;
use std::path::Path;

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
        // The last partial block goes out padded with zeros, then the file is cut to length.
        let padded = self.len.div_ceil(ALIGN) * ALIGN;
        let tail = self.len;
        self.buffer()[tail..padded].fill(0);
        self.flush_blocks(padded)?;
        if self.flushed != len {
            self.file.set_len(len)?;
        }
        Ok(self.file)
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
            drop(w.into_file().unwrap());
            assert_eq!(std::fs::read(&path).unwrap(), expect, "buffer {buffer}");
        }
    }
}
