//! A varied gait for the walk simulator: steps whose frequency and length change from
//! leg to leg and from step to step, accelerations whose size follows Weinberg's
//! relation, and the truth of every step.
//!
//! The model, per step k (one gait cycle; its phase φ runs from 0 to 2π):
//!
//! - **Pace.** Each walking phase of the route (the calibration circle, a straight leg,
//!   a turn) draws a target step frequency uniformly in `frequency_range_hz`. The pace
//!   moves halfway to the target at every step (a walker changes pace over two or three
//!   steps) and starts at the target after a stop. The step's frequency SF is the pace
//!   times 1 ± `frequency_jitter` (uniform).
//! - **Length.** A full step at that frequency is `SL = a + b·SF` long, times
//!   1 ± `length_jitter` (uniform). Step length grows about linearly with step frequency;
//!   this is the linear model of the PDR paper (Eq. 2) without its variance term. With
//!   a = 0.30 m and b = 0.22 m·s, 1.5 Hz gives 0.63 m, 1.8 Hz 0.70 m and 2.1 Hz 0.76 m.
//! - **Phase.** φ = 2π·SF·(t − t_start), the gait phase integrated exactly over the step
//!   (its frequency is constant within it); the step ends when φ reaches 2π and the next
//!   one starts at that instant.
//! - **Speed.** `w(φ)·SL·SF`. The gait weight w is 1, except in the first and the last
//!   step of a bout of walking: in the first step it rises as (1 − cos φ)/2 over the
//!   first half cycle, in the last it falls the same way over the second half. So the
//!   walker stands exactly still between bouts, a first or last step covers 3/4 of SL,
//!   and a bout of a single step covers half of it.
//! - **Vertical acceleration.** Up positive, `a_up = P·s(φ)/(max s − min s)`: its
//!   peak-to-peak P over the step is Weinberg's relation inverted,
//!   `P = Amax − Amin = (L/K)⁴` (H. Weinberg, "Using the ADXL202 in pedestrian dead
//!   reckoning applications", Analog Devices AN-602, 2002; Eq. 3 of the PDR paper), with
//!   L the distance this step covers and K ≈ 0.48 (L in m, accelerations in m/s²: a
//!   0.70 m step has P = 4.5 m/s²). The shape `s(φ) = sin φ + h·(cos φ − cos 2φ)` is the
//!   fundamental with a second harmonic: a sharp peak after the heel strike at φ = 0 and
//!   a flatter trough during single support. s(0) = s(2π) = 0 and s has zero mean, so
//!   steps of different sizes join without a jump and no step changes the vertical
//!   velocity.
//! - **Fore-aft surge.** `a_fwd = −r·P·sin φ`: braking after the heel strike, push-off
//!   in the second half.
//!
//! Limits: the truth position moves at the speed above; the surge is zero-mean over
//! each step and is not integrated into it (it would move the walker by a centimetre
//! within a step and not at all over a whole one). There is no lateral acceleration;
//! the hand's sway is simulated in `walk/`. Step frequencies are kept within
//! 0.5-4 Hz whatever the configuration says.

use std::f64::consts::{PI, TAU};

use serde::Serialize;

use crate::base::angle::wrap_to_2pi;
use crate::base::rng::SplitMix64;

/// How the simulated pedestrian walks.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Gait {
    /// The gait of [`super::walk::WalkConfig::from_seed`] and of the committed demo:
    /// the config's fixed step frequency and length, a sinusoidal bounce of fixed size,
    /// a phase that runs from t = 0 whether walking or not, and a 0.5 s fade when
    /// walking starts and stops. It has no step truth.
    Steady,
    /// Steps that vary, with per-step truth (this module's header).
    Varied(GaitVariation),
}

impl Gait {
    pub fn is_steady(&self) -> bool {
        matches!(self, Gait::Steady)
    }
}

/// The parameters of the varied gait (this module's header gives the model).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GaitVariation {
    /// Each walking phase of the route draws its target step frequency uniformly in
    /// `[low, high]` (Hz).
    pub frequency_range_hz: [f64; 2],
    /// Per-step variation of the frequency about the pace, as a fraction (0.03: ±3 %).
    pub frequency_jitter: f64,
    /// `a` of `SL = a + b·SF` (m).
    pub length_intercept_m: f64,
    /// `b` of `SL = a + b·SF` (m per Hz, that is m·s).
    pub length_per_frequency_m_s: f64,
    /// Per-step variation of the length, as a fraction (0.04: ±4 %).
    pub length_jitter: f64,
    /// Weinberg's K in `L = K·(Amax − Amin)^(1/4)`, L in m and accelerations in m/s².
    pub weinberg_k: f64,
    /// h, the weight of the heel-strike harmonic in the bounce's shape.
    pub heel_strike: f64,
    /// r, the fore-aft surge's amplitude as a fraction of the vertical peak-to-peak.
    pub surge_ratio: f64,
}

impl Default for GaitVariation {
    fn default() -> Self {
        GaitVariation {
            frequency_range_hz: [1.5, 2.1],
            frequency_jitter: 0.03,
            length_intercept_m: 0.30,
            length_per_frequency_m_s: 0.22,
            length_jitter: 0.04,
            weinberg_k: 0.48,
            heel_strike: 0.35,
            surge_ratio: 0.25,
        }
    }
}

/// The truth of one step: one gait cycle of the varied gait.
///
/// Every gait cycle that the walker completes is a step, including the first and the
/// last of a bout (whose gait weight ramps and whose length is about 3/4 of a full
/// step); between bouts the walker stands still and no cycle runs, so the steps
/// account for all the distance walked. A step runs from the upward zero crossing of
/// the vertical acceleration just before one heel-strike peak to the next one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StepTruth {
    pub t_start_s: f64,
    pub t_end_s: f64,
    /// 1 / (t_end − t_start).
    pub frequency_hz: f64,
    /// The distance the truth position moved along its path during the step.
    pub length_m: f64,
    /// The direction from the step's start to its end, clockwise from north (the
    /// walking direction, not the device's: the misalignment is not in it).
    pub heading_rad: f64,
    /// The truth position (east, north) at the step's start and end, in the frame of
    /// the reference columns.
    pub start_en_m: [f64; 2],
    pub end_en_m: [f64; 2],
    /// The peak-to-peak of the vertical acceleration during the step, (length / K)⁴,
    /// before sensor noise and tilt.
    pub vertical_peak_to_peak_mps2: f64,
}

/// Step frequencies are kept in this range whatever the configuration says.
const MIN_FREQUENCY_HZ: f64 = 0.5;
const MAX_FREQUENCY_HZ: f64 = 4.0;
/// The longest step, so that the last step of the walk ends before the log does.
const MAX_STEP_S: f64 = 1.0 / MIN_FREQUENCY_HZ;
/// The pace moves this fraction of the way to the leg's target at each step.
const PACE_FOLLOW_PER_STEP: f64 = 0.5;
/// The gait's random draws come from their own stream, so that the sensor noise of a
/// varied walk is the same sequence as that of the steady walk with the same seed.
const GAIT_STREAM: u64 = 0x6A17_57E9_0000_0001;

/// The gait at one instant, as the walk simulator uses it. Both gaits produce it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct GaitMotion {
    /// 0 standing, 1 walking; the hand's sway is scaled by it.
    pub weight: f64,
    /// The gait phase since the walk began: 2π per completed step, so half of it is the
    /// stride phase.
    pub phase_rad: f64,
    pub phase_rate_radps: f64,
    /// The body's acceleration: vertical (down positive, NED) and along the walking
    /// direction.
    pub down_mps2: f64,
    pub forward_mps2: f64,
    pub speed_mps: f64,
}

#[derive(Debug, Clone, Copy)]
struct PlannedStep {
    t_start_s: f64,
    frequency_hz: f64,
    /// SL: the length of a full step at this frequency.
    full_length_m: f64,
    starts_bout: bool,
    ends_bout: bool,
    /// The distance the step covers: SL times its mean gait weight.
    length_m: f64,
    peak_to_peak_mps2: f64,
    /// The distance walked before this step began.
    distance_before_m: f64,
}

impl PlannedStep {
    fn t_end_s(&self) -> f64 {
        self.t_start_s + 1.0 / self.frequency_hz
    }
}

/// The steps of a whole walk, laid out before the walk is simulated.
#[derive(Debug, Clone)]
pub(super) struct GaitPlan {
    steps: Vec<PlannedStep>,
    heel_strike: f64,
    surge_ratio: f64,
    /// max s − min s of the bounce's shape.
    shape_peak_to_peak: f64,
}

impl GaitPlan {
    /// Lays out the steps of a walk whose route walks during `walking_phases` (start and
    /// end times in seconds, in order; phases that touch form one bout) and lasts
    /// `duration_s`. Walking ends early enough that the last step completes within the
    /// walk.
    pub(super) fn new(
        variation: &GaitVariation,
        walking_phases: &[(f64, f64)],
        duration_s: f64,
        seed: u64,
    ) -> Self {
        let mut rng = SplitMix64::new(seed ^ GAIT_STREAM);
        let [low_hz, high_hz] = variation.frequency_range_hz;
        let targets_hz: Vec<f64> = walking_phases
            .iter()
            .map(|_| rng.uniform_in(low_hz, high_hz))
            .collect();
        let walking_ends_by_s = duration_s - MAX_STEP_S;
        let mut steps: Vec<PlannedStep> = Vec::new();
        let mut distance_m = 0.0;
        let mut phase_idx = 0usize;
        while phase_idx < walking_phases.len() {
            // A bout: this phase and the ones that follow it without a gap.
            let bout_first_idx = phase_idx;
            while phase_idx + 1 < walking_phases.len()
                && walking_phases[phase_idx + 1].0 <= walking_phases[phase_idx].1 + 1e-9
            {
                phase_idx += 1;
            }
            let bout_last_idx = phase_idx;
            phase_idx += 1;
            let previous_end_s = steps.last().map_or(0.0, PlannedStep::t_end_s);
            let bout_start_s = walking_phases[bout_first_idx].0.max(previous_end_s);
            let bout_end_s = walking_phases[bout_last_idx].1.min(walking_ends_by_s);

            let mut t_s = bout_start_s;
            let mut pace_hz: Option<f64> = None;
            let mut target_idx = bout_first_idx;
            while t_s < bout_end_s {
                while target_idx < bout_last_idx && t_s >= walking_phases[target_idx].1 {
                    target_idx += 1;
                }
                let target_hz = targets_hz[target_idx];
                let pace = pace_hz.map_or(target_hz, |pace| {
                    pace + PACE_FOLLOW_PER_STEP * (target_hz - pace)
                });
                pace_hz = Some(pace);
                let frequency_jitter = rng.uniform_in(-1.0, 1.0) * variation.frequency_jitter;
                let length_jitter = rng.uniform_in(-1.0, 1.0) * variation.length_jitter;
                let frequency_hz =
                    (pace * (1.0 + frequency_jitter)).clamp(MIN_FREQUENCY_HZ, MAX_FREQUENCY_HZ);
                let full_length_m = ((variation.length_intercept_m
                    + variation.length_per_frequency_m_s * frequency_hz)
                    * (1.0 + length_jitter))
                    .max(0.0);
                let starts_bout = t_s == bout_start_s;
                let ends_bout = t_s + 1.0 / frequency_hz >= bout_end_s;
                let length_m = full_length_m * weight_integral(TAU, starts_bout, ends_bout) / TAU;
                steps.push(PlannedStep {
                    t_start_s: t_s,
                    frequency_hz,
                    full_length_m,
                    starts_bout,
                    ends_bout,
                    length_m,
                    peak_to_peak_mps2: (length_m / variation.weinberg_k).powi(4),
                    distance_before_m: distance_m,
                });
                distance_m += length_m;
                t_s += 1.0 / frequency_hz;
                if ends_bout {
                    break;
                }
            }
        }
        GaitPlan {
            steps,
            heel_strike: variation.heel_strike,
            surge_ratio: variation.surge_ratio,
            shape_peak_to_peak: shape_peak_to_peak(variation.heel_strike),
        }
    }

    /// The step under way at `t_s` (the last one started), with its index and phase;
    /// the phase is 2π or more once that step has ended.
    fn step_at(&self, t_s: f64) -> Option<(usize, &PlannedStep, f64)> {
        let n_started = self.steps.partition_point(|step| step.t_start_s <= t_s);
        let step_idx = n_started.checked_sub(1)?;
        let step = &self.steps[step_idx];
        Some((
            step_idx,
            step,
            TAU * step.frequency_hz * (t_s - step.t_start_s),
        ))
    }

    pub(super) fn motion_at(&self, t_s: f64) -> GaitMotion {
        let standing = |n_completed: usize| GaitMotion {
            weight: 0.0,
            phase_rad: TAU * n_completed as f64,
            phase_rate_radps: 0.0,
            down_mps2: 0.0,
            forward_mps2: 0.0,
            speed_mps: 0.0,
        };
        let Some((step_idx, step, phase_rad)) = self.step_at(t_s) else {
            return standing(0);
        };
        if phase_rad >= TAU {
            return standing(step_idx + 1);
        }
        let weight = weight_at(phase_rad, step.starts_bout, step.ends_bout);
        let up_mps2 = step.peak_to_peak_mps2 * bounce_shape(phase_rad, self.heel_strike)
            / self.shape_peak_to_peak;
        GaitMotion {
            weight,
            phase_rad: TAU * step_idx as f64 + phase_rad,
            phase_rate_radps: TAU * step.frequency_hz,
            down_mps2: -up_mps2,
            forward_mps2: -self.surge_ratio * step.peak_to_peak_mps2 * phase_rad.sin(),
            speed_mps: weight * step.full_length_m * step.frequency_hz,
        }
    }

    /// The distance walked from the start of the walk to `t_s`: the exact integral of
    /// the speed, so that the truth position moves by exactly each step's length.
    pub(super) fn distance_at(&self, t_s: f64) -> f64 {
        match self.step_at(t_s) {
            None => 0.0,
            Some((_, step, phase_rad)) => {
                step.distance_before_m
                    + step.full_length_m
                        * weight_integral(phase_rad.min(TAU), step.starts_bout, step.ends_bout)
                        / TAU
            }
        }
    }

    /// The instants at which steps start and end, in order, each with the step it
    /// starts (or ends): the walk records the truth position there.
    pub(super) fn step_boundaries(&self) -> Vec<StepBoundary> {
        let mut boundaries = Vec::with_capacity(2 * self.steps.len());
        for (step_idx, step) in self.steps.iter().enumerate() {
            boundaries.push(StepBoundary {
                t_s: step.t_start_s,
                step_idx,
                is_start: true,
            });
            boundaries.push(StepBoundary {
                t_s: step.t_end_s(),
                step_idx,
                is_start: false,
            });
        }
        crate::base::sort::sort_by_key(&mut boundaries, |boundary| boundary.t_s);
        boundaries
    }

    /// The truth of the steps whose start and end positions the walk recorded.
    pub(super) fn truth(&self, positions: &[StepPositions]) -> Vec<StepTruth> {
        self.steps
            .iter()
            .zip(positions)
            .filter_map(|(step, position)| {
                let (start, end) = (position.start_en_m?, position.end_en_m?);
                let (d_east_m, d_north_m) = (end[0] - start[0], end[1] - start[1]);
                let t_end_s = step.t_end_s();
                Some(StepTruth {
                    t_start_s: step.t_start_s,
                    t_end_s,
                    frequency_hz: 1.0 / (t_end_s - step.t_start_s),
                    length_m: step.length_m,
                    heading_rad: wrap_to_2pi(d_east_m.atan2(d_north_m)),
                    start_en_m: start,
                    end_en_m: end,
                    vertical_peak_to_peak_mps2: step.peak_to_peak_mps2,
                })
            })
            .collect()
    }

    pub(super) fn n_steps(&self) -> usize {
        self.steps.len()
    }
}

/// A step starts or ends at `t_s`.
#[derive(Debug, Clone, Copy)]
pub(super) struct StepBoundary {
    pub t_s: f64,
    pub step_idx: usize,
    pub is_start: bool,
}

/// The truth positions at a step's start and end, once the walk has passed them.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct StepPositions {
    pub start_en_m: Option<[f64; 2]>,
    pub end_en_m: Option<[f64; 2]>,
}

/// The gait weight at phase φ of a step: (1 − cos φ)/2 in the first half of a bout's
/// first step and in the second half of its last, 1 elsewhere.
fn weight_at(phase_rad: f64, starts_bout: bool, ends_bout: bool) -> f64 {
    let ramps = if phase_rad < PI {
        starts_bout
    } else {
        ends_bout
    };
    if ramps {
        (1.0 - phase_rad.cos()) / 2.0
    } else {
        1.0
    }
}

/// ∫₀^φ w(φ') dφ' for [`weight_at`]; the antiderivative of (1 − cos φ)/2 is
/// (φ − sin φ)/2. A step covers `SL · weight_integral(2π) / 2π`.
fn weight_integral(phase_rad: f64, starts_bout: bool, ends_bout: bool) -> f64 {
    let piece = |from_rad: f64, to_rad: f64, ramps: bool| {
        if ramps {
            ((to_rad - to_rad.sin()) - (from_rad - from_rad.sin())) / 2.0
        } else {
            to_rad - from_rad
        }
    };
    let first_half = piece(0.0, phase_rad.min(PI), starts_bout);
    let second_half = if phase_rad > PI {
        piece(PI, phase_rad, ends_bout)
    } else {
        0.0
    };
    first_half + second_half
}

/// s(φ) = sin φ + h·(cos φ − cos 2φ): zero at both ends of the step, zero mean.
fn bounce_shape(phase_rad: f64, heel_strike: f64) -> f64 {
    phase_rad.sin() + heel_strike * (phase_rad.cos() - (2.0 * phase_rad).cos())
}

/// max s − min s over a cycle, on a grid fine enough that the error is below 1e-6.
fn shape_peak_to_peak(heel_strike: f64) -> f64 {
    const N_GRID: usize = 8192;
    let (min, max) = (0..N_GRID)
        .map(|grid_idx| bounce_shape(TAU * grid_idx as f64 / N_GRID as f64, heel_strike))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(min, max), value| {
            (min.min(value), max.max(value))
        });
    max - min
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(walking_phases: &[(f64, f64)], duration_s: f64) -> GaitPlan {
        GaitPlan::new(&GaitVariation::default(), walking_phases, duration_s, 7)
    }

    #[test]
    fn the_weight_integral_is_the_integral_of_the_weight() {
        for (starts_bout, ends_bout) in [(false, false), (true, false), (false, true), (true, true)]
        {
            let n_grid = 20_000;
            let mut sum = 0.0;
            for grid_idx in 0..n_grid {
                let phase_rad = TAU * (grid_idx as f64 + 0.5) / n_grid as f64;
                sum += weight_at(phase_rad, starts_bout, ends_bout) * TAU / n_grid as f64;
                let exact = weight_integral(
                    TAU * (grid_idx + 1) as f64 / n_grid as f64,
                    starts_bout,
                    ends_bout,
                );
                assert!(
                    (sum - exact).abs() < 1e-6,
                    "{starts_bout} {ends_bout} {grid_idx}: {sum} vs {exact}"
                );
            }
        }
        assert!((weight_integral(TAU, true, false) - 0.75 * TAU).abs() < 1e-12);
        assert!((weight_integral(TAU, true, true) - 0.5 * TAU).abs() < 1e-12);
    }

    #[test]
    fn the_bounce_shape_joins_steps_without_a_jump_and_has_zero_mean() {
        let heel_strike = GaitVariation::default().heel_strike;
        assert!(bounce_shape(0.0, heel_strike).abs() < 1e-12);
        assert!(bounce_shape(TAU, heel_strike).abs() < 1e-12);
        let n_grid = 10_000;
        let mean = (0..n_grid)
            .map(|grid_idx| bounce_shape(TAU * grid_idx as f64 / n_grid as f64, heel_strike))
            .sum::<f64>()
            / n_grid as f64;
        assert!(mean.abs() < 1e-9, "{mean}");
        // The heel-strike peak is sharper than the trough is deep.
        let peak_to_peak = shape_peak_to_peak(heel_strike);
        assert!(peak_to_peak > 2.0, "{peak_to_peak}");
    }

    #[test]
    fn steps_tile_each_bout_and_the_distance_is_continuous() {
        let gait = plan(&[(3.0, 27.0), (27.0, 40.0), (44.0, 60.0)], 80.0);
        let boundaries = gait.step_boundaries();
        assert_eq!(boundaries.len(), 2 * gait.n_steps());
        let bouts: Vec<&[PlannedStep]> =
            gait.steps.split_inclusive(|step| step.ends_bout).collect();
        assert_eq!(bouts.len(), 2);
        for bout in &bouts {
            assert!(bout[0].starts_bout);
            assert!(bout.iter().skip(1).all(|step| !step.starts_bout));
            for pair in bout.windows(2) {
                assert_eq!(pair[0].t_end_s(), pair[1].t_start_s);
                let at_end = pair[0].distance_before_m + pair[0].length_m;
                assert!((at_end - pair[1].distance_before_m).abs() < 1e-12);
                assert!((gait.distance_at(pair[1].t_start_s) - at_end).abs() < 1e-12);
            }
        }
        assert!((bouts[0][0].t_start_s - 3.0).abs() < 1e-12);
        // A bout ends with the step that reaches the end of its route phases.
        let first_end = bouts[0].last().map_or(0.0, PlannedStep::t_end_s);
        assert!((40.0..41.0).contains(&first_end), "{first_end}");
        assert!(gait.motion_at(42.0).speed_mps == 0.0);
        assert!(gait.motion_at(20.0).speed_mps > 0.9);
    }
}
