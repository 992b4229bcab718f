//! A `Blob` (a dropped `File`) read in chunks, the next chunk asked for while the caller
//! works on this one: the browser reads the file on its own threads while the page
//! parses, so reading and parsing overlap instead of taking turns.

use js_sys::{Promise, Uint8Array};
use wasm_bindgen_futures::JsFuture;
use web_sys::Blob;

use super::page::describe_js_error;

/// Reads a blob in chunks of `chunk_bytes`, one read ahead.
pub struct ChunkReader {
    blob: Blob,
    size: f64,
    chunk_bytes: f64,
    /// Where the next read not yet asked for starts.
    next_start: f64,
    /// The read asked for ahead: its length and its promise.
    ahead: Option<(f64, Promise)>,
}

impl ChunkReader {
    pub fn new(blob: Blob, chunk_bytes: f64) -> ChunkReader {
        ChunkReader {
            size: blob.size(),
            blob,
            chunk_bytes,
            next_start: 0.0,
            ahead: None,
        }
    }

    pub fn size(&self) -> f64 {
        self.size
    }

    /// Asks the browser for the next chunk; `None` at the end.
    fn ask(&mut self) -> Option<Result<(f64, Promise), String>> {
        if self.next_start >= self.size {
            return None;
        }
        let start = self.next_start;
        let end = (start + self.chunk_bytes).min(self.size);
        self.next_start = end;
        Some(
            self.blob
                .slice_with_f64_and_f64(start, end)
                .map(|slice| (end - start, slice.array_buffer()))
                .map_err(describe_js_error),
        )
    }

    /// The next chunk's bytes, copied into `into` (whose room is reused), having asked
    /// for the one after; `None` at the end of the blob.
    pub async fn next_into(&mut self, into: &mut Vec<u8>) -> Option<Result<(), String>> {
        let current = match self.ahead.take() {
            Some(ahead) => ahead,
            None => match self.ask()? {
                Ok(ahead) => ahead,
                Err(message) => return Some(Err(message)),
            },
        };
        match self.ask() {
            Some(Ok(ahead)) => self.ahead = Some(ahead),
            Some(Err(message)) => return Some(Err(message)),
            None => {}
        }
        let (_, promise) = current;
        Some(match JsFuture::from(promise).await {
            Ok(buffer) => {
                let bytes = Uint8Array::new(&buffer);
                into.resize(bytes.length() as usize, 0);
                bytes.copy_to(into);
                Ok(())
            }
            Err(error) => Err(describe_js_error(error)),
        })
    }
}
