#![no_main]

use libfuzzer_sys::fuzz_target;

#[allow(dead_code)] // each target uses part of it
#[path = "../inputs.rs"]
mod inputs;

// The chunk size comes from the first byte (1..=255); whole and chunked must agree.
fuzz_target!(|data: &[u8]| inputs::check_import(data));
