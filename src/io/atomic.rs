//! The one way every output file is written (LAS, JSON, CSV, TOML, PNG, binary).
//!
//! [`AtomicFile`] writes to a temporary file in the destination's folder, named
//! `.<file name>.kinescan-<pid>-<n>.tmp`, and [`AtomicFile::commit`] publishes it: flush, fsync
//! the file, rename it onto the destination, fsync the folder. Until then the destination keeps
//! its previous content; dropping an uncommitted file removes the temporary. Every output gets
//! the permissions of an ordinarily created file (`0o666 & !umask` on Unix): the temporary is
//! created with mode 0o666 and the kernel applies the umask.
//!
//! Temporaries of a process that died (kill -9, power loss) stay behind; the pid in their
//! name lets [`remove_stale_temps`] recognise and remove them. Staging folders made with
//! [`create_temp_dir`] follow the same naming.

use crate::{Error, Result};
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Marker between the destination's name and the pid in a temporary's name.
const TEMP_MARKER: &str = ".kinescan-";
/// Suffix of every temporary file or folder.
const TEMP_SUFFIX: &str = ".tmp";
/// End of a publication journal's name (`io::publish`): while one is in a folder, the staging
/// folders it names are the material of an interrupted publication, not garbage.
pub(crate) const PUBLISH_JOURNAL_SUFFIX: &str = ".kinescan-publish.json";
/// Buffer of [`AtomicFile::create`] (bytes).
const DEFAULT_BUFFER_BYTES: usize = 1 << 20;

/// How an [`AtomicFile`] writes its temporary: through a [`BufWriter`] (the default) or with
/// direct I/O (`io::direct`, for large sequential outputs).
pub trait TempWriter: Sized {
    /// Wraps the temporary `file`, just created at `temp_path`, with a buffer of about
    /// `buffer_bytes`.
    fn wrap(file: File, temp_path: &Path, buffer_bytes: usize) -> std::io::Result<Self>;
    /// Appends all of `bytes`.
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()>;
    /// Overwrites `bytes` at absolute `offset` of what was written; later writes append.
    fn write_at(&mut self, offset: u64, bytes: &[u8]) -> std::io::Result<()>;
    /// Writes what is buffered and gives the file back (to be fsynced).
    fn into_file(self) -> std::io::Result<File>;
}

impl TempWriter for BufWriter<File> {
    fn wrap(file: File, _temp_path: &Path, buffer_bytes: usize) -> std::io::Result<Self> {
        Ok(BufWriter::with_capacity(buffer_bytes, file))
    }

    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        Write::write_all(self, bytes)
    }

    fn write_at(&mut self, offset: u64, bytes: &[u8]) -> std::io::Result<()> {
        self.seek(SeekFrom::Start(offset))?;
        Write::write_all(self, bytes)?;
        self.seek(SeekFrom::End(0))?;
        Ok(())
    }

    fn into_file(self) -> std::io::Result<File> {
        self.into_inner().map_err(|e| e.into_error())
    }
}

/// A writer whose content appears at `path` only when committed.
pub struct AtomicFile<W: TempWriter = BufWriter<File>> {
    path: PathBuf,
    temp_path: PathBuf,
    writer: Option<W>,
}

impl AtomicFile {
    /// Starts writing `path`, creating its folder if missing.
    pub fn create(path: &Path) -> Result<Self> {
        Self::with_capacity(path, DEFAULT_BUFFER_BYTES)
    }
}

impl<W: TempWriter> AtomicFile<W> {
    /// [`create`](AtomicFile::create) with a write buffer of `buffer_bytes`.
    pub fn with_capacity(path: &Path, buffer_bytes: usize) -> Result<Self> {
        let dir = parent_dir(path);
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let name = path
            .file_name()
            .ok_or_else(|| Error::bad_file(path, "output path has no file name".to_string()))?;
        let (temp_path, file) =
            create_temp_file(dir, &name.to_string_lossy()).map_err(|e| Error::io(path, e))?;
        let writer = W::wrap(file, &temp_path, buffer_bytes);
        let mut f = AtomicFile {
            path: path.to_path_buf(),
            temp_path,
            writer: None,
        };
        f.writer = Some(writer.map_err(|e| Error::io(path, e))?);
        Ok(f)
    }

    /// Destination path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes all of `bytes`.
    pub fn write_all(&mut self, bytes: &[u8]) -> Result<()> {
        crate::interrupt::check()?;
        let result = self.writer().write_all(bytes);
        result.map_err(|e| Error::io(&self.path, e))
    }

    /// The underlying writer (for formatting APIs); map its errors with [`Error::io`] on
    /// [`path`](AtomicFile::path).
    pub fn writer(&mut self) -> &mut W {
        self.writer
            .as_mut()
            .expect("the writer is only taken by commit, which consumes self")
    }

    /// Overwrites `bytes` at absolute `offset` (e.g. a header completed at the end); later
    /// writes append.
    pub fn write_at(&mut self, offset: u64, bytes: &[u8]) -> Result<()> {
        let result = self.writer().write_at(offset, bytes);
        result.map_err(|e| Error::io(&self.path, e))
    }

    /// Flushes and fsyncs the temporary file, renames it onto the destination and fsyncs the
    /// folder. On error the temporary is removed and the destination is unchanged.
    pub fn commit(mut self) -> Result<()> {
        let io = |e| Error::io(&self.path, e);
        let writer = self.writer.take().expect("commit runs once");
        let file = writer.into_file().map_err(io)?;
        file.sync_all().map_err(io)?;
        drop(file);
        std::fs::rename(&self.temp_path, &self.path).map_err(io)?;
        // Published: nothing left to remove on drop.
        self.temp_path = PathBuf::new();
        sync_dir(parent_dir(&self.path)).map_err(io)
    }
}

impl<W: TempWriter> Drop for AtomicFile<W> {
    fn drop(&mut self) {
        if !self.temp_path.as_os_str().is_empty() {
            drop(self.writer.take());
            let _ = std::fs::remove_file(&self.temp_path);
        }
    }
}

/// Writes `bytes` to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut f = AtomicFile::create(path)?;
    f.write_all(bytes)?;
    f.commit()
}

/// Writes a copy of the file `from` to `to` atomically (copied in the kernel where it can).
pub fn copy_atomic(from: &Path, to: &Path) -> Result<()> {
    let mut source = File::open(from).map_err(|e| Error::io(from, e))?;
    let mut copy = AtomicFile::create(to)?;
    std::io::copy(&mut source, copy.writer()).map_err(|e| Error::io(to, e))?;
    copy.commit()
}

/// Opens the existing file `path` to be written in place (a file made of parts, written one
/// after another, possibly by several processes: `io::direct::PartWriter`). When the file has
/// other names (a hard link: an output published from it by `OutputSet::stage_file`), it is
/// first replaced by a copy of itself ([`copy_atomic`]), so the other names keep their bytes.
pub fn open_in_place(path: &Path) -> Result<File> {
    let io = |e| Error::io(path, e);
    let meta = std::fs::metadata(path).map_err(io)?;
    #[cfg(unix)]
    if std::os::unix::fs::MetadataExt::nlink(&meta) > 1 {
        copy_atomic(path, path)?;
    }
    #[cfg(not(unix))]
    let _ = meta;
    let mut options = std::fs::OpenOptions::new();
    options.read(true).write(true).open(path).map_err(io)
}

/// Creates `path` anew, empty, for writing in place: an earlier file of that name is unlinked
/// first (other names of it keep their bytes). The caller makes the name durable
/// ([`sync_dir`]) once the content is.
pub fn create_in_place(path: &Path) -> Result<File> {
    let io = |e| Error::io(path, e);
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(io(e)),
        _ => {}
    }
    let mut options = std::fs::OpenOptions::new();
    options.read(true).write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o666);
    options.open(path).map_err(io)
}

/// Serialises `value` as pretty JSON into `path` atomically.
pub fn write_json<T: serde::Serialize + ?Sized>(path: &Path, value: &T) -> Result<()> {
    let json = serde_json::to_vec_pretty(value)
        .map_err(|e| Error::Invalid(format!("{}: JSON encoding: {e}", path.display())))?;
    write_atomic(path, &json)
}

/// Appends `line` (no newline inside) and a newline to the append-only log `path` (created if
/// missing), durably: under an exclusive lock on the file (processes appending at once do not
/// interleave), a torn last line left by a killed writer is cut off first, and the file is
/// fsynced before returning. The one append-only output (a work journal); every other output
/// is written whole with [`AtomicFile`].
pub fn append_line_durably(path: &Path, line: &str) -> Result<()> {
    use std::io::Read;
    let io = |e| Error::io(path, e);
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .read(true)
        .write(true)
        .open(path)
        .map_err(io)?;
    f.lock().map_err(io)?;
    let mut text = Vec::new();
    f.read_to_end(&mut text).map_err(io)?;
    let whole = text.iter().rposition(|&b| b == b'\n').map_or(0, |k| k + 1);
    if whole < text.len() {
        f.set_len(whole as u64).map_err(io)?;
    }
    f.seek(SeekFrom::Start(whole as u64)).map_err(io)?;
    f.write_all(format!("{line}\n").as_bytes()).map_err(io)?;
    f.sync_all().map_err(io)
}

/// Creates a private staging folder in `parent` named `.<label>.kinescan-<pid>-<random>.tmp`
/// (removed when the returned handle drops; recognised by [`remove_stale_temps`] if the
/// process dies first).
pub fn create_temp_dir(parent: &Path, label: &str) -> Result<tempfile::TempDir> {
    tempfile::Builder::new()
        .prefix(&format!(".{label}{TEMP_MARKER}{}-", std::process::id()))
        .suffix(TEMP_SUFFIX)
        .tempdir_in(parent)
        .map_err(|e| Error::io(parent, e))
}

/// Removes the temporary files and folders in `dir` left by kinescan processes that are no
/// longer running (pid in the name not alive; Linux only, elsewhere nothing is removed).
/// Returns the paths removed. Temporaries of running processes, including this one, stay.
/// A pid reused by a new process keeps its old temporaries until that process ends.
pub fn remove_stale_temps(dir: &Path) -> Result<Vec<PathBuf>> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(Error::io(dir, e)),
    };
    let entries: Vec<std::fs::DirEntry> = entries
        .collect::<std::io::Result<_>>()
        .map_err(|e| Error::io(dir, e))?;
    let journal = |e: &std::fs::DirEntry| {
        e.file_name()
            .to_str()
            .is_some_and(|n| n.starts_with('.') && n.ends_with(PUBLISH_JOURNAL_SUFFIX))
    };
    if entries.iter().any(journal) {
        // An interrupted publication: `io::publish::prepare_folder` completes it first.
        return Ok(Vec::new());
    }
    let mut removed = Vec::new();
    for entry in entries {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(temp_owner_pid) else {
            continue;
        };
        if process_alive(pid) {
            continue;
        }
        let path = entry.path();
        let is_dir = entry.file_type().map_err(|e| Error::io(&path, e))?.is_dir();
        let result = if is_dir {
            std::fs::remove_dir_all(&path)
        } else {
            std::fs::remove_file(&path)
        };
        match result {
            Ok(()) => removed.push(path),
            // Another process cleaned it first.
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io(&path, e)),
        }
    }
    removed.sort();
    Ok(removed)
}

/// The pid in a temporary's name `.<name>.kinescan-<pid>-<alphanumerics>.tmp`, if it is one.
fn temp_owner_pid(file_name: &str) -> Option<u32> {
    let body = file_name.strip_prefix('.')?.strip_suffix(TEMP_SUFFIX)?;
    let tail = &body[body.rfind(TEMP_MARKER)? + TEMP_MARKER.len()..];
    let (pid, unique) = tail.split_once('-')?;
    let alnum = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_alphanumeric());
    if !alnum(unique) || !pid.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

#[cfg(target_os = "linux")]
pub(crate) fn process_alive(pid: u32) -> bool {
    pid == std::process::id() || Path::new("/proc").join(pid.to_string()).exists()
}

/// Without a process table to ask, every owner counts as alive (nothing is removed).
#[cfg(not(target_os = "linux"))]
pub(crate) fn process_alive(_pid: u32) -> bool {
    true
}

/// Creates `.<name>.kinescan-<pid>-<n>.tmp` in `dir` with the mode of an ordinary new file.
fn create_temp_file(dir: &Path, name: &str) -> std::io::Result<(PathBuf, File)> {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let pid = std::process::id();
    loop {
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let temp_path = dir.join(format!(".{name}{TEMP_MARKER}{pid}-{n}{TEMP_SUFFIX}"));
        let mut options = std::fs::OpenOptions::new();
        options.read(true).write(true).create_new(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o666);
        match options.open(&temp_path) {
            Ok(file) => return Ok((temp_path, file)),
            // Left by an earlier process with this pid: take the next number.
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

pub(crate) fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Makes a rename in `dir` durable. Filesystems that cannot fsync a folder (EINVAL) are
/// accepted: the rename itself has happened.
pub(crate) fn sync_dir(dir: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        match File::open(dir)?.sync_all() {
            Err(e) if e.kind() == std::io::ErrorKind::InvalidInput => Ok(()),
            other => other,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    /// A pid that no running process has: above Linux's maximum pid (2^22).
    const DEAD_PID: u32 = 4_194_305;

    #[test]
    fn temp_names_carry_pid_and_are_recognised() {
        let dir = tempfile::tempdir().unwrap();
        let (temp, _file) = create_temp_file(dir.path(), "out.las").unwrap();
        let name = temp.file_name().unwrap().to_str().unwrap();
        assert!(name.starts_with(&format!(".out.las.kinescan-{}-", std::process::id())));
        assert_eq!(temp_owner_pid(name), Some(std::process::id()));
        assert_eq!(temp_owner_pid(".a.b.kinescan-12-x9.tmp"), Some(12));
        for not_temp in [
            "a.kinescan-12-x9.tmp",
            ".a.kinescan-12-x9.las",
            ".a.kinescan--x9.tmp",
            ".a.kinescan-12-.tmp",
            ".a.kinescan-1a-x.tmp",
            ".a.las.XXXX.tmp",
        ] {
            assert_eq!(temp_owner_pid(not_temp), None, "{not_temp}");
        }
    }

    #[test]
    fn commit_publishes_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub").join("a.csv");
        write_atomic(&path, b"x,y\n").unwrap();
        write_atomic(&path, b"x,y\n1,2\n").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"x,y\n1,2\n");
        assert_eq!(names(&dir.path().join("sub")), ["a.csv"]);
    }

    #[test]
    fn drop_or_failed_commit_leaves_destination_and_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.json");
        std::fs::write(&path, b"old").unwrap();
        let mut f = AtomicFile::create(&path).unwrap();
        f.write_all(b"new").unwrap();
        drop(f);
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(names(dir.path()), ["a.json"]);
        // Renaming a file onto a non-empty folder fails at commit.
        let blocked = dir.path().join("blocked");
        std::fs::create_dir_all(blocked.join("inside")).unwrap();
        let err = write_atomic(&blocked, b"new").unwrap_err().to_string();
        assert!(err.contains("blocked"), "{err}");
        assert_eq!(names(dir.path()), ["a.json", "blocked"]);
    }

    #[cfg(unix)]
    #[test]
    fn mode_is_that_of_an_ordinary_new_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain");
        File::create(&plain).unwrap();
        let atomic = dir.path().join("atomic");
        write_atomic(&atomic, b"1").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o7777;
        assert_eq!(mode(&atomic), mode(&plain));
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn stale_temps_of_dead_processes_are_removed_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let dead_file = format!(".out.las.kinescan-{DEAD_PID}-0.tmp");
        let dead_dir = format!(".import.kinescan-{DEAD_PID}-Ab12.tmp");
        std::fs::write(d.join(&dead_file), b"partial").unwrap();
        std::fs::create_dir(d.join(&dead_dir)).unwrap();
        std::fs::write(d.join(&dead_dir).join("input0.ksprof"), b"x").unwrap();
        // pid 1 (init) is always alive; so is this process.
        let live_other = ".out.las.kinescan-1-0.tmp".to_string();
        let (live_own, _file) = create_temp_file(d, "out.las").unwrap();
        let own_dir = create_temp_dir(d, "import").unwrap();
        let unrelated = [".hidden.tmp", "out.las", ".out.las.abc123.tmp"];
        for name in unrelated.iter().chain([&live_other.as_str()]) {
            std::fs::write(d.join(name), b"keep").unwrap();
        }
        let removed = remove_stale_temps(d).unwrap();
        let mut expected = vec![d.join(&dead_dir), d.join(&dead_file)];
        expected.sort();
        assert_eq!(removed, expected);
        let left = names(d);
        assert!(
            !left.contains(&dead_file) && !left.contains(&dead_dir),
            "{left:?}"
        );
        let own_name = live_own.file_name().unwrap().to_string_lossy().into_owned();
        let own_dir_name = own_dir.path().file_name().unwrap().to_string_lossy();
        assert!(left.contains(&own_name) && left.contains(&own_dir_name.into_owned()));
        assert!(left.contains(&live_other));
        assert!(unrelated.iter().all(|n| left.contains(&n.to_string())));
        assert!(remove_stale_temps(&d.join("missing")).unwrap().is_empty());
    }
}
