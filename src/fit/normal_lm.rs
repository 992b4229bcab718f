//! Levenberg-Marquardt on the normal equations, for fits of a few parameters to many
//! samples ([`crate::fit::ellipse`] and [`crate::fit::ellipse_isotropic`]).
//!
//! ## Why not the `levenberg-marquardt` crate here
//!
//! The crate is MINPACK's `lmder`: every evaluation builds the `2N × p` Jacobian and
//! factors it by a pivoted QR, `2·(2N)·p²` operations (for 10⁴ samples and ten
//! parameters, four million, a few milliseconds), and its default tolerances (30
//! machine epsilons) ask for dozens of evaluations on real data and hundreds (its
//! patience, `100·(p + 1)`) on data that never settle: 4 s for one fit on a real
//! walk. Here each evaluation is one pass over the samples that accumulates the
//! `p × p` matrix `JᵀJ`, the gradient `Jᵀr` and the cost `rᵀr` (`p(p + 1)/2 + p + 1`
//! multiply-adds per residual), and the step solves the damped normal equations of
//! Marquardt (1963, *An algorithm for least-squares estimation of nonlinear
//! parameters*, SIAM J. Appl. Math. 11(2)):
//!
//! ```text
//! (JᵀJ + λ·diag(JᵀJ))·δ = −Jᵀr
//! ```
//!
//! by Cholesky, with Nielsen's (1999) update of `λ` from the ratio of the actual to the
//! predicted decrease (Madsen, Nielsen and Tingleff 2004, *Methods for non-linear least
//! squares problems*, IMM, Eq. 3.14, 3.16).
//!
//! ## Limits
//!
//! Forming `JᵀJ` squares the Jacobian's condition number: the minimum is found to
//! about `cond(J)²·ε` relative, against MINPACK's `cond(J)·ε`. For these fits (well
//! scaled µT, condition numbers of 10²-10⁴ after the diagonal scaling) that is far
//! below the parameters' noise. The fit stops when an accepted step lowers the cost
//! by less than [`COST_TOLERANCE`] of it (and predicted no more), when the step is
//! below [`STEP_TOLERANCE`] of the parameters, or when no step lowers the cost any more
//! at the arithmetic's precision (`λ` beyond [`MAX_LAMBDA`]); the caller bounds the
//! number of steps and keeps the best parameters found when it runs out.

use nalgebra::{SMatrix, SVector};

/// An accepted step that lowers the cost by less than this share of it (and was
/// predicted to lower it by no more) ends the fit: the parameters then move by about
/// `√(COST_TOLERANCE)` of their standard deviations.
const COST_TOLERANCE: f64 = 1e-12;

/// A step shorter than this share of the free parameters' norm ends the fit.
const STEP_TOLERANCE: f64 = 1e-12;

/// The damping beyond which no step can lower the cost at double precision.
const MAX_LAMBDA: f64 = 1e16;

/// The normal equations of `N` parameters at one point: `JᵀJ`, `Jᵀr` and `rᵀr`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Normal<const N: usize> {
    pub jtj: SMatrix<f64, N, N>,
    pub jtr: SVector<f64, N>,
    pub cost: f64,
}

impl<const N: usize> Normal<N> {
    pub fn zeros() -> Self {
        Normal {
            jtj: SMatrix::zeros(),
            jtr: SVector::zeros(),
            cost: 0.0,
        }
    }

    /// Adds two residuals (one sample's) and their gradients, in one sweep over the
    /// upper triangle of `jtj` (the lower one is filled in by [`Normal::finished`]).
    #[inline]
    pub fn add_pair(&mut self, rows: &[(f64, [f64; N]); 2]) {
        let [(residual_a, gradient_a), (residual_b, gradient_b)] = rows;
        for (row, (&a_row, &b_row)) in gradient_a.iter().zip(gradient_b).enumerate() {
            for (col, (&a_col, &b_col)) in gradient_a.iter().zip(gradient_b).enumerate().skip(row) {
                self.jtj[(row, col)] += a_row * a_col + b_row * b_col;
            }
            self.jtr[row] += a_row * residual_a + b_row * residual_b;
        }
        self.cost += residual_a * residual_a + residual_b * residual_b;
    }

    /// Mirrors the upper triangle into the lower one; `None` when anything is not finite.
    pub fn finished(mut self) -> Option<Self> {
        for row in 0..N {
            for col in 0..row {
                self.jtj[(row, col)] = self.jtj[(col, row)];
            }
        }
        let finite = self.cost.is_finite()
            && self.jtr.iter().all(|value| value.is_finite())
            && self.jtj.iter().all(|value| value.is_finite());
        finite.then_some(self)
    }
}

/// How a fit ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Termination {
    /// The cost or the step fell below the tolerances, or no step lowers the cost at
    /// the arithmetic's precision.
    Converged,
    /// `max_steps` steps were tried; the parameters are the best found.
    OutOfSteps,
}

/// The damping of the first step, relative to the diagonal of `JᵀJ`.
const START_LAMBDA: f64 = 1e-3;

/// Minimises `rᵀr` over the parameters listed in `free` (the others keep their values
/// in `params`), from `params`, which end at the best point found, with the damping
/// `lambda` at the start and at the end. `normal_at` gives the normal equations at a
/// point, or `None` where the residuals are not finite. `Err` when they are not finite
/// at the start.
fn minimize<const N: usize>(
    params: &mut [f64; N],
    free: &[usize],
    max_steps: usize,
    lambda: &mut f64,
    mut normal_at: impl FnMut(&[f64; N]) -> Option<Normal<N>>,
) -> Result<Termination, &'static str> {
    let is_free: [bool; N] = std::array::from_fn(|idx| free.contains(&idx));
    let mut normal = normal_at(params).ok_or("the residuals are not finite at the start")?;
    let mut lambda_growth = 2.0;
    for _ in 0..max_steps {
        // The damped system on the free parameters; the fixed ones get the identity
        // and no gradient, hence a zero step.
        let mut damped = normal.jtj;
        let mut gradient = normal.jtr;
        for idx in 0..N {
            if is_free[idx] {
                damped[(idx, idx)] += *lambda * normal.jtj[(idx, idx)].max(1e-12);
            } else {
                damped.row_mut(idx).fill(0.0);
                damped.column_mut(idx).fill(0.0);
                damped[(idx, idx)] = 1.0;
                gradient[idx] = 0.0;
            }
        }
        let Some(cholesky) = damped.cholesky() else {
            *lambda *= lambda_growth;
            lambda_growth *= 2.0;
            if *lambda > MAX_LAMBDA {
                return Ok(Termination::Converged);
            }
            continue;
        };
        let step = -cholesky.solve(&gradient);
        // The model's decrease of rᵀr: −(2·δᵀJᵀr + δᵀJᵀJδ).
        let predicted = -(2.0 * step.dot(&gradient) + (step.transpose() * normal.jtj * step)[0]);
        let mut trial = *params;
        for (value, delta) in trial.iter_mut().zip(step.iter()) {
            *value += delta;
        }
        let trial_normal = normal_at(&trial).filter(|trial| trial.cost < normal.cost);
        let Some(trial_normal) = trial_normal else {
            // A step that could at best gain what the tolerance ignores, and gains
            // nothing, says the minimum is reached at the arithmetic's precision.
            if predicted <= COST_TOLERANCE * normal.cost {
                return Ok(Termination::Converged);
            }
            *lambda *= lambda_growth;
            lambda_growth *= 2.0;
            if *lambda > MAX_LAMBDA {
                return Ok(Termination::Converged);
            }
            continue;
        };
        let decrease = normal.cost - trial_normal.cost;
        let ratio = if predicted > 0.0 {
            decrease / predicted
        } else {
            0.0
        };
        *lambda *= (1.0 - (2.0 * ratio - 1.0).powi(3)).max(1.0 / 3.0);
        lambda_growth = 2.0;
        let step_norm = step.norm();
        let params_norm = free
            .iter()
            .map(|&idx| params[idx] * params[idx])
            .sum::<f64>()
            .sqrt();
        let cost_before = normal.cost;
        *params = trial;
        normal = trial_normal;
        let settled =
            decrease <= COST_TOLERANCE * cost_before && predicted <= COST_TOLERANCE * cost_before;
        if settled || step_norm <= STEP_TOLERANCE * (params_norm + STEP_TOLERANCE) {
            return Ok(Termination::Converged);
        }
    }
    Ok(Termination::OutOfSteps)
}

/// A fit on many samples first settles on an evenly spaced subset of at most this many
/// (where it does most of its steps, at a fraction of the cost), then on all of them.
pub(super) const MAX_THINNED_SAMPLES: usize = 2_000;

/// [`minimize`] on every `stride`-th sample, `stride` chosen so that at most
/// [`MAX_THINNED_SAMPLES`] are used, then from there on all of them: the same minimum
/// (that of all the samples), most of the steps at a fraction of the cost. From the
/// subset's minimum all the samples need a few steps (3-20 on the real logs), and at
/// most a quarter of `max_steps` (a fit that does not settle on the subset will not
/// settle on all samples either). `normal_at(params, stride)` gives the normal
/// equations of every `stride`-th sample.
pub(super) fn minimize_thinned_then_all<const N: usize>(
    params: &mut [f64; N],
    free: &[usize],
    n_samples: usize,
    max_steps: usize,
    normal_at: impl Fn(&[f64; N], usize) -> Option<Normal<N>>,
) -> Result<Termination, &'static str> {
    let stride = n_samples.div_ceil(MAX_THINNED_SAMPLES).max(1);
    // The damping found on the subset suits all the samples (their `JᵀJ` is the
    // subset's, scaled): starting again from `START_LAMBDA` would spend steps on
    // shrinking it.
    let mut lambda = START_LAMBDA;
    let mut max_steps_on_all = max_steps;
    if stride > 1 {
        minimize(params, free, max_steps, &mut lambda, |params| {
            normal_at(params, stride)
        })?;
        max_steps_on_all = max_steps.div_ceil(4);
    }
    minimize(params, free, max_steps_on_all, &mut lambda, |params| {
        normal_at(params, 1)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `y = a·exp(b·x)` through noisy points: the classic small nonlinear fit.
    fn exponential(params: &[f64; 2], points: &[(f64, f64)]) -> Option<Normal<2>> {
        let mut normal = Normal::zeros();
        for &(x, y) in points {
            let exp = (params[1] * x).exp();
            let row = (params[0] * exp - y, [exp, params[0] * x * exp]);
            normal.add_pair(&[row, (0.0, [0.0; 2])]);
        }
        normal.finished()
    }

    fn fit(
        params: &mut [f64; 2],
        free: &[usize],
        points: &[(f64, f64)],
    ) -> Result<Termination, &'static str> {
        let mut lambda = START_LAMBDA;
        minimize(params, free, 200, &mut lambda, |params| {
            exponential(params, points)
        })
    }

    #[test]
    fn an_exponential_is_fitted_from_far_away() {
        let points: Vec<(f64, f64)> = (0..50)
            .map(|idx| {
                let x = idx as f64 / 10.0;
                (
                    x,
                    2.5 * (-1.3 * x).exp() + 0.001 * ((idx * 7919) % 13) as f64 / 13.0,
                )
            })
            .collect();
        let mut params = [1.0, 0.0];
        assert_eq!(
            fit(&mut params, &[0, 1], &points),
            Ok(Termination::Converged)
        );
        assert!((params[0] - 2.5).abs() < 0.01, "{params:?}");
        assert!((params[1] + 1.3).abs() < 0.01, "{params:?}");
        // At the minimum the gradient vanishes.
        let normal = exponential(&params, &points).expect("finite");
        assert!(
            normal.jtr.norm() < 1e-6 * normal.jtj.norm(),
            "{}",
            normal.jtr
        );
    }

    #[test]
    fn fixed_parameters_stay_and_non_finite_starts_are_errors() {
        let points: Vec<(f64, f64)> = (0..20)
            .map(|idx| (idx as f64, 3.0 * (-0.2 * idx as f64).exp()))
            .collect();
        let mut params = [1.0, -0.2];
        assert_eq!(fit(&mut params, &[0], &points), Ok(Termination::Converged));
        assert_eq!(params[1], -0.2);
        assert!((params[0] - 3.0).abs() < 1e-9, "{params:?}");
        let mut params = [f64::NAN, 0.0];
        assert!(fit(&mut params, &[0, 1], &points).is_err());
    }

    #[test]
    fn the_subset_then_all_the_samples_find_the_minimum_of_all() {
        let points: Vec<(f64, f64)> = (0..10_000)
            .map(|idx| {
                let x = idx as f64 / 2_000.0;
                (
                    x,
                    2.5 * (-1.3 * x).exp() + 0.01 * (((idx * 7919) % 101) as f64 / 101.0 - 0.5),
                )
            })
            .collect();
        let mut thinned_then_all = [1.0, 0.0];
        minimize_thinned_then_all(
            &mut thinned_then_all,
            &[0, 1],
            points.len(),
            200,
            |params, stride| {
                let thinned: Vec<(f64, f64)> = points.iter().step_by(stride).copied().collect();
                exponential(params, &thinned)
            },
        )
        .expect("finite");
        let mut all = [1.0, 0.0];
        fit(&mut all, &[0, 1], &points).expect("finite");
        for (a, b) in thinned_then_all.iter().zip(all) {
            assert!((a - b).abs() < 1e-9, "{thinned_then_all:?} against {all:?}");
        }
    }
}
