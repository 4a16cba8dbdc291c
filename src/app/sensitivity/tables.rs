//! The study's CSV tables and share-against-range plots.

use super::{FactorRow, PointResult, SensitivityReport, OUTPUTS};
use crate::plot::{Plot, PALETTE};
use crate::uncertainty::model::{Group, N_INPUTS};
use crate::Result;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Inputs drawn in the per-input plots: those whose linear share of the output reaches this.
const PLOT_INPUT_MIN_SHARE: f64 = 0.1;

/// The PNG plots of share against range, like paper 003's scatter plots, two per output
/// ([`OUTPUTS`]): `share_vs_range_<output>.png` with the six groups and
/// `share_vs_range_inputs_<output>.png` with the inputs whose linear share reaches 10% at
/// some point (at most 8, largest first). Each factor is drawn in one colour: its first-order
/// Sobol index at every point as markers, its analytic linear share as a line through the
/// points in range order.
pub(super) fn plot_share_against_range(
    r: &SensitivityReport,
    out_dir: &Path,
) -> Result<Vec<PathBuf>> {
    let mut order: Vec<&PointResult> = r.points.iter().collect();
    order.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
    let mut written = Vec::new();
    for (k, output) in OUTPUTS.iter().enumerate() {
        let series = |f: usize| -> [Vec<(f64, f64)>; 2] {
            let pts = |v: &dyn Fn(&FactorRow) -> f64| {
                order
                    .iter()
                    .map(|p| (p.range_m, v(&p.factors[f])))
                    .collect()
            };
            [
                pts(&|row| row.sobol[k].first),
                pts(&|row| row.linear_share[k]),
            ]
        };
        let groups: Vec<usize> = (N_INPUTS..N_INPUTS + Group::ALL.len()).collect();
        let mut inputs: Vec<(usize, f64)> = (0..N_INPUTS)
            .map(|i| {
                (
                    i,
                    order
                        .iter()
                        .map(|p| p.factors[i].linear_share[k])
                        .fold(0.0, f64::max),
                )
            })
            .filter(|&(_, m)| m >= PLOT_INPUT_MIN_SHARE)
            .collect();
        inputs.sort_by(|a, b| b.1.total_cmp(&a.1));
        let inputs: Vec<usize> = inputs.iter().take(PALETTE.len()).map(|&(i, _)| i).collect();
        for (what, factors, file) in [
            ("groups", groups, format!("share_vs_range_{output}.png")),
            (
                "inputs",
                inputs,
                format!("share_vs_range_inputs_{output}.png"),
            ),
        ] {
            if factors.is_empty() || order.is_empty() {
                continue;
            }
            let title =
                format!("Share of the {output} variance by {what} (S1 markers, linear lines)");
            let mut plot = Plot::new(&title, "range (m)", "share of variance")
                .size(1000, 700)
                .y_range(0.0, 1.0);
            for (c, &f) in factors.iter().enumerate() {
                let [first, linear] = series(f);
                let name = &order[0].factors[f].factor;
                plot = plot
                    .scatter(&format!("{name} S1"), &first)
                    .color(PALETTE[c % PALETTE.len()])
                    .line(&format!("{name} linear"), &linear)
                    .color(PALETTE[c % PALETTE.len()]);
            }
            let path = out_dir.join(file);
            plot.save_png(&path)?;
            written.push(path);
        }
    }
    Ok(written)
}

pub(super) fn points_table(r: &SensitivityReport) -> String {
    let mut s = String::from(
        "range_m,beta_deg,factor,kind,output,first,first_conf,total,total_conf,linear_share\n",
    );
    for p in &r.points {
        for f in &p.factors {
            for (k, output) in OUTPUTS.iter().enumerate() {
                let i = &f.sobol[k];
                let _ = writeln!(
                    s,
                    "{:.3},{:.4},{},{},{output},{:.6},{:.6},{:.6},{:.6},{:.6}",
                    p.range_m,
                    p.beta_deg,
                    f.factor,
                    f.kind,
                    i.first,
                    i.first_conf,
                    i.total,
                    i.total_conf,
                    f.linear_share[k]
                );
            }
        }
    }
    s
}

/// Plot data: one row per range; for each factor and output, the first-order and total Sobol
/// indices and the linear share (`<factor>_<output>_first`, `_total`, `_linear`).
pub(super) fn share_vs_range_table(r: &SensitivityReport) -> String {
    let Some(first) = r.points.first() else {
        return String::new();
    };
    let mut s = String::from("range_m,sigma_e_m,sigma_n_m,sigma_u_m");
    for f in &first.factors {
        for o in OUTPUTS {
            let _ = write!(s, ",{0}_{o}_first,{0}_{o}_total,{0}_{o}_linear", f.factor);
        }
    }
    s.push('\n');
    for p in &r.points {
        let [e, n, u, _] = p.sigma_enu_m;
        let _ = write!(s, "{:.3},{e:.6},{n:.6},{u:.6}", p.range_m);
        for f in &p.factors {
            for k in 0..OUTPUTS.len() {
                let i = &f.sobol[k];
                let _ = write!(s, ",{:.6},{:.6},{:.6}", i.first, i.total, f.linear_share[k]);
            }
        }
        s.push('\n');
    }
    s
}
