//! The import benchmark's entry point (`bench/wasm/index.html`): the file's bytes
//! are copied into the module's memory once, then each run imports them there, as the
//! native benchmark (`benches/import.rs`) imports bytes already in memory. The copy and
//! the stream summaries are timed apart, by the page's `inspect_file`.

use wasm_bindgen::prelude::*;

/// A file held in the module's memory, to be imported again and again.
#[wasm_bindgen]
pub struct ImportBench {
    file_name: String,
    bytes: Vec<u8>,
}

#[wasm_bindgen]
impl ImportBench {
    /// Copies `bytes` into the module's memory.
    #[wasm_bindgen(constructor)]
    pub fn new(file_name: String, bytes: Vec<u8>) -> ImportBench {
        ImportBench { file_name, bytes }
    }

    /// Imports the held bytes (`io::import::import`, what the native benchmark times)
    /// and returns the number of data lines; throws an `Error` with the import's message.
    pub fn run(&self) -> Result<f64, JsError> {
        crate::io::import::import(&self.file_name, &self.bytes)
            .map(|report| report.n_data_lines as f64)
            .map_err(|error| JsError::new(&error.to_string()))
    }
}
