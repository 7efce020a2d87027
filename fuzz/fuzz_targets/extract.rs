#![no_main]
//! Fuzz the library calls of `surfrecon extract` on small structured inputs
//! (see `surfrecon_fuzz::algo::extract`).

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| surfrecon_fuzz::algo::extract(data));
