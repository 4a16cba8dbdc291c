//! The morning report of a day: `report.md` and `report.html` (self-contained: the plot is an
//! embedded PNG) beside the day's files. Warnings first; then per pass the counts, the sync,
//! the sigma statistics (per pass and per tile), the diagnosis and the timings.

use super::plan::Plan;
use super::DayReport;
use crate::pipeline::report::RejectReason;
use crate::plot::Plot;
use crate::Result;
use std::fmt::Write;

/// Share of a pass's returns rejected (other than for no echo) above which the report warns.
const REJECTED_WARNING: f64 = 0.01;

/// `report.md`: the report in Markdown.
pub fn markdown(r: &DayReport, plan: &Plan) -> String {
    let mut s = format!("# kinescan morning report: {}\n\n", r.day_file.display());
    for (title, table) in sections(r, plan) {
        let _ = write!(s, "## {title}\n\n");
        if let Some((head, rows)) = table.split_first() {
            let _ = writeln!(s, "| {} |", head.join(" | "));
            let _ = writeln!(s, "|{}", "---|".repeat(head.len()));
            for row in rows {
                let _ = writeln!(s, "| {} |", row.join(" | "));
            }
        }
        s.push('\n');
    }
    s
}

/// `report.html`: the same sections as HTML tables, with the sigma plot embedded.
pub fn html(r: &DayReport, plan: &Plan) -> Result<String> {
    let esc = |t: &str| {
        t.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
    };
    let title = format!("kinescan morning report: {}", r.day_file.display());
    let mut s = format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{}</title>\n<style>\
         body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse}}\
         td,th{{border:1px solid #999;padding:3px 8px;text-align:right}}\
         .warn{{color:#a00}}</style></head><body>\n<h1>{}</h1>\n",
        esc(&title),
        esc(&title)
    );
    for (heading, table) in sections(r, plan) {
        let _ = writeln!(s, "<h2>{}</h2>", esc(&heading));
        let Some((head, rows)) = table.split_first() else {
            continue;
        };
        s.push_str("<table><tr>");
        head.iter().for_each(|h| {
            let _ = write!(s, "<th>{}</th>", esc(h));
        });
        s.push_str("</tr>\n");
        for row in rows {
            s.push_str("<tr>");
            row.iter().for_each(|c| {
                let _ = write!(s, "<td>{}</td>", esc(c));
            });
            s.push_str("</tr>\n");
        }
        s.push_str("</table>\n");
    }
    if let Some(png) = sigma_plot(r)? {
        let _ = writeln!(
            s,
            "<h2>sigma_z per pass</h2>\n<img alt=\"sigma_z per pass\" src=\"data:image/png;base64,{}\">",
            base64(&png)
        );
    }
    s.push_str("</body></html>\n");
    Ok(s)
}

/// The report's sections: a title and a table (header row first; one column for notes).
fn sections(r: &DayReport, plan: &Plan) -> Vec<(String, Vec<Vec<String>>)> {
    let mut warnings = warnings(r, plan);
    if warnings.is_empty() {
        warnings.push("none".to_string());
    }
    let note = |head: &str, lines: Vec<String>| {
        let mut t = vec![vec![head.to_string()]];
        t.extend(lines.into_iter().map(|l| vec![l]));
        t
    };
    vec![
        ("Warnings".into(), note("warning", warnings)),
        ("Passes".into(), passes(r)),
        ("Sync".into(), sync(r, plan)),
        ("Sigma".into(), sigma(r)),
        ("Diagnosis".into(), diagnosis(r)),
        ("Timings".into(), timings(r)),
    ]
}

fn warnings(r: &DayReport, plan: &Plan) -> Vec<String> {
    let mut w = Vec::new();
    for p in &r.passes {
        // No echo (open sky) is not a fault of the data; every other reason is.
        let missing = p
            .counts
            .rejected
            .get(&RejectReason::MissingReturn)
            .copied()
            .unwrap_or(0);
        let faulty = p.counts.rejected_total() - missing;
        let share = faulty as f64 / p.counts.read.max(1) as f64;
        if share > REJECTED_WARNING {
            w.push(format!(
                "pass {}: {:.1}% of its returns rejected for other reasons than no echo ({})",
                p.name,
                100.0 * share,
                reasons(&p.counts)
            ));
        }
    }
    for i in &plan.inputs {
        if let Some(why) = i.sync.as_ref().and_then(|s| s.fallback.as_ref()) {
            let pass = &r.passes[i.pass].name;
            w.push(format!(
                "pass {pass}, {}: sync by the paper method ({why})",
                i.profiles.display()
            ));
        }
    }
    for d in r.diagnosis.iter().filter(|d| !d.set.is_empty()) {
        match &d.applied {
            None => w.push(format!(
                "pass {}: the diagnosis names a correction, not applied: {}",
                d.pass,
                d.set.join(" ")
            )),
            Some(a) => w.push(format!(
                "pass {}: re-processed with the diagnosed correction {} ({}; held-out chi2/dof \
                 {:.2} -> {:.2}, RMS {:.1} -> {:.1} mm)",
                d.pass,
                d.set.join(" "),
                estimates(a),
                d.chi2_per_dof[0],
                d.chi2_per_dof[1],
                d.rms_m[0] * 1e3,
                d.rms_m[1] * 1e3
            )),
        }
    }
    if r.sigma.is_empty() {
        w.push("no per-point sigma: the template has no [uncertainty]".into());
    }
    w
}

fn reasons(c: &crate::pipeline::report::ReturnCounts) -> String {
    let list: Vec<String> = c
        .rejected
        .iter()
        .filter(|(_, n)| **n > 0)
        .map(|(k, n)| {
            format!(
                "{}: {n}",
                serde_json::to_value(k)
                    .unwrap_or_default()
                    .as_str()
                    .unwrap_or("?")
            )
        })
        .collect();
    if list.is_empty() {
        "none".into()
    } else {
        list.join(", ")
    }
}

fn passes(r: &DayReport) -> Vec<Vec<String>> {
    let head = [
        "pass",
        "units",
        "read",
        "written",
        "rejected",
        "by reason",
        "unit s",
    ];
    let mut t = vec![head.map(String::from).to_vec()];
    let row =
        |name: &str, units: usize, c: &crate::pipeline::report::ReturnCounts, secs: String| {
            vec![
                name.to_string(),
                units.to_string(),
                c.read.to_string(),
                c.written.to_string(),
                c.rejected_total().to_string(),
                reasons(c),
                secs,
            ]
        };
    for p in &r.passes {
        t.push(row(
            &p.name,
            p.units,
            &p.counts,
            format!("{:.1}", p.unit_seconds),
        ));
    }
    t.push(row("day", r.units, &r.totals, String::new()));
    t
}

fn sync(r: &DayReport, plan: &Plan) -> Vec<Vec<String>> {
    let head = [
        "pass",
        "profiles",
        "method",
        "t0 (s)",
        "sigma t0 (ms)",
        "T (s)",
        "sigma T (ns)",
        "chi2/dof",
    ];
    let mut t = vec![head.map(String::from).to_vec()];
    for i in &plan.inputs {
        let c = &i.clock;
        let (method, chi2) = match &i.sync {
            Some(s) => (
                serde_json::to_value(s.method)
                    .unwrap_or_default()
                    .as_str()
                    .unwrap_or("?")
                    .to_string(),
                format!("{:.2}", s.chi2 / s.dof.max(1) as f64),
            ),
            None => ("configured".to_string(), "-".to_string()),
        };
        t.push(vec![
            r.passes[i.pass].name.clone(),
            i.profiles.display().to_string(),
            method,
            format!("{:.6}", c.t0_s),
            format!("{:.3}", c.clock_covariance_s2[0][0].sqrt() * 1e3),
            format!("{:.9}", c.period_s),
            format!("{:.3}", c.clock_covariance_s2[1][1].sqrt() * 1e9),
            chi2,
        ]);
    }
    t
}

fn sigma(r: &DayReport) -> Vec<Vec<String>> {
    let head = [
        "scope",
        "points",
        "sigma_z median (mm)",
        "sigma_z 95% (mm)",
        "thu95 median (mm)",
        "thu95 95% (mm)",
    ];
    let mut t = vec![head.map(String::from).to_vec()];
    let mm = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{:.1}", v * 1e3));
    for s in &r.sigma {
        t.push(vec![
            s.scope.clone(),
            s.points.to_string(),
            mm(s.sigma_z_median_m),
            mm(s.sigma_z_p95_m),
            mm(s.thu95_median_m),
            mm(s.thu95_p95_m),
        ]);
    }
    t
}

fn diagnosis(r: &DayReport) -> Vec<Vec<String>> {
    if r.diagnosis.is_empty() {
        let off = "not run (day.night.diagnose = false)".to_string();
        return vec![vec!["verdict".into()], vec![off]];
    }
    let applies = r.diagnosis.iter().any(|d| d.applied.is_some());
    let correction = if applies {
        "correction"
    } else {
        "correction (not applied)"
    };
    let head = [
        "pass",
        "verdict",
        "chi2/dof before",
        "after",
        "RMS before (mm)",
        "after (mm)",
        correction,
    ];
    let mut t = vec![head.map(String::from).to_vec()];
    for d in &r.diagnosis {
        let set = d.set.join(" ");
        let correction = match (&d.applied, applies && !set.is_empty()) {
            (Some(a), _) => format!("applied: {set} ({})", estimates(a)),
            (None, true) => format!("not applied: {set}"),
            (None, false) => set,
        };
        t.push(vec![
            d.pass.clone(),
            d.verdict.clone(),
            format!("{:.2}", d.chi2_per_dof[0]),
            format!("{:.2}", d.chi2_per_dof[1]),
            format!("{:.1}", d.rms_m[0] * 1e3),
            format!("{:.1}", d.rms_m[1] * 1e3),
            correction,
        ]);
    }
    t
}

/// The named effects of an applied correction, `name = estimate +- sigma` each.
fn estimates(a: &super::night::AppliedCorrection) -> String {
    let named: Vec<String> = a
        .effects
        .iter()
        .map(|e| format!("{} = {:.4e} +- {:.1e}", e.effect, e.estimate, e.sigma))
        .collect();
    named.join(", ")
}

fn timings(r: &DayReport) -> Vec<Vec<String>> {
    let mut t = vec![vec!["step".to_string(), "seconds".to_string()]];
    t.extend(
        r.timings_s
            .iter()
            .map(|(k, v)| vec![k.clone(), format!("{v:.2}")]),
    );
    t
}

/// Median and 95th percentile of sigma_z per pass (mm), as a PNG; None without sigmas.
fn sigma_plot(r: &DayReport) -> Result<Option<Vec<u8>>> {
    let per_pass: Vec<_> = r
        .sigma
        .iter()
        .filter(|s| s.scope.starts_with("pass "))
        .collect();
    let at = |f: fn(&super::quality::SigmaStats) -> Option<f64>| -> Vec<(f64, f64)> {
        let points = per_pass.iter().enumerate();
        points
            .filter_map(|(k, s)| f(s).map(|v| ((k + 1) as f64, v * 1e3)))
            .collect()
    };
    let (median, p95) = (at(|s| s.sigma_z_median_m), at(|s| s.sigma_z_p95_m));
    if median.is_empty() {
        return Ok(None);
    }
    let top = p95.iter().map(|p| p.1).fold(0.0, f64::max) * 1.2;
    let plot = Plot::new("sigma_z per pass", "pass (day-file order)", "sigma_z (mm)")
        .x_range(0.5, per_pass.len() as f64 + 0.5)
        .y_range(0.0, top.max(1e-3))
        .scatter("median", &median)
        .scatter("95th percentile", &p95);
    Ok(Some(plot.render()?.png_bytes()?))
}

/// Standard base64 (RFC 4648, with padding).
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                s.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

#[cfg(test)]
mod tests {
    #[test]
    fn base64_of_rfc_4648_vectors() {
        for (input, want) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(super::base64(input.as_bytes()), want);
        }
    }
}
