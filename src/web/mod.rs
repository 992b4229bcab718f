//! The browser edge: the only module that knows wasm-bindgen, web-sys, gloo and the
//! DOM. It reads what the user drops, hands bytes to the core, and puts the core's
//! results into the page. No calibration or statistics are computed here.
//!
//! `www/bootstrap.js` loads the module and calls [`run_page`]; [`analyse_file`] is the
//! same analysis for scripts, returning the summary as a plain object.

mod canvas;
mod chunks;
mod controls;
mod dom;
mod exports;
// The import benchmark (bench/wasm/bench.js) in the plain module, and in the threaded
// one only when bench/run builds it with the feature.
#[cfg(any(not(target_feature = "atomics"), feature = "import-bench"))]
mod import_bench;
mod live_panel;
mod mapping;
// The fits' benchmarks (bench/wasm/{ellipsoid,mlp}.js) and `analyse_file` load the
// plain module only: their entry points are left out of the threaded one.
#[cfg(not(target_feature = "atomics"))]
mod nn_bench;
mod page;
// The whole pipeline on a log's bytes: the PDR benchmark's entry points
// (bench/wasm/pdr.js, bench/module_vs_native.mjs) and, in the threaded module, the
// analysis worker's warm-up (www/analysis-worker.js).
mod pdr_bench;
mod storage;
#[cfg(target_feature = "atomics")]
mod threads;
mod wording;
#[cfg(target_feature = "atomics")]
mod worker;

#[cfg(test)]
mod tests;

use std::sync::Once;

use wasm_bindgen::prelude::*;

/// Wires up the page (`www/index.html`) and analyses the demo log named by the body's
/// `data-demo-url`. `analysis_worker`: the worker that analyses logs off the main
/// thread (`www/analysis-worker.js`, started by `www/bootstrap.js` on the threaded
/// module's memory); without it (and always in the plain module) they are analysed on
/// the page's own thread.
#[wasm_bindgen]
pub fn run_page(analysis_worker: Option<web_sys::Worker>) -> Result<(), JsError> {
    install_panic_hook();
    let page =
        page::Page::from_document(analysis_worker).map_err(|message| JsError::new(&message))?;
    let live = live_panel::LivePanel::from_document(&page.document)
        .map_err(|message| JsError::new(&message))?;
    exports::wire(&page);
    controls::wire(&page);
    page.start();
    live.start();
    Ok(())
}

/// The calibration of a log with the pipeline's one best (the calibration and heading
/// stages of [`crate::pipeline`], as the page runs them), returned as a plain object
/// (the fields of `compass-pdr calibrate --json`'s report). Throws an `Error` whose
/// message says what is wrong with the file and what to do.
#[cfg(not(target_feature = "atomics"))]
#[wasm_bindgen]
pub fn analyse_file(file_name: &str, bytes: &[u8]) -> Result<JsValue, JsError> {
    let import = crate::io::import::import(file_name, bytes)
        .map_err(|error| JsError::new(&error.to_string()))?;
    let (analysis, _) = crate::pipeline::headings(
        &import,
        &crate::analysis::headings::HeadingOptions::default(),
    )
    .map_err(|error| JsError::new(&error.to_string()))?;
    let serializer = serde_wasm_bindgen::Serializer::json_compatible();
    serde::Serialize::serialize(&analysis.report, &serializer)
        .map_err(|error| JsError::new(&error.to_string()))
}

/// What a log holds, as `compass-pdr inspect --json` prints it (format, stream
/// summaries, notes, diagnostics), returned as a plain object. Throws an `Error` whose
/// message says what is wrong with the file and what to do.
#[wasm_bindgen]
pub fn inspect_file(file_name: &str, bytes: &[u8]) -> Result<JsValue, JsError> {
    let report = crate::io::import::import(file_name, bytes)
        .map_err(|error| JsError::new(&error.to_string()))?;
    let inspection = crate::io::import::Inspection::of(&report);
    let serializer = serde_wasm_bindgen::Serializer::json_compatible();
    serde::Serialize::serialize(&inspection, &serializer)
        .map_err(|error| JsError::new(&error.to_string()))
}

/// [`inspect_file`] for a `Blob` (a dropped `File`), read as the page reads one: in
/// chunks, the next read while this one is parsed, through a
/// [`ChunkedImport`](crate::io::import::ChunkedImport). For the import benchmark.
#[wasm_bindgen]
pub async fn inspect_blob(file_name: String, blob: web_sys::Blob) -> Result<JsValue, JsError> {
    let mut reader = chunks::ChunkReader::new(blob, page::CHUNK_BYTES);
    let mut import =
        crate::io::import::ChunkedImport::new(&file_name, Some(reader.size() as usize));
    let mut bytes = Vec::new();
    while let Some(read) = reader.next_into(&mut bytes).await {
        read.map_err(|message| JsError::new(&message))?;
        import
            .feed(&bytes)
            .map_err(|error| JsError::new(&error.to_string()))?;
    }
    let report = crate::io::import::merge(vec![(file_name, import.finish())])
        .map_err(|error| JsError::new(&error.to_string()))?;
    let inspection = crate::io::import::Inspection::of(&report);
    let serializer = serde_wasm_bindgen::Serializer::json_compatible();
    serde::Serialize::serialize(&inspection, &serializer)
        .map_err(|error| JsError::new(&error.to_string()))
}

/// An ellipsoid fit of magnetometer samples given as `x, y, z` triples (µT) in one flat
/// array (a `Float64Array`), with the default model; `refine` adds the
/// Levenberg-Marquardt refinement to the algebraic fit. Returns the fit as a plain object
/// (the fields of `EllipsoidFit`). Throws an `Error` whose message says what is wrong.
/// Used by the ellipsoid benchmark (`bench/wasm/ellipsoid.html`).
#[cfg(not(target_feature = "atomics"))]
#[wasm_bindgen]
pub fn fit_ellipsoid_xyz(xyz: &[f64], refine: bool) -> Result<JsValue, JsError> {
    if !xyz.len().is_multiple_of(3) {
        return Err(JsError::new(&format!(
            "{} numbers are not x, y, z triples: give 3 numbers per sample.",
            xyz.len()
        )));
    }
    let samples: Vec<nalgebra::Vector3<f64>> = xyz
        .chunks_exact(3)
        .map(|triple| nalgebra::Vector3::new(triple[0], triple[1], triple[2]))
        .collect();
    let options = crate::fit::streaming_ellipsoid::EllipsoidOptions {
        refine,
        ..Default::default()
    };
    let fit = crate::fit::streaming_ellipsoid::fit_ellipsoid(&samples, &options)
        .map_err(|error| JsError::new(&error.to_string()))?;
    let serializer = serde_wasm_bindgen::Serializer::json_compatible();
    serde::Serialize::serialize(&fit, &serializer).map_err(|error| JsError::new(&error.to_string()))
}

/// A panic is a bug: report it in the console and in the page's status area, so the
/// user sees that something broke instead of a page that silently stops.
fn install_panic_hook() {
    static INSTALL: Once = Once::new();
    INSTALL.call_once(|| {
        std::panic::set_hook(Box::new(|info| {
            console_error_panic_hook::hook(info);
            page::show_bug(&format!(
                "Internal error (a bug in compass-pdr): {info}. Reload the page to continue, and please report it."
            ));
        }));
    });
}
