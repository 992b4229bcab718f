//! Step-length models, fitted to reference step lengths.
//!
//! Chen et al., *A unified heading error model and step length estimation for PDR*,
//! Section III:
//!
//! - linear (Eq. 2): `SL = A + B·SF + C·SV`, by least squares;
//! - nonlinear, Weinberg's (Eq. 3): `SL = K·(Amax − Amin)^¼`, one parameter;
//! - a neural network with 16 `tansig` (tanh) hidden neurons fed by SF, SV, Amax and
//!   Amin (the network code is [`crate::deviation::network`], shared with the heading
//!   correction).
//!
//! References are per step (GNSS speed over the step) or a distance for a run of steps
//! (GNSS fixes or reference positions at its ends on a straight stretch, a loop of known
//! length). Weinberg's and the linear model fit segment totals by least squares (one
//! segment fits K exactly: `K = D / Σ(Amax − Amin)^¼`); the network needs per-step
//! references.

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;
use thiserror::Error;

use super::steps::Step;
use crate::deviation::network::{self, Activation, Dataset, Mlp, TrainOptions};

/// Weinberg's K when nothing trains it (m per (m/s²)^¼): a typical adult walking with a
/// phone in hand. The paper trains K on GPS; use a known distance or GNSS to do better.
pub const DEFAULT_WEINBERG_K: f64 = 0.47;

/// Step lengths outside this range (m) are not believable as walking references.
const PLAUSIBLE_STEP_M: std::ops::RangeInclusive<f64> = 0.15..=1.6;

/// Which model to fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StepModelKind {
    Linear,
    Weinberg,
    Neural,
}

impl StepModelKind {
    pub fn parse(text: &str) -> Option<StepModelKind> {
        match text.trim().to_ascii_lowercase().as_str() {
            "linear" => Some(StepModelKind::Linear),
            "weinberg" | "nonlinear" => Some(StepModelKind::Weinberg),
            "mlp" | "neural" | "ann" => Some(StepModelKind::Neural),
            _ => None,
        }
    }

    pub fn key(self) -> &'static str {
        match self {
            StepModelKind::Linear => "linear",
            StepModelKind::Weinberg => "weinberg",
            StepModelKind::Neural => "mlp",
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            StepModelKind::Linear => "linear (SL = A + B·SF + C·SV)",
            StepModelKind::Weinberg => "Weinberg (SL = K·(Amax − Amin)^¼)",
            StepModelKind::Neural => "neural network (16 tanh neurons)",
        }
    }
}

/// A fitted step-length model.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StepLengthModel {
    Linear {
        a_m: f64,
        b_m_per_hz: f64,
        c_m_per_var: f64,
    },
    Weinberg {
        k: f64,
    },
    Neural {
        network: Box<Mlp>,
    },
}

impl StepLengthModel {
    pub fn kind(&self) -> StepModelKind {
        match self {
            StepLengthModel::Linear { .. } => StepModelKind::Linear,
            StepLengthModel::Weinberg { .. } => StepModelKind::Weinberg,
            StepLengthModel::Neural { .. } => StepModelKind::Neural,
        }
    }

    /// The model's step length (m), kept within the plausible range of a walking step.
    pub fn length_m(&self, step: &Step) -> f64 {
        let raw = match self {
            StepLengthModel::Linear {
                a_m,
                b_m_per_hz,
                c_m_per_var,
            } => a_m + b_m_per_hz * step.frequency_hz + c_m_per_var * step.variance_mps2_sq,
            StepLengthModel::Weinberg { k } => k * weinberg_feature(step),
            StepLengthModel::Neural { network } => network
                .predict(&neural_inputs(step))
                .ok()
                .and_then(|out| out.first().copied())
                .unwrap_or(f64::NAN),
        };
        if raw.is_finite() {
            raw.clamp(*PLAUSIBLE_STEP_M.start(), *PLAUSIBLE_STEP_M.end())
        } else {
            DEFAULT_WEINBERG_K * weinberg_feature(step)
        }
    }
}

/// A reference length for one step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StepReference {
    pub step_idx: usize,
    pub length_m: f64,
}

/// Why a model could not be fitted, and what to do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StepModelError {
    #[error("the {model} step model needs at least {needed} steps with a reference length, and {found} have one; walk longer with good GNSS (speed reported) or give reference positions")]
    TooFewReferences {
        model: &'static str,
        needed: usize,
        found: usize,
    },
    #[error("the linear step model cannot be fitted: the step frequency and variance hardly vary over the reference steps; use the Weinberg model")]
    Degenerate,
    #[error("the {model} step model needs per-step references (GNSS speed or reference positions); a known total distance fits only the Weinberg model")]
    NeedsPerStepReferences { model: &'static str },
    #[error("the step-length network could not be trained: {0}")]
    Training(#[from] network::NnError),
}

/// (Amax − Amin)^¼, the feature of Weinberg's model.
pub fn weinberg_feature(step: &Step) -> f64 {
    (step.a_max_mps2 - step.a_min_mps2).max(0.0).powf(0.25)
}

fn neural_inputs(step: &Step) -> [f64; 4] {
    [
        step.frequency_hz,
        step.variance_mps2_sq,
        step.a_max_mps2,
        step.a_min_mps2,
    ]
}

/// A distance walked by a run of consecutive steps: one step (GNSS speed over it), the
/// steps between two GNSS fixes on a straight stretch or between two reference
/// positions, or a whole walk of known length.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SegmentReference {
    pub steps: std::ops::Range<usize>,
    pub distance_m: f64,
}

/// Fits `kind` to per-step references. `seed` fixes the network's initial weights.
pub fn fit(
    kind: StepModelKind,
    steps: &[Step],
    references: &[StepReference],
    seed: u64,
) -> Result<StepLengthModel, StepModelError> {
    let segments: Vec<SegmentReference> = references
        .iter()
        .map(|reference| SegmentReference {
            steps: reference.step_idx..reference.step_idx + 1,
            distance_m: reference.length_m,
        })
        .collect();
    fit_segments(kind, steps, &segments, seed)
}

/// Fits `kind` to segment references by least squares on the segments' totals: Weinberg's
/// K minimises Σ (D − K·Σx)², the linear model Σ (D − n·A − B·ΣSF − C·ΣSV)². The network
/// needs one step per segment. Segments whose mean step is not a believable walking
/// step, or that reach past the steps, are left out.
pub fn fit_segments(
    kind: StepModelKind,
    steps: &[Step],
    segments: &[SegmentReference],
    seed: u64,
) -> Result<StepLengthModel, StepModelError> {
    let usable: Vec<(&[Step], f64)> = segments
        .iter()
        .filter_map(|segment| {
            let run = steps.get(segment.steps.clone())?;
            let finite = run.iter().all(|step| {
                step.frequency_hz.is_finite()
                    && step.variance_mps2_sq.is_finite()
                    && step.a_max_mps2.is_finite()
                    && step.a_min_mps2.is_finite()
            });
            let mean_m = segment.distance_m / run.len().max(1) as f64;
            (!run.is_empty() && finite && PLAUSIBLE_STEP_M.contains(&mean_m))
                .then_some((run, segment.distance_m))
        })
        .collect();
    let n_steps: usize = usable.iter().map(|(run, _)| run.len()).sum();
    match kind {
        StepModelKind::Weinberg => {
            let (sum_xy, sum_xx) = usable.iter().fold((0.0, 0.0), |(xy, xx), (run, distance)| {
                let x: f64 = run.iter().map(weinberg_feature).sum();
                (xy + x * distance, xx + x * x)
            });
            if n_steps < 5 || sum_xx <= 0.0 {
                return Err(StepModelError::TooFewReferences {
                    model: "Weinberg",
                    needed: 5,
                    found: n_steps,
                });
            }
            Ok(StepLengthModel::Weinberg { k: sum_xy / sum_xx })
        }
        StepModelKind::Linear => {
            if usable.len() < 20 {
                return Err(StepModelError::TooFewReferences {
                    model: "linear",
                    needed: 20,
                    found: usable.len(),
                });
            }
            let mut normal = Matrix3::<f64>::zeros();
            let mut rhs = Vector3::<f64>::zeros();
            for (run, distance) in &usable {
                let row = run.iter().fold(Vector3::zeros(), |sum, step| {
                    sum + Vector3::new(1.0, step.frequency_hz, step.variance_mps2_sq)
                });
                normal += row * row.transpose();
                rhs += row * *distance;
            }
            // Scale the columns so the conditioning test means something.
            let scale = Vector3::from_iterator((0..3).map(|i| normal[(i, i)].sqrt().max(1e-12)));
            let scaled = Matrix3::from_fn(|i, j| normal[(i, j)] / (scale[i] * scale[j]));
            let eigen = scaled.symmetric_eigenvalues();
            let (min_eig, max_eig) = (eigen.min(), eigen.max());
            if min_eig.is_nan() || min_eig <= 1e-10 * max_eig {
                return Err(StepModelError::Degenerate);
            }
            let solution = scaled
                .cholesky()
                .map(|chol| chol.solve(&rhs.component_div(&scale)))
                .ok_or(StepModelError::Degenerate)?
                .component_div(&scale);
            Ok(StepLengthModel::Linear {
                a_m: solution[0],
                b_m_per_hz: solution[1],
                c_m_per_var: solution[2],
            })
        }
        StepModelKind::Neural => {
            if usable.iter().any(|(run, _)| run.len() != 1) {
                return Err(StepModelError::NeedsPerStepReferences {
                    model: "neural-network",
                });
            }
            if usable.len() < 40 {
                return Err(StepModelError::TooFewReferences {
                    model: "neural-network",
                    needed: 40,
                    found: usable.len(),
                });
            }
            let inputs: Vec<f64> = usable
                .iter()
                .flat_map(|(run, _)| run.iter().flat_map(neural_inputs))
                .collect();
            let targets: Vec<f64> = usable.iter().map(|(_, length)| *length).collect();
            let data = Dataset::new(&inputs, 4, &targets, 1)?;
            let options = TrainOptions {
                n_hidden: 16,
                activation: Activation::Tanh,
                // A step length is noisy: a stronger penalty keeps 97 weights from
                // learning the GNSS noise of a few hundred steps.
                l2_penalty: 1e-2,
                seed,
                ..TrainOptions::default()
            };
            let (model, _report): (Mlp, network::TrainingReport) = network::train(&data, &options)?;
            Ok(StepLengthModel::Neural {
                network: Box::new(model),
            })
        }
    }
}

/// Fits Weinberg's K to a known total distance walked over `steps`.
pub fn fit_weinberg_to_distance(
    steps: &[Step],
    distance_m: f64,
) -> Result<StepLengthModel, StepModelError> {
    fit_segments(
        StepModelKind::Weinberg,
        steps,
        &[SegmentReference {
            steps: 0..steps.len(),
            distance_m,
        }],
        0,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::SplitMix64;
    use crate::io::STANDARD_GRAVITY_MPS2;

    fn step_with(frequency_hz: f64, variance: f64, peak_to_peak: f64) -> Step {
        Step {
            t_start_s: 0.0,
            t_end_s: 1.0 / frequency_hz,
            t_peak_s: 0.1,
            frequency_hz,
            variance_mps2_sq: variance,
            a_max_mps2: STANDARD_GRAVITY_MPS2 + peak_to_peak / 2.0,
            a_min_mps2: STANDARD_GRAVITY_MPS2 - peak_to_peak / 2.0,
            ends_bout: false,
        }
    }

    /// Steps whose true length follows SL = 0.3 + 0.22·SF and whose bounce follows
    /// Weinberg with K = 0.45, with 2 cm of reference noise.
    fn training_set(n: usize, seed: u64) -> (Vec<Step>, Vec<StepReference>, Vec<f64>) {
        let mut rng = SplitMix64::new(seed);
        let mut steps = Vec::new();
        let mut references = Vec::new();
        let mut truth = Vec::new();
        for idx in 0..n {
            let frequency_hz = rng.uniform_in(1.5, 2.2);
            let length_m = 0.3 + 0.22 * frequency_hz;
            let peak_to_peak = (length_m / 0.45).powi(4);
            let variance = peak_to_peak * peak_to_peak / 8.0;
            steps.push(step_with(frequency_hz, variance, peak_to_peak));
            references.push(StepReference {
                step_idx: idx,
                length_m: length_m + 0.02 * rng.gaussian(),
            });
            truth.push(length_m);
        }
        (steps, references, truth)
    }

    #[test]
    fn each_model_recovers_the_lengths_it_was_trained_on() {
        let (steps, references, truth) = training_set(300, 1);
        for (kind, tolerance_m) in [
            (StepModelKind::Weinberg, 0.005),
            (StepModelKind::Linear, 0.01),
            (StepModelKind::Neural, 0.01),
        ] {
            let model = fit(kind, &steps, &references, 1).expect("fits");
            let rms = (steps
                .iter()
                .zip(&truth)
                .map(|(step, length)| (model.length_m(step) - length).powi(2))
                .sum::<f64>()
                / truth.len() as f64)
                .sqrt();
            assert!(rms < tolerance_m, "{kind:?}: {rms} m");
        }
        let Ok(StepLengthModel::Weinberg { k }) =
            fit(StepModelKind::Weinberg, &steps, &references, 1)
        else {
            panic!("weinberg");
        };
        assert!((k - 0.45).abs() < 0.003, "{k}");
    }

    #[test]
    fn a_known_distance_fits_k() {
        let (steps, _, truth) = training_set(100, 2);
        let total: f64 = truth.iter().sum();
        let Ok(StepLengthModel::Weinberg { k }) = fit_weinberg_to_distance(&steps, total) else {
            panic!("fits");
        };
        assert!((k - 0.45).abs() < 1e-9, "{k}");
    }

    #[test]
    fn too_few_or_degenerate_references_are_errors_that_say_what_to_do() {
        let (steps, references, _) = training_set(10, 3);
        let error = fit(StepModelKind::Linear, &steps, &references, 1).unwrap_err();
        assert!(error.to_string().contains("at least 20 steps"), "{error}");
        let same: Vec<Step> = (0..30).map(|_| step_with(1.8, 1.0, 2.0)).collect();
        let refs: Vec<StepReference> = (0..30)
            .map(|step_idx| StepReference {
                step_idx,
                length_m: 0.7,
            })
            .collect();
        assert_eq!(
            fit(StepModelKind::Linear, &same, &refs, 1),
            Err(StepModelError::Degenerate)
        );
        // Implausible references and out-of-range indices are ignored, not trusted.
        let wild = [
            StepReference {
                step_idx: 0,
                length_m: 30.0,
            },
            StepReference {
                step_idx: 999,
                length_m: 0.7,
            },
        ];
        assert!(fit(StepModelKind::Weinberg, &same, &wild, 1).is_err());
    }
}
