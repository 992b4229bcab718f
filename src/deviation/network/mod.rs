//! A small neural network: a multilayer perceptron with one hidden layer, for the
//! heading-deviation correction and the step-length model.
//!
//! Noureldin, Osman and El-Sheimy (2007), *Autocalibration and dynamic calibration of a
//! 3-axis magnetometer with an ANN*, Sections 3 and 5: five inputs (raw heading, |H|, gyro
//! heading, dip, temperature), 10-15 logistic neurons in one hidden layer, a linear output
//! (the compass deviation), inputs normalised with the mean removed, trained by
//! back-propagation. Chen et al. (*A unified heading error model and step length
//! estimation for PDR*), Section III: 16 `tansig` (tanh) neurons for the step length.
//!
//! ## Layout
//!
//! - `dataset.rs`: [`Dataset`], the checked training samples (row-major, finite).
//! - `normalise.rs`: [`Standardiser`], mean removed and scaled by the standard deviation.
//! - `activation.rs`: the logistic and tanh functions in single precision (an `exp` of
//!   plain arithmetic, so native and wasm builds give the same bits).
//! - `mlp.rs`: [`Mlp`], the trained model (weights and normalisation, serde), `predict`.
//! - `loss.rs`: the mean-squared error with its L2 penalty and its analytic gradient over
//!   a whole batch (column-major, in parts of fixed size added in a fixed order).
//! - `kernels.rs`: one part's forward pass and gradient, eight samples at a time in `f32`
//!   (portable lanes, WebAssembly's SIMD, or AVX2 when the processor has it, with the
//!   same bits).
//! - `workers.rs`: helper threads that evaluate a large batch's parts (native builds).
//! - `lbfgs.rs`: L-BFGS with a strong-Wolfe line search, for any smooth objective.
//! - `train.rs`: [`train`]: splitting, initialisation, the two optimisers (L-BFGS and
//!   back-propagation with momentum), early stopping and the [`TrainingReport`].
//! - `correlation.rs`: the Pearson correlation matrix of the inputs (the paper's Table 1).
//!
//! Everything here is pure: samples and options in, a model and a report out. Random
//! numbers (initial weights, shuffling) come from [`crate::base::rng::SplitMix64`] seeded by
//! the caller, so a seed gives bit-identical weights on every platform.

mod activation;
mod correlation;
mod dataset;
mod error;
mod kernels;
mod lbfgs;
mod loss;
mod mlp;
mod normalise;
mod train;
#[cfg(not(target_arch = "wasm32"))]
mod workers;

pub use activation::Activation;
pub use correlation::{correlation_matrix, CorrelationMatrix};
pub use dataset::{DataPart, Dataset};
pub use error::NnError;
pub use lbfgs::{minimise, LbfgsOptions, LbfgsOutcome, LbfgsStop, Objective};
pub use mlp::Mlp;
pub use normalise::Standardiser;
pub use train::{train, Optimiser, StopReason, TrainOptions, TrainingReport};
