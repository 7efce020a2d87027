//! Helpers shared by the CLI integration tests: run the real binary, read
//! its JSON summary.
#![allow(dead_code)] // each test binary uses its own subset

use std::path::Path;
use std::process::{Command, Output};

/// Run `surfrecon` with `args`, capturing stdout, stderr and the exit code.
pub fn surfrecon(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_surfrecon"))
        .args(args)
        .output()
        .expect("the surfrecon binary runs")
}

/// A temporary path as a command-line argument.
pub fn path_str(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

/// The one JSON object a successful `--json` run printed on stdout.
pub fn json_of(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout.clone()).unwrap();
    assert_eq!(text.trim().lines().count(), 1, "one JSON object: {text}");
    serde_json::from_str(text.trim()).unwrap()
}
