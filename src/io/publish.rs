//! A run's outputs published as one set. Every file of a run is written into a staging folder
//! beside its destination (`.<stem>.kinescan-<pid>-<n>.tmp/`, named like every temporary of
//! [`super::atomic`], so a killed run's folder is recognised and removed later); only when the
//! whole run has succeeded are the files renamed onto their final names, the report last. A
//! failed or interrupted run drops the set: the staging folders go, the previous outputs stay.
//!
//! A lock per output stem ([`StemLock`]) keeps two runs from interleaving their files.

use super::atomic::{
    copy_atomic, create_temp_dir, parent_dir, process_alive, remove_stale_temps, sync_dir,
    write_json, PUBLISH_JOURNAL_SUFFIX,
};
use super::paths::{self, KeyedPath};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::fs::File;
use std::path::{Path, PathBuf};

/// Staging folders of one run, one per destination folder.
pub struct OutputSet {
    label: String,
    staging: Vec<(PathBuf, tempfile::TempDir)>,
}

impl OutputSet {
    /// An empty set; `label` (the output stem) names its staging folders.
    pub fn new(label: &str) -> Self {
        OutputSet {
            label: label.to_string(),
            staging: Vec::new(),
        }
    }

    /// Where to write `final_path` during the run: the same name in the staging folder of its
    /// destination folder (created on first use; the destination folder too).
    pub fn stage(&mut self, final_path: &Path) -> Result<PathBuf> {
        let dir = parent_dir(final_path).to_path_buf();
        let name = final_path
            .file_name()
            .ok_or_else(|| Error::bad_file(final_path, "output path has no file name"))?;
        if let Some((_, t)) = self.staging.iter().find(|(d, _)| *d == dir) {
            return Ok(t.path().join(name));
        }
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        let t = create_temp_dir(&dir, &self.label)?;
        let staged = t.path().join(name);
        self.staging.push((dir, t));
        Ok(staged)
    }

    /// Stages the complete, durable file `from` (written with [`super::atomic::AtomicFile`])
    /// as `final_path`'s content without copying it: a hard link in the staging folder, so
    /// both names share the bytes on disk. Where the filesystem cannot link (`from` on another
    /// filesystem, no hard links there) the bytes are copied (in the kernel where it can) into
    /// an atomic file. `from` keeps its name and must not be changed afterwards.
    pub fn stage_file(&mut self, final_path: &Path, from: &Path) -> Result<PathBuf> {
        let staged = self.stage(final_path)?;
        if std::fs::hard_link(from, &staged).is_ok() {
            return Ok(staged);
        }
        copy_atomic(from, &staged)?;
        Ok(staged)
    }

    /// The destination of a path inside a staging folder (other paths unchanged).
    pub fn final_path(&self, path: &Path) -> PathBuf {
        for (dir, t) in &self.staging {
            if let Ok(rest) = path.strip_prefix(t.path()) {
                return dir.join(rest);
            }
        }
        path.to_path_buf()
    }

    /// `e` with every staged path replaced by its destination, so messages name the user's
    /// file, never a staging folder.
    pub fn user_error(&self, e: Error) -> Error {
        match e {
            Error::Io { path, source } => Error::Io {
                path: self.final_path(&path),
                source: self.without_staged_paths(source),
            },
            Error::BadFile { path, problem } => Error::BadFile {
                path: self.final_path(&path),
                problem,
            },
            Error::BadRecord { path, at, problem } => Error::BadRecord {
                path: self.final_path(&path),
                at,
                problem,
            },
            other => other,
        }
    }

    /// An OS error whose text names a staged path (some writers add it) reduced to the OS's
    /// own text.
    fn without_staged_paths(&self, e: std::io::Error) -> std::io::Error {
        let text = e.to_string();
        let staged = self
            .staging
            .iter()
            .any(|(_, t)| text.contains(&*t.path().to_string_lossy()));
        if !staged {
            return e;
        }
        match e.raw_os_error() {
            Some(code) => std::io::Error::from_raw_os_error(code),
            // `tempfile` appends ` at path "<temporary>"` to the OS's text.
            None => {
                let own = text.split(" at path \"").next().unwrap_or_default();
                std::io::Error::new(e.kind(), own.to_string())
            }
        }
    }

    /// Renames every staged file (not folder) onto its destination (`last` after all others, in the order
    /// given), makes the renames durable and removes the staging folders. Returns the
    /// destinations, in publication order.
    pub fn publish(self, last: &[PathBuf]) -> Result<Vec<PathBuf>> {
        self.publish_replacing(last, &[])
    }

    /// [`Self::publish`], then removes the files of `previous` (an earlier run's) that this
    /// set does not hold. The renames and removals are first written to a journal
    /// (`.<label>.kinescan-publish.json` beside the last file, durably), removed when all are
    /// done: a process killed in between leaves the journal, and the next command that
    /// writes the folder completes the publication from it ([`prepare_folder`]) before
    /// anything else, so the folder holds the old set or the new one, never a mix.
    pub fn publish_replacing(self, last: &[PathBuf], previous: &[PathBuf]) -> Result<Vec<PathBuf>> {
        let mut moves = Vec::new();
        for (dir, t) in &self.staging {
            let entries = std::fs::read_dir(t.path()).map_err(|e| Error::io(dir, e))?;
            for entry in entries {
                let entry = entry.map_err(|e| Error::io(dir, e))?;
                // Folders (an import staging folder still being removed) are not outputs.
                if entry.file_type().is_ok_and(|t| t.is_file()) {
                    moves.push((entry.path(), dir.join(entry.file_name())));
                }
            }
        }
        let rank = |dest: &PathBuf| last.iter().position(|l| l == dest).map_or(0, |k| k + 1);
        moves.sort_by(|a, b| rank(&a.1).cmp(&rank(&b.1)).then_with(|| a.1.cmp(&b.1)));
        let produced: Vec<PathBuf> = moves.iter().map(|(_, to)| to.clone()).collect();
        let absolute = |p: &Path| std::path::absolute(p).map_err(|e| Error::io(p, e));
        let journal = Journal {
            pid: std::process::id(),
            moves: moves
                .iter()
                .map(|(from, to)| Ok((absolute(from)?, absolute(to)?)))
                .collect::<Result<_>>()?,
            remove: previous
                .iter()
                .filter(|p| !produced.contains(p))
                .map(|p| absolute(p))
                .collect::<Result<_>>()?,
        };
        let Some((_, anchor)) = moves.last() else {
            journal.apply()?;
            return Ok(produced);
        };
        let journal_dir = parent_dir(anchor).to_path_buf();
        let journal_path = journal_dir.join(format!(".{}{PUBLISH_JOURNAL_SUFFIX}", self.label));
        write_json(&journal_path, &journal)?;
        journal.apply()?;
        std::fs::remove_file(&journal_path).map_err(|e| Error::io(&journal_path, e))?;
        sync_dir(&journal_dir).map_err(|e| Error::io(&journal_dir, e))?;
        Ok(produced)
    }
}

/// A publication's renames (staged file, destination) and removals, absolute paths.
#[derive(Debug, Serialize, Deserialize)]
struct Journal {
    /// The publishing process: its journal is completed by another only once it is dead.
    pid: u32,
    moves: Vec<(PathBuf, PathBuf)>,
    remove: Vec<PathBuf>,
}

/// Test hook: the process aborts (as a kill would stop it) right after this many renames of a
/// publication (`KINESCAN_TEST_ABORT_AFTER_RENAMES=N`), so tests can stop one between its
/// renames.
const ABORT_HOOK: &str = "KINESCAN_TEST_ABORT_AFTER_RENAMES";

impl Journal {
    /// Does what the journal says; what a killed publication already did is skipped (a staged
    /// file gone and its destination there was renamed).
    fn apply(&self) -> Result<()> {
        let abort_after: Option<usize> =
            std::env::var(ABORT_HOOK).ok().and_then(|v| v.parse().ok());
        for (k, (from, to)) in self.moves.iter().enumerate() {
            match std::fs::rename(from, to) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound && to.is_file() => {}
                Err(e) => return Err(Error::io(to, e)),
            }
            if abort_after == Some(k + 1) {
                std::process::abort();
            }
        }
        let mut dirs: Vec<&Path> = self.moves.iter().map(|(_, to)| parent_dir(to)).collect();
        dirs.sort();
        dirs.dedup();
        for dir in dirs {
            sync_dir(dir).map_err(|e| Error::io(dir, e))?;
        }
        remove_unproduced(&self.remove, &[])?;
        Ok(())
    }
}

/// Completes the publications a killed process left in `dir` (their journals), then removes
/// the temporaries of dead processes: what every command does first in a folder it writes.
/// Returns the journals completed.
pub fn prepare_folder(dir: &Path) -> Result<Vec<PathBuf>> {
    let completed = complete_interrupted(dir)?;
    remove_stale_temps(dir)?;
    Ok(completed)
}

/// The journals of interrupted publications in `dir`.
pub fn interrupted_publications(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut found: Vec<PathBuf> = entries
        .filter_map(|e| e.ok())
        .filter(|e| {
            e.file_name()
                .to_str()
                .is_some_and(|n| n.starts_with('.') && n.ends_with(PUBLISH_JOURNAL_SUFFIX))
        })
        .map(|e| e.path())
        .collect();
    found.sort();
    found
}

/// Completes every interrupted publication of `dir` from its journal.
fn complete_interrupted(dir: &Path) -> Result<Vec<PathBuf>> {
    let journals = interrupted_publications(dir);
    let mut completed = Vec::new();
    for path in &journals {
        let text = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let journal: Journal = serde_json::from_slice(&text).map_err(|e| {
            Error::bad_file(
                path,
                format!("publication journal unreadable ({e}): remove it and run again"),
            )
        })?;
        if journal.pid != std::process::id() && process_alive(journal.pid) {
            continue;
        }
        journal.apply()?;
        std::fs::remove_file(path).map_err(|e| Error::io(path, e))?;
        sync_dir(dir).map_err(|e| Error::io(dir, e))?;
        completed.push(path.clone());
    }
    Ok(completed)
}

/// Ends a run writing into `set`: when `result` is a success, publishes the set (`report`
/// last) and removes the `previous` run's files this run did not produce; otherwise drops the
/// set (the previous outputs stay) and gives the error naming the user's paths.
pub fn conclude<T>(
    set: OutputSet,
    result: Result<T>,
    report: &Path,
    previous: &[PathBuf],
) -> Result<T> {
    let value = result.map_err(|e| set.user_error(e))?;
    set.publish_replacing(&[report.to_path_buf()], previous)?;
    Ok(value)
}

/// Runs a command's `write` with the staging folder of `out_dir` and publishes what it wrote
/// there as one set, `last` (a file name) after all others. Files of `names` (every name the
/// command may write) that a previous run left and this one did not write are removed. On an
/// error nothing under a final name changes and the error names `out_dir`'s files.
pub fn publish_folder<T>(
    out_dir: &Path,
    label: &str,
    last: &str,
    names: &[&str],
    write: impl FnOnce(&Path) -> Result<T>,
) -> Result<T> {
    // A killed run's publication is completed, its staging folder goes, before this run
    // stages its own.
    prepare_folder(out_dir)?;
    let mut set = OutputSet::new(label);
    let last = out_dir.join(last);
    let staged = set.stage(&last)?;
    let value = write(parent_dir(&staged));
    let previous: Vec<PathBuf> = names
        .iter()
        .map(|n| out_dir.join(n))
        .filter(|f| f.is_file())
        .collect();
    conclude(set, value, &last, &previous)
}

/// An exclusive lock on an output stem, held while a run writes and publishes it: the file
/// `.<stem>.kinescan-lock` beside the output (empty, kept; the lock is the OS's, released when
/// the process ends however it ends).
///
/// The lock file is opened close-on-exec (std opens every file with `O_CLOEXEC`), so a child
/// process never keeps it past its `exec`. A child forked by another thread holds a copy of
/// the descriptor between its fork and its exec, and a `flock` lock lasts until the last copy
/// is closed: dropping the lock therefore unlocks explicitly (`LOCK_UN` acts on the shared
/// open file, whatever copies exist) before closing.
pub struct StemLock {
    file: File,
}

impl Drop for StemLock {
    fn drop(&mut self) {
        // An error here leaves the lock to the close below (and to the process's end).
        let _ = self.file.unlock();
    }
}

impl StemLock {
    /// Takes the lock for outputs named after `las`, or fails at once naming the lock when
    /// another run holds it.
    pub fn acquire(las: &Path) -> Result<StemLock> {
        let stem = las.file_stem().unwrap_or_default().to_string_lossy();
        Self::acquire_in(parent_dir(las), &stem, las)
    }

    /// Takes the lock `.<stem>.kinescan-lock` in `dir`, or fails at once naming `what` (the
    /// output or folder the user gave) and the lock when another run holds it.
    pub fn acquire_in(dir: &Path, stem: &str, what: &Path) -> Result<StemLock> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let path = dir.join(format!(".{stem}.kinescan-lock"));
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| Error::io(&path, e))?;
        match file.try_lock() {
            Ok(()) => Ok(StemLock { file }),
            Err(std::fs::TryLockError::WouldBlock) => Err(Error::bad_file(
                what,
                format!(
                    "another kinescan run is writing these outputs (it holds {}): wait for it \
                     to end, or write to another path",
                    path.display()
                ),
            )),
            Err(std::fs::TryLockError::Error(e)) => Err(Error::io(&path, e)),
        }
    }
}

/// Whether file name `name` is an output of stem `stem` with one of `extensions`: `<stem>.*`
/// or `<stem>_*` (a split or a tile), the names a run may replace.
pub fn stem_owns(stem: &str, name: &str, extensions: &[&str]) -> bool {
    let named = name
        .strip_prefix(stem)
        .is_some_and(|rest| rest.starts_with('.') || rest.starts_with('_'));
    named && extensions.iter().any(|e| name.ends_with(e))
}

/// The outputs a previous run listed in its report at `report` (`outputs[].path` and
/// `sync[].plots[]`) that this run may remove ([`paths::removable`]): by file name in
/// `folder`, named as this run would name them (`owned`), none of `inputs`. None without a
/// readable report.
pub fn previous_outputs(
    report: &Path,
    folder: &Path,
    owned: impl Fn(&str) -> bool,
    inputs: &[KeyedPath],
) -> Vec<PathBuf> {
    let Ok(text) = std::fs::read(report) else {
        return Vec::new();
    };
    let Ok(json) = serde_json::from_slice::<serde_json::Value>(&text) else {
        return Vec::new();
    };
    let outputs = json["outputs"].as_array().into_iter().flatten();
    let plots = json["sync"]
        .as_array()
        .into_iter()
        .flatten()
        .flat_map(|s| s["plots"].as_array().into_iter().flatten());
    let listed = outputs
        .map(|o| &o["path"])
        .chain(plots)
        .filter_map(|p| p.as_str().map(PathBuf::from));
    paths::removable(listed, folder, owned, inputs)
}

/// Removes the files of `previous` that this run did not produce (`produced`), so a folder
/// never mixes two runs' files; returns those removed.
pub fn remove_unproduced(previous: &[PathBuf], produced: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut removed = Vec::new();
    for p in previous {
        if produced.contains(p) {
            continue;
        }
        match std::fs::remove_file(p) {
            Ok(()) => removed.push(p.clone()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io(p, e)),
        }
    }
    Ok(removed)
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

    #[test]
    fn nothing_appears_before_publish_and_a_dropped_set_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.las"), b"old").unwrap();
        let mut set = OutputSet::new("a");
        let staged = set.stage(&dir.path().join("a.las")).unwrap();
        std::fs::write(&staged, b"new").unwrap();
        assert_eq!(set.final_path(&staged), dir.path().join("a.las"));
        drop(set);
        assert_eq!(names(dir.path()), ["a.las"]);
        assert_eq!(std::fs::read(dir.path().join("a.las")).unwrap(), b"old");
    }

    #[test]
    fn publish_moves_every_staged_file_and_the_last_ones_last() {
        let dir = tempfile::tempdir().unwrap();
        let mut set = OutputSet::new("a");
        let report = dir.path().join("a.report.json");
        for name in ["a_0001.las", "a_0002.las", "a.report.json"] {
            std::fs::write(set.stage(&dir.path().join(name)).unwrap(), name).unwrap();
        }
        let order = set.publish(std::slice::from_ref(&report)).unwrap();
        assert_eq!(order.last(), Some(&report));
        assert_eq!(
            names(dir.path()),
            ["a.report.json", "a_0001.las", "a_0002.las"]
        );
    }

    #[test]
    fn a_staged_file_is_published_with_the_bytes_of_its_source_which_stays() {
        let dir = tempfile::tempdir().unwrap();
        let unit = dir.path().join("units").join("u.las");
        crate::io::atomic::write_atomic(&unit, b"records").unwrap();
        std::fs::write(dir.path().join("p.las"), b"old").unwrap();
        let mut set = OutputSet::new("day");
        let staged = set.stage_file(&dir.path().join("p.las"), &unit).unwrap();
        assert_eq!(set.final_path(&staged), dir.path().join("p.las"));
        assert_eq!(std::fs::read(dir.path().join("p.las")).unwrap(), b"old");
        set.publish(&[]).unwrap();
        assert_eq!(std::fs::read(dir.path().join("p.las")).unwrap(), b"records");
        assert_eq!(std::fs::read(&unit).unwrap(), b"records");
        assert_eq!(names(dir.path()), ["p.las", "units"]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let links = std::fs::metadata(&unit).unwrap().nlink();
            assert_eq!(links, 2, "linked, not copied");
        }
        // Staging it again over its own link publishes the same bytes.
        let mut set = OutputSet::new("day");
        set.stage_file(&dir.path().join("p.las"), &unit).unwrap();
        set.publish(&[]).unwrap();
        assert_eq!(std::fs::read(dir.path().join("p.las")).unwrap(), b"records");
        assert_eq!(names(dir.path()), ["p.las", "units"]);
        // A source that is not there is named.
        let mut set = OutputSet::new("day");
        let gone = dir.path().join("units").join("gone.las");
        let e = set
            .stage_file(&dir.path().join("q.las"), &gone)
            .unwrap_err();
        assert!(e.to_string().contains("gone.las"), "{e}");
    }

    /// A source on another filesystem (tmpfs /dev/shm against the temporary folder's) cannot
    /// be linked: its bytes are copied into the staging folder instead.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_file_from_another_filesystem_is_staged_by_a_copy() {
        use std::os::unix::fs::MetadataExt;
        let shm = tempfile::tempdir_in("/dev/shm").unwrap();
        let dir = tempfile::tempdir().unwrap();
        let dev = |p: &Path| std::fs::metadata(p).unwrap().dev();
        assert_ne!(dev(shm.path()), dev(dir.path()), "needs two filesystems");
        let unit = shm.path().join("u.las");
        std::fs::write(&unit, b"records").unwrap();
        let mut set = OutputSet::new("day");
        set.stage_file(&dir.path().join("p.las"), &unit).unwrap();
        set.publish(&[]).unwrap();
        assert_eq!(std::fs::read(dir.path().join("p.las")).unwrap(), b"records");
        assert_eq!(names(dir.path()), ["p.las"]);
        assert_eq!(
            std::fs::metadata(&unit).unwrap().nlink(),
            1,
            "copied, not linked"
        );
    }

    #[test]
    fn a_second_lock_on_one_stem_fails_naming_the_lock() {
        let dir = tempfile::tempdir().unwrap();
        let las = dir.path().join("day.las");
        let held = StemLock::acquire(&las).unwrap();
        let e = StemLock::acquire(&las).err().unwrap().to_string();
        assert!(
            e.contains("another kinescan run") && e.contains(".day.kinescan-lock"),
            "{e}"
        );
        drop(held);
        StemLock::acquire(&las).unwrap();
    }

    /// The lock is close-on-exec (a child never inherits it past exec) and a child that holds
    /// a copy of the descriptor (forked, not yet exec'd) does not keep it after the drop.
    #[test]
    fn a_dropped_lock_is_free_even_while_a_forked_child_holds_its_descriptor() {
        use std::os::fd::AsRawFd;
        let dir = tempfile::tempdir().unwrap();
        let las = dir.path().join("day.las");
        let held = StemLock::acquire(&las).unwrap();
        // SAFETY: fcntl(F_GETFD) on a descriptor this test owns.
        let flags = unsafe { libc::fcntl(held.file.as_raw_fd(), libc::F_GETFD) };
        assert!(
            flags >= 0 && flags & libc::FD_CLOEXEC != 0,
            "fd flags {flags}"
        );
        let listing = std::process::Command::new("ls")
            .args(["-l", "/proc/self/fd"])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&listing.stdout);
        assert!(
            listing.status.success() && text.contains("/proc/"),
            "{text}"
        );
        assert!(
            !text.contains("kinescan-lock"),
            "a child inherited the lock: {text}"
        );
        // SAFETY: the child only calls async-signal-safe functions (sleep, _exit).
        let child = unsafe { libc::fork() };
        if child == 0 {
            unsafe {
                libc::sleep(3);
                libc::_exit(0);
            }
        }
        assert!(child > 0, "fork failed");
        drop(held);
        let again = StemLock::acquire(&las);
        // SAFETY: reaping the child forked above.
        unsafe {
            libc::kill(child, libc::SIGKILL);
            libc::waitpid(child, std::ptr::null_mut(), 0);
        }
        again.expect("the lock outlived its drop in a forked child");
    }
}
