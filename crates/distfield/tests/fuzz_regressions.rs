//! Inputs found by `fuzz/run.sh` (targets `odf`, `udf`), replayed: each must
//! be a clear error, not a field the writer then stores differently.

use std::path::Path;
use surfrecon_distfield::format::{read_odf, read_udf};

fn stored(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn nan_sample_positions_are_refused() {
    // Found by the fuzzer: a moved sample (.odf) or a position extra (.udf)
    // with a NaN coordinate passed the "inside its cell" check (the NaN was
    // skipped by max_element) and came back from a round trip unequal.
    let dir = tempfile::tempdir().unwrap();
    let odf = stored(
        dir.path(),
        "nan.odf",
        include_bytes!("data/fuzz-odf-nan-position.odf"),
    );
    let message = read_odf(&odf).unwrap_err().to_string();
    assert!(
        message.contains("outside its cell") && message.contains("NaN"),
        "{message}"
    );
    let udf = stored(
        dir.path(),
        "nan.udf",
        include_bytes!("data/fuzz-udf-nan-position.udf"),
    );
    let message = read_udf(&udf).unwrap_err().to_string();
    assert!(
        message.contains("outside its cell") && message.contains("NaN"),
        "{message}"
    );
}
