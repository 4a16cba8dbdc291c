//! Progress bars for long work: drawn on stderr only when it is a terminal.

use indicatif::{ProgressBar, ProgressState, ProgressStyle};
use std::io::IsTerminal;

/// A rate with three significant digits and an SI prefix: `7.73 M/s`, `12.4 k/s`, `850/s`
/// (indicatif's own `{per_sec}` prints `7,728,778.1459/s`).
pub fn rate_text(per_s: f64) -> String {
    let (value, prefix) = match per_s.abs() {
        r if r >= 1e9 => (per_s / 1e9, " G"),
        r if r >= 1e6 => (per_s / 1e6, " M"),
        r if r >= 1e3 => (per_s / 1e3, " k"),
        _ => (per_s, ""),
    };
    let digits = match value.abs() {
        v if v >= 100.0 => 0,
        v if v >= 10.0 => 1,
        _ => 2,
    };
    if prefix.is_empty() {
        format!("{per_s:.0}/s")
    } else {
        format!("{value:.digits$}{prefix}/s")
    }
}

/// A bar of `len` steps labelled `what`; hidden when stderr is not a terminal (logs, CI).
pub fn bar(len: u64, what: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    let template = format!(
        "{{spinner}} {what} [{{bar:40}}] {{human_pos}}/{{human_len}}, {{rate}}, eta {{eta}}"
    );
    let style = ProgressStyle::with_template(&template)
        .expect("static template")
        .with_key("rate", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = w.write_str(&rate_text(s.per_sec()));
        })
        .progress_chars("=> ");
    bar.set_style(style);
    bar
}

/// A bar of `len` stages labelled `what`, the current stage's message beside it; hidden when
/// stderr is not a terminal.
pub fn stages(len: u64, what: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    let template = format!("{{spinner}} {what} [{{bar:20}}] {{pos}}/{{len}} {{elapsed}}: {{msg}}");
    bar.set_style(
        ProgressStyle::with_template(&template)
            .expect("static template")
            .progress_chars("=> "),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar
}

#[cfg(test)]
mod tests {
    use super::rate_text;

    /// Three significant digits, an SI prefix; the "7,728,778.1459/s" is 7.73 M/s.
    #[test]
    fn rates_read_as_three_digits() {
        assert_eq!(rate_text(7_728_778.145_9), "7.73 M/s");
        assert_eq!(rate_text(12_380.0), "12.4 k/s");
        assert_eq!(rate_text(849.6), "850/s");
        assert_eq!(rate_text(250_000.0), "250 k/s");
        assert_eq!(rate_text(0.0), "0/s");
    }
}
