#![no_main]

use libfuzzer_sys::fuzz_target;

#[allow(dead_code)] // each target uses part of it
#[path = "../inputs.rs"]
mod inputs;

fuzz_target!(|data: &[u8]| {
    let fixed = inputs::fix_nmea_checksums(data);
    let _ = compass_pdr::io::nmea::read("fuzz.nmea", &fixed);
});
