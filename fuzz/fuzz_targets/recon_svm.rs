#![no_main]
//! Fuzz `surfrecon::reconstruct` with the svm method on small structured
//! inputs and arbitrary options (see `surfrecon_fuzz::algo`).

use libfuzzer_sys::fuzz_target;
use surfrecon_fuzz::algo::{reconstruct, MethodKind};

fuzz_target!(|data: &[u8]| reconstruct(data, MethodKind::Svm));
