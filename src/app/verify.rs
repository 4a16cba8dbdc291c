//! `kinescan info FOLDER`: whether a folder holds whole output sets. Every run and day report
//! lists its outputs with their SHA-256; a set is whole when each listed file is in the
//! folder with those bytes and no publication was interrupted there (its journal left,
//! completed by the next command that writes the folder: `io::publish`).

use crate::io::digest::FileRecord;
use crate::io::publish::interrupted_publications;
use crate::{Error, Result};
use serde::Serialize;
use std::fmt;
use std::path::{Path, PathBuf};

/// What `info FOLDER` found.
#[derive(Debug, Clone, Serialize)]
pub struct FolderCheck {
    /// The folder.
    pub folder: PathBuf,
    /// One entry per report found (`*.report.json`), in name order.
    pub sets: Vec<SetCheck>,
    /// Journals of publications a killed process left half done.
    pub interrupted: Vec<PathBuf>,
}

/// One report's set.
#[derive(Debug, Clone, Serialize)]
pub struct SetCheck {
    /// The report.
    pub report: PathBuf,
    /// Outputs listed.
    pub outputs: usize,
    /// Problems: a listed file missing, of other bytes, or listed without a SHA-256.
    pub problems: Vec<String>,
}

impl FolderCheck {
    /// Whether every set is whole and no publication is pending.
    pub fn whole(&self) -> bool {
        self.interrupted.is_empty() && self.sets.iter().all(|s| s.problems.is_empty())
    }
}

/// Checks every report's set in `folder` (files taken by name in the folder, as the reports
/// may hold paths relative to another working folder).
pub fn check_folder(folder: &Path) -> Result<FolderCheck> {
    let entries = std::fs::read_dir(folder).map_err(|e| Error::io(folder, e))?;
    let mut reports: Vec<PathBuf> = entries
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.ends_with(".report.json") && !n.starts_with('.'))
        })
        .collect();
    reports.sort();
    let sets = reports
        .into_iter()
        .map(|r| check_set(folder, r))
        .collect::<Result<_>>()?;
    Ok(FolderCheck {
        folder: folder.to_path_buf(),
        sets,
        interrupted: interrupted_publications(folder),
    })
}

fn check_set(folder: &Path, report: PathBuf) -> Result<SetCheck> {
    let text = std::fs::read(&report).map_err(|e| Error::io(&report, e))?;
    let json: serde_json::Value = serde_json::from_slice(&text)
        .map_err(|e| Error::bad_file(&report, format!("not a JSON report: {e}")))?;
    let listed = json["outputs"].as_array().cloned().unwrap_or_default();
    let mut problems = Vec::new();
    for o in &listed {
        let Some(name) = o["path"].as_str().and_then(|p| Path::new(p).file_name()) else {
            problems.push(format!("an output without a path: {o}"));
            continue;
        };
        let file = folder.join(name);
        let Some(want) = o["sha256"].as_str() else {
            problems.push(format!("{} is listed without a SHA-256", file.display()));
            continue;
        };
        if !file.is_file() {
            problems.push(format!("{} is missing", file.display()));
            continue;
        }
        if FileRecord::of("output", &file)?.sha256 != want {
            problems.push(format!(
                "{} has other bytes than the report lists (another run's, or changed)",
                file.display()
            ));
        }
    }
    Ok(SetCheck {
        report,
        outputs: listed.len(),
        problems,
    })
}

impl fmt::Display for FolderCheck {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let verdict = if self.whole() { "whole" } else { "NOT whole" };
        write!(f, "{}: output sets {verdict}", self.folder.display())?;
        if self.sets.is_empty() {
            write!(f, "\n  no report (*.report.json) in the folder")?;
        }
        for s in &self.sets {
            let state = if s.problems.is_empty() {
                "whole"
            } else {
                "NOT whole"
            };
            write!(
                f,
                "\n  {}: {} output(s), {state}",
                s.report.display(),
                s.outputs
            )?;
            for p in &s.problems {
                write!(f, "\n    {p}")?;
            }
        }
        for j in &self.interrupted {
            write!(
                f,
                "\n  interrupted publication ({}): the next command that writes this folder \
                 completes it",
                j.display()
            )?;
        }
        Ok(())
    }
}
