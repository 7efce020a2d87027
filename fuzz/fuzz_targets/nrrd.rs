#![no_main]
//! Fuzz the nrrd field reader (and write-back in both field formats).

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| surfrecon_fuzz::check_field(data, "nrrd"));
