#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = compass_pdr::io::gpx::read("fuzz.gpx", data);
});
