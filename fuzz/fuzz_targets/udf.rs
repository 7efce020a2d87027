#![no_main]
//! Fuzz the udf reader (and write-back of whatever it accepts).

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| surfrecon_fuzz::check_udf(data));
