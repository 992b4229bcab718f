//! Training an [`Mlp`]: the split into training and validation samples, the
//! initialisation, the optimiser, early stopping and the report.
//!
//! - **Split**: with `validation_fraction > 0` the samples are shuffled (SplitMix64,
//!   seeded) and the last `round(fraction·n)` (at least one) are held out; the
//!   normalisation is fitted on the training part only.
//! - **Initialisation**: Glorot and Bengio (2010) uniform, `±√(k / (fan_in + fan_out))`
//!   with `k = 6` for tanh and `k = 2` for the logistic function, for weights and biases,
//!   as scikit-learn's `MLPRegressor` does.
//! - **Optimisers** on the objective of `loss.rs` (mean squared error / 2 plus
//!   `α·‖W‖² / 2n`):
//!   - [`Optimiser::Lbfgs`]: full-batch L-BFGS (`lbfgs.rs`); an iteration is one
//!     quasi-Newton step.
//!   - [`Optimiser::GradientDescent`]: back-propagation as in Noureldin et al. (2007),
//!     Section 3 (Principe et al. 2000): gradient descent with momentum,
//!     `v ← μ·v − η·∇L`, `θ ← θ + v`, on mini-batches of a reshuffled order each
//!     epoch (or the full batch); an iteration is one epoch.
//! - **Early stopping** (with a validation part): after each iteration the validation
//!   MSE is computed; training stops when it has not improved for `patience` iterations,
//!   and the weights with the lowest validation MSE are returned.
//!
//! The same data, options and seed give bit-identical weights.

use std::cell::Cell;
use std::ops::ControlFlow;

use super::activation::Activation;
use super::dataset::Dataset;
use super::error::NnError;
use super::lbfgs::{self, LbfgsOptions, LbfgsStop, Objective};
use super::loss::{Batch, Shape};
use super::mlp::{raw_mse_from_sums, raw_mse_of, Mlp};
use super::normalise::Standardiser;
use crate::base::rng::SplitMix64;

/// How the weights are optimised.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Optimiser {
    /// Full-batch L-BFGS keeping `memory` correction pairs (10 is usual).
    Lbfgs { memory: usize },
    /// Back-propagation: gradient descent with momentum on mini-batches of `batch_size`
    /// samples (`None`: the full batch each step).
    GradientDescent {
        learning_rate: f64,
        momentum: f64,
        batch_size: Option<usize>,
    },
}

/// Training options. [`TrainOptions::default`] is 15 logistic neurons, L-BFGS, α = 10⁻⁴,
/// at most 200 iterations, 10 % held out with a patience of 20.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrainOptions {
    pub n_hidden: usize,
    pub activation: Activation,
    pub optimiser: Optimiser,
    /// α of the L2 penalty `α·‖W‖² / 2n` (scikit-learn's `alpha`; 0 for none).
    pub l2_penalty: f64,
    /// L-BFGS iterations or gradient-descent epochs.
    pub max_iterations: usize,
    /// Share of the samples held out for early stopping, in `[0, 1)`; 0 turns early
    /// stopping off.
    pub validation_fraction: f64,
    /// Iterations without a lower validation MSE before training stops.
    pub patience: usize,
    /// L-BFGS only: stop when every gradient component is at most this (scikit-learn's
    /// `tol` for its `lbfgs` solver).
    pub gradient_tolerance: f64,
    /// L-BFGS only: stop when an iteration lowers the objective by at most this
    /// relative amount (SciPy's `ftol`).
    pub relative_decrease_tolerance: f64,
    pub seed: u64,
}

impl Default for TrainOptions {
    fn default() -> Self {
        TrainOptions {
            n_hidden: 15,
            activation: Activation::Logistic,
            optimiser: Optimiser::Lbfgs { memory: 10 },
            l2_penalty: 1e-4,
            max_iterations: 200,
            validation_fraction: 0.1,
            patience: 20,
            gradient_tolerance: 1e-4,
            relative_decrease_tolerance: 1e7 * f64::EPSILON,
            seed: 0,
        }
    }
}

/// Why training stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    MaxIterations,
    /// The validation MSE had not improved for `patience` iterations.
    EarlyStopping,
    GradientTolerance,
    RelativeDecrease,
    MaxEvaluations,
    /// L-BFGS found no step that lowers the objective (a minimum to within rounding).
    LineSearchFailed,
    /// Gradient descent diverged (a non-finite loss): lower the learning rate. The
    /// weights returned are the best seen before.
    Diverged,
}

/// What training did.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrainingReport {
    /// L-BFGS iterations or gradient-descent epochs run.
    pub iterations: usize,
    /// Objective-and-gradient evaluations (L-BFGS) or mini-batch steps (gradient descent).
    pub evaluations: usize,
    pub n_train: usize,
    pub n_validation: usize,
    /// Training MSE (raw units², mean over outputs) at the start and after each
    /// iteration; for gradient descent, the mean over the epoch's mini-batches.
    pub train_mse_history: Vec<f64>,
    /// Validation MSE at the start and after each iteration (empty without validation).
    pub validation_mse_history: Vec<f64>,
    /// The iteration whose weights are returned (0: the initial weights).
    pub best_iteration: usize,
    /// Training and validation MSE of the returned weights.
    pub train_mse: f64,
    pub validation_mse: Option<f64>,
    pub stop: StopReason,
}

/// Trains a network on `data` (raw units: the model learns the normalisation).
pub fn train(data: &Dataset, options: &TrainOptions) -> Result<(Mlp, TrainingReport), NnError> {
    check_options(options)?;
    let n_samples = data.n_samples();
    let Some((n_train, n_validation)) = split_sizes(n_samples, options.validation_fraction) else {
        let min = (2..1_000_000)
            .find(|&n| split_sizes(n, options.validation_fraction).is_some())
            .unwrap_or(usize::MAX);
        return Err(NnError::TooFewSamples { n_samples, min });
    };

    let mut rng = SplitMix64::new(options.seed);
    let (train_data, validation_data) = if n_validation > 0 {
        let mut order: Vec<usize> = (0..n_samples).collect();
        shuffle(&mut order, &mut rng);
        let (train_idx, validation_idx) = order.split_at(n_train);
        (data.select(train_idx), Some(data.select(validation_idx)))
    } else {
        (data.clone(), None)
    };

    let shape = Shape {
        n_inputs: data.n_inputs(),
        n_hidden: options.n_hidden,
        n_outputs: data.n_outputs(),
    };
    let input_scaling = Standardiser::fit(train_data.inputs(), shape.n_inputs);
    let output_scaling = Standardiser::fit(train_data.targets(), shape.n_outputs);
    let params = glorot_uniform(shape, options.activation, &mut rng);
    let mut model = Mlp::new(
        shape,
        options.activation,
        input_scaling,
        output_scaling,
        params,
    );
    let mut train_batch = model.batch(&train_data);
    let mut validation =
        validation_data.map(|data| Validation::new(&model, &data, options.patience));

    let mut report = TrainingReport {
        iterations: 0,
        evaluations: 0,
        n_train,
        n_validation,
        train_mse_history: vec![model.raw_mse(&mut train_batch)],
        validation_mse_history: Vec::new(),
        best_iteration: 0,
        train_mse: f64::NAN,
        validation_mse: None,
        stop: StopReason::MaxIterations,
    };
    if let Some(validation) = validation.as_mut() {
        let (mse, _) = validation.record(0, model.params());
        report.validation_mse_history.push(mse);
    }

    match &options.optimiser {
        Optimiser::Lbfgs { memory } => run_lbfgs(
            &mut model,
            &mut train_batch,
            validation.as_mut(),
            *memory,
            options,
            &mut report,
        ),
        Optimiser::GradientDescent {
            learning_rate,
            momentum,
            batch_size,
        } => run_gradient_descent(
            &mut model,
            &mut train_batch,
            validation.as_mut(),
            GradientDescent {
                learning_rate: *learning_rate,
                momentum: *momentum,
                batch_size: batch_size.unwrap_or(n_train).min(n_train),
            },
            options,
            &mut rng,
            &mut report,
        ),
    }

    if let Some(validation) = validation {
        model.params_mut().copy_from_slice(&validation.best_params);
        report.best_iteration = validation.best_iteration;
        report.validation_mse = Some(validation.best_mse);
    }
    report.train_mse = model.raw_mse(&mut train_batch);
    Ok((model, report))
}

fn check_options(options: &TrainOptions) -> Result<(), NnError> {
    if options.n_hidden == 0 {
        return Err(NnError::HiddenSizeZero);
    }
    let invalid = |name, value, what_to_do| {
        Err(NnError::InvalidOption {
            name,
            value,
            what_to_do,
        })
    };
    if !(0.0..1.0).contains(&options.validation_fraction) {
        return invalid(
            "validation_fraction",
            options.validation_fraction,
            "choose a share in [0, 1), such as 0.1.",
        );
    }
    if !(options.l2_penalty.is_finite() && options.l2_penalty >= 0.0) {
        return invalid(
            "l2_penalty",
            options.l2_penalty,
            "choose 0 or a small positive α such as 1e-4.",
        );
    }
    match options.optimiser {
        Optimiser::Lbfgs { memory: 0 } => {
            return invalid(
                "memory",
                0.0,
                "keep at least one correction pair; 10 is usual.",
            )
        }
        Optimiser::GradientDescent {
            learning_rate,
            momentum,
            batch_size,
        } => {
            if !(learning_rate.is_finite() && learning_rate > 0.0) {
                return invalid(
                    "learning_rate",
                    learning_rate,
                    "choose a small positive rate such as 0.01.",
                );
            }
            if !(0.0..1.0).contains(&momentum) {
                return invalid(
                    "momentum",
                    momentum,
                    "choose a momentum in [0, 1), such as 0.9.",
                );
            }
            if batch_size == Some(0) {
                return invalid(
                    "batch_size",
                    0.0,
                    "choose at least one sample per batch, or None for the full batch.",
                );
            }
        }
        Optimiser::Lbfgs { .. } => {}
    }
    Ok(())
}

/// Training and validation sizes, or `None` when there would be fewer than two training
/// samples (or no validation sample although one was asked for).
fn split_sizes(n_samples: usize, validation_fraction: f64) -> Option<(usize, usize)> {
    let n_validation = if validation_fraction > 0.0 {
        ((n_samples as f64 * validation_fraction).round() as usize).max(1)
    } else {
        0
    };
    let n_train = n_samples.checked_sub(n_validation)?;
    (n_train >= 2).then_some((n_train, n_validation))
}

/// Fisher-Yates shuffle.
fn shuffle(order: &mut [usize], rng: &mut SplitMix64) {
    for idx in (1..order.len()).rev() {
        let other = (rng.next_u64() % (idx as u64 + 1)) as usize;
        order.swap(idx, other);
    }
}

fn glorot_uniform(shape: Shape, activation: Activation, rng: &mut SplitMix64) -> Vec<f64> {
    let factor = match activation {
        Activation::Logistic => 2.0,
        Activation::Tanh => 6.0,
    };
    let mut params = vec![0.0; shape.n_params()];
    let blocks = shape.split_mut(&mut params);
    let hidden_bound = (factor / (shape.n_inputs + shape.n_hidden) as f64).sqrt();
    let output_bound = (factor / (shape.n_hidden + shape.n_outputs) as f64).sqrt();
    for (block, bound) in [
        (blocks.hidden_weights, hidden_bound),
        (blocks.hidden_biases, hidden_bound),
        (blocks.output_weights, output_bound),
        (blocks.output_biases, output_bound),
    ] {
        for value in block.iter_mut() {
            *value = rng.uniform_in(-bound, bound);
        }
    }
    params
}

/// The held-out samples and the best weights seen on them.
struct Validation {
    batch: Batch,
    best_params: Vec<f64>,
    best_mse: f64,
    best_iteration: usize,
    patience: usize,
    output_scaling: Standardiser,
}

impl Validation {
    fn new(model: &Mlp, data: &Dataset, patience: usize) -> Self {
        Validation {
            batch: model.batch(data),
            best_params: model.params().to_vec(),
            best_mse: f64::INFINITY,
            best_iteration: 0,
            patience,
            output_scaling: model.output_scaling().clone(),
        }
    }

    /// Scores `params` after `iteration`, keeping them if they are the best so far;
    /// returns the validation MSE and `Break` when the patience has run out.
    fn record(&mut self, iteration: usize, params: &[f64]) -> (f64, ControlFlow<()>) {
        let mse = raw_mse_of(params, &self.output_scaling, &mut self.batch);
        if mse < self.best_mse {
            self.best_mse = mse;
            self.best_iteration = iteration;
            self.best_params.copy_from_slice(params);
        }
        let flow = if iteration - self.best_iteration >= self.patience.max(1) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        };
        (mse, flow)
    }
}

/// The L-BFGS objective on the whole training batch; each evaluation leaves its raw
/// training MSE in `train_mse` for the report.
struct TrainObjective<'a> {
    batch: &'a mut Batch,
    l2_penalty: f64,
    output_scaling: &'a Standardiser,
    train_mse: &'a Cell<f64>,
}

impl Objective for TrainObjective<'_> {
    fn value_and_gradient(&mut self, x: &[f64], gradient: &mut [f64]) -> f64 {
        let n = self.batch.n_samples();
        let value = self
            .batch
            .evaluate(x, 0..n, self.l2_penalty, Some(gradient));
        self.train_mse.set(raw_mse_from_sums(
            self.batch.sum_squared_residuals(),
            self.output_scaling,
            n,
        ));
        value
    }
}

fn run_lbfgs(
    model: &mut Mlp,
    train_batch: &mut Batch,
    mut validation: Option<&mut Validation>,
    memory: usize,
    options: &TrainOptions,
    report: &mut TrainingReport,
) {
    let output_scaling = model.output_scaling().clone();
    let train_mse = Cell::new(f64::NAN);
    let mut objective = TrainObjective {
        batch: train_batch,
        l2_penalty: options.l2_penalty,
        output_scaling: &output_scaling,
        train_mse: &train_mse,
    };
    let lbfgs_options = LbfgsOptions {
        memory,
        max_iterations: options.max_iterations,
        max_evaluations: usize::MAX,
        gradient_tolerance: options.gradient_tolerance,
        relative_decrease_tolerance: options.relative_decrease_tolerance,
    };
    let mut early_stop = false;
    let mut train_history = Vec::new();
    let mut validation_history = Vec::new();
    let outcome = lbfgs::minimise(
        &mut objective,
        model.params_mut(),
        &lbfgs_options,
        |iteration, x, _| {
            train_history.push(train_mse.get());
            let Some(validation) = validation.as_deref_mut() else {
                return ControlFlow::Continue(());
            };
            let (mse, flow) = validation.record(iteration, x);
            validation_history.push(mse);
            early_stop = flow.is_break();
            flow
        },
    );
    report.train_mse_history.extend(train_history);
    report.validation_mse_history.extend(validation_history);
    report.iterations = outcome.iterations;
    report.evaluations = outcome.evaluations;
    if validation.is_none() {
        report.best_iteration = outcome.iterations;
    }
    report.stop = match outcome.stop {
        LbfgsStop::Interrupted if early_stop => StopReason::EarlyStopping,
        LbfgsStop::Interrupted | LbfgsStop::MaxIterations => StopReason::MaxIterations,
        LbfgsStop::MaxEvaluations => StopReason::MaxEvaluations,
        LbfgsStop::GradientTolerance => StopReason::GradientTolerance,
        LbfgsStop::RelativeDecrease => StopReason::RelativeDecrease,
        LbfgsStop::LineSearchFailed | LbfgsStop::NonFiniteStart => StopReason::LineSearchFailed,
    };
}

#[derive(Debug, Clone, Copy)]
struct GradientDescent {
    learning_rate: f64,
    momentum: f64,
    batch_size: usize,
}

fn run_gradient_descent(
    model: &mut Mlp,
    train_batch: &mut Batch,
    mut validation: Option<&mut Validation>,
    settings: GradientDescent,
    options: &TrainOptions,
    rng: &mut SplitMix64,
    report: &mut TrainingReport,
) {
    let n_train = train_batch.n_samples();
    let output_scaling = model.output_scaling().clone();
    let n_params = model.params().len();
    let mut velocity = vec![0.0; n_params];
    let mut gradient = vec![0.0; n_params];
    let mut order: Vec<usize> = (0..n_train).collect();
    let mut scratch = Vec::new();
    let mut last_good = model.params().to_vec();
    report.stop = StopReason::MaxIterations;
    for epoch in 1..=options.max_iterations {
        if settings.batch_size < n_train {
            // The batch holds the previous epoch's order: shuffle that order again.
            for (idx, value) in order.iter_mut().enumerate() {
                *value = idx;
            }
            shuffle(&mut order, rng);
            train_batch.permute(&order, &mut scratch);
        }
        let mut sum_squared = 0.0;
        let mut batch_start = 0;
        while batch_start < n_train {
            let batch_end = (batch_start + settings.batch_size).min(n_train);
            train_batch.evaluate(
                model.params(),
                batch_start..batch_end,
                options.l2_penalty,
                Some(&mut gradient),
            );
            report.evaluations += 1;
            sum_squared +=
                raw_mse_from_sums(train_batch.sum_squared_residuals(), &output_scaling, 1);
            for ((param, velocity), gradient) in model
                .params_mut()
                .iter_mut()
                .zip(velocity.iter_mut())
                .zip(&gradient)
            {
                *velocity = settings.momentum * *velocity - settings.learning_rate * gradient;
                *param += *velocity;
            }
            batch_start = batch_end;
        }
        report.iterations = epoch;
        let epoch_mse = sum_squared / n_train as f64;
        report.train_mse_history.push(epoch_mse);
        if !epoch_mse.is_finite() || model.params().iter().any(|value| !value.is_finite()) {
            model.params_mut().copy_from_slice(&last_good);
            report.stop = StopReason::Diverged;
            break;
        }
        last_good.copy_from_slice(model.params());
        if let Some(validation) = validation.as_deref_mut() {
            let (mse, flow) = validation.record(epoch, model.params());
            report.validation_mse_history.push(mse);
            if flow.is_break() {
                report.stop = StopReason::EarlyStopping;
                break;
            }
        } else {
            report.best_iteration = epoch;
        }
    }
    if report.stop == StopReason::Diverged && validation.is_none() {
        report.best_iteration = report.iterations.saturating_sub(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` samples of `y = f(x)` for `x` uniform in `[low, high)^width`, with Gaussian
    /// noise of `noise` on `y`.
    fn samples(
        n: usize,
        width: usize,
        range: (f64, f64),
        noise: f64,
        seed: u64,
        f: impl Fn(&[f64]) -> Vec<f64>,
    ) -> Dataset {
        let mut rng = SplitMix64::new(seed);
        let mut inputs = Vec::new();
        let mut targets = Vec::new();
        for _ in 0..n {
            let x: Vec<f64> = (0..width)
                .map(|_| rng.uniform_in(range.0, range.1))
                .collect();
            targets.extend(f(&x).into_iter().map(|y| y + noise * rng.gaussian()));
            inputs.extend(x);
        }
        Dataset::new(&inputs, width, &targets, targets.len() / n).unwrap()
    }

    fn sine() -> Dataset {
        samples(300, 1, (-3.0, 3.0), 0.0, 1, |x| vec![x[0].sin()])
    }

    fn no_validation(options: TrainOptions) -> TrainOptions {
        TrainOptions {
            validation_fraction: 0.0,
            ..options
        }
    }

    #[test]
    fn lbfgs_learns_a_sine_with_either_activation() {
        for activation in [Activation::Logistic, Activation::Tanh] {
            let options = no_validation(TrainOptions {
                n_hidden: 10,
                activation,
                max_iterations: 500,
                l2_penalty: 0.0,
                gradient_tolerance: 1e-7,
                ..Default::default()
            });
            let (model, report) = train(&sine(), &options).unwrap();
            // sin has variance 0.5 on [−3, 3]: an MSE of 10⁻⁴ is 99.98 % explained.
            assert!(report.train_mse < 1e-4, "{activation:?}: {report:?}");
            let predicted = model.predict(&[1.0]).unwrap()[0];
            assert!((predicted - 1f64.sin()).abs() < 0.03, "{predicted}");
            assert_eq!(report.train_mse_history.len(), report.iterations + 1);
        }
    }

    #[test]
    fn lbfgs_learns_an_xor_like_product_and_two_outputs() {
        // y = x₀·x₁ is XOR on the corners (±1) and smooth in between.
        let data = samples(400, 2, (-1.0, 1.0), 0.0, 2, |x| {
            vec![x[0] * x[1], (x[0] - x[1]).cos()]
        });
        let options = no_validation(TrainOptions {
            n_hidden: 12,
            activation: Activation::Tanh,
            max_iterations: 1000,
            l2_penalty: 0.0,
            gradient_tolerance: 1e-8,
            ..Default::default()
        });
        let (model, report) = train(&data, &options).unwrap();
        assert!(report.train_mse < 1e-4, "{report:?}");
        for (corner, xor) in [
            ([1.0, 1.0], 1.0),
            ([-1.0, 1.0], -1.0),
            ([1.0, -1.0], -1.0),
            ([-1.0, -1.0], 1.0),
        ] {
            let predicted = model.predict(&corner).unwrap();
            assert!(
                (predicted[0] - xor).abs() < 0.1,
                "{corner:?}: {predicted:?}"
            );
        }
    }

    #[test]
    fn back_propagation_with_momentum_learns_a_sine() {
        let options = no_validation(TrainOptions {
            n_hidden: 10,
            activation: Activation::Tanh,
            optimiser: Optimiser::GradientDescent {
                learning_rate: 0.02,
                momentum: 0.9,
                batch_size: Some(16),
            },
            max_iterations: 400,
            l2_penalty: 0.0,
            ..Default::default()
        });
        let (_, report) = train(&sine(), &options).unwrap();
        assert_eq!(report.stop, StopReason::MaxIterations);
        assert!(report.train_mse < 2e-3, "{}", report.train_mse);
        // Full batch, the paper's setting (one weight update per epoch).
        let options = TrainOptions {
            optimiser: Optimiser::GradientDescent {
                learning_rate: 0.5,
                momentum: 0.9,
                batch_size: None,
            },
            max_iterations: 3000,
            ..options
        };
        let (_, report) = train(&sine(), &options).unwrap();
        assert!(report.train_mse < 5e-3, "{}", report.train_mse);
        assert_eq!(report.evaluations, 3000);
    }

    #[test]
    fn the_same_seed_gives_bit_identical_weights() {
        let data = samples(200, 3, (-2.0, 2.0), 0.1, 3, |x| {
            vec![x[0] * x[1] + x[2].sin()]
        });
        for optimiser in [
            Optimiser::Lbfgs { memory: 10 },
            Optimiser::GradientDescent {
                learning_rate: 0.01,
                momentum: 0.9,
                batch_size: Some(32),
            },
        ] {
            let options = TrainOptions {
                optimiser,
                max_iterations: 50,
                seed: 11,
                ..Default::default()
            };
            let (first, first_report) = train(&data, &options).unwrap();
            let (second, second_report) = train(&data, &options).unwrap();
            assert_eq!(first.params(), second.params());
            assert_eq!(first_report, second_report);
            let (other, _) = train(
                &data,
                &TrainOptions {
                    seed: 12,
                    ..options
                },
            )
            .unwrap();
            assert_ne!(first.params(), other.params());
        }
    }

    #[test]
    fn early_stopping_stops_and_keeps_the_best_weights() {
        // Few noisy samples and many neurons without a penalty: the network overfits.
        let data = samples(60, 2, (-1.0, 1.0), 0.3, 4, |x| vec![x[0] + x[1]]);
        let options = TrainOptions {
            n_hidden: 16,
            l2_penalty: 0.0,
            max_iterations: 5000,
            gradient_tolerance: 0.0,
            relative_decrease_tolerance: 0.0,
            validation_fraction: 0.25,
            patience: 10,
            ..Default::default()
        };
        let (model, report) = train(&data, &options).unwrap();
        assert_eq!(report.stop, StopReason::EarlyStopping, "{report:?}");
        assert_eq!(report.iterations, report.best_iteration + 10);
        assert_eq!((report.n_train, report.n_validation), (45, 15));
        let best = report
            .validation_mse_history
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        assert_eq!(report.validation_mse, Some(best));
        assert_eq!(report.validation_mse_history[report.best_iteration], best);
        assert_eq!(report.validation_mse_history.len(), report.iterations + 1);
        assert!(model.params().iter().all(|value| value.is_finite()));
    }

    #[test]
    fn a_constant_input_gives_no_nan() {
        let data = samples(100, 2, (0.0, 1.0), 0.0, 5, |x| vec![2.0 * x[0]]);
        let inputs: Vec<f64> = data
            .inputs()
            .chunks_exact(2)
            .flat_map(|row| [row[0], 42.0])
            .collect();
        let data = Dataset::new(&inputs, 2, data.targets(), 1).unwrap();
        let (model, report) = train(&data, &TrainOptions::default()).unwrap();
        assert!(
            report.train_mse.is_finite() && report.train_mse < 1e-3,
            "{report:?}"
        );
        assert!(model.predict(&[0.5, 42.0]).unwrap()[0].is_finite());
        assert!(model.predict(&[0.5, -1e300]).unwrap()[0].is_finite());
    }

    #[test]
    fn bad_data_and_options_are_errors_not_panics() {
        let data = sine();
        let error = |options: TrainOptions| train(&data, &options).unwrap_err();
        assert_eq!(
            error(TrainOptions {
                n_hidden: 0,
                ..Default::default()
            }),
            NnError::HiddenSizeZero
        );
        assert!(matches!(
            error(TrainOptions {
                validation_fraction: 1.0,
                ..Default::default()
            }),
            NnError::InvalidOption {
                name: "validation_fraction",
                ..
            }
        ));
        assert!(matches!(
            error(TrainOptions {
                l2_penalty: f64::NAN,
                ..Default::default()
            }),
            NnError::InvalidOption {
                name: "l2_penalty",
                ..
            }
        ));
        assert!(matches!(
            error(TrainOptions {
                optimiser: Optimiser::GradientDescent {
                    learning_rate: 0.0,
                    momentum: 0.9,
                    batch_size: None
                },
                ..Default::default()
            }),
            NnError::InvalidOption {
                name: "learning_rate",
                ..
            }
        ));
        let two = Dataset::new(&[1.0, 2.0], 1, &[1.0, 2.0], 1).unwrap();
        assert_eq!(
            train(&two, &TrainOptions::default()).unwrap_err(),
            NnError::TooFewSamples {
                n_samples: 2,
                min: 3
            }
        );
        assert!(train(&two, &no_validation(TrainOptions::default())).is_ok());
        let (model, _) = train(&data, &TrainOptions::default()).unwrap();
        assert!(matches!(
            model.predict(&[1.0, 2.0]),
            Err(NnError::WrongWidth {
                expected: 1,
                found: 2,
                ..
            })
        ));
        assert!(matches!(
            model.predict(&[f64::NAN]),
            Err(NnError::NonFinite { column: 0, .. })
        ));
        assert!(matches!(
            model.predict_rows(&[1.0, f64::INFINITY]),
            Err(NnError::NonFinite {
                row: 1,
                column: 0,
                ..
            })
        ));
    }

    // serde_json and proptest are native dev-dependencies.
    #[cfg(not(target_arch = "wasm32"))]
    #[test]
    fn a_saved_model_reloads_with_the_same_predictions() {
        let data = samples(200, 2, (-1.0, 1.0), 0.05, 6, |x| {
            vec![x[0].sin() + x[1], x[1] * x[1]]
        });
        let (model, _) = train(
            &data,
            &TrainOptions {
                max_iterations: 30,
                ..Default::default()
            },
        )
        .unwrap();
        let json = serde_json::to_string(&model).unwrap();
        let reloaded: Mlp = serde_json::from_str(&json).unwrap();
        // serde_json's default parser may round the last bit of a number.
        for (a, b) in reloaded.params().iter().zip(model.params()) {
            assert!((a - b).abs() <= 1e-15 * b.abs(), "{a} {b}");
        }
        let before = model.predict_rows(data.inputs()).unwrap();
        let after = reloaded.predict_rows(data.inputs()).unwrap();
        for (a, b) in after.iter().zip(&before) {
            assert!((a - b).abs() < 1e-12, "{a} {b}");
        }
        // A damaged file is refused, not trusted.
        let mut value: serde_json::Value = serde_json::from_str(&json).unwrap();
        value["params"].as_array_mut().unwrap().pop();
        let error = serde_json::from_value::<Mlp>(value)
            .unwrap_err()
            .to_string();
        assert!(error.contains("inconsistent"), "{error}");
    }

    #[test]
    fn predicting_many_rows_gives_each_row_its_own_bits() {
        // Three inputs, two outputs, tanh and logistic, and a block and a bit of rows.
        for (activation, n_rows) in [(Activation::Logistic, 600), (Activation::Tanh, 257)] {
            let data = samples(n_rows, 3, (-2.0, 2.0), 0.1, 9, |x| {
                vec![x[0] * x[1] - x[2], (x[0] + x[2]).sin()]
            });
            let (model, _) = train(
                &data,
                &no_validation(TrainOptions {
                    activation,
                    max_iterations: 15,
                    ..Default::default()
                }),
            )
            .unwrap();
            let many = model.predict_rows(data.inputs()).unwrap();
            for (row, outputs) in data.inputs().chunks_exact(3).zip(many.chunks_exact(2)) {
                let one = model.predict(row).unwrap();
                assert_eq!(
                    one.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    outputs.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    "{row:?}"
                );
            }
        }
    }

    #[test]
    fn mean_squared_error_agrees_with_predictions() {
        let data = samples(150, 2, (-1.0, 1.0), 0.1, 8, |x| vec![x[0] - x[1]]);
        let (model, report) = train(
            &data,
            &no_validation(TrainOptions {
                max_iterations: 20,
                ..Default::default()
            }),
        )
        .unwrap();
        let predicted = model.predict_rows(data.inputs()).unwrap();
        let mse = predicted
            .iter()
            .zip(data.targets())
            .map(|(p, t)| (p - t) * (p - t))
            .sum::<f64>()
            / 150.0;
        // The batch forms the residuals in the kernels' f32, the predictions end in f64.
        assert!((model.mean_squared_error(&data).unwrap() - mse).abs() < 1e-6 * (1.0 + mse));
        assert!((report.train_mse - mse).abs() < 1e-6 * (1.0 + mse));
    }

    #[cfg(not(target_arch = "wasm32"))]
    mod properties {
        use super::*;
        use proptest::prelude::*;
        use std::sync::OnceLock;

        fn model() -> &'static Mlp {
            static MODEL: OnceLock<Mlp> = OnceLock::new();
            MODEL.get_or_init(|| {
                let data = samples(100, 3, (-5.0, 5.0), 0.1, 9, |x| {
                    vec![x[0] * x[1] - x[2], x[2].cos()]
                });
                train(
                    &data,
                    &TrainOptions {
                        max_iterations: 40,
                        ..Default::default()
                    },
                )
                .unwrap()
                .0
            })
        }

        proptest! {
            #[test]
            fn predict_is_finite_for_any_finite_input(
                inputs in proptest::collection::vec(proptest::num::f64::NORMAL | proptest::num::f64::SUBNORMAL | proptest::num::f64::ZERO, 3)
            ) {
                let outputs = model().predict(&inputs).unwrap();
                prop_assert!(outputs.iter().all(|value| value.is_finite()), "{:?} -> {:?}", inputs, outputs);
            }

            #[test]
            fn predict_never_panics(inputs in proptest::collection::vec(proptest::num::f64::ANY, 0..6)) {
                let _ = model().predict(&inputs);
                let _ = model().predict_rows(&inputs);
            }
        }
    }
}
