//! The trained network: one hidden layer, a linear output, and the normalisation of
//! inputs and targets, so that [`Mlp::predict`] takes and returns raw values (degrees,
//! µT, °C; metres for a step length).
//!
//! ```text
//! x̂ = (x − μₓ) / σₓ,   h = f(W₁·x̂ + b₁),   ŷ = W₂·h + b₂,   y = ŷ·σᵧ + μᵧ
//! ```
//!
//! A model is serialisable (serde) with its normalisation; a loaded model is checked
//! (sizes consistent, every number finite) before it can be used.

use super::activation::Activation;
use super::dataset::{check_finite, rows_of, DataPart, Dataset};
use super::error::NnError;
use super::loss::{Batch, Shape, INPUT_CLAMP};
use super::normalise::Standardiser;

/// Networks with up to this many inputs normalise them on the stack when predicting.
const STACK_INPUTS: usize = 16;

/// Samples per block of [`Mlp::predict_rows`] (a block's inputs and sums stay in L1).
const PREDICT_BLOCK: usize = 256;

/// A multilayer perceptron with one hidden layer and its input and output
/// normalisation. Made by [`super::train`] or loaded with serde.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "MlpParts", into = "MlpParts")]
pub struct Mlp {
    shape: Shape,
    activation: Activation,
    input_scaling: Standardiser,
    output_scaling: Standardiser,
    /// `[W₁ (hidden × inputs, row-major) | b₁ | W₂ (outputs × hidden) | b₂]`.
    params: Vec<f64>,
}

/// The serialised form of [`Mlp`].
#[derive(Clone, serde::Serialize, serde::Deserialize)]
struct MlpParts {
    n_inputs: usize,
    n_hidden: usize,
    n_outputs: usize,
    activation: Activation,
    input_scaling: Standardiser,
    output_scaling: Standardiser,
    params: Vec<f64>,
}

impl From<Mlp> for MlpParts {
    fn from(mlp: Mlp) -> Self {
        MlpParts {
            n_inputs: mlp.shape.n_inputs,
            n_hidden: mlp.shape.n_hidden,
            n_outputs: mlp.shape.n_outputs,
            activation: mlp.activation,
            input_scaling: mlp.input_scaling,
            output_scaling: mlp.output_scaling,
            params: mlp.params,
        }
    }
}

impl TryFrom<MlpParts> for Mlp {
    type Error = NnError;

    fn try_from(parts: MlpParts) -> Result<Self, NnError> {
        let shape = Shape {
            n_inputs: parts.n_inputs,
            n_hidden: parts.n_hidden,
            n_outputs: parts.n_outputs,
        };
        let inconsistent = |reason: String| Err(NnError::InconsistentModel { reason });
        if shape.n_inputs == 0 || shape.n_hidden == 0 || shape.n_outputs == 0 {
            return inconsistent(format!(
                "{} inputs, {} hidden neurons, {} outputs",
                shape.n_inputs, shape.n_hidden, shape.n_outputs
            ));
        }
        if parts.params.len() != shape.n_params() {
            return inconsistent(format!(
                "{} parameters where the sizes need {}",
                parts.params.len(),
                shape.n_params()
            ));
        }
        if parts.params.iter().any(|value| !value.is_finite()) {
            return inconsistent("a parameter is not finite".to_owned());
        }
        for (scaling, width, part) in [
            (&parts.input_scaling, shape.n_inputs, "input"),
            (&parts.output_scaling, shape.n_outputs, "output"),
        ] {
            let checked =
                Standardiser::from_parts(scaling.mean().to_vec(), scaling.scale().to_vec());
            if scaling.width() != width || checked.is_none() {
                return inconsistent(format!(
                    "the {part} normalisation does not have {width} finite columns with positive scales"
                ));
            }
        }
        Ok(Mlp::new(
            shape,
            parts.activation,
            parts.input_scaling,
            parts.output_scaling,
            parts.params,
        ))
    }
}

impl Mlp {
    /// Assembles a model from parts whose sizes the caller has made consistent.
    pub(crate) fn new(
        shape: Shape,
        activation: Activation,
        input_scaling: Standardiser,
        output_scaling: Standardiser,
        params: Vec<f64>,
    ) -> Self {
        debug_assert_eq!(params.len(), shape.n_params());
        Mlp {
            shape,
            activation,
            input_scaling,
            output_scaling,
            params,
        }
    }

    pub fn n_inputs(&self) -> usize {
        self.shape.n_inputs
    }

    pub fn n_hidden(&self) -> usize {
        self.shape.n_hidden
    }

    pub fn n_outputs(&self) -> usize {
        self.shape.n_outputs
    }

    pub fn activation(&self) -> Activation {
        self.activation
    }

    /// Weights and biases, `[W₁ (hidden × inputs, row-major) | b₁ | W₂ (outputs ×
    /// hidden) | b₂]`, acting on normalised values.
    pub fn params(&self) -> &[f64] {
        &self.params
    }

    pub fn input_scaling(&self) -> &Standardiser {
        &self.input_scaling
    }

    pub fn output_scaling(&self) -> &Standardiser {
        &self.output_scaling
    }

    /// The outputs (raw units) for one sample's raw inputs.
    pub fn predict(&self, inputs: &[f64]) -> Result<Vec<f64>, NnError> {
        let mut outputs = vec![0.0; self.shape.n_outputs];
        self.predict_into(inputs, &mut outputs)?;
        Ok(outputs)
    }

    /// [`Mlp::predict`] into the caller's `outputs` (`n_outputs` long).
    pub fn predict_into(&self, inputs: &[f64], outputs: &mut [f64]) -> Result<(), NnError> {
        let shape = self.shape;
        if inputs.len() != shape.n_inputs {
            return Err(NnError::WrongWidth {
                part: DataPart::Input,
                expected: shape.n_inputs,
                found: inputs.len(),
            });
        }
        if outputs.len() != shape.n_outputs {
            return Err(NnError::WrongWidth {
                part: DataPart::Target,
                expected: shape.n_outputs,
                found: outputs.len(),
            });
        }
        if let Some(column) = inputs.iter().position(|value| !value.is_finite()) {
            return Err(NnError::NonFinite {
                part: DataPart::Input,
                row: 0,
                column,
                value: inputs[column],
            });
        }
        let params = shape.split(&self.params);
        // The inputs normalised once (on the stack for the usual few inputs).
        let mut on_stack = [0f32; STACK_INPUTS];
        let mut on_heap = Vec::new();
        let normalised: &mut [f32] = match on_stack.get_mut(..shape.n_inputs) {
            Some(slice) => slice,
            None => {
                on_heap.resize(shape.n_inputs, 0f32);
                &mut on_heap
            }
        };
        for (input_idx, (slot, raw)) in normalised.iter_mut().zip(inputs).enumerate() {
            *slot = self
                .input_scaling
                .normalise(input_idx, *raw)
                .clamp(-INPUT_CLAMP, INPUT_CLAMP) as f32;
        }
        // The training's forward pass for one sample: the same f32 operations in the
        // same order (`kernels.rs`), so the network predicts what it was trained on.
        // Each output's sum is kept in `outputs` (an f32 value is exact in f64).
        for (output, bias) in outputs.iter_mut().zip(params.output_biases) {
            *output = f64::from(*bias as f32);
        }
        for (neuron_idx, (weights, bias)) in params
            .hidden_weights
            .chunks_exact(shape.n_inputs)
            .zip(params.hidden_biases)
            .enumerate()
        {
            let mut z = *bias as f32;
            for (weight, normalised) in weights.iter().zip(normalised.iter()) {
                z += *weight as f32 * *normalised;
            }
            let h = self.activation.of(z);
            for (output, weights) in outputs
                .iter_mut()
                .zip(params.output_weights.chunks_exact(shape.n_hidden))
            {
                let weight = weights.get(neuron_idx).copied().unwrap_or_default() as f32;
                *output = f64::from(*output as f32 + weight * h);
            }
        }
        for (output_idx, output) in outputs.iter_mut().enumerate() {
            *output = self.output_scaling.denormalise(output_idx, *output);
        }
        Ok(())
    }

    /// The outputs of many samples: `rows` holds `n_inputs` raw inputs per sample, the
    /// result `n_outputs` per sample, both row-major. The same bits as
    /// [`Mlp::predict_into`] row by row (each sample sees the same f32 operations in the
    /// same order), computed a block of samples at a time, neuron by neuron: the loops
    /// over a block's samples are independent, so the compiler vectorises them (a
    /// recording's hour of samples is predicted in milliseconds, not a quarter second).
    pub fn predict_rows(&self, rows: &[f64]) -> Result<Vec<f64>, NnError> {
        let shape = self.shape;
        let n_inputs = shape.n_inputs;
        let n_rows = rows_of(rows, n_inputs, DataPart::Input)?;
        check_finite(rows, n_inputs, DataPart::Input)?;
        let params = shape.split(&self.params);
        let single = |values: &[f64]| {
            values
                .iter()
                .map(|&value| value as f32)
                .collect::<Vec<f32>>()
        };
        let (hidden_weights, hidden_biases) =
            (single(params.hidden_weights), single(params.hidden_biases));
        let (output_weights, output_biases) =
            (single(params.output_weights), single(params.output_biases));
        let mut outputs = Vec::with_capacity(n_rows * shape.n_outputs);
        // Per block: the normalised inputs column by column, a neuron's pre-activations,
        // and each output's sum.
        let mut inputs = vec![0f32; n_inputs * PREDICT_BLOCK];
        let mut z = [0f32; PREDICT_BLOCK];
        let mut sums = vec![0f32; shape.n_outputs * PREDICT_BLOCK];
        for block in rows.chunks(n_inputs * PREDICT_BLOCK) {
            let n = block.len() / n_inputs;
            for (sample, row) in block.chunks_exact(n_inputs).enumerate() {
                for (input_idx, raw) in row.iter().enumerate() {
                    inputs[input_idx * PREDICT_BLOCK + sample] =
                        self.input_scaling
                            .normalise(input_idx, *raw)
                            .clamp(-INPUT_CLAMP, INPUT_CLAMP) as f32;
                }
            }
            for (sum, bias) in sums.chunks_exact_mut(PREDICT_BLOCK).zip(&output_biases) {
                sum[..n].fill(*bias);
            }
            for (neuron_idx, (weights, bias)) in hidden_weights
                .chunks_exact(n_inputs)
                .zip(&hidden_biases)
                .enumerate()
            {
                let z = &mut z[..n];
                z.fill(*bias);
                for (weight, column) in weights.iter().zip(inputs.chunks_exact(PREDICT_BLOCK)) {
                    for (z, input) in z.iter_mut().zip(&column[..n]) {
                        *z += *weight * *input;
                    }
                }
                for z in z.iter_mut() {
                    *z = self.activation.of(*z);
                }
                for (sum, weights) in sums
                    .chunks_exact_mut(PREDICT_BLOCK)
                    .zip(output_weights.chunks_exact(shape.n_hidden))
                {
                    let weight = weights.get(neuron_idx).copied().unwrap_or_default();
                    for (sum, h) in sum[..n].iter_mut().zip(z.iter()) {
                        *sum += weight * *h;
                    }
                }
            }
            for sample in 0..n {
                for (output_idx, sum) in sums.chunks_exact(PREDICT_BLOCK).enumerate() {
                    outputs.push(
                        self.output_scaling
                            .denormalise(output_idx, f64::from(sum[sample])),
                    );
                }
            }
        }
        Ok(outputs)
    }

    /// The mean squared error (raw units², over every sample and output) on `data`.
    pub fn mean_squared_error(&self, data: &Dataset) -> Result<f64, NnError> {
        for (part, expected, found) in [
            (DataPart::Input, self.shape.n_inputs, data.n_inputs()),
            (DataPart::Target, self.shape.n_outputs, data.n_outputs()),
        ] {
            if expected != found {
                return Err(NnError::WrongWidth {
                    part,
                    expected,
                    found,
                });
            }
        }
        let mut batch = self.batch(data);
        Ok(self.raw_mse(&mut batch))
    }

    /// `data` normalised as this model normalises, for evaluations.
    pub(crate) fn batch(&self, data: &Dataset) -> Batch {
        Batch::new(
            self.shape,
            self.activation,
            data.inputs(),
            data.targets(),
            |column, value| self.input_scaling.normalise(column, value),
            |column, value| self.output_scaling.normalise(column, value),
        )
    }

    /// The mean squared error in raw units of the current parameters on `batch`.
    pub(crate) fn raw_mse(&self, batch: &mut Batch) -> f64 {
        raw_mse_of(&self.params, &self.output_scaling, batch)
    }

    pub(crate) fn params_mut(&mut self) -> &mut [f64] {
        &mut self.params
    }
}

/// The mean squared error in raw units of `params` on the whole of `batch` (a forward
/// pass, no gradient).
pub(crate) fn raw_mse_of(params: &[f64], output_scaling: &Standardiser, batch: &mut Batch) -> f64 {
    batch.evaluate(params, 0..batch.n_samples(), 0.0, None);
    raw_mse_from_sums(
        batch.sum_squared_residuals(),
        output_scaling,
        batch.n_samples(),
    )
}

/// The mean squared error in raw units from the sums of squared normalised residuals of
/// `n_samples` samples.
pub(crate) fn raw_mse_from_sums(
    sum_squared_residuals: &[f64],
    output_scaling: &Standardiser,
    n_samples: usize,
) -> f64 {
    let total: f64 = sum_squared_residuals
        .iter()
        .zip(output_scaling.scale())
        .map(|(sum, scale)| sum * scale * scale)
        .sum();
    total / (n_samples.max(1) * sum_squared_residuals.len().max(1)) as f64
}
