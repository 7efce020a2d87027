#![no_main]
//! Fuzz the library calls of `surfrecon eval` on small structured inputs
//! (see `surfrecon_fuzz::algo::eval`).

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| surfrecon_fuzz::algo::eval(data));
