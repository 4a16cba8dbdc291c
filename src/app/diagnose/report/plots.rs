//! The diagnosis PNGs, drawn with [`crate::plot::Plot`] and written with the project's atomic
//! writer: normalised residuals against the leading covariates, and the held-out normalised
//! residuals before and after the correction.

use super::BinReport;
use crate::io::atomic::write_atomic;
use crate::plot::Plot;
use crate::Result;
use std::path::Path;

/// At most this many points are drawn in a scatter (evenly thinned: the PNG stays readable and
/// its bytes depend only on the data).
const MAX_SCATTER: usize = 4000;
/// The before/after histograms' file.
pub const BEFORE_AFTER: &str = "before_after.png";

/// The file of the plot against covariate `name`.
pub fn covariate_file(name: &str) -> String {
    format!("residuals_{name}.png")
}

/// Image size (px).
const SIZE: (u32, u32) = (900, 560);

/// Normalised residuals against one covariate, with the bin means of its test.
pub fn covariate_plot(name: &str, points: &[(f64, f64)], bins: &[BinReport]) -> Plot {
    let means: Vec<(f64, f64)> = bins
        .iter()
        .map(|b| (0.5 * (b.range[0] + b.range[1]), b.mean))
        .collect();
    Plot::new(
        &format!("Normalised residuals against {name}"),
        name,
        "residual / sigma",
    )
    .size(SIZE.0, SIZE.1)
    .scatter("returns", &thin(points))
    .line("bin mean", &means)
}

/// Histograms of held-out normalised residuals before and after the correction.
pub fn before_after_plot(before: &[f64], after: &[f64]) -> Plot {
    Plot::new(
        "Held-out normalised residuals before and after",
        "residual / sigma",
        "returns",
    )
    .size(SIZE.0, SIZE.1)
    .histogram("before", before, 60)
    .histogram("after", after, 60)
}

/// Renders `plot` into `dir/file` atomically; returns `file`.
pub fn write_png(plot: &Plot, dir: &Path, file: &str) -> Result<String> {
    let bytes = plot.render()?.png_bytes()?;
    write_atomic(&dir.join(file), &bytes)?;
    Ok(file.to_string())
}

fn thin(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    if points.len() <= MAX_SCATTER {
        return points.to_vec();
    }
    (0..MAX_SCATTER)
        .map(|k| points[k * points.len() / MAX_SCATTER])
        .collect()
}
