//! Inputs found by `fuzz/run.sh` (target `svm`), replayed: each must be a
//! clear error, not a panic.

use surfrecon_svm::SvmModel;

/// A model file with one level of width `width` and centres `xs` on the x axis.
fn model_bytes(width: f64, xs: &[f64]) -> Vec<u8> {
    let mut b = b"SRSVMMDL".to_vec();
    b.extend(1u32.to_le_bytes());
    b.extend(0.5f64.to_le_bytes());
    b.extend(1u32.to_le_bytes());
    b.extend(width.to_le_bytes());
    b.extend((xs.len() as u64).to_le_bytes());
    for &x in xs {
        for v in [x, 0.0, 0.0, 1.0] {
            b.extend(v.to_le_bytes());
        }
    }
    b
}

#[test]
fn centres_beyond_the_cell_index_are_refused() {
    // Found by the fuzzer: a level whose centres spread over more than the
    // 2^20 cells the index spans per axis. Before, the far centres silently
    // dropped out of the level (and a debug assertion fired).
    let found = include_bytes!("data/fuzz-svm-centres-beyond-cell-index.svm");
    let (_, message) = SvmModel::from_bytes(found).unwrap_err();
    assert!(message.contains("2^20 kernel widths"), "{message}");

    let far = model_bytes(1.0, &[0.0, 2.0f64.powi(21)]);
    let (at, message) = SvmModel::from_bytes(&far).unwrap_err();
    assert_eq!(at, 32, "error names the level's centre count: {message}");
    assert!(message.contains("level 0"), "{message}");

    // Just inside the span: both centres kept.
    let near = model_bytes(1.0, &[0.0, 2.0f64.powi(20) - 1.0]);
    let model = SvmModel::from_bytes(&near).unwrap();
    assert_eq!(model.levels[0].centres.len(), 2);
}
