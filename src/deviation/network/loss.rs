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
//! The samples are stored column-major (one contiguous vector per input, padded with
//! zeros to whole vectors) and the batch is cut into *parts* of [`PART`] samples whose
//! sums are formed separately (`kernels.rs`: the forward pass, the residuals and the
//! gradient, eight samples at a time in single precision, in chunks that stay in the L1
//! cache, each chunk's sums added in `f64`) and then added
//! in the order of the parts. The parts do not depend on the number of threads: on native
//! builds a large batch spreads its parts over the cores and gives the same bits as one
//! thread (and as wasm, which runs them one after the other). Every buffer is allocated
//! when the batch is built; an evaluation allocates nothing (a multi-threaded one
//! starts its threads). The order of every sum is fixed, so an evaluation gives the same
//! bits every time.

use std::ops::Range;
use std::sync::Arc;

use super::activation::Activation;
#[cfg(target_arch = "wasm32")]
use super::kernels::PartInput;
use super::kernels::{self, Scratch, PAIR};

/// Samples per part: a multiple of the kernels' chunk. 10,000 samples make 10 parts,
/// which two cores share evenly.
const PART: usize = 8 * kernels::CHUNK;

/// Batches of at least this many samples are evaluated on several threads (native
/// builds): below it, starting a thread costs more than it saves.
const PARALLEL_MIN_SAMPLES: usize = 4 * PART;

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

    pub fn split<'a, T>(&self, params: &'a [T]) -> Blocks<&'a [T]> {
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

/// The normalised samples, column-major and padded with zeros to whole pairs of vectors.
#[derive(Clone)]
pub(crate) struct Samples {
    /// `inputs[i·stride + s]`: input `i` of sample `s` (zero past the last sample), in
    /// the kernels' single precision.
    pub inputs: Vec<f32>,
    /// `targets[k·stride + s]`: target `k` of sample `s` (zero past the last sample).
    pub targets: Vec<f32>,
    /// Length of a column: the number of samples rounded up to a whole pair of vectors,
    /// plus one pair (a range that starts anywhere reads at most that far).
    pub stride: usize,
}

/// Normalised samples with the scratch space of an evaluation.
pub(crate) struct Batch {
    shape: Shape,
    #[cfg(target_arch = "wasm32")]
    activation: Activation,
    n_samples: usize,
    /// Shared with the helper threads while they evaluate.
    samples: Arc<Samples>,
    scratch: Scratch,
    /// The weights of the evaluation rounded to the kernels' `f32`.
    params_f32: Vec<f32>,
    /// Each part's sums: `n_outputs` sums of squared residuals, then the gradient.
    part_sums: Vec<f64>,
    /// Sum of squared residuals per output over the last evaluation.
    sum_squared_residuals: Vec<f64>,
    #[cfg(not(target_arch = "wasm32"))]
    workers: super::workers::Workers,
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
        let stride = n_samples.div_ceil(PAIR) * PAIR + PAIR;
        let mut columns = vec![0.0; stride * shape.n_inputs];
        for (sample_idx, row) in inputs.chunks_exact(shape.n_inputs).enumerate() {
            for (input_idx, value) in row.iter().enumerate() {
                columns[input_idx * stride + sample_idx] =
                    normalise_input(input_idx, *value).clamp(-INPUT_CLAMP, INPUT_CLAMP) as f32;
            }
        }
        let mut target_columns = vec![0.0; stride * shape.n_outputs];
        for (sample_idx, row) in targets.chunks_exact(shape.n_outputs).enumerate() {
            for (output_idx, value) in row.iter().enumerate() {
                target_columns[output_idx * stride + sample_idx] =
                    normalise_target(output_idx, *value) as f32;
            }
        }
        Batch {
            shape,
            #[cfg(target_arch = "wasm32")]
            activation,
            n_samples,
            samples: Arc::new(Samples {
                inputs: columns,
                targets: target_columns,
                stride,
            }),
            scratch: Scratch::new(shape),
            params_f32: vec![0.0; shape.n_params()],
            part_sums: vec![
                0.0;
                n_samples.div_ceil(PART).max(1) * (shape.n_outputs + shape.n_params())
            ],
            sum_squared_residuals: vec![0.0; shape.n_outputs],
            #[cfg(not(target_arch = "wasm32"))]
            workers: super::workers::Workers::new(shape, activation),
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
    pub fn permute(&mut self, order: &[usize], scratch: &mut Vec<f32>) {
        // The helpers hold no reference between evaluations, so this does not copy.
        let samples = Arc::make_mut(&mut self.samples);
        let stride = samples.stride;
        for data in [&mut samples.inputs, &mut samples.targets] {
            scratch.clear();
            for column in data.chunks_exact(stride) {
                scratch.extend(order.iter().map(|&old| column[old]));
                scratch.extend_from_slice(&column[order.len()..]);
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
        gradient: Option<&mut [f64]>,
    ) -> f64 {
        let shape = self.shape;
        let n_outputs = shape.n_outputs;
        let sums_len = n_outputs
            + if gradient.is_some() {
                shape.n_params()
            } else {
                0
            };
        let n_parts = range.len().div_ceil(PART);
        let part_sums = &mut self.part_sums[..n_parts * sums_len];
        self.params_f32.clear();
        self.params_f32
            .extend(params.iter().map(|&value| value as f32));
        let n_threads = if range.len() >= PARALLEL_MIN_SAMPLES {
            crate::base::par::n_threads()
        } else {
            1
        };
        #[cfg(not(target_arch = "wasm32"))]
        self.workers.evaluate(
            &self.samples,
            &self.params_f32,
            range.clone(),
            PART,
            n_threads,
            &mut self.scratch,
            part_sums,
            sums_len,
        );
        #[cfg(target_arch = "wasm32")]
        {
            let _ = n_threads;
            let input = PartInput {
                shape,
                activation: self.activation,
                params: &self.params_f32,
                inputs: &self.samples.inputs,
                targets: &self.samples.targets,
                stride: self.samples.stride,
            };
            for (part_idx, sums) in part_sums.chunks_exact_mut(sums_len).enumerate() {
                let start = range.start + part_idx * PART;
                let part = start..(start + PART).min(range.end);
                kernels::evaluate_part(&input, part, &mut self.scratch, sums);
            }
        }

        // The parts' sums in the order of the parts.
        self.sum_squared_residuals.fill(0.0);
        let mut gradient = gradient;
        if let Some(gradient) = gradient.as_deref_mut() {
            gradient.fill(0.0);
        }
        for sums in part_sums.chunks_exact(sums_len) {
            let (squares, gradient_sums) = sums.split_at(n_outputs);
            for (total, part) in self.sum_squared_residuals.iter_mut().zip(squares) {
                *total += part;
            }
            if let Some(gradient) = gradient.as_deref_mut() {
                for (total, part) in gradient.iter_mut().zip(gradient_sums) {
                    *total += part;
                }
            }
        }

        let params = shape.split(params);
        let m = range.len().max(1) as f64;
        let penalty = dot(params.hidden_weights, params.hidden_weights)
            + dot(params.output_weights, params.output_weights);
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

/// `Σ xᵢ·yᵢ` in order.
fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::SplitMix64;

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
                // The kernels evaluate in f32: a step far above its rounding of the
                // weights (10⁻⁷ relative), small enough for the central difference.
                let step = 3e-3;
                let mut plus = params.clone();
                plus[idx] += step;
                let mut minus = params.clone();
                minus[idx] -= step;
                let numeric = (batch.evaluate(&plus, 0..300, l2_penalty, None)
                    - batch.evaluate(&minus, 0..300, l2_penalty, None))
                    / (2.0 * step);
                assert!(
                    (numeric - gradient[idx]).abs() < 1e-4 * (1.0 + numeric.abs()),
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
        // Summed in other chunks (so other f32 lanes): equal to f32 rounding.
        assert!((value - sub_value).abs() < 1e-6 * value.abs());
        for (a, b) in gradient.iter().zip(&sub_gradient) {
            assert!((a - b).abs() < 1e-6 * (1.0 + a.abs()));
        }
    }

    #[test]
    fn a_large_batch_gives_the_same_bits_on_any_number_of_threads() {
        let shape = Shape {
            n_inputs: 5,
            n_hidden: 7,
            n_outputs: 2,
        };
        let n = PARALLEL_MIN_SAMPLES + 1000;
        let (mut batch, params) = random_case(shape, Activation::Logistic, n, 11);
        let mut gradient = vec![0.0; shape.n_params()];
        let value = batch.evaluate(&params, 0..n, 0.01, Some(&mut gradient));
        // The same parts, one after the other on this thread, added in order.
        let params_f32: Vec<f32> = params.iter().map(|&value| value as f32).collect();
        let input = kernels::PartInput {
            shape,
            activation: Activation::Logistic,
            params: &params_f32,
            inputs: &batch.samples.inputs,
            targets: &batch.samples.targets,
            stride: batch.samples.stride,
        };
        let mut scratch = Scratch::new(shape);
        let mut totals = vec![0.0; shape.n_outputs + shape.n_params()];
        let mut sums = totals.clone();
        for start in (0..n).step_by(PART) {
            kernels::evaluate_part(
                &input,
                start..(start + PART).min(n),
                &mut scratch,
                &mut sums,
            );
            for (total, sum) in totals.iter_mut().zip(&sums) {
                *total += sum;
            }
        }
        let m = n as f64;
        let blocks = shape.split(&params);
        let penalty = dot(blocks.hidden_weights, blocks.hidden_weights)
            + dot(blocks.output_weights, blocks.output_weights);
        let expected = totals[..2].iter().sum::<f64>() / (2.0 * m) + 0.01 * penalty / (2.0 * m);
        assert_eq!(value.to_bits(), expected.to_bits());
        assert_eq!(totals[2] / m + 0.01 * params[0] / m, gradient[0]);
        assert_eq!(
            totals[2 + shape.n_params() - 1] / m,
            gradient[shape.n_params() - 1]
        );
        let mut again = vec![0.0; shape.n_params()];
        assert_eq!(
            batch
                .evaluate(&params, 0..n, 0.01, Some(&mut again))
                .to_bits(),
            value.to_bits()
        );
        assert_eq!(again, gradient);
    }
}
