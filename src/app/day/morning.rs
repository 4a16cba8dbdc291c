//! The morning report of a day: `report.md` and `report.html` (self-contained: the plot is an
//! embedded PNG) beside the day's files. The day (date, CRS) and the warnings first, computed
//! from the numbers below them; then per pass the points, rejected shares, trajectory
//! (outages from the SMRMSG, SBET gaps), sigma medians, file and extent and the diagnosis's
//! verdict with a link to its summary; the files; the sync; the sigma statistics per pass and
//! the tiles summarised; the diagnosis; the timings in processing order.

use super::plan::Plan;
use super::DayReport;
use crate::pipeline::report::RejectReason;
use crate::plot::Plot;
use crate::Result;
use std::fmt::Write;

/// Share of a pass's returns rejected (other than for no echo) above which the report warns.
const REJECTED_WARNING: f64 = 0.01;
/// Share of a pass's returns outside the trajectory (its span, a gap, the SMRMSG's span) above
/// which the report warns.
const OUTSIDE_TRAJECTORY_WARNING: f64 = 0.05;
/// A pass whose sigma_z median exceeds this multiple of the day's median gets a warning.
const SIGMA_WARNING_FACTOR: f64 = 2.0;
/// More tiles than this are summarised (count, points, sigma range) rather than listed.
const TILES_LISTED: usize = 8;
/// The steps of a day in processing order (the report's timings).
const STEP_ORDER: [&str; 5] = ["plan", "units", "diagnose", "corrected_units", "merge"];

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
                let _ = write!(s, "<td>{}</td>", linked(&esc(c)));
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

/// A cell's Markdown links `[text](href)` as HTML anchors (the cell already escaped).
fn linked(cell: &str) -> String {
    let mut out = String::new();
    let mut rest = cell;
    while let Some(open) = rest.find('[') {
        let Some((text, after)) = rest[open + 1..].split_once("](") else {
            break;
        };
        let Some((href, tail)) = after.split_once(')') else {
            break;
        };
        let _ = write!(out, "{}<a href=\"{href}\">{text}</a>", &rest[..open]);
        rest = tail;
    }
    out.push_str(rest);
    out
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
    let day = vec![
        vec!["item".to_string(), "value".to_string()],
        vec![
            "survey date".into(),
            r.survey_date
                .clone()
                .unwrap_or_else(|| "unknown (no inputs.gps_week in the template)".into()),
        ],
        vec!["CRS".into(), r.crs.clone()],
        vec!["day file".into(), r.day_file.display().to_string()],
        vec![
            "points".into(),
            format!(
                "{} written of {} returns read, in {} files ({})",
                r.totals.written,
                r.totals.read,
                r.outputs.len(),
                size(r.outputs.iter().map(|o| o.bytes).sum())
            ),
        ],
        vec!["kinescan".into(), r.kinescan_version.clone()],
    ];
    vec![
        ("Day".into(), day),
        ("Warnings".into(), note("warning", warnings)),
        ("Passes".into(), passes(r)),
        ("Files".into(), files(r)),
        ("Sync".into(), sync(r, plan)),
        ("Sigma".into(), sigma(r)),
        ("Diagnosis".into(), diagnosis(r)),
        ("Timings".into(), timings(r)),
    ]
}

/// A byte count in MB (or kB below 1 MB).
fn size(bytes: u64) -> String {
    if bytes >= 1_000_000 {
        format!("{:.1} MB", bytes as f64 / 1e6)
    } else {
        format!("{:.1} kB", bytes as f64 / 1e3)
    }
}

/// The day's sigma_z median over every pass's points (m): the median of the per-pass medians
/// weighted by their points (the histograms are per pass).
fn day_sigma_median(r: &DayReport) -> Option<f64> {
    let mut per_pass: Vec<(f64, u64)> = r
        .sigma
        .iter()
        .filter(|s| s.scope.starts_with("pass "))
        .filter_map(|s| s.sigma_z_median_m.map(|m| (m, s.points)))
        .collect();
    per_pass.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: u64 = per_pass.iter().map(|p| p.1).sum();
    let mut seen = 0;
    per_pass.into_iter().find_map(|(m, n)| {
        seen += n;
        (2 * seen >= total).then_some(m)
    })
}

/// Returns of `c` outside the trajectory: beyond its span, in a gap, beyond the SMRMSG's span.
fn outside_trajectory(c: &crate::pipeline::report::ReturnCounts) -> u64 {
    [
        RejectReason::OutsideTrajectory,
        RejectReason::TrajectoryGap,
        RejectReason::OutsideAccuracy,
    ]
    .iter()
    .map(|k| c.rejected.get(k).copied().unwrap_or(0))
    .sum()
}

/// The sigma statistics of pass `name`.
fn pass_sigma<'a>(r: &'a DayReport, name: &str) -> Option<&'a super::quality::SigmaStats> {
    r.sigma.iter().find(|s| s.scope == format!("pass {name}"))
}

/// The output file of pass `name` (per-pass layout: the file named after the pass).
fn pass_file<'a>(r: &'a DayReport, name: &str) -> Option<&'a super::OutputFile> {
    r.outputs.iter().find(|o| {
        let stem = o.path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        stem.split('.').next() == Some(name)
    })
}

fn warnings(r: &DayReport, plan: &Plan) -> Vec<String> {
    let mut w: Vec<String> = r
        .passes
        .iter()
        .filter_map(|p| Some(format!("pass {} FAILED: {}", p.name, p.failed.as_ref()?)))
        .collect();
    for p in r.passes.iter().filter(|p| p.failed.is_none()) {
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
    for p in &r.passes {
        for o in &p.trajectory.outages {
            w.push(format!(
                "pass {}: GNSS outage in the SMRMSG for {:.0} s (GPS {:.1} to {:.1} s), \
                 horizontal position RMS up to {:.0} mm",
                p.name,
                o.seconds(),
                o.span_s[0],
                o.span_s[1],
                o.peak_horizontal_rms_m * 1e3
            ));
        }
        for g in &p.trajectory.reported_gnss_gaps {
            w.push(format!(
                "pass {}: GNSS outage of {:.0} s (GPS {:.1} to {:.1} s) in the trajectory \
                 report (kinescan trajectory), smoothed horizontal sigma up to {:.0} mm",
                p.name,
                g.seconds(),
                g.span_s[0],
                g.span_s[1],
                g.max_horizontal_sigma_m * 1e3
            ));
        }
        if !p.trajectory.gaps_s.is_empty() {
            let longest = p.trajectory.gaps_s.iter().map(|g| g[1] - g[0]);
            w.push(format!(
                "pass {}: {} gap(s) in the SBET records, longest {:.2} s",
                p.name,
                p.trajectory.gaps_s.len(),
                longest.fold(0.0, f64::max)
            ));
        }
        let outside = outside_trajectory(&p.counts) as f64 / p.counts.read.max(1) as f64;
        if outside > OUTSIDE_TRAJECTORY_WARNING {
            w.push(format!(
                "pass {}: {:.1}% of its returns lie outside the trajectory (its span, a gap or \
                 the SMRMSG's span)",
                p.name,
                100.0 * outside
            ));
        }
    }
    if let Some(day) = day_sigma_median(r) {
        for p in &r.passes {
            let median = pass_sigma(r, &p.name).and_then(|s| s.sigma_z_median_m);
            if let Some(m) = median.filter(|m| *m > SIGMA_WARNING_FACTOR * day) {
                w.push(format!(
                    "pass {}: sigma_z median {:.1} mm, {:.1}x the day's {:.1} mm",
                    p.name,
                    m * 1e3,
                    m / day,
                    day * 1e3
                ));
            }
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
        "rejected %",
        "outside trajectory %",
        "by reason",
        "GNSS outages",
        "SBET gaps",
        "sigma_z median (mm)",
        "thu95 median (mm)",
        "file",
        "extent X x Y",
        "diagnosis",
        "unit s",
    ];
    let mut t = vec![head.map(String::from).to_vec()];
    for p in &r.passes {
        let c = &p.counts;
        let sigma = pass_sigma(r, &p.name);
        let outages: Vec<String> = p
            .trajectory
            .outages
            .iter()
            .map(|o| format!("{:.0} s at {:.1}", o.seconds(), o.span_s[0]))
            .chain(
                p.trajectory
                    .reported_gnss_gaps
                    .iter()
                    .map(|g| format!("{:.0} s at {:.1} (no fix)", g.seconds(), g.span_s[0])),
            )
            .collect();
        let file = pass_file(r, &p.name);
        let diagnosis =
            r.diagnosis
                .iter()
                .find(|d| d.pass == p.name)
                .map_or("-".to_string(), |d| {
                    let folder = d
                        .folder
                        .file_name()
                        .map(|f| f.to_string_lossy().into_owned());
                    let summary = crate::app::diagnose::report::SUMMARY_MD;
                    format!("[{}]({}/{summary})", d.verdict, folder.unwrap_or_default())
                });
        let mut row = vec![p.name.clone(), p.units.to_string()];
        row.extend(count_cells(c));
        row.extend([
            if outages.is_empty() {
                "none".into()
            } else {
                outages.join("; ")
            },
            p.trajectory.gaps_s.len().to_string(),
            mm(sigma.and_then(|s| s.sigma_z_median_m)),
            mm(sigma.and_then(|s| s.thu95_median_m)),
            file.map_or_else(
                || missing_file(p),
                |f| {
                    let name = f.path.file_name().unwrap_or_default().to_string_lossy();
                    format!("{name} ({})", size(f.bytes))
                },
            ),
            file.map_or("-".into(), |f| {
                format!("{:.0} x {:.0}", f.max[0] - f.min[0], f.max[1] - f.min[1])
            }),
            diagnosis,
            format!("{:.1}", p.unit_seconds),
        ]);
        t.push(row);
    }
    let mut day = vec!["day".to_string(), r.units.to_string()];
    day.extend(count_cells(&r.totals));
    day.extend(["", "", &mm(day_sigma_median(r)), "", "", "", "", ""].map(String::from));
    t.push(day);
    t
}

/// A length in metres as millimetres to 0.1 mm, `-` for none.
fn mm(v: Option<f64>) -> String {
    v.map_or("-".to_string(), |v| format!("{:.1}", v * 1e3))
}

/// The count cells of a pass's (or the day's) row: read, written, rejected, rejected %,
/// outside the trajectory %, rejected by reason.
fn count_cells(c: &crate::pipeline::report::ReturnCounts) -> [String; 6] {
    let share = |n: u64| format!("{:.2}", 100.0 * n as f64 / c.read.max(1) as f64);
    [
        c.read.to_string(),
        c.written.to_string(),
        c.rejected_total().to_string(),
        share(c.rejected_total()),
        share(outside_trajectory(c)),
        reasons(c),
    ]
}

/// The file cell of a pass without a file of its own: not published (failed), or in tiles.
fn missing_file(p: &super::PassReport) -> String {
    match p.failed {
        Some(_) => "not published (failed)".into(),
        None => "-".into(),
    }
}

/// The day's files (listed up to [`TILES_LISTED`], else summarised): points, size, extent.
fn files(r: &DayReport) -> Vec<Vec<String>> {
    let head = ["file", "points", "size", "min X, Y, Z", "max X, Y, Z"];
    let mut t = vec![head.map(String::from).to_vec()];
    let xyz = |v: [f64; 3]| format!("{:.1}, {:.1}, {:.1}", v[0], v[1], v[2]);
    if r.outputs.len() <= TILES_LISTED {
        for o in &r.outputs {
            t.push(vec![
                o.path
                    .file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .into(),
                o.points.to_string(),
                size(o.bytes),
                xyz(o.min),
                xyz(o.max),
            ]);
        }
        return t;
    }
    let points: Vec<u64> = r.outputs.iter().map(|o| o.points).collect();
    let min = r.outputs.iter().fold([f64::INFINITY; 3], |a, o| {
        [0, 1, 2].map(|k| a[k].min(o.min[k]))
    });
    let max = r.outputs.iter().fold([f64::NEG_INFINITY; 3], |a, o| {
        [0, 1, 2].map(|k| a[k].max(o.max[k]))
    });
    t.push(vec![
        format!(
            "{} tiles: {} to {} points each",
            r.outputs.len(),
            points.iter().min().copied().unwrap_or(0),
            points.iter().max().copied().unwrap_or(0)
        ),
        points.iter().sum::<u64>().to_string(),
        size(r.outputs.iter().map(|o| o.bytes).sum()),
        xyz(min),
        xyz(max),
    ]);
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
    let (passes, tiles): (Vec<_>, Vec<_>) =
        r.sigma.iter().partition(|s| s.scope.starts_with("pass "));
    let listed = if tiles.len() <= TILES_LISTED {
        r.sigma.iter().collect()
    } else {
        passes
    };
    for s in listed {
        t.push(vec![
            s.scope.clone(),
            s.points.to_string(),
            mm(s.sigma_z_median_m),
            mm(s.sigma_z_p95_m),
            mm(s.thu95_median_m),
            mm(s.thu95_p95_m),
        ]);
    }
    if tiles.len() > TILES_LISTED {
        let range = |f: fn(&super::quality::SigmaStats) -> Option<f64>| {
            let v: Vec<f64> = tiles.iter().filter_map(|s| f(s)).collect();
            let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if v.is_empty() {
                "-".to_string()
            } else {
                format!("{:.1} to {:.1}", lo * 1e3, hi * 1e3)
            }
        };
        let points = tiles.iter().map(|s| s.points);
        t.push(vec![
            format!("{} tiles (range over tiles)", tiles.len()),
            format!(
                "{} to {}",
                points.clone().min().unwrap_or(0),
                points.max().unwrap_or(0)
            ),
            range(|s| s.sigma_z_median_m),
            range(|s| s.sigma_z_p95_m),
            range(|s| s.thu95_median_m),
            range(|s| s.thu95_p95_m),
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
    let rank = |k: &str| {
        STEP_ORDER
            .iter()
            .position(|s| *s == k)
            .unwrap_or(STEP_ORDER.len())
    };
    let mut steps: Vec<(&String, &f64)> = r.timings_s.iter().collect();
    steps.sort_by_key(|(k, _)| rank(k));
    t.extend(
        steps
            .into_iter()
            .map(|(k, v)| vec![k.clone(), format!("{v:.2}")]),
    );
    t
}

/// Median and 95th percentile of sigma_z per pass (mm), as a PNG, the passes named in the
/// legend (one marker colour each, the median a marker and the 95th percentile a second one
/// above it, at the pass's position in day-file order); None without sigmas.
fn sigma_plot(r: &DayReport) -> Result<Option<Vec<u8>>> {
    let per_pass: Vec<_> = r
        .sigma
        .iter()
        .filter(|s| s.scope.starts_with("pass "))
        .collect();
    let top = per_pass
        .iter()
        .filter_map(|s| s.sigma_z_p95_m.or(s.sigma_z_median_m))
        .fold(0.0, f64::max)
        * 1e3
        * 1.2;
    let mut plot = Plot::new(
        "sigma_z per pass: median and 95th percentile",
        "pass (day-file order)",
        "sigma_z (mm)",
    )
    .x_range(0.5, per_pass.len() as f64 + 0.5)
    .y_range(0.0, top.max(1e-3));
    let mut any = false;
    for (k, s) in per_pass.iter().enumerate() {
        let x = (k + 1) as f64;
        let points: Vec<(f64, f64)> = [s.sigma_z_median_m, s.sigma_z_p95_m]
            .into_iter()
            .flatten()
            .map(|v| (x, v * 1e3))
            .collect();
        if !points.is_empty() {
            any = true;
            let name = s.scope.trim_start_matches("pass ");
            plot = plot.scatter(name, &points);
        }
    }
    if !any {
        return Ok(None);
    }
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
