//! Progress bars for long work: drawn on stderr only when it is a terminal.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;

/// A bar of `len` steps labelled `what`; hidden when stderr is not a terminal (logs, CI).
pub fn bar(len: u64, what: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    let template = format!(
        "{{spinner}} {what} [{{bar:40}}] {{human_pos}}/{{human_len}}, {{per_sec}}, eta {{eta}}"
    );
    let style = ProgressStyle::with_template(&template)
        .expect("static template")
        .progress_chars("=> ");
    bar.set_style(style);
    bar
}
