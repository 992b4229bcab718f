#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = compass_pdr::io::tagged_lines::read_android_dump("fuzz.txt", data);
    let _ = compass_pdr::io::tagged_lines::read_get_sensor_data("fuzz.txt", data);
});
