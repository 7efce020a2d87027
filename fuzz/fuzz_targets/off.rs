#![no_main]
//! Fuzz the off reader (and write-back of whatever it accepts).

use libfuzzer_sys::fuzz_target;
use surfrecon_geom::io::Format;

fuzz_target!(|data: &[u8]| surfrecon_fuzz::check(data, Format::Off));
