//! What a fuzz target does to its input, shared by the targets (`fuzz_targets/*.rs`,
//! `#[path = "../inputs.rs"]`) and their replay on stable (`tests/fuzz_regressions.rs`),
//! so that a regression input is replayed exactly as it was fuzzed.

use compass_pdr::io::import::{import, merge, ChunkedImport};
use compass_pdr::io::ImportError;

/// The `nmea` target's rewrite: every line (split on '\n') that starts with '$' or '!'
/// loses anything from its last '*' on and gets `*XX`, the XOR of the bytes after the
/// leading '$'/'!' in two uppercase hex digits, so that the input passes the checksum.
pub fn fix_nmea_checksums(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len() + data.len() / 8);
    for (index, line) in data.split(|&byte| byte == b'\n').enumerate() {
        if index > 0 {
            out.push(b'\n');
        }
        match line.first() {
            Some(b'$' | b'!') => {
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
pub fn check_import(data: &[u8]) {
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
