//! Neural-network dynamic calibration: a one-hidden-layer perceptron learns the heading
//! deviation from the heading and the conditions it depends on.
//!
//! Source: Noureldin, Osman and El-Sheimy (2007), `compass-calibration-ann-2007.txt`,
//! Sections 3 and 5: five inputs (raw heading, |H|, gyro heading, magnetic dip,
//! temperature), 10-15 logistic hidden neurons, the heading correction as the output,
//! trained on a reference heading. Here:
//!
//! - each heading input enters as its sine and cosine, so that 359° and 1° are
//!   neighbours (the paper's raw angle has a jump at north);
//! - |H| is the horizontal magnitude of the levelled raw field, the dip
//!   `acos(|H| / |B|)` from the same field;
//! - the gyro heading is the attitude filter's where the log has one
//!   ([`crate::attitude`]), else the integrated gyroscope;
//! - an input the log does not have (no gyro, no temperature) is left out, and the
//!   report names the inputs used;
//! - the target is the deviation (reference − heading) in degrees, unwrapped about its
//!   circular mean, as for the Fourier model; samples are 1 s circular means;
//! - training is [`crate::deviation::network::train`]: L-BFGS with early stopping on a
//!   validation share, from a fixed seed (the same data give the same weights).

use serde::Serialize;
use thiserror::Error;

use crate::base::angle::wrap_to_pi;
use crate::deviation::network::{
    correlation_matrix, train, Dataset, Mlp, NnError, TrainOptions, TrainingReport,
};

/// The fewest one-second pairs (train samples with a reference heading) the network
/// trains on.
const MIN_PAIRS: usize = 50;
/// The most one-second pairs the network trains on (evenly thinned beyond): 50 minutes
/// are plenty for 15 neurons (about 120 weights), and keep training in the page short.
const MAX_PAIRS: usize = 3000;

/// Why the network correction ([`train_correction`]) could not be trained.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum NeuralTrainError {
    /// Fewer one-second pairs than the network needs (50).
    #[error(
        "needs at least {MIN_PAIRS} seconds of train samples with a reference heading; there \
         were {n_pairs}"
    )]
    TooFewPairs { n_pairs: usize },
    /// The network's data or training failed.
    #[error(transparent)]
    Network(#[from] NnError),
}
/// Share of samples a condition must be known at for it to be an input.
const MIN_INPUT_COVERAGE: f64 = 0.9;

/// The per-sample conditions the network may use.
pub struct Conditions<'a> {
    pub horizontal_ut: &'a [f64],
    pub dip_deg: &'a [f64],
    pub gyro_heading_deg: &'a [Option<f64>],
    pub gyro_heading_source: GyroHeadingSource,
    pub temp_c: &'a [Option<f64>],
}

/// Where the "gyro heading" input comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GyroHeadingSource {
    /// The attitude filter's heading ([`crate::attitude`]): the gyroscope's, with its
    /// drift held by gravity and the field.
    AttitudeFilter,
    /// The gyroscope integrated from the start of the log (relative, drifting).
    IntegratedGyroscope,
}

/// What the network learned from and how training went.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NeuralReport {
    pub base_key: String,
    pub base_label: String,
    /// The paper's inputs used, in order.
    pub inputs: Vec<&'static str>,
    /// The paper's inputs the log lacks.
    pub missing_inputs: Vec<&'static str>,
    pub n_pairs: usize,
    /// Pearson correlation of the inputs over the training pairs (the paper's Table 1),
    /// row-major over `inputs`; `None` for a constant input.
    pub correlation: Vec<Option<f64>>,
    pub n_hidden: usize,
    pub iterations: usize,
    pub stop: crate::deviation::network::StopReason,
    pub train_mse_deg2: f64,
    pub validation_mse_deg2: Option<f64>,
}

/// Which of the paper's optional inputs the network takes (each where the log covers
/// enough of its samples, [`MIN_INPUT_COVERAGE`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct OptionalInputs {
    /// The gyro heading's sine and cosine.
    gyro: bool,
    /// The temperature.
    temp: bool,
}

/// A trained correction: predicts the deviation (radians) at a sample.
pub struct NeuralCorrection {
    model: Mlp,
    inputs: OptionalInputs,
    pub report: NeuralReport,
}

fn coverage(values: &[Option<f64>]) -> f64 {
    values
        .iter()
        .filter(|value| value.is_some_and(f64::is_finite))
        .count() as f64
        / values.len().max(1) as f64
}

impl NeuralCorrection {
    /// The corrected heading (radians, `[0, 2π)`) at every sample (`headings_rad[i]` is
    /// sample `i`'s base heading), NaN where an input is missing; the network runs on
    /// blocks of rows ([`crate::deviation::network::Mlp::predict_rows`]).
    pub fn correct_all_rad(&self, headings_rad: &[f64], conditions: &Conditions<'_>) -> Vec<f64> {
        let mut corrected = vec![f64::NAN; headings_rad.len()];
        let (mut rows, mut indices) = (Vec::new(), Vec::new());
        for (start, headings) in (0..)
            .step_by(ROWS_PER_CALL)
            .zip(headings_rad.chunks(ROWS_PER_CALL))
        {
            rows.clear();
            indices.clear();
            for (idx, &heading_rad) in (start..).zip(headings) {
                if push_input_row(&mut rows, heading_rad, conditions, idx, self.inputs) {
                    indices.push(idx);
                }
            }
            let Ok(deviations_deg) = self.model.predict_rows(&rows) else {
                continue;
            };
            for (&idx, deviation_deg) in indices.iter().zip(deviations_deg) {
                if let (Some(slot), Some(&heading_rad)) =
                    (corrected.get_mut(idx), headings_rad.get(idx))
                {
                    if deviation_deg.is_finite() {
                        *slot = crate::base::angle::wrap_to_2pi(
                            heading_rad + deviation_deg.to_radians(),
                        );
                    }
                }
            }
        }
        corrected
    }
}

/// Samples per call of the network in [`NeuralCorrection::correct_all_rad`] (bounds the
/// rows held at once).
const ROWS_PER_CALL: usize = 8192;

fn input_row(
    heading_rad: f64,
    conditions: &Conditions<'_>,
    idx: usize,
    inputs: OptionalInputs,
) -> Option<Vec<f64>> {
    let mut row = Vec::with_capacity(7);
    push_input_row(&mut row, heading_rad, conditions, idx, inputs).then_some(row)
}

/// Appends the network's inputs at sample `idx` to `rows`; `false`, with nothing
/// appended, where an input is missing or not finite.
fn push_input_row(
    rows: &mut Vec<f64>,
    heading_rad: f64,
    conditions: &Conditions<'_>,
    idx: usize,
    inputs: OptionalInputs,
) -> bool {
    let start = rows.len();
    let mut push = || -> Option<()> {
        let (sin, cos) = heading_rad.sin_cos();
        rows.extend_from_slice(&[sin, cos, *conditions.horizontal_ut.get(idx)?]);
        if inputs.gyro {
            let gyro_rad = (*conditions.gyro_heading_deg.get(idx)?)?.to_radians();
            let (sin, cos) = gyro_rad.sin_cos();
            rows.extend_from_slice(&[sin, cos]);
        }
        rows.push(*conditions.dip_deg.get(idx)?);
        if inputs.temp {
            rows.push((*conditions.temp_c.get(idx)?)?);
        }
        Some(())
    };
    let complete = push().is_some();
    let appended = rows.get(start..).unwrap_or(&[]);
    if complete && appended.iter().all(|value| value.is_finite()) {
        true
    } else {
        rows.truncate(start);
        false
    }
}

/// Trains the correction on `bins` (groups of train sample indices, each a second of
/// samples with a reference) of the base heading `heading_rad` against `reference_rad`.
pub fn train_correction(
    base_key: &str,
    base_label: &str,
    heading_rad: &[f64],
    reference_rad: &[Option<f64>],
    conditions: &Conditions<'_>,
    bins: &[Vec<usize>],
    seed: u64,
) -> Result<NeuralCorrection, NeuralTrainError> {
    let optional = OptionalInputs {
        gyro: coverage(conditions.gyro_heading_deg) >= MIN_INPUT_COVERAGE,
        temp: coverage(conditions.temp_c) >= MIN_INPUT_COVERAGE,
    };
    let mut inputs = vec!["heading", "|H|"];
    let mut missing = Vec::new();
    if optional.gyro {
        inputs.push(match conditions.gyro_heading_source {
            GyroHeadingSource::AttitudeFilter => "gyro heading (attitude filter)",
            GyroHeadingSource::IntegratedGyroscope => "gyro heading",
        });
    } else {
        missing.push("gyro heading");
    }
    inputs.push("dip");
    if optional.temp {
        inputs.push("temperature");
    } else {
        missing.push("temperature");
    }
    // One row per bin: the mean of its samples' rows, the circular mean deviation.
    let mut rows: Vec<f64> = Vec::new();
    let mut targets_rad: Vec<f64> = Vec::new();
    let mut paper_rows: Vec<f64> = Vec::new();
    let mut width = 0usize;
    let stride = bins.len().div_ceil(MAX_PAIRS).max(1);
    for bin in bins.iter().step_by(stride) {
        let mut sum: Vec<f64> = Vec::new();
        let (mut sum_sin, mut sum_cos, mut n) = (0.0, 0.0, 0usize);
        for &idx in bin {
            let (Some(&heading), Some(&Some(reference))) =
                (heading_rad.get(idx), reference_rad.get(idx))
            else {
                continue;
            };
            let Some(row) = input_row(heading, conditions, idx, optional) else {
                continue;
            };
            if sum.is_empty() {
                sum = vec![0.0; row.len()];
            }
            for (total, value) in sum.iter_mut().zip(&row) {
                *total += value;
            }
            let deviation = wrap_to_pi(reference - heading);
            sum_sin += deviation.sin();
            sum_cos += deviation.cos();
            n += 1;
        }
        if n == 0 {
            continue;
        }
        width = sum.len();
        let mean: Vec<f64> = sum.iter().map(|total| total / n as f64).collect();
        // The paper's five inputs, for its correlation table: angles in degrees.
        let heading_deg = mean[0].atan2(mean[1]).to_degrees().rem_euclid(360.0);
        paper_rows.push(heading_deg);
        paper_rows.push(mean[2]);
        let mut next = 3;
        if optional.gyro {
            paper_rows.push(mean[3].atan2(mean[4]).to_degrees().rem_euclid(360.0));
            next = 5;
        }
        paper_rows.extend(mean.get(next..).unwrap_or_default());
        rows.extend(mean);
        targets_rad.push(sum_sin.atan2(sum_cos));
    }
    let n_pairs = targets_rad.len();
    if n_pairs < MIN_PAIRS || width == 0 {
        return Err(NeuralTrainError::TooFewPairs { n_pairs });
    }
    // Unwrap about the circular mean, in degrees.
    let (sum_sin, sum_cos) = targets_rad.iter().fold((0.0, 0.0), |(s, c), &target| {
        (s + target.sin(), c + target.cos())
    });
    let mean_rad = sum_sin.atan2(sum_cos);
    let targets_deg: Vec<f64> = targets_rad
        .iter()
        .map(|&target| (mean_rad + wrap_to_pi(target - mean_rad)).to_degrees())
        .collect();
    let data = Dataset::new(&rows, width, &targets_deg, 1)?;
    let options = TrainOptions {
        seed,
        ..TrainOptions::default()
    };
    let (model, training): (Mlp, TrainingReport) = train(&data, &options)?;
    let correlation = correlation_matrix(&paper_rows, inputs.len())
        .map(|matrix| matrix.coefficients)
        .unwrap_or_default();
    Ok(NeuralCorrection {
        model,
        inputs: optional,
        report: NeuralReport {
            base_key: base_key.to_string(),
            base_label: base_label.to_string(),
            inputs,
            missing_inputs: missing,
            n_pairs,
            correlation,
            n_hidden: options.n_hidden,
            iterations: training.iterations,
            stop: training.stop,
            train_mse_deg2: training.train_mse,
            validation_mse_deg2: training.validation_mse,
        },
    })
}
