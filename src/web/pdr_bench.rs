//! The PDR benchmark's entry points (`bench/wasm/pdr.html`): the EKF steps and
//! the whole pipeline of `benches/pdr.rs`, on inputs the page fetched.

use wasm_bindgen::prelude::*;

use crate::pdr::ekf::{EkfNoise, PdrEkf};
use crate::pdr::PdrOptions;
use crate::pipeline::dead_reckoning;

/// What one pipeline run found, for the page.
#[derive(serde::Serialize)]
struct BenchPipeline {
    n_steps: usize,
    distance_m: f64,
    duration_s: f64,
    heading_key: String,
}

/// Runs the first `n_steps` of `steps` (pairs of step length in m and measured heading
/// in rad) through the `[E, N, l, a]` filter with `EkfNoise::default()`, started at
/// (`start_east_m`, `start_north_m`) with `start_sigma_m` of position uncertainty and the
/// first pair's length and heading, as `benches/pdr.rs` does. Returns the final state
/// `[E, N, l, a]` followed by the covariance row by row (20 numbers). Throws an `Error`
/// when there are fewer pairs than asked for.
#[wasm_bindgen]
pub fn pdr_ekf_steps(
    steps: &[f64],
    n_steps: usize,
    start_east_m: f64,
    start_north_m: f64,
    start_sigma_m: f64,
) -> Result<Vec<f64>, JsError> {
    let n_pairs = steps.len() / 2;
    if !steps.len().is_multiple_of(2) || n_pairs == 0 || n_pairs < n_steps {
        return Err(JsError::new(&format!(
            "{} numbers are not at least {n_steps} (and at least one) pairs of step length and heading.",
            steps.len()
        )));
    }
    let mut ekf = PdrEkf::new(
        [start_east_m, start_north_m],
        start_sigma_m,
        steps[0],
        steps[1],
        EkfNoise::default(),
    );
    for pair in steps.chunks_exact(2).take(n_steps) {
        ekf.step(pair[0], pair[1], None);
    }
    Ok(ekf
        .x
        .iter()
        .chain(ekf.p.iter().flatten())
        .copied()
        .collect())
}

/// The whole pipeline on a log's bytes: `import` then `pipeline::dead_reckoning` with the default
/// options (calibrations and heading models, steps, step model, EKF, metrics). Returns
/// the step count, the dead-reckoned distance (m), the walk's duration (s) and the
/// heading used as a plain object; throws an `Error` saying what is wrong with the log.
#[wasm_bindgen]
pub fn pdr_pipeline(file_name: &str, bytes: &[u8]) -> Result<JsValue, JsError> {
    pipeline_on(&[(file_name, bytes)])
}

/// [`pdr_pipeline`] on a recording of several files read together (as the page reads a
/// dropped folder): `file_names[i]` names `contents[i]`.
// wasm-bindgen hands a JS array over as an owned `Vec`.
#[allow(clippy::needless_pass_by_value)]
#[wasm_bindgen]
pub fn pdr_pipeline_files(
    file_names: Vec<String>,
    contents: Vec<js_sys::Uint8Array>,
) -> Result<JsValue, JsError> {
    let bytes: Vec<Vec<u8>> = contents.iter().map(js_sys::Uint8Array::to_vec).collect();
    let files: Vec<(&str, &[u8])> = file_names
        .iter()
        .zip(&bytes)
        .map(|(name, bytes)| (name.as_str(), bytes.as_slice()))
        .collect();
    pipeline_on(&files)
}

fn pipeline_on(files: &[(&str, &[u8])]) -> Result<JsValue, JsError> {
    let report =
        crate::io::import::import_files(files).map_err(|error| JsError::new(&error.to_string()))?;
    let analysis = dead_reckoning(&report, &PdrOptions::default())
        .map_err(|error| JsError::new(&error.to_string()))?;
    let result = BenchPipeline {
        n_steps: analysis.report.n_steps,
        distance_m: analysis.report.pdr_distance_m,
        duration_s: analysis.report.duration_s,
        heading_key: analysis.report.heading_key,
    };
    let serializer = serde_wasm_bindgen::Serializer::json_compatible();
    serde::Serialize::serialize(&result, &serializer)
        .map_err(|error| JsError::new(&error.to_string()))
}

/// The analysis worker's warm-up of the code a car's log takes (www/analysis-worker.js,
/// after the small logs of each format): the pipeline on a simulated drive of
/// `duration_s` (the octagonal loop of `compass-pdr simulate --scenario vehicle`, at
/// 50 Hz, as canonical CSV). Returns what [`pdr_pipeline`] returns. Only in the threaded
/// module, whose worker runs it.
#[cfg(target_feature = "atomics")]
#[wasm_bindgen]
pub fn pdr_pipeline_simulated_drive(duration_s: f64) -> Result<JsValue, JsError> {
    let config = crate::sim::walk::WalkConfig::vehicle_loop(8, duration_s, 50.0);
    let text = crate::io::canonical_csv::write(&crate::sim::walk::simulate(&config));
    pipeline_on(&[("simulated-drive.csv", text.as_bytes())])
}
