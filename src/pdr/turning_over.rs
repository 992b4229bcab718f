//! Steps that are not walking: the phone turned over in the hand.
//!
//! A compass is calibrated by turning the phone through every orientation, the figure
//! eight that apps ask for and that the IPIN 2023 walks begin with (half a minute, the
//! phone turning at 2-7 rad/s). `|f|` bounces as the hand moves, so the detector of
//! `steps.rs` counts "steps" there, and Weinberg's model makes them long: 30-40 m of
//! walk where the walker stood, which the track carries and the step-length scale
//! learns from.
//!
//! Walking tilts the phone little: with the phone in hand or flat, its rate about the
//! horizontal axes (the gyro's rate less its part about gravity) stays under 0.9 rad/s
//! on every step of the twelve IPIN walks (1,748 steps), where the figure eight's steps
//! have 1-7 rad/s. A swinging arm or a pocket tilts the phone fast as well, but back and
//! forth with each stride: over two steps (one stride), the mean direction of gravity
//! in the phone comes back. So a step is **turned over** when both hold:
//!
//! - its tilt rate, `|ω − (ω·ĝ) ĝ|` averaged over the step and half a second either
//!   side, is above [`TILT_RATE_RADPS`], with `ĝ` the direction of the specific force
//!   averaged over a second;
//! - the mean direction of the specific force over the stride before the step and over
//!   the stride from it differ by more than [`GRAVITY_DRIFT_DEG`].
//!
//! A bout of steps (no pause longer than the detector's `max_step_s`) of which at least
//! half are turned over, at a walking pace or slower (its median step at least
//! [`MIN_FIGURE_EIGHT_STEP_S`]: a runner's phone turns as fast), is left out whole, and no
//! step of any other bout is: a phone
//! in hand tilts at 1.2-1.5 rad/s through a few steps of a walk (8 of the 56 steps of
//! the first bout of the msft F1 walk pass both tests), where a figure eight is a bout
//! of its own. Without a gyroscope nothing is left out.
//!
//! Limits: a figure eight with no pause before the walk is one bout with it, and is
//! kept when it is the shorter part; a walk with the phone turned over and over (a
//! phone juggled in the hand) is taken for a figure eight.

use nalgebra::Vector3;

use crate::io::recording::Stream;

use super::steps::{bout_ranges, Step};

/// Above this mean tilt rate a step may be the phone turned over (rad/s): walking with
/// the phone in hand stayed under 0.9 on the IPIN walks, the figure eights' steps are
/// 1-7.
pub const TILT_RATE_RADPS: f64 = 1.0;
/// ... if the direction of gravity in the phone also moved this far from one stride to
/// the next (degrees): a swinging arm's comes back within a stride.
pub const GRAVITY_DRIFT_DEG: f64 = 5.0;
/// A bout whose median step is shorter than this is running, never a figure eight (s):
/// a runner's phone, in the hand or a pocket, tilts and swings like one (TYREX's running
/// trials: 0.37-0.40 s steps, 2.5-2.6 rad/s of tilt, gravity moving 6-8° from stride to
/// stride), where a hand turning a phone over bounces it every 0.6-1.0 s (IPIN's figure
/// eights).
pub const MIN_FIGURE_EIGHT_STEP_S: f64 = 0.45;
/// Half the window over which `ĝ` is averaged for the tilt rate (s).
const GRAVITY_HALF_WINDOW_S: f64 = 0.5;
/// How far the tilt rate's window reaches beyond the step (s).
const TILT_MARGIN_S: f64 = 0.5;

/// The steps left after the turned-over ones are taken out.
#[derive(Debug, Clone, PartialEq)]
pub struct Walking {
    pub steps: Vec<Step>,
    /// The steps left out, and the time span they covered (s).
    pub n_left_out: usize,
    pub left_out_span_s: Option<(f64, f64)>,
    /// The median tilt rate of the steps left out (rad/s).
    pub left_out_tilt_rate_radps: Option<f64>,
}

impl Walking {
    /// A note for the user, when steps were left out.
    pub fn note(&self) -> Option<String> {
        let (first_s, last_s) = self.left_out_span_s?;
        Some(format!(
            "{} steps between {first_s:.1} and {last_s:.1} s were the phone being turned over (tilting at {:.1} rad/s, as in a compass-calibration figure eight), not walking: they were left out of the track.",
            self.n_left_out,
            self.left_out_tilt_rate_radps.unwrap_or(f64::NAN),
        ))
    }
}

/// Takes the turned-over steps out of `steps` (see the module header).
pub fn walking_steps(
    steps: &[Step],
    acc_in_body_mps2: &Stream<Vector3<f64>>,
    gyro_in_body_radps: &Stream<Vector3<f64>>,
) -> Walking {
    let all = Walking {
        steps: steps.to_vec(),
        n_left_out: 0,
        left_out_span_s: None,
        left_out_tilt_rate_radps: None,
    };
    if gyro_in_body_radps.len() < 2 || acc_in_body_mps2.len() < 2 {
        return all;
    }
    let gravity = GravityDirection::of(acc_in_body_mps2);
    let tilt = TiltRate::of(&gravity, gyro_in_body_radps);
    let tilt_rates: Vec<Option<f64>> = steps
        .iter()
        .map(|step| tilt.mean(step.t_start_s - TILT_MARGIN_S, step.t_end_s + TILT_MARGIN_S))
        .collect();
    let bouts = bout_ranges(steps);
    let mut turned_over = vec![false; steps.len()];
    for bout in &bouts {
        for idx in bout.clone() {
            let fast = tilt_rates[idx].is_some_and(|rate| rate > TILT_RATE_RADPS);
            turned_over[idx] =
                fast && gravity_drift_deg(&gravity, steps, bout, idx) > GRAVITY_DRIFT_DEG;
        }
        let n_turned = bout.clone().filter(|&idx| turned_over[idx]).count();
        let mut durations_s: Vec<f64> = steps[bout.clone()].iter().map(Step::duration_s).collect();
        let running = crate::base::stats::median(&mut durations_s)
            .is_some_and(|median_s| median_s < MIN_FIGURE_EIGHT_STEP_S);
        turned_over[bout.clone()].fill(2 * n_turned >= bout.len() && !running);
    }
    let left_out: Vec<usize> = (0..steps.len()).filter(|&idx| turned_over[idx]).collect();
    let (Some(&first), Some(&last)) = (left_out.first(), left_out.last()) else {
        return all;
    };
    let mut rates: Vec<f64> = left_out.iter().filter_map(|&idx| tilt_rates[idx]).collect();
    rates.sort_by(f64::total_cmp);
    Walking {
        steps: steps
            .iter()
            .zip(&turned_over)
            .filter(|(_, &out)| !out)
            .map(|(step, _)| *step)
            .collect(),
        n_left_out: left_out.len(),
        left_out_span_s: Some((steps[first].t_start_s, steps[last].t_end_s)),
        left_out_tilt_rate_radps: rates.get(rates.len() / 2).copied(),
    }
}

/// The mean direction of the specific force over any time window, from prefix sums of
/// its unit vectors (in the phone, gravity dominates it once averaged).
struct GravityDirection<'a> {
    t_s: &'a [f64],
    prefix: Vec<Vector3<f64>>,
}

impl<'a> GravityDirection<'a> {
    fn of(acc: &'a Stream<Vector3<f64>>) -> Self {
        let mut prefix = Vec::with_capacity(acc.len() + 1);
        let mut sum = Vector3::zeros();
        prefix.push(sum);
        for value in &acc.values {
            if let Some(unit) = value
                .try_normalize(1e-6)
                .filter(|unit| unit.iter().all(|c| c.is_finite()))
            {
                sum += unit;
            }
            prefix.push(sum);
        }
        GravityDirection {
            t_s: &acc.t_s,
            prefix,
        }
    }

    /// Whether the samples reach from `start_s` to `end_s`.
    fn covers(&self, start_s: f64, end_s: f64) -> bool {
        matches!((self.t_s.first(), self.t_s.last()), (Some(&first_s), Some(&last_s)) if first_s <= start_s && end_s <= last_s)
    }

    /// The unit mean direction over `[start_s, end_s)`, `None` without samples.
    fn mean(&self, start_s: f64, end_s: f64) -> Option<Vector3<f64>> {
        let first = self.t_s.partition_point(|&t| t < start_s);
        let last = self.t_s.partition_point(|&t| t < end_s);
        self.mean_of(first, last)
    }

    /// The unit mean direction over the samples `first..last`.
    fn mean_of(&self, first: usize, last: usize) -> Option<Vector3<f64>> {
        if last <= first || last >= self.prefix.len() {
            return None;
        }
        (self.prefix[last] - self.prefix[first]).try_normalize(1e-9)
    }
}

/// The gyro's rate about the horizontal axes, `|ω − (ω·ĝ) ĝ|` with `ĝ` gravity's mean
/// direction within [`GRAVITY_HALF_WINDOW_S`] of each sample, as prefix sums over the
/// gyro's samples, so that any window's mean is two searches (one pass over the log,
/// where a search per sample and step cost a simulated hour 30 ms).
struct TiltRate<'a> {
    t_s: &'a [f64],
    /// Sums of the finite tilt rates and their count, before each sample.
    prefix: Vec<(f64, usize)>,
}

impl<'a> TiltRate<'a> {
    fn of(gravity: &GravityDirection, gyro: &'a Stream<Vector3<f64>>) -> Self {
        let mut prefix = Vec::with_capacity(gyro.len() + 1);
        let (mut sum, mut n) = (0.0, 0usize);
        prefix.push((sum, n));
        // Both streams are in time order: the window's ends only move forward.
        let (mut first, mut last) = (0usize, 0usize);
        for (&t_s, rate) in gyro.t_s.iter().zip(&gyro.values) {
            while first < gravity.t_s.len() && gravity.t_s[first] < t_s - GRAVITY_HALF_WINDOW_S {
                first += 1;
            }
            last = last.max(first);
            while last < gravity.t_s.len() && gravity.t_s[last] < t_s + GRAVITY_HALF_WINDOW_S {
                last += 1;
            }
            if let Some(down) = gravity.mean_of(first, last) {
                let tilt = (rate - down * rate.dot(&down)).norm();
                if tilt.is_finite() {
                    sum += tilt;
                    n += 1;
                }
            }
            prefix.push((sum, n));
        }
        TiltRate {
            t_s: &gyro.t_s,
            prefix,
        }
    }

    /// The mean tilt rate over `[start_s, end_s)` (rad/s), `None` without samples.
    fn mean(&self, start_s: f64, end_s: f64) -> Option<f64> {
        let first = self.t_s.partition_point(|&t| t < start_s);
        let last = self.t_s.partition_point(|&t| t < end_s).max(first);
        let (sum, n) = (
            self.prefix[last].0 - self.prefix[first].0,
            self.prefix[last].1 - self.prefix[first].1,
        );
        (n > 0).then(|| sum / n as f64)
    }
}

/// The angle between gravity's mean direction over the stride (two steps' time) before
/// step `idx` and over the stride from it (degrees). The stride is the two steps from
/// `idx` where the bout has them, else the two before, else twice the step.
fn gravity_drift_deg(
    gravity: &GravityDirection,
    steps: &[Step],
    bout: &std::ops::Range<usize>,
    idx: usize,
) -> f64 {
    let start_s = steps[idx].t_start_s;
    let stride_s = if idx + 2 <= bout.end {
        steps[idx + 1].t_end_s - start_s
    } else if idx >= bout.start + 2 {
        start_s - steps[idx - 2].t_start_s
    } else {
        2.0 * steps[idx].duration_s()
    };
    // A window cut short by the recording's ends is no stride: no drift is seen there.
    if !gravity.covers(start_s - stride_s, start_s + stride_s) {
        return 0.0;
    }
    match (
        gravity.mean(start_s - stride_s, start_s),
        gravity.mean(start_s, start_s + stride_s),
    ) {
        (Some(before), Some(after)) => before.dot(&after).clamp(-1.0, 1.0).acos().to_degrees(),
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::STANDARD_GRAVITY_MPS2;
    use crate::pdr::steps::{detect_steps, StepOptions};
    use nalgebra::Rotation3;
    use std::f64::consts::TAU;

    const RATE_HZ: f64 = 100.0;

    /// 20 s of a phone whose attitude (world to body) is `attitude(t)` while a bounce of
    /// 2.5 m/s² at 1.8 Hz runs along the vertical: the specific force and the gyro's
    /// rates in the body, from the attitude's change between samples.
    fn motion(
        attitude: impl Fn(f64) -> Rotation3<f64>,
    ) -> (Stream<Vector3<f64>>, Stream<Vector3<f64>>) {
        motion_at(1.8, attitude)
    }

    /// [`motion`] with the bounce at `bounce_hz`.
    fn motion_at(
        bounce_hz: f64,
        attitude: impl Fn(f64) -> Rotation3<f64>,
    ) -> (Stream<Vector3<f64>>, Stream<Vector3<f64>>) {
        let (mut acc, mut gyro) = (Stream::default(), Stream::default());
        let dt_s = 1.0 / RATE_HZ;
        for idx in 0..(20.0 * RATE_HZ) as usize {
            let t_s = idx as f64 * dt_s;
            let bounce = 2.5 * (TAU * bounce_hz * t_s).sin();
            // z down: a level phone at rest reads z = −g.
            let force_in_world = Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2 - bounce);
            let body_from_world = attitude(t_s);
            acc.push(t_s, body_from_world * force_in_world);
            let turn = attitude(t_s + dt_s) * body_from_world.inverse();
            gyro.push(t_s, turn.scaled_axis() / dt_s);
        }
        (acc, gyro)
    }

    /// A phone turned through every orientation, 1-3 rad/s about changing axes.
    fn figure_eight(t: f64) -> Rotation3<f64> {
        Rotation3::from_euler_angles(
            1.5 * (TAU * 0.4 * t).sin(),
            1.2 * (TAU * 0.27 * t + 1.0).sin(),
            2.0 * (TAU * 0.2 * t).sin(),
        )
    }

    fn walking_of(acc: &Stream<Vector3<f64>>, gyro: &Stream<Vector3<f64>>) -> (usize, Walking) {
        let detection = detect_steps(acc, &StepOptions::default());
        let n_detected = detection.steps.len();
        (n_detected, walking_steps(&detection.steps, acc, gyro))
    }

    #[test]
    fn a_phone_carried_in_hand_keeps_every_step() {
        // Turning a corner (0.3 rad/s of yaw) with the hand nodding 3° at each step.
        let (acc, gyro) = motion(|t| {
            Rotation3::from_euler_angles(0.0, 3f64.to_radians() * (TAU * 1.8 * t).sin(), 0.3 * t)
        });
        let (n_detected, walking) = walking_of(&acc, &gyro);
        assert!(n_detected >= 30, "{n_detected} steps");
        assert_eq!(walking.n_left_out, 0);
        assert_eq!(walking.steps.len(), n_detected);
        assert!(walking.note().is_none());
    }

    #[test]
    fn a_swinging_arm_keeps_every_step() {
        // The phone in a swinging hand: ±40° of pitch once per stride (two steps), a
        // tilt rate of 2.5 rad/s on average that comes back with each stride.
        let (acc, gyro) = motion(|t| {
            Rotation3::from_euler_angles(0.0, 40f64.to_radians() * (TAU * 0.9 * t).sin(), 0.1 * t)
        });
        let (n_detected, walking) = walking_of(&acc, &gyro);
        assert!(n_detected >= 15, "{n_detected} steps");
        assert_eq!(walking.n_left_out, 0, "{walking:?}");
    }

    #[test]
    fn a_calibration_figure_eight_is_not_walking() {
        // The phone turned through every orientation, 1-3 rad/s about changing axes.
        let (acc, gyro) = motion(figure_eight);
        let (n_detected, walking) = walking_of(&acc, &gyro);
        assert!(n_detected >= 15, "{n_detected} steps");
        assert_eq!(walking.n_left_out, n_detected, "{walking:?}");
        assert!(walking.steps.is_empty());
        let note = walking.note().expect("a note");
        assert!(note.contains("turned over"), "{note}");
        assert!(walking
            .left_out_tilt_rate_radps
            .is_some_and(|rate| rate > TILT_RATE_RADPS));
    }

    #[test]
    fn a_runner_s_phone_turning_as_fast_keeps_every_step() {
        // The figure eight's turning, at a runner's 2.7 steps per second.
        let (acc, gyro) = motion_at(2.7, figure_eight);
        let (n_detected, walking) = walking_of(&acc, &gyro);
        assert!(n_detected >= 30, "{n_detected} steps");
        assert_eq!(walking.n_left_out, 0, "{walking:?}");
    }

    #[test]
    fn without_a_gyroscope_nothing_is_left_out() {
        let (acc, _) = motion(figure_eight);
        let (n_detected, walking) = walking_of(&acc, &Stream::default());
        assert_eq!(walking.steps.len(), n_detected);
    }
}
