#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = compass_pdr::io::dataflash::read_binary("fuzz.bin", data);
    let _ = compass_pdr::io::dataflash::read_text("fuzz.log", data);
});
