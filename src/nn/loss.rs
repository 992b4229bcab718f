//! The training objective and its analytic gradient over a batch of samples.
//!
//! For normalised inputs `x` and targets `t` of `m` samples, weights `W₁` (hidden ×
//! inputs), `W₂` (outputs × hidden) and biases `b₁`, `b₂`:
//!
//! ```text
//! h = f(W₁·x + b₁),   y = W₂·h + b₂,   r = y − t
//! L = Σₛ |rₛ|² / (2m) + α·(|W₁|² + |W₂|²) / (2m)
//! ∂L/∂W₂ = (Σₛ rₛ·hₛᵀ + α·W₂) / m,   ∂L/∂b₂ = Σₛ rₛ / m
//! δₛ = (W₂ᵀ·rₛ) ⊙ f'(hₛ)
//! ∂L/∂W₁ = (Σₛ δₛ·xₛᵀ + α·W₁) / m,   ∂L/∂b₁ = Σₛ δₛ / m
//! ```
//!
//! This is back-propagation (Rumelhart, Hinton and Williams 1986) and, for one output,
//! exactly scikit-learn's `MLPRegressor` objective (`squared_loss / 2` plus
//! `alpha · ‖W‖² / (2 n_samples)`; biases are not penalised).
//!
//! The samples are stored column-major (one contiguous vector per input) and processed
//! in chunks of [`CHUNK`] samples: for each chunk the hidden activations of all its
//! samples are computed in one pass (the inner loops run over samples, so they are SIMD
//! loops), then the residuals, then the gradient. Every buffer is allocated once, when
//! the batch is built; an evaluation allocates nothing. The order of every sum is fixed,
//! so an evaluation gives the same bits every time.

use std::ops::Range;

use super::activation::Activation;
use super::kernels;

/// Samples per chunk: the chunk's hidden activations (16 × 128 × 8 bytes = 16 KiB)
/// stay in the L1 cache while its gradient is accumulated.
const CHUNK: usize = 128;

/// Normalised inputs further than this many standard deviations from the training mean
/// are clamped to it: the hidden layer is saturated long before, and the clamp keeps
/// every product finite whatever the input.
pub(crate) const INPUT_CLAMP: f64 = 1e6;

/// The sizes of the network and where each block of parameters lies in the flat
/// parameter vector `[W₁ (row-major) | b₁ | W₂ (row-major) | b₂]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Shape {
    pub n_inputs: usize,
    pub n_hidden: usize,
    pub n_outputs: usize,
}

/// The four blocks of a parameter (or gradient) vector.
pub(crate) struct Blocks<T> {
    pub hidden_weights: T,
    pub hidden_biases: T,
    pub output_weights: T,
    pub output_biases: T,
}

impl Shape {
    pub fn n_params(&self) -> usize {
        (self.n_inputs + 1) * self.n_hidden + (self.n_hidden + 1) * self.n_outputs
    }

    pub fn split<'a>(&self, params: &'a [f64]) -> Blocks<&'a [f64]> {
        let (hidden_weights, rest) = params.split_at(self.n_inputs * self.n_hidden);
        let (hidden_biases, rest) = rest.split_at(self.n_hidden);
        let (output_weights, output_biases) = rest.split_at(self.n_hidden * self.n_outputs);
        Blocks {
            hidden_weights,
            hidden_biases,
            output_weights,
            output_biases,
        }
    }

    pub fn split_mut<'a>(&self, params: &'a mut [f64]) -> Blocks<&'a mut [f64]> {
        let (hidden_weights, rest) = params.split_at_mut(self.n_inputs * self.n_hidden);
        let (hidden_biases, rest) = rest.split_at_mut(self.n_hidden);
        let (output_weights, output_biases) = rest.split_at_mut(self.n_hidden * self.n_outputs);
        Blocks {
            hidden_weights,
            hidden_biases,
            output_weights,
            output_biases,
        }
    }
}

/// Normalised samples in column-major order with the scratch space of an evaluation.
pub(crate) struct Batch {
    shape: Shape,
    activation: Activation,
    n_samples: usize,
    /// `inputs[i·n_samples + s]`: input `i` of sample `s`.
    inputs: Vec<f64>,
    /// `targets[k·n_samples + s]`: target `k` of sample `s`.
    targets: Vec<f64>,
    /// Hidden activations of one chunk, `hidden[j·CHUNK + s]`; then their deltas.
    hidden: Vec<f64>,
    /// Residuals of one chunk, `residuals[k·CHUNK + s]`.
    residuals: Vec<f64>,
    /// Sum of squared residuals per output over the last evaluation.
    sum_squared_residuals: Vec<f64>,
    /// `W₂ᵀ` (hidden × outputs) of the current evaluation.
    output_weights_by_neuron: Vec<f64>,
}

impl Batch {
    /// Column-major copies of row-major `inputs` and `targets`, each value passed
    /// through `normalise_input(column, value)` or `normalise_target(column, value)`.
    pub fn new(
        shape: Shape,
        activation: Activation,
        inputs: &[f64],
        targets: &[f64],
        normalise_input: impl Fn(usize, f64) -> f64,
        normalise_target: impl Fn(usize, f64) -> f64,
    ) -> Self {
        let n_samples = inputs.len() / shape.n_inputs;
        let mut columns = vec![0.0; n_samples * shape.n_inputs];
        for (sample_idx, row) in inputs.chunks_exact(shape.n_inputs).enumerate() {
            for (input_idx, value) in row.iter().enumerate() {
                columns[input_idx * n_samples + sample_idx] =
                    normalise_input(input_idx, *value).clamp(-INPUT_CLAMP, INPUT_CLAMP);
            }
        }
        let mut target_columns = vec![0.0; n_samples * shape.n_outputs];
        for (sample_idx, row) in targets.chunks_exact(shape.n_outputs).enumerate() {
            for (output_idx, value) in row.iter().enumerate() {
                target_columns[output_idx * n_samples + sample_idx] =
                    normalise_target(output_idx, *value);
            }
        }
        Batch {
            shape,
            activation,
            n_samples,
            inputs: columns,
            targets: target_columns,
            hidden: vec![0.0; shape.n_hidden * CHUNK],
            residuals: vec![0.0; shape.n_outputs * CHUNK],
            sum_squared_residuals: vec![0.0; shape.n_outputs],
            output_weights_by_neuron: vec![0.0; shape.n_hidden * shape.n_outputs],
        }
    }

    pub fn n_samples(&self) -> usize {
        self.n_samples
    }

    /// Sum of squared residuals (normalised units) of each output in the last evaluation.
    pub fn sum_squared_residuals(&self) -> &[f64] {
        &self.sum_squared_residuals
    }

    /// Reorders the samples: sample `s` becomes the old sample `order[s]`. `scratch` is
    /// reused between calls. `order` must be a permutation of `0..n_samples`.
    pub fn permute(&mut self, order: &[usize], scratch: &mut Vec<f64>) {
        for data in [&mut self.inputs, &mut self.targets] {
            scratch.clear();
            for column in data.chunks_exact(self.n_samples) {
                scratch.extend(order.iter().map(|&old| column[old]));
            }
            std::mem::swap(data, scratch);
        }
    }

    /// The objective `L` on the samples in `range` (see the module documentation) with
    /// penalty `l2_penalty` (α), and its gradient written to `gradient` when given. Also
    /// leaves the sums of squared residuals in [`Batch::sum_squared_residuals`].
    pub fn evaluate(
        &mut self,
        params: &[f64],
        range: Range<usize>,
        l2_penalty: f64,
        mut gradient: Option<&mut [f64]>,
    ) -> f64 {
        let shape = self.shape;
        let n = self.n_samples;
        let params = shape.split(params);
        self.sum_squared_residuals.fill(0.0);
        if let Some(gradient) = gradient.as_deref_mut() {
            gradient.fill(0.0);
        }
        // W₂ᵀ, so that the weights from one hidden neuron to every output are contiguous.
        for (output_idx, row) in params
            .output_weights
            .chunks_exact(shape.n_hidden)
            .enumerate()
        {
            for (neuron_idx, weight) in row.iter().enumerate() {
                self.output_weights_by_neuron[neuron_idx * shape.n_outputs + output_idx] = *weight;
            }
        }
        let mut chunk_start = range.start;
        while chunk_start < range.end {
            let chunk_end = (chunk_start + CHUNK).min(range.end);
            let m = chunk_end - chunk_start;
            let inputs = &self.inputs[chunk_start..];

            // Hidden layer: h = f(b₁ + W₁·x), one hidden neuron (a row of samples) at a time.
            for ((hidden, weights), bias) in self
                .hidden
                .chunks_exact_mut(CHUNK)
                .zip(params.hidden_weights.chunks_exact(shape.n_inputs))
                .zip(params.hidden_biases)
            {
                let hidden = &mut hidden[..m];
                kernels::affine_rows(*bias, weights, inputs, n, hidden);
                kernels::activate(self.activation, hidden);
            }

            // Output layer and residuals: r = b₂ + W₂·h − t.
            for (output_idx, ((residual, weights), bias)) in self
                .residuals
                .chunks_exact_mut(CHUNK)
                .zip(params.output_weights.chunks_exact(shape.n_hidden))
                .zip(params.output_biases)
                .enumerate()
            {
                let residual = &mut residual[..m];
                kernels::affine_rows(*bias, weights, &self.hidden, CHUNK, residual);
                let target = &self.targets[output_idx * n + chunk_start..][..m];
                for (r, t) in residual.iter_mut().zip(target) {
                    *r -= t;
                }
                self.sum_squared_residuals[output_idx] += kernels::dot(residual, residual);
            }

            if let Some(gradient) = gradient.as_deref_mut() {
                let gradient = shape.split_mut(gradient);
                // Output layer: Σ r·hᵀ and Σ r.
                for ((residual, row), bias_gradient) in self
                    .residuals
                    .chunks_exact(CHUNK)
                    .zip(gradient.output_weights.chunks_exact_mut(shape.n_hidden))
                    .zip(gradient.output_biases.iter_mut())
                {
                    let residual = &residual[..m];
                    *bias_gradient += sum(residual);
                    for (weight_gradient, hidden) in
                        row.iter_mut().zip(self.hidden.chunks_exact(CHUNK))
                    {
                        *weight_gradient += kernels::dot(residual, &hidden[..m]);
                    }
                }
                // Hidden layer: δ = (W₂ᵀ·r) ⊙ f'(h), written over h, then Σ δ·xᵀ and Σ δ.
                let mut back = [0.0; CHUNK];
                let back = &mut back[..m];
                for (((hidden, weights_to_outputs), row), bias_gradient) in self
                    .hidden
                    .chunks_exact_mut(CHUNK)
                    .zip(self.output_weights_by_neuron.chunks_exact(shape.n_outputs))
                    .zip(gradient.hidden_weights.chunks_exact_mut(shape.n_inputs))
                    .zip(gradient.hidden_biases.iter_mut())
                {
                    let hidden = &mut hidden[..m];
                    kernels::affine_rows(0.0, weights_to_outputs, &self.residuals, CHUNK, back);
                    kernels::back_propagate(self.activation, back, hidden);
                    *bias_gradient += sum(hidden);
                    for (input_idx, weight_gradient) in row.iter_mut().enumerate() {
                        *weight_gradient += kernels::dot(hidden, &inputs[input_idx * n..][..m]);
                    }
                }
            }
            chunk_start = chunk_end;
        }

        let m = range.len().max(1) as f64;
        let penalty = kernels::dot(params.hidden_weights, params.hidden_weights)
            + kernels::dot(params.output_weights, params.output_weights);
        if let Some(gradient) = gradient {
            for value in gradient.iter_mut() {
                *value /= m;
            }
            let gradient = shape.split_mut(gradient);
            for (blocks_gradient, blocks_value) in [
                (gradient.hidden_weights, params.hidden_weights),
                (gradient.output_weights, params.output_weights),
            ] {
                for (gradient, value) in blocks_gradient.iter_mut().zip(blocks_value) {
                    *gradient += l2_penalty * value / m;
                }
            }
        }
        self.sum_squared_residuals.iter().sum::<f64>() / (2.0 * m)
            + l2_penalty * penalty / (2.0 * m)
    }
}

/// `Σ xᵢ` with four partial sums.
#[inline]
fn sum(x: &[f64]) -> f64 {
    let mut partial = [0.0; 4];
    let chunks = x.chunks_exact(4);
    let tail: f64 = chunks.remainder().iter().sum();
    for x in chunks {
        partial[0] += x[0];
        partial[1] += x[1];
        partial[2] += x[2];
        partial[3] += x[3];
    }
    (partial[0] + partial[1]) + (partial[2] + partial[3]) + tail
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::SplitMix64;

    /// A batch of random normalised samples and random parameters.
    fn random_case(
        shape: Shape,
        activation: Activation,
        n_samples: usize,
        seed: u64,
    ) -> (Batch, Vec<f64>) {
        let mut rng = SplitMix64::new(seed);
        let inputs: Vec<f64> = (0..n_samples * shape.n_inputs)
            .map(|_| rng.gaussian())
            .collect();
        let targets: Vec<f64> = (0..n_samples * shape.n_outputs)
            .map(|_| rng.gaussian())
            .collect();
        let params: Vec<f64> = (0..shape.n_params())
            .map(|_| rng.uniform_in(-1.0, 1.0))
            .collect();
        let batch = Batch::new(shape, activation, &inputs, &targets, |_, v| v, |_, v| v);
        (batch, params)
    }

    #[test]
    fn the_gradient_matches_finite_differences() {
        let shape = Shape {
            n_inputs: 3,
            n_hidden: 5,
            n_outputs: 2,
        };
        for activation in [Activation::Logistic, Activation::Tanh] {
            // 300 samples: more than two chunks, the last one partial.
            let (mut batch, params) = random_case(shape, activation, 300, 7);
            let l2_penalty = 0.3;
            let mut gradient = vec![0.0; shape.n_params()];
            batch.evaluate(&params, 0..300, l2_penalty, Some(&mut gradient));
            for idx in 0..shape.n_params() {
                let step = 1e-6;
                let mut plus = params.clone();
                plus[idx] += step;
                let mut minus = params.clone();
                minus[idx] -= step;
                let numeric = (batch.evaluate(&plus, 0..300, l2_penalty, None)
                    - batch.evaluate(&minus, 0..300, l2_penalty, None))
                    / (2.0 * step);
                assert!(
                    (numeric - gradient[idx]).abs() < 1e-7 * (1.0 + numeric.abs()),
                    "{activation:?} parameter {idx}: analytic {} numeric {numeric}",
                    gradient[idx]
                );
            }
        }
    }

    #[test]
    fn a_sub_range_is_the_same_as_a_batch_of_those_samples() {
        let shape = Shape {
            n_inputs: 2,
            n_hidden: 4,
            n_outputs: 1,
        };
        let (mut batch, params) = random_case(shape, Activation::Tanh, 200, 3);
        let mut gradient = vec![0.0; shape.n_params()];
        let value = batch.evaluate(&params, 50..170, 0.01, Some(&mut gradient));
        let mut rng = SplitMix64::new(3);
        let inputs: Vec<f64> = (0..400).map(|_| rng.gaussian()).collect();
        let targets: Vec<f64> = (0..200).map(|_| rng.gaussian()).collect();
        let mut sub = Batch::new(
            shape,
            Activation::Tanh,
            &inputs[100..340],
            &targets[50..170],
            |_, v| v,
            |_, v| v,
        );
        let mut sub_gradient = vec![0.0; shape.n_params()];
        let sub_value = sub.evaluate(&params, 0..120, 0.01, Some(&mut sub_gradient));
        assert!((value - sub_value).abs() < 1e-12);
        for (a, b) in gradient.iter().zip(&sub_gradient) {
            assert!((a - b).abs() < 1e-12);
        }
    }
}
