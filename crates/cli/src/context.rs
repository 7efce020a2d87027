//! What every subcommand shares: verbosity, JSON output, progress bars.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::time::Instant;

pub struct Context {
    pub quiet: bool,
    pub json: bool,
    pub verbose: u8,
    start: Instant,
}

impl Context {
    pub fn new(quiet: bool, json: bool, verbose: u8) -> Self {
        Context {
            quiet,
            json,
            verbose,
            start: Instant::now(),
        }
    }

    /// A human-readable line on stderr, unless quiet.
    pub fn say(&self, msg: impl AsRef<str>) {
        if !self.quiet {
            eprintln!("{}", msg.as_ref());
        }
    }

    /// Detail printed only with `-v`.
    pub fn detail(&self, msg: impl AsRef<str>) {
        if self.verbose > 0 && !self.quiet {
            eprintln!("{}", msg.as_ref());
        }
    }

    /// "wrote PATH in T s", plus `detail` in parentheses when given.
    pub fn say_wrote(&self, path: &std::path::Path, detail: Option<String>) {
        let detail = detail.map(|d| format!(" ({d})")).unwrap_or_default();
        self.say(format!(
            "wrote {} in {:.2} s{detail}",
            path.display(),
            self.elapsed()
        ));
    }

    /// Seconds since the command started.
    pub fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Print `value` as one JSON object on stdout when `--json` was given.
    pub fn emit_json(&self, value: &serde_json::Value) {
        if self.json {
            println!("{value}");
        }
    }

    /// A spinner for a long step when stderr is a terminal; hidden otherwise.
    pub fn spinner(&self, msg: &str) -> ProgressBar {
        if self.quiet || self.json || !std::io::stderr().is_terminal() {
            return ProgressBar::hidden();
        }
        let pb = ProgressBar::new_spinner();
        pb.set_style(ProgressStyle::with_template("{spinner} {msg} [{elapsed}]").unwrap());
        pb.set_message(msg.to_string());
        pb.enable_steady_tick(std::time::Duration::from_millis(120));
        pb
    }
}
