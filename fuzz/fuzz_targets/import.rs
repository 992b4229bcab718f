#![no_main]

use compass_pdr::io::import::{import, merge, ChunkedImport};
use compass_pdr::io::ImportError;
use libfuzzer_sys::fuzz_target;

const FILE_NAME: &str = "fuzz.csv";

/// The whole input through `ChunkedImport`, in chunks of `chunk_bytes`, stopping at the
/// first failed `feed` as the CLI does; then merged as the CLI and the page merge.
fn import_chunked(data: &[u8], chunk_bytes: usize) -> Result<(), ImportError> {
    let mut chunked = ChunkedImport::new(FILE_NAME, Some(data.len()));
    let mut fed = Ok(());
    for chunk in data.chunks(chunk_bytes) {
        fed = chunked.feed(chunk);
        if fed.is_err() {
            break;
        }
    }
    merge(vec![(
        FILE_NAME.to_string(),
        fed.and_then(|()| chunked.finish()),
    )])
    .map(|_| ())
}

fuzz_target!(|data: &[u8]| {
    // The chunk size comes from the first byte (1..=255); the whole input is imported.
    let chunk_bytes = usize::from(data.first().copied().unwrap_or(1).max(1));
    let whole = import(FILE_NAME, data).map(|_| ());
    let chunked = import_chunked(data, chunk_bytes);
    match (&whole, &chunked) {
        (Ok(()), Ok(())) => {}
        (Err(a), Err(b)) if std::mem::discriminant(a) == std::mem::discriminant(b) => {}
        _ => panic!(
            "whole and chunked imports disagree (chunks of {chunk_bytes} bytes): \
             whole = {whole:?}, chunked = {chunked:?}"
        ),
    }
});
