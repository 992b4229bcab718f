//! The fuzz targets' inputs worth keeping, replayed on stable: every file under
//! `fuzz/regressions/<target>/` (minimised crashes, timeouts and OOMs the fuzzers found)
//! and `fuzz/seeds/<target>/` (the committed seeds) goes through the same entry points
//! as `fuzz/fuzz_targets/<target>.rs`. Asserts only that nothing panics, and for
//! `import` that the chunked import agrees with the whole one on Ok/Err (and the error's
//! kind). A folder that is absent is skipped with a note.
#![cfg(not(target_arch = "wasm32"))]

use std::path::{Path, PathBuf};

use compass_pdr::io::{dataflash, delimited, gpx, nmea, serial_lines, tagged_lines, ulog};

#[path = "../fuzz/inputs.rs"]
mod inputs;
use inputs::{check_import, fix_nmea_checksums};

/// The regression and seed files of one fuzz target, sorted; absent folders are noted.
fn inputs(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut files = Vec::new();
    for kind in ["regressions", "seeds"] {
        let dir = fuzz.join(kind).join(target);
        let Ok(entries) = std::fs::read_dir(&dir) else {
            eprintln!("skipped: no {} (nothing to replay)", dir.display());
            continue;
        };
        let mut paths: Vec<PathBuf> = entries
            .filter_map(Result::ok)
            .map(|entry| entry.path())
            .filter(|path| path.is_file())
            .collect();
        paths.sort();
        for path in paths {
            let bytes = std::fs::read(&path)
                .unwrap_or_else(|error| panic!("cannot read {}: {error}", path.display()));
            files.push((path, bytes));
        }
    }
    files
}

/// Runs `check` on every input of `target`, naming the file when it panics.
fn replay(target: &str, check: impl Fn(&[u8])) {
    for (path, bytes) in inputs(target) {
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| check(&bytes)));
        assert!(
            outcome.is_ok(),
            "fuzz target {target}: {} panicked",
            path.display()
        );
    }
}

#[test]
fn delimited_inputs_do_not_panic() {
    replay("delimited", |data| {
        let _ = delimited::read("fuzz.csv", data);
    });
}

#[test]
fn nmea_inputs_do_not_panic() {
    replay("nmea", |data| {
        let _ = nmea::read("fuzz.nmea", &fix_nmea_checksums(data));
    });
}

#[test]
fn serial_lines_inputs_do_not_panic() {
    replay("serial_lines", |data| {
        let _ = serial_lines::read("fuzz.txt", data);
    });
}

#[test]
fn tagged_lines_inputs_do_not_panic() {
    replay("tagged_lines", |data| {
        let _ = tagged_lines::read_android_dump("fuzz.txt", data);
        let _ = tagged_lines::read_get_sensor_data("fuzz.txt", data);
    });
}

#[test]
fn dataflash_inputs_do_not_panic() {
    replay("dataflash", |data| {
        let _ = dataflash::read_binary("fuzz.bin", data);
        let _ = dataflash::read_text("fuzz.log", data);
    });
}

#[test]
fn ulog_inputs_do_not_panic() {
    replay("ulog", |data| {
        let _ = ulog::read("fuzz.ulg", data);
    });
}

#[test]
fn gpx_inputs_do_not_panic() {
    replay("gpx", |data| {
        let _ = gpx::read("fuzz.gpx", data);
    });
}

#[test]
fn import_inputs_agree_whole_and_chunked() {
    replay("import", check_import);
}

#[test]
fn nmea_checksum_fixer_writes_valid_checksums() {
    let fixed = fix_nmea_checksums(b"$GPHDT,123.4,T*00\n!AIVDM,x\nplain*1\n$");
    assert_eq!(
        String::from_utf8(fixed).expect("ASCII"),
        "$GPHDT,123.4,T*31\n!AIVDM,x*03\nplain*1\n$*00"
    );
}
