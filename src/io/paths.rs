//! Output paths checked against input paths before a command does any work: an output may
//! never be an input (a night's raw data cannot be recorded again), and two outputs of one
//! command may never be one file.
//!
//! Two paths are the same file when their canonical paths are equal (symbolic links resolved)
//! or, for files that exist, when they share device and inode (hard links). Every command
//! calls [`check_collisions`] with its inputs and outputs, each named by the key the user sets
//! it with (`inputs.sbet`, `output.las`, a command-line argument...).

use crate::{Error, Result};
use std::path::{Component, Path, PathBuf};

/// A file named by the key that sets it (a dotted config key or an argument name).
pub type KeyedPath = (String, PathBuf);

/// What identifies a file on disk: its canonical path and, when it exists, (device, inode).
#[derive(Debug, Clone, PartialEq, Eq)]
struct FileId {
    canonical: PathBuf,
    device_inode: Option<(u64, u64)>,
}

impl FileId {
    fn of(path: &Path) -> FileId {
        FileId {
            canonical: canonical(path),
            device_inode: device_inode(path),
        }
    }

    fn same_as(&self, other: &FileId) -> bool {
        self.canonical == other.canonical
            || (self.device_inode.is_some() && self.device_inode == other.device_inode)
    }
}

#[cfg(unix)]
fn device_inode(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn device_inode(_path: &Path) -> Option<(u64, u64)> {
    None
}

/// The canonical path when the file exists; else its canonical folder joined with its name;
/// else the absolute path with `.` and `..` removed lexically.
fn canonical(path: &Path) -> PathBuf {
    if let Ok(c) = std::fs::canonicalize(path) {
        return c;
    }
    if let (Some(dir), Some(name)) = (path.parent(), path.file_name()) {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        if let Ok(d) = std::fs::canonicalize(dir) {
            return d.join(name);
        }
    }
    lexical_absolute(path)
}

fn lexical_absolute(path: &Path) -> PathBuf {
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut out = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// The files `names` a command writes into its `--out` folder, keyed `--out <name>`.
pub fn in_out_dir(out_dir: &Path, names: &[&str]) -> Vec<KeyedPath> {
    names
        .iter()
        .map(|n| (format!("--out {n}"), out_dir.join(n)))
        .collect()
}

/// Refuses any output that is the same file as an input, and any two outputs that are the
/// same file, with an error naming both keys and both paths. Call it before any work.
pub fn check_collisions(inputs: &[KeyedPath], outputs: &[KeyedPath]) -> Result<()> {
    let input_ids: Vec<FileId> = inputs.iter().map(|(_, p)| FileId::of(p)).collect();
    let output_ids: Vec<FileId> = outputs.iter().map(|(_, p)| FileId::of(p)).collect();
    let collision = |(key, path): &KeyedPath, (other_key, other): &KeyedPath, what: &str| {
        Err(Error::Collision {
            output_key: key.clone(),
            output: path.clone(),
            other_key: other_key.clone(),
            other: other.clone(),
            problem: format!("is the same file as the {what}"),
        })
    };
    for (o, output) in outputs.iter().enumerate() {
        if let Some(i) = input_ids.iter().position(|id| output_ids[o].same_as(id)) {
            return collision(output, &inputs[i], "input");
        }
        if let Some(e) = output_ids[..o]
            .iter()
            .position(|id| output_ids[o].same_as(id))
        {
            return collision(output, &outputs[e], "output");
        }
    }
    Ok(())
}

/// Existing files directly in `dir` whose name `owned` accepts, keyed `key`: the files a
/// command may overwrite or remove though it cannot name them before it runs (split parts,
/// tiles, work units). List them among its outputs so that none of them may be an input.
pub fn existing_owned(dir: &Path, key: &str, owned: impl Fn(&str) -> bool) -> Vec<KeyedPath> {
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut found: Vec<KeyedPath> = entries
        .filter_map(|e| e.ok())
        .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
        .filter(|e| e.file_name().to_str().is_some_and(&owned))
        .map(|e| (key.to_string(), dir.join(e.file_name())))
        .collect();
    found.sort();
    found
}

/// The files of a previous run's list (its report: a hint, never a licence to delete) that a
/// command may remove: each taken by its file name inside `folder` (where this command
/// writes, whatever folder the list names), kept only when `owned` accepts the name (a file
/// this command would write) and it is none of `inputs`.
pub fn removable(
    listed: impl IntoIterator<Item = PathBuf>,
    folder: &Path,
    owned: impl Fn(&str) -> bool,
    inputs: &[KeyedPath],
) -> Vec<PathBuf> {
    let input_ids: Vec<FileId> = inputs.iter().map(|(_, p)| FileId::of(p)).collect();
    let mut kept: Vec<PathBuf> = listed
        .into_iter()
        .filter_map(|p| {
            let name = p.file_name()?.to_str()?.to_string();
            // A name, never a path: `..` or a separator cannot leave the folder.
            (owned(&name) && name != ".." && name != ".").then(|| folder.join(name))
        })
        .filter(|p| {
            let id = FileId::of(p);
            !input_ids.iter().any(|i| id.same_as(i))
        })
        .collect();
    kept.sort();
    kept.dedup();
    kept
}

/// Refuses two inputs of `inputs` that are one file (the same path, a symbolic or hard link)
/// or hold the same bytes (a copy): their records would be processed twice.
pub fn check_distinct_inputs(inputs: &[KeyedPath]) -> Result<()> {
    let ids: Vec<FileId> = inputs.iter().map(|(_, p)| FileId::of(p)).collect();
    let sizes: Vec<Option<u64>> = inputs
        .iter()
        .map(|(_, p)| std::fs::metadata(p).ok().map(|m| m.len()))
        .collect();
    for b in 0..inputs.len() {
        for a in 0..b {
            let how = if ids[a].same_as(&ids[b]) {
                "is the same file as"
            } else if sizes[a].is_some()
                && sizes[a] == sizes[b]
                && same_bytes(&inputs[a].1, &inputs[b].1)?
            {
                "holds the same bytes as"
            } else {
                continue;
            };
            let ((ka, pa), (kb, pb)) = (&inputs[a], &inputs[b]);
            return Err(Error::Invalid(format!(
                "`{kb}` ({}) {how} `{ka}` ({}): its records would be processed twice; list \
                 each file once",
                pb.display(),
                pa.display()
            )));
        }
    }
    Ok(())
}

/// Whether two files of equal size hold the same bytes (compared in blocks, stopping at the
/// first difference, so two different recordings cost one block each).
fn same_bytes(a: &Path, b: &Path) -> Result<bool> {
    use std::io::Read;
    let open = |p: &Path| std::fs::File::open(p).map_err(|e| Error::io(p, e));
    let (mut fa, mut fb) = (open(a)?, open(b)?);
    let (mut ba, mut bb) = (vec![0u8; 1 << 16], vec![0u8; 1 << 16]);
    loop {
        let na = read_full(&mut fa, &mut ba).map_err(|e| Error::io(a, e))?;
        let nb = read_full(&mut fb, &mut bb).map_err(|e| Error::io(b, e))?;
        if na != nb || ba[..na] != bb[..nb] {
            return Ok(false);
        }
        if na == 0 {
            return Ok(true);
        }
    }
    fn read_full(f: &mut std::fs::File, buf: &mut [u8]) -> std::io::Result<usize> {
        let mut n = 0;
        while n < buf.len() {
            match f.read(&mut buf[n..])? {
                0 => break,
                k => n += k,
            }
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keyed(key: &str, p: &Path) -> KeyedPath {
        (key.to_string(), p.to_path_buf())
    }

    #[test]
    fn distinct_paths_pass_and_equal_paths_fail_naming_both_keys() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("a.sbet");
        std::fs::write(&input, b"x").unwrap();
        let las = dir.path().join("out.las");
        check_collisions(
            &[keyed("inputs.sbet", &input)],
            &[keyed("output.las", &las)],
        )
        .unwrap();
        // The same file through `./` and `..` is still the same file.
        let odd = dir.path().join("sub").join("..").join(".").join("a.sbet");
        let e = check_collisions(
            &[keyed("inputs.sbet", &input)],
            &[keyed("output.las", &odd)],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("output.las") && e.contains("inputs.sbet"), "{e}");
        assert!(e.contains(&*input.display().to_string()), "{e}");
    }

    #[test]
    fn outputs_colliding_with_each_other_fail_even_before_they_exist() {
        let dir = tempfile::tempdir().unwrap();
        let las = dir.path().join("out.las");
        let e = check_collisions(
            &[],
            &[keyed("output.las", &las), keyed("output.report", &las)],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("output.las") && e.contains("output.report"),
            "{e}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn symbolic_and_hard_links_are_the_same_file() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("p.ksprof");
        std::fs::write(&input, b"x").unwrap();
        let sym = dir.path().join("sym.las");
        std::os::unix::fs::symlink(&input, &sym).unwrap();
        let hard = dir.path().join("hard.las");
        std::fs::hard_link(&input, &hard).unwrap();
        for out in [&sym, &hard] {
            let r = check_collisions(&[keyed("inputs.profiles[0]", &input)], &[keyed("o", out)]);
            assert!(r.is_err(), "{} not refused", out.display());
        }
    }

    #[test]
    fn a_listed_file_is_removable_only_inside_the_folder_by_an_owned_name_and_no_input() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let input = out.join("p01.las");
        std::fs::write(&input, b"x").unwrap();
        let listed = vec![
            dir.path().join("elsewhere").join("a.las"),
            Path::new("/etc/passwd").to_path_buf(),
            out.join("p01.las"),
            out.join("notes.txt"),
        ];
        let owned = |n: &str| n.ends_with(".las");
        let kept = removable(
            listed,
            &out,
            owned,
            &[keyed("passes[0].profiles[0]", &input)],
        );
        assert_eq!(kept, [out.join("a.las")]);
    }

    #[test]
    fn the_same_file_twice_by_path_link_or_copy_is_refused_naming_both_keys() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.ksprof");
        std::fs::write(&a, vec![7u8; 200_000]).unwrap();
        let mut other = vec![7u8; 200_000];
        other[150_000] = 8;
        let b = dir.path().join("b.ksprof");
        std::fs::write(&b, &other).unwrap();
        check_distinct_inputs(&[keyed("p[0]", &a), keyed("p[1]", &b)]).unwrap();
        let copy = dir.path().join("copy.ksprof");
        std::fs::copy(&a, &copy).unwrap();
        let mut twins = vec![a.clone(), dir.path().join(".").join("a.ksprof"), copy];
        #[cfg(unix)]
        {
            let sym = dir.path().join("sym.ksprof");
            std::os::unix::fs::symlink(&a, &sym).unwrap();
            twins.push(sym);
        }
        for twin in twins {
            let e = check_distinct_inputs(&[keyed("p[0]", &a), keyed("p[1]", &twin)])
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("`p[1]`") && e.contains("`p[0]`") && e.contains("twice"),
                "{e}"
            );
        }
    }
}
