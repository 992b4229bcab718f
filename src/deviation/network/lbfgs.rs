//! L-BFGS: limited-memory quasi-Newton minimisation of a smooth function.
//!
//! Nocedal and Wright (2006), *Numerical Optimization*, 2nd ed.: the search direction
//! `d = −H·g` by the two-loop recursion (Algorithm 7.4) over the last `memory` pairs
//! `sₖ = xₖ₊₁ − xₖ`, `yₖ = gₖ₊₁ − gₖ`, with the initial matrix `H₀ = (sᵀy / yᵀy)·I`
//! (Eq. 7.20); the step length by a line search for the strong Wolfe conditions
//! (Algorithms 3.5 and 3.6, `c₁ = 10⁻⁴`, `c₂ = 0.9`, cubic interpolation in the zoom).
//! The first step is `min(1, 1/|g|)` long, later ones start at 1, which L-BFGS usually
//! accepts: about one evaluation per iteration.
//!
//! The stopping rules are those of SciPy's L-BFGS-B (which scikit-learn's `lbfgs` solver
//! calls), so the two can be run to the same rule: at most `max_iterations` iterations
//! and `max_evaluations` evaluations; stop when the largest gradient component is at
//! most `gradient_tolerance` (SciPy's `gtol`, scikit-learn's `tol`), or when the relative
//! decrease `(fₖ − fₖ₊₁) / max(|fₖ|, |fₖ₊₁|, 1)` is at most `relative_decrease_tolerance`
//! (SciPy's `ftol`). A pair with `sᵀy ≤ 10⁻¹⁰·yᵀy` is skipped to keep `H` positive
//! definite; a direction that does not descend, or a failed line search, restarts from
//! the steepest descent once before giving up.
//!
//! Limits: no bounds (L-BFGS-B's "B"), and the caller's objective must be finite near
//! the start; a non-finite value in the line search is treated as a step too long.

use std::ops::ControlFlow;

/// A function to minimise: its value at `x`, with its gradient written to `gradient`.
pub trait Objective {
    fn value_and_gradient(&mut self, x: &[f64], gradient: &mut [f64]) -> f64;
}

/// How long L-BFGS runs and how many correction pairs it keeps.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LbfgsOptions {
    /// Correction pairs kept (SciPy's `maxcor`, 10).
    pub memory: usize,
    pub max_iterations: usize,
    /// Evaluations of the objective (SciPy's `maxfun`; scikit-learn's `max_fun`, 15,000).
    pub max_evaluations: usize,
    /// Stop when every gradient component is at most this in absolute value.
    pub gradient_tolerance: f64,
    /// Stop when the relative decrease of one iteration is at most this (SciPy's
    /// `ftol`, 2.22·10⁻⁹ = 10⁷ machine epsilons).
    pub relative_decrease_tolerance: f64,
}

impl Default for LbfgsOptions {
    fn default() -> Self {
        LbfgsOptions {
            memory: 10,
            max_iterations: 200,
            max_evaluations: 15_000,
            gradient_tolerance: 1e-5,
            relative_decrease_tolerance: 1e7 * f64::EPSILON,
        }
    }
}

/// Why L-BFGS stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LbfgsStop {
    MaxIterations,
    MaxEvaluations,
    GradientTolerance,
    RelativeDecrease,
    /// No step along the steepest descent lowered the objective (a minimum to within
    /// rounding, or a non-smooth objective).
    LineSearchFailed,
    /// The objective was not finite at the start.
    NonFiniteStart,
    /// The caller's `after_iteration` asked to stop.
    Interrupted,
}

/// The result of [`minimise`]; the minimiser itself is left in the caller's `x`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LbfgsOutcome {
    pub value: f64,
    pub iterations: usize,
    pub evaluations: usize,
    pub stop: LbfgsStop,
}

/// Minimises `objective` from `x`, leaving the last iterate in `x`. After each iteration
/// `after_iteration(iteration, x, value)` is called (iterations count from 1); it may
/// return `ControlFlow::Break(())` to stop (early stopping).
pub fn minimise<O: Objective>(
    objective: &mut O,
    x: &mut [f64],
    options: &LbfgsOptions,
    mut after_iteration: impl FnMut(usize, &[f64], f64) -> ControlFlow<()>,
) -> LbfgsOutcome {
    let n = x.len();
    let memory = options.memory.max(1);
    let mut gradient = vec![0.0; n];
    let mut value = objective.value_and_gradient(x, &mut gradient);
    let mut counter = Counter {
        evaluations: 1,
        max_evaluations: options.max_evaluations.max(1),
    };
    let outcome = |value, iterations, evaluations, stop| LbfgsOutcome {
        value,
        iterations,
        evaluations,
        stop,
    };
    if !value.is_finite() {
        return outcome(value, 0, 1, LbfgsStop::NonFiniteStart);
    }
    if max_abs(&gradient) <= options.gradient_tolerance {
        return outcome(value, 0, 1, LbfgsStop::GradientTolerance);
    }

    let mut state = IterationState::new(n, memory);
    let mut iteration = 0;
    loop {
        if iteration >= options.max_iterations {
            return outcome(
                value,
                iteration,
                counter.evaluations,
                LbfgsStop::MaxIterations,
            );
        }
        state.x_start.copy_from_slice(x);
        state.gradient_start.copy_from_slice(&gradient);
        let value_start = value;

        let step = state.step(objective, value_start, x, &mut gradient, &mut counter);
        let Some(new_value) = step else {
            x.copy_from_slice(&state.x_start);
            gradient.copy_from_slice(&state.gradient_start);
            let stop = if counter.exhausted() {
                LbfgsStop::MaxEvaluations
            } else {
                LbfgsStop::LineSearchFailed
            };
            return outcome(value_start, iteration, counter.evaluations, stop);
        };
        value = new_value;
        iteration += 1;
        state
            .history
            .push(x, &state.x_start, &gradient, &state.gradient_start);

        if after_iteration(iteration, x, value).is_break() {
            return outcome(
                value,
                iteration,
                counter.evaluations,
                LbfgsStop::Interrupted,
            );
        }
        let stop = stop_after_iteration(options, value_start, value, &gradient, &counter);
        if let Some(stop) = stop {
            return outcome(value, iteration, counter.evaluations, stop);
        }
    }
}

/// Why to stop after an iteration that lowered the value from `value_start` to `value`
/// (the relative decrease, the gradient, the evaluations, in that order); `None` to go on.
fn stop_after_iteration(
    options: &LbfgsOptions,
    value_start: f64,
    value: f64,
    gradient: &[f64],
    counter: &Counter,
) -> Option<LbfgsStop> {
    let relative_decrease = (value_start - value) / value_start.abs().max(value.abs()).max(1.0);
    if relative_decrease <= options.relative_decrease_tolerance {
        return Some(LbfgsStop::RelativeDecrease);
    }
    if max_abs(gradient) <= options.gradient_tolerance {
        return Some(LbfgsStop::GradientTolerance);
    }
    if counter.exhausted() {
        return Some(LbfgsStop::MaxEvaluations);
    }
    None
}

/// What the iterations share: the correction pairs, the buffers of the direction and of
/// the two-loop recursion, and the iterate and gradient an iteration starts from.
struct IterationState {
    history: History,
    direction: Vec<f64>,
    alphas: Vec<f64>,
    x_start: Vec<f64>,
    gradient_start: Vec<f64>,
}

impl IterationState {
    /// Empty state for `n` unknowns and `memory` correction pairs.
    fn new(n: usize, memory: usize) -> Self {
        IterationState {
            history: History::new(n, memory),
            direction: vec![0.0; n],
            alphas: vec![0.0; memory],
            x_start: vec![0.0; n],
            gradient_start: vec![0.0; n],
        }
    }

    /// One iteration's line search from `x_start`: its new value, with the step left in
    /// `x` and `gradient`; `None` when no step was found.
    fn step<O: Objective>(
        &mut self,
        objective: &mut O,
        value_start: f64,
        x: &mut [f64],
        gradient: &mut [f64],
        counter: &mut Counter,
    ) -> Option<f64> {
        let mut step = None;
        // The quasi-Newton direction, then (after a failure) the steepest descent.
        for attempt in 0..2 {
            if attempt == 1 {
                if self.history.is_empty() {
                    break;
                }
                self.history.clear();
            }
            self.history
                .direction(&self.gradient_start, &mut self.direction, &mut self.alphas);
            let mut slope = dot(&self.direction, &self.gradient_start);
            // NaN counts as not descending.
            if slope.is_nan() || slope >= 0.0 {
                self.history.clear();
                for (d, g) in self.direction.iter_mut().zip(&self.gradient_start) {
                    *d = -g;
                }
                slope = dot(&self.direction, &self.gradient_start);
            }
            let initial_step = if self.history.is_empty() {
                (1.0 / norm(&self.gradient_start)).min(1.0)
            } else {
                1.0
            };
            let search = LineSearch {
                x_start: &self.x_start,
                value_start,
                direction: &self.direction,
                slope_start: slope,
            };
            step = search.run(objective, initial_step, x, gradient, counter);
            if step.is_some() {
                break;
            }
        }
        step
    }
}

struct Counter {
    evaluations: usize,
    max_evaluations: usize,
}

impl Counter {
    fn exhausted(&self) -> bool {
        self.evaluations >= self.max_evaluations
    }
}

/// The last `memory` correction pairs in a ring.
struct History {
    n: usize,
    memory: usize,
    /// `s[slot·n..][..n]`, `y[slot·n..][..n]`, `rho[slot] = 1 / sᵀy`.
    s: Vec<f64>,
    y: Vec<f64>,
    rho: Vec<f64>,
    /// Pairs stored (at most `memory`) and the slot of the newest.
    len: usize,
    newest: usize,
}

impl History {
    fn new(n: usize, memory: usize) -> Self {
        History {
            n,
            memory,
            s: vec![0.0; n * memory],
            y: vec![0.0; n * memory],
            rho: vec![0.0; memory],
            len: 0,
            newest: 0,
        }
    }

    fn is_empty(&self) -> bool {
        self.len == 0
    }

    fn clear(&mut self) {
        self.len = 0;
    }

    fn push(&mut self, x: &[f64], x_old: &[f64], g: &[f64], g_old: &[f64]) {
        let slot = if self.len == 0 {
            0
        } else {
            (self.newest + 1) % self.memory
        };
        let s = &mut self.s[slot * self.n..][..self.n];
        for ((s, x), x_old) in s.iter_mut().zip(x).zip(x_old) {
            *s = x - x_old;
        }
        let y = &mut self.y[slot * self.n..][..self.n];
        for ((y, g), g_old) in y.iter_mut().zip(g).zip(g_old) {
            *y = g - g_old;
        }
        let sy = dot(s, y);
        let yy = dot(y, y);
        if !sy.is_finite() || sy.is_nan() || sy <= 1e-10 * yy || yy.is_nan() {
            return;
        }
        self.rho[slot] = 1.0 / sy;
        self.newest = slot;
        self.len = (self.len + 1).min(self.memory);
    }

    /// `direction = −H·g` (two-loop recursion; with no pairs, `−g`).
    fn direction(&self, g: &[f64], direction: &mut [f64], alphas: &mut [f64]) {
        for (d, g) in direction.iter_mut().zip(g) {
            *d = -g;
        }
        if self.len == 0 {
            return;
        }
        let slot_of = |age: usize| (self.newest + self.memory - age) % self.memory;
        for age in 0..self.len {
            let slot = slot_of(age);
            let alpha = self.rho[slot] * dot(&self.s[slot * self.n..][..self.n], direction);
            alphas[slot] = alpha;
            axpy(-alpha, &self.y[slot * self.n..][..self.n], direction);
        }
        let newest_y = &self.y[self.newest * self.n..][..self.n];
        let gamma = 1.0 / (self.rho[self.newest] * dot(newest_y, newest_y));
        for d in direction.iter_mut() {
            *d *= gamma;
        }
        for age in (0..self.len).rev() {
            let slot = slot_of(age);
            let beta = self.rho[slot] * dot(&self.y[slot * self.n..][..self.n], direction);
            axpy(
                alphas[slot] - beta,
                &self.s[slot * self.n..][..self.n],
                direction,
            );
        }
    }
}

/// One point of the line search: step, value and slope `gᵀd`.
#[derive(Clone, Copy)]
struct Point {
    step: f64,
    value: f64,
    slope: f64,
}

struct LineSearch<'a> {
    x_start: &'a [f64],
    value_start: f64,
    direction: &'a [f64],
    slope_start: f64,
}

const SUFFICIENT_DECREASE: f64 = 1e-4;
const CURVATURE: f64 = 0.9;
const MAX_TRIALS: usize = 30;

impl LineSearch<'_> {
    /// Evaluates the objective at `x_start + step·direction` into `x` and `gradient`.
    fn evaluate<O: Objective>(
        &self,
        objective: &mut O,
        step: f64,
        x: &mut [f64],
        gradient: &mut [f64],
        counter: &mut Counter,
    ) -> Point {
        for ((x, x_start), d) in x.iter_mut().zip(self.x_start).zip(self.direction) {
            *x = x_start + step * d;
        }
        counter.evaluations += 1;
        let value = objective.value_and_gradient(x, gradient);
        Point {
            step,
            value,
            slope: dot(gradient, self.direction),
        }
    }

    fn decreases_enough(&self, point: &Point) -> bool {
        point.value.is_finite()
            && point.value <= self.value_start + SUFFICIENT_DECREASE * point.step * self.slope_start
    }

    fn curvature_holds(&self, point: &Point) -> bool {
        point.slope.abs() <= -CURVATURE * self.slope_start
    }

    /// Algorithm 3.5: a step satisfying the strong Wolfe conditions, left in `x` and
    /// `gradient`, with its value; `None` when none was found.
    fn run<O: Objective>(
        &self,
        objective: &mut O,
        initial_step: f64,
        x: &mut [f64],
        gradient: &mut [f64],
        counter: &mut Counter,
    ) -> Option<f64> {
        let mut previous = Point {
            step: 0.0,
            value: self.value_start,
            slope: self.slope_start,
        };
        let mut step = initial_step;
        for trial in 0..MAX_TRIALS {
            if counter.exhausted() {
                return None;
            }
            let point = self.evaluate(objective, step, x, gradient, counter);
            if !self.decreases_enough(&point) || (trial > 0 && point.value >= previous.value) {
                return self.zoom(objective, previous, point, x, gradient, counter);
            }
            if self.curvature_holds(&point) {
                return Some(point.value);
            }
            if point.slope >= 0.0 {
                return self.zoom(objective, point, previous, x, gradient, counter);
            }
            previous = point;
            step *= 2.0;
        }
        None
    }

    /// Algorithm 3.6: `low` satisfies the sufficient decrease and has the lowest value so
    /// far; the interval between `low` and `high` holds a step satisfying both conditions.
    fn zoom<O: Objective>(
        &self,
        objective: &mut O,
        mut low: Point,
        mut high: Point,
        x: &mut [f64],
        gradient: &mut [f64],
        counter: &mut Counter,
    ) -> Option<f64> {
        for _ in 0..MAX_TRIALS {
            if counter.exhausted()
                || (high.step - low.step).abs() <= 1e-12 * low.step.abs().max(1e-300)
            {
                break;
            }
            let step = interpolate(&low, &high);
            let point = self.evaluate(objective, step, x, gradient, counter);
            if !self.decreases_enough(&point) || point.value >= low.value {
                high = point;
            } else {
                if self.curvature_holds(&point) {
                    return Some(point.value);
                }
                if point.slope * (high.step - low.step) >= 0.0 {
                    high = low;
                }
                low = point;
            }
        }
        // No Wolfe step, but `low` lowered the objective: take it.
        if low.step > 0.0 && low.value < self.value_start && !counter.exhausted() {
            let point = self.evaluate(objective, low.step, x, gradient, counter);
            return Some(point.value);
        }
        None
    }
}

/// The minimiser of the cubic through `a` and `b` (values and slopes), kept at least a
/// tenth of the interval away from its ends; the midpoint when the cubic has none or a
/// value is not finite.
fn interpolate(a: &Point, b: &Point) -> f64 {
    let (low, high) = if a.step < b.step { (a, b) } else { (b, a) };
    let width = high.step - low.step;
    let midpoint = low.step + 0.5 * width;
    if !(a.value.is_finite() && b.value.is_finite() && a.slope.is_finite() && b.slope.is_finite()) {
        return midpoint;
    }
    // Nocedal and Wright, Eq. 3.59.
    let d1 = a.slope + b.slope - 3.0 * (a.value - b.value) / (a.step - b.step);
    let discriminant = d1 * d1 - a.slope * b.slope;
    if discriminant.is_nan() || discriminant < 0.0 {
        return midpoint;
    }
    let d2 = (b.step - a.step).signum() * discriminant.sqrt();
    let step = b.step - (b.step - a.step) * (b.slope + d2 - d1) / (b.slope - a.slope + 2.0 * d2);
    let margin = 0.1 * width;
    if step.is_finite() && step >= low.step + margin && step <= high.step - margin {
        step
    } else {
        midpoint
    }
}

fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(x, y)| x * y).sum()
}

fn norm(x: &[f64]) -> f64 {
    dot(x, x).sqrt()
}

fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0, |max, value| max.max(value.abs()))
}

fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += a * x;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Rosenbrock function in `n` dimensions, minimum 0 at (1, …, 1).
    struct Rosenbrock;

    impl Objective for Rosenbrock {
        fn value_and_gradient(&mut self, x: &[f64], gradient: &mut [f64]) -> f64 {
            gradient.fill(0.0);
            let mut value = 0.0;
            for i in 0..x.len() - 1 {
                let a = x[i + 1] - x[i] * x[i];
                let b = 1.0 - x[i];
                value += 100.0 * a * a + b * b;
                gradient[i] += -400.0 * a * x[i] - 2.0 * b;
                gradient[i + 1] += 200.0 * a;
            }
            value
        }
    }

    #[test]
    fn finds_the_minimum_of_rosenbrock() {
        let mut x = vec![-1.2, 1.0, -1.2, 1.0, -1.2, 1.0];
        let options = LbfgsOptions {
            max_iterations: 500,
            gradient_tolerance: 1e-8,
            relative_decrease_tolerance: 0.0,
            ..Default::default()
        };
        let outcome = minimise(&mut Rosenbrock, &mut x, &options, |_, _, _| {
            ControlFlow::Continue(())
        });
        assert_eq!(outcome.stop, LbfgsStop::GradientTolerance, "{outcome:?}");
        for value in &x {
            assert!((value - 1.0).abs() < 1e-6, "{x:?}");
        }
        // Quasi-Newton: far fewer evaluations than gradient descent would need.
        assert!(
            outcome.evaluations < 2 * outcome.iterations + 20,
            "{outcome:?}"
        );
    }

    #[test]
    fn stops_when_asked_and_at_the_iteration_cap() {
        let mut x = vec![-1.2, 1.0];
        let outcome = minimise(
            &mut Rosenbrock,
            &mut x,
            &LbfgsOptions::default(),
            |iteration, _, _| {
                if iteration == 3 {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            },
        );
        assert_eq!(
            (outcome.stop, outcome.iterations),
            (LbfgsStop::Interrupted, 3)
        );
        let options = LbfgsOptions {
            max_iterations: 5,
            ..Default::default()
        };
        let mut x = vec![-1.2, 1.0];
        let outcome = minimise(&mut Rosenbrock, &mut x, &options, |_, _, _| {
            ControlFlow::Continue(())
        });
        assert_eq!(
            (outcome.stop, outcome.iterations),
            (LbfgsStop::MaxIterations, 5)
        );
    }
}
