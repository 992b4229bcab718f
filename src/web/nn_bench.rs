//! The MLP benchmark's entry point (`bench/wasm/mlp.html`): the same training as
//! `benches/mlp.rs`, on samples the page fetched.

use wasm_bindgen::prelude::*;

use crate::deviation::network::{train, Dataset, TrainOptions};

/// What one training did, for the page.
#[derive(serde::Serialize)]
struct BenchTraining {
    iterations: usize,
    evaluations: usize,
    stop: crate::deviation::network::StopReason,
    train_mse: f64,
    test_mse: f64,
}

/// Trains the benchmark's network (15 logistic neurons, L-BFGS, α = 10⁻⁴, no validation
/// split, seed 0: `TrainOptions::default()` without validation) on the first `n_train`
/// of `rows` (each `n_inputs` inputs then one target) for at most `max_iterations`
/// iterations, and scores it on the other rows. Returns iterations, evaluations, why it
/// stopped and the training and test MSE as a plain object; throws an `Error` saying what
/// is wrong with the data.
#[wasm_bindgen]
pub fn train_mlp_rows(
    rows: &[f64],
    n_inputs: usize,
    n_train: usize,
    max_iterations: usize,
) -> Result<JsValue, JsError> {
    let width = n_inputs + 1;
    if n_inputs == 0 || !rows.len().is_multiple_of(width) || rows.len() / width <= n_train {
        return Err(JsError::new(&format!(
            "{} numbers are not rows of {n_inputs} inputs and a target with more than {n_train} rows.",
            rows.len()
        )));
    }
    let split = |part: &[f64]| {
        let inputs: Vec<f64> = part
            .chunks_exact(width)
            .flat_map(|row| row.iter().take(n_inputs).copied())
            .collect();
        let targets: Vec<f64> = part
            .chunks_exact(width)
            .filter_map(|row| row.last().copied())
            .collect();
        Dataset::new(&inputs, n_inputs, &targets, 1)
    };
    let (train_rows, test_rows) = rows.split_at(n_train * width);
    let error = |error: crate::deviation::network::NnError| JsError::new(&error.to_string());
    let train_data = split(train_rows).map_err(error)?;
    let test_data = split(test_rows).map_err(error)?;
    let options = TrainOptions {
        validation_fraction: 0.0,
        max_iterations,
        ..TrainOptions::default()
    };
    let (model, report) = train(&train_data, &options).map_err(error)?;
    let result = BenchTraining {
        iterations: report.iterations,
        evaluations: report.evaluations,
        stop: report.stop,
        train_mse: report.train_mse,
        test_mse: model.mean_squared_error(&test_data).map_err(error)?,
    };
    let serializer = serde_wasm_bindgen::Serializer::json_compatible();
    serde::Serialize::serialize(&result, &serializer)
        .map_err(|error| JsError::new(&error.to_string()))
}
