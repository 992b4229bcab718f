//! The fuzz targets' inputs worth keeping, replayed on stable: every file under
//! `fuzz/regressions/<target>/` (minimised crashes, timeouts and OOMs the fuzzers found)
//! and `fuzz/seeds/<target>/` (the committed seeds) goes through the same entry points
//! as `fuzz/fuzz_targets/<target>.rs`. Asserts only that nothing panics, and for
//! `import` that the chunked import agrees with the whole one on Ok/Err (and the error's
//! kind). A folder that is absent is skipped with a note.
#![cfg(not(target_arch = "wasm32"))]

use std::path::{Path, PathBuf};

use compass_pdr::io::import::{import, merge, ChunkedImport};
use compass_pdr::io::{
    dataflash, delimited, gpx, nmea, serial_lines, tagged_lines, ulog, ImportError,
};

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

/// The `nmea` target's rewrite: every line (split on '\n') that starts with '$' or '!'
/// loses anything from its last '*' on and gets `*XX`, the XOR of the bytes after the
/// leading '$'/'!' in two uppercase hex digits, so that the input passes the checksum.
fn fix_nmea_checksums(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len() + data.len() / 8);
    for (index, line) in data.split(|&byte| byte == b'\n').enumerate() {
        if index > 0 {
            out.push(b'\n');
        }
        match line.first() {
            Some(b'$') | Some(b'!') => {
                let body = match line.iter().rposition(|&byte| byte == b'*') {
                    Some(star) => &line[..star],
                    None => line,
                };
                let checksum = body[1..].iter().fold(0u8, |acc, &byte| acc ^ byte);
                out.extend_from_slice(body);
                out.push(b'*');
                out.extend_from_slice(format!("{checksum:02X}").as_bytes());
            }
            _ => out.extend_from_slice(line),
        }
    }
    out
}

const IMPORT_FILE_NAME: &str = "fuzz.csv";

/// The `import` target's chunked path: `ChunkedImport` fed `chunk_bytes` at a time,
/// stopping at the first failed `feed`, then merged as the CLI and the page merge.
fn import_chunked(data: &[u8], chunk_bytes: usize) -> Result<(), ImportError> {
    let mut chunked = ChunkedImport::new(IMPORT_FILE_NAME, Some(data.len()));
    let mut fed = Ok(());
    for chunk in data.chunks(chunk_bytes) {
        fed = chunked.feed(chunk);
        if fed.is_err() {
            break;
        }
    }
    merge(vec![(
        IMPORT_FILE_NAME.to_string(),
        fed.and_then(|()| chunked.finish()),
    )])
    .map(|_| ())
}

/// The `import` target: the whole import and the chunked one (chunk size from the first
/// byte, 1..=255) agree on Ok/Err and on the error's kind.
fn check_import(data: &[u8]) {
    let chunk_bytes = usize::from(data.first().copied().unwrap_or(1).max(1));
    let whole = import(IMPORT_FILE_NAME, data).map(|_| ());
    let chunked = import_chunked(data, chunk_bytes);
    let agree = match (&whole, &chunked) {
        (Ok(()), Ok(())) => true,
        (Err(a), Err(b)) => std::mem::discriminant(a) == std::mem::discriminant(b),
        _ => false,
    };
    assert!(
        agree,
        "whole and chunked imports disagree (chunks of {chunk_bytes} bytes): \
         whole = {whole:?}, chunked = {chunked:?}"
    );
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
