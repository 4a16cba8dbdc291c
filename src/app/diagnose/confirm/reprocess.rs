//! Re-processing with the chosen effects: each estimate is added to the configured value it
//! corrects (docs/conventions.md §8), as `--set` lines on the loaded pipeline, and a corrected
//! pipeline file that `kinescan run` accepts is written.

use crate::app::diagnose::model::Effect;
use crate::io::atomic::write_atomic;
use crate::io::config_file;
use crate::pipeline::config::{LoadedPipeline, PipelineConfig, TimeModel};
use crate::{Error, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// File name of the corrected pipeline in the diagnosis folder.
pub const CORRECTED_PIPELINE: &str = "corrected.toml";
/// File name of the LAS the corrected pipeline writes (beside it).
pub const CORRECTED_LAS: &str = "corrected.las";

/// The pipeline key an effect corrects, and the element for array keys.
pub fn corrected_key(e: Effect) -> (&'static str, Option<usize>) {
    match e {
        Effect::AttitudeLatency => ("latency.attitude_s", None),
        Effect::PositionLatency => ("latency.position_s", None),
        Effect::ClockOffset => ("time.t0_s", None),
        Effect::ClockDrift => ("time.period_s", None),
        Effect::BoresightX => ("sensor.boresight_deg", Some(0)),
        Effect::BoresightY => ("sensor.boresight_deg", Some(1)),
        Effect::BoresightZ => ("sensor.boresight_deg", Some(2)),
        Effect::LeverArmX => ("sensor.lever_arm_b_m", Some(0)),
        Effect::LeverArmY => ("sensor.lever_arm_b_m", Some(1)),
        Effect::LeverArmZ => ("sensor.lever_arm_b_m", Some(2)),
        Effect::RangeZero => ("sensor.range_zero_m", None),
        Effect::RangeScale => ("sensor.range_scale_ppm", None),
        Effect::EncoderOffset => ("sensor.encoder_offset_deg", None),
        Effect::Cone => ("sensor.alpha0_deg", None),
        Effect::HeadingOffset => ("trajectory.heading_offset_deg", None),
    }
}

/// A pipeline value as a number or a 3-array.
#[derive(Debug, Clone, PartialEq)]
enum Value {
    Scalar(f64),
    Vector([f64; 3]),
}

/// The configured value of a key.
fn configured(c: &PipelineConfig, key: &str) -> Result<Value> {
    Ok(match key {
        "latency.attitude_s" => Value::Scalar(c.latency.attitude_s),
        "latency.position_s" => Value::Scalar(c.latency.position_s),
        "time.t0_s" => {
            if c.time.model != TimeModel::Software {
                let problem = "clock_offset_s corrects time.t0_s, used by the software time \
                               model only";
                return Err(Error::Invalid(problem.into()));
            }
            Value::Scalar(c.time.t0_s.unwrap_or(0.0))
        }
        "time.period_s" => Value::Scalar(c.time.period_s),
        "sensor.boresight_deg" => Value::Vector(c.sensor.boresight_deg),
        "sensor.lever_arm_b_m" => Value::Vector(c.sensor.lever_arm_b_m),
        "sensor.range_zero_m" => Value::Scalar(c.sensor.range_zero_m),
        "sensor.alpha0_deg" => Value::Scalar(c.sensor.alpha0_deg),
        "sensor.range_scale_ppm" => Value::Scalar(c.sensor.range_scale_ppm),
        "sensor.encoder_offset_deg" => Value::Scalar(c.sensor.encoder_offset_deg),
        "trajectory.heading_offset_deg" => Value::Scalar(c.trajectory.heading_offset_deg),
        other => unreachable!("{other} is not a corrected key"),
    })
}

/// The `--set` lines that add each estimate to the value it corrects (`clock_drift_ppm`
/// scales the period: `T (1 + x 1e-6)`). Array keys get one line with every element.
pub fn set_lines(c: &PipelineConfig, estimates: &[(Effect, f64)]) -> Result<Vec<String>> {
    let mut values: BTreeMap<&str, Value> = BTreeMap::new();
    for &(e, x) in estimates {
        let (key, element) = corrected_key(e);
        let v = match values.remove(key) {
            Some(v) => v,
            None => configured(c, key)?,
        };
        let v = match (v, element) {
            (Value::Scalar(p), None) if e == Effect::ClockDrift => {
                Value::Scalar(p * (1.0 + x * 1e-6))
            }
            (Value::Scalar(p), None) => Value::Scalar(p + x),
            (Value::Vector(mut a), Some(k)) => {
                a[k] += x;
                Value::Vector(a)
            }
            _ => unreachable!("element given for array keys only"),
        };
        values.insert(key, v);
    }
    Ok(values
        .into_iter()
        .map(|(key, v)| match v {
            Value::Scalar(x) => format!("{key}={x:?}"),
            Value::Vector([a, b, c]) => format!("{key}=[{a:?}, {b:?}, {c:?}]"),
        })
        .collect())
}

/// The pipeline `p` as given (in memory: a day's pass pipeline carries its own profile files
/// and clock) with `set` added, writing its LAS to `out_dir/corrected.las`.
pub fn corrected(p: &LoadedPipeline, set: &[String], out_dir: &Path) -> Result<LoadedPipeline> {
    let mut loaded = p.with_overrides(set)?;
    loaded.config.output.las = out_dir.join(CORRECTED_LAS).into();
    loaded.config.output.report = None;
    Ok(loaded)
}

/// Writes `c` as a pipeline file at `path` that `kinescan run` accepts on its own: every path
/// absolute, the origin and the `--set` lines in a header comment.
pub fn write_pipeline(
    c: &PipelineConfig,
    origin: &Path,
    set: &[String],
    path: &Path,
) -> Result<()> {
    let body = toml::to_string(c).map_err(|e| Error::Invalid(format!("pipeline TOML: {e}")))?;
    // Re-read with relative paths resolved against the working directory: every path absolute.
    let cwd = std::path::absolute(".").map_err(|e| Error::io(".", e))?;
    let c: PipelineConfig = config_file::parse(&body, "corrected pipeline", &cwd, &[])?.value;
    let body = toml::to_string(&c).map_err(|e| Error::Invalid(format!("pipeline TOML: {e}")))?;
    let mut text = format!(
        "# Written by `kinescan diagnose`: {} with the diagnosed correction added\n",
        origin.display()
    );
    for line in set {
        text.push_str(&format!("#   --set {line}\n"));
    }
    text.push('\n');
    text.push_str(&body);
    write_atomic(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::config;

    const PIPELINE: &str = r#"
[inputs]
sbet = "survey/trajectory.sbet"
smrmsg = "survey/trajectory.smrmsg"
profiles = ["survey/profiles.bin"]
[sensor]
lever_arm_b_m = [-0.6, 0.0, -0.5]
boresight_deg = [0.1, 0.0, 0.0]
[time]
t0_s = 345601.0
period_s = 0.01
[output]
las = "out/x.las"
"#;

    fn loaded(dir: &Path) -> LoadedPipeline {
        let path = dir.join("p.toml");
        std::fs::write(&path, PIPELINE).unwrap();
        config::load(&path, &["latency.attitude_s=0.001".into()]).unwrap()
    }

    #[test]
    fn set_lines_add_the_estimates_to_the_configured_values() {
        let dir = tempfile::tempdir().unwrap();
        let p = loaded(dir.path());
        let est = [
            (Effect::LeverArmY, 0.03),
            (Effect::BoresightX, -0.05),
            (Effect::LeverArmZ, 0.01),
            (Effect::AttitudeLatency, 0.002),
            (Effect::ClockDrift, 100.0),
        ];
        let lines = set_lines(&p.config, &est).unwrap();
        assert_eq!(
            lines,
            [
                "latency.attitude_s=0.003",
                "sensor.boresight_deg=[0.05, 0.0, 0.0]",
                "sensor.lever_arm_b_m=[-0.6, 0.03, -0.49]",
                "time.period_s=0.010001",
            ]
        );
    }

    #[test]
    fn the_corrected_pipeline_file_loads_to_the_corrected_configuration() {
        let dir = tempfile::tempdir().unwrap();
        let p = loaded(dir.path());
        let lines = set_lines(&p.config, &[(Effect::RangeZero, 0.02)]).unwrap();
        let out = dir.path().join("diag");
        std::fs::create_dir_all(&out).unwrap();
        let c = corrected(&p, &lines, &out).unwrap();
        assert_eq!(c.config.sensor.range_zero_m, 0.02);
        assert_eq!(
            c.config.latency.attitude_s, 0.001,
            "the run's own overrides are kept"
        );
        // A change made in memory after loading (a day's pass: its own profile files) stays.
        let mut pass = p.clone();
        pass.config.inputs.profiles = vec![dir.path().join("survey/p02.bin").into()];
        let c2 = corrected(&pass, &lines, &out).unwrap();
        assert_eq!(c2.config.inputs.profiles, pass.config.inputs.profiles);
        assert_eq!(c2.config.sensor.range_zero_m, 0.02);
        let path = out.join(CORRECTED_PIPELINE);
        write_pipeline(&c.config, &p.path, &lines, &path).unwrap();
        let again = config::load(&path, &[]).unwrap();
        assert_eq!(again.config, c.config);
        assert_eq!(again.config.output.las.as_path(), out.join(CORRECTED_LAS));
    }
}
