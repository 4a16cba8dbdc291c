//! Every file a pipeline reads and every file a run may write, named by the key that sets it,
//! checked against each other before any work (`io::paths`).

use super::config::{LoadedPipeline, OutputConfig, OutputFormat, PipelineConfig, SplitMode};
use crate::io::paths::{check_collisions, check_distinct_inputs, KeyedPath};
use crate::Result;
use std::path::{Path, PathBuf};

impl OutputConfig {
    /// The run report's path: `output.report`, or `<las stem>.report.json` beside the LAS.
    pub fn report_path(&self) -> PathBuf {
        self.report
            .as_deref()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| self.las.with_extension("report.json"))
    }

    /// The output file (unsplit): `output.las` with the format's extension (`.laz` for LAZ;
    /// LAS keeps the name as given).
    pub fn cloud_path(&self) -> PathBuf {
        match self.format {
            OutputFormat::Las => self.las.to_path_buf(),
            f => self.las.with_extension(f.extension()),
        }
    }

    /// File stem of `output.las`: the base of split names and sync plot names.
    pub fn stem(&self) -> String {
        self.las
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "cloud".into())
    }
}

/// Path of split part `part` (1-based) of a `split = "max_points"` output with extension
/// `ext`.
pub fn numbered_part(las: &Path, stem: &str, part: u32, ext: &str) -> PathBuf {
    las.with_file_name(format!("{stem}_{part:04}.{ext}"))
}

/// Path of the output of profile file `profile` with `split = "per_input"` and extension
/// `ext`.
pub fn per_input_part(las: &Path, stem: &str, profile: &Path, ext: &str) -> PathBuf {
    let input_stem = profile
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    las.with_file_name(format!("{stem}_{input_stem}.{ext}"))
}

/// Every input of a pipeline: the pipeline file, trajectory, accuracy, profile, sync point and
/// target files, geoid grid, diagnosis reference patches.
pub fn inputs(p: &LoadedPipeline) -> Vec<KeyedPath> {
    let c = &p.config;
    let mut v = vec![
        ("pipeline file".to_string(), p.path.clone()),
        ("inputs.sbet".to_string(), c.inputs.sbet.to_path_buf()),
    ];
    if let Some(s) = &c.inputs.smrmsg {
        v.push(("inputs.smrmsg".into(), s.to_path_buf()));
    }
    for (k, f) in c.inputs.profiles.iter().enumerate() {
        v.push((format!("inputs.profiles[{k}]"), f.to_path_buf()));
    }
    if let Some(sy) = &c.sync {
        v.push(("sync.points".into(), sy.points.to_path_buf()));
        if let Some(t) = &sy.targets {
            v.push(("sync.targets".into(), t.to_path_buf()));
        }
    }
    if let Some(g) = &c.output.geoid {
        v.push(("output.geoid".into(), g.to_path_buf()));
    }
    if let Some(patches) = c.diagnose.as_ref().and_then(|d| d.patches.as_ref()) {
        v.push(("diagnose.patches".into(), patches.to_path_buf()));
    }
    v
}

/// Every file a run may write: the LAS (or LAZ) file(s), the report and the sync plots. With
/// `split = "max_points"` the number of parts is not known before the run: the first part and
/// every existing file the run could overwrite (`<stem>_NNNN.las`, `.laz`) are listed.
pub fn outputs(c: &PipelineConfig) -> Vec<KeyedPath> {
    let o = &c.output;
    let stem = o.stem();
    let ext = o.format.extension();
    let mut v: Vec<KeyedPath> = match o.split {
        SplitMode::None => vec![("output.las".into(), o.cloud_path())],
        SplitMode::PerInput => c
            .inputs
            .profiles
            .iter()
            .enumerate()
            .map(|(k, f)| {
                let key = format!("output.las (split per input, inputs.profiles[{k}])");
                (key, per_input_part(&o.las, &stem, f, ext))
            })
            .collect(),
        SplitMode::MaxPoints => {
            let mut parts = existing_numbered_parts(&o.las, &stem, ext);
            parts.push(numbered_part(&o.las, &stem, 1, ext));
            parts.sort();
            parts.dedup();
            parts
                .into_iter()
                .map(|p| ("output.las (split by max_points)".to_string(), p))
                .collect()
        }
    };
    v.push(("output.report".into(), o.report_path()));
    if c.sync.as_ref().is_some_and(|s| s.plots) {
        let dir = o.las.parent().unwrap_or(Path::new(""));
        for k in 0..c.inputs.profiles.len() {
            for kind in ["times", "residuals", "hardware"] {
                let name = format!("{stem}_sync{k}_{kind}.png");
                v.push(("sync.plots".into(), dir.join(name)));
            }
        }
    }
    v
}

/// Existing files `<stem>_NNNN.<ext>` (four or more digits) beside `las`.
pub fn existing_numbered_parts(las: &Path, stem: &str, ext: &str) -> Vec<PathBuf> {
    let dir = match las.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let (prefix, suffix) = (format!("{stem}_"), format!(".{ext}"));
    entries
        .filter_map(|e| e.ok())
        .filter(|e| {
            let name = e.file_name();
            let name = name.to_string_lossy();
            name.strip_prefix(&prefix)
                .and_then(|rest| rest.strip_suffix(&suffix))
                .is_some_and(|n| n.len() >= 4 && n.bytes().all(|b| b.is_ascii_digit()))
        })
        .map(|e| las.with_file_name(e.file_name()))
        .collect()
}

/// Refuses a pipeline whose outputs would overwrite one of its inputs or each other, and a
/// profile file listed twice (by path, link or a copy: its points would be written twice).
pub fn check_collisions_of(p: &LoadedPipeline) -> Result<()> {
    let inputs = inputs(p);
    check_collisions(&inputs, &outputs(&p.config))?;
    let profiles: Vec<KeyedPath> = inputs
        .into_iter()
        .filter(|(k, _)| k.starts_with("inputs.profiles"))
        .collect();
    check_distinct_inputs(&profiles)
}
