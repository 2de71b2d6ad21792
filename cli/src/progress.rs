//! Progress bars on standard error (indicatif), hidden on request.

use indicatif::{ProgressBar, ProgressStyle};
use std::time::Duration;

/// A spinner with the elapsed time and a message, ticking on its own.
pub fn spinner(hidden: bool) -> ProgressBar {
    let bar = if hidden { ProgressBar::hidden() } else { ProgressBar::new_spinner() };
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
            .expect("valid template"),
    );
    bar.enable_steady_tick(Duration::from_millis(200));
    bar
}

/// A bar of `len` steps; `template` is an indicatif template (`{bar:30}`, `{pos}/{len}`,
/// `{percent}`, `{msg}`, ...).
pub fn bar(hidden: bool, len: u64, template: &str) -> ProgressBar {
    let bar = if hidden { ProgressBar::hidden() } else { ProgressBar::new(len) };
    bar.set_style(ProgressStyle::with_template(template).expect("valid template"));
    bar
}
