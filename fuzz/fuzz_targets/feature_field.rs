#![no_main]
//! Fuzz the library calls of `surfrecon distance --kind odf|udf` and `extract` on small structured inputs
//! (see `surfrecon_fuzz::algo::feature_field`).

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| surfrecon_fuzz::algo::feature_field(data));
