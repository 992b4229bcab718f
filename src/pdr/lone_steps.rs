//! Steps that are not gait: a bout of one or two steps.
//!
//! The detector of `steps.rs` counts every bounce of `|f|`, and a walker who stops at a
//! place (a landmark, a door, a shelf) and turns about there shifts the feet a few times,
//! each alone, seconds apart: on the twelve IPIN 2023 walks, where the walkers stand
//! 30-40 s at the turn-about landmark, 3-11 such "steps" per walk, 1.4-5.3 m of track
//! where the walker moved nowhere (the landmark is the same before and after). Weinberg's
//! model gives each a walking step's length, as it knows only the bounce.
//!
//! Walking is periodic: a bout (steps with no pause longer than the detector's
//! `max_step_s`, 1.5 s, between their starts) of walking from one place to another has
//! at least [`MIN_GAIT_BOUT_STEPS`] steps, as a step counter asks of a run before it
//! counts it. A shorter bout is left out of the track whole and said in a note; its
//! displacement is at most a step or two (under a metre), where leaving in a shuffle
//! in place adds as much that never happened.
//!
//! Only in a log that walks: where the bouts of gait hold under half of the steps (a
//! car's vibrations at 1 Hz, every "step" alone), nothing is left out, and the dead
//! reckoning says what it says of any log that is not a walk.
//!
//! Limits: two real steps taken alone (a step aside) are left out too.

use super::steps::{bout_ranges, Step};

/// The fewest steps of a bout that the track takes as walking.
pub const MIN_GAIT_BOUT_STEPS: usize = 3;

/// The steps of the bouts of gait, and how many were left out.
#[derive(Debug, Clone, PartialEq)]
pub struct Gait {
    pub steps: Vec<Step>,
    pub n_left_out: usize,
    pub n_bouts_left_out: usize,
}

impl Gait {
    /// A note for the user, when steps were left out.
    pub fn note(&self) -> Option<String> {
        (self.n_left_out > 0).then(|| {
            format!(
                "{} {} in {} {} of fewer than {MIN_GAIT_BOUT_STEPS} steps (feet shifted while standing or turning about) {} left out of the track: they are not walking from one place to another.",
                self.n_left_out,
                crate::base::words::plural(self.n_left_out, "step", "steps"),
                self.n_bouts_left_out,
                crate::base::words::plural(self.n_bouts_left_out, "bout", "bouts"),
                if self.n_left_out == 1 { "was" } else { "were" },
            )
        })
    }
}

/// Leaves out the steps of bouts shorter than [`MIN_GAIT_BOUT_STEPS`], where the bouts
/// of gait hold at least half of the steps.
pub fn gait_steps(steps: &[Step]) -> Gait {
    let mut kept = Vec::with_capacity(steps.len());
    let (mut n_left_out, mut n_bouts_left_out) = (0, 0);
    for bout in bout_ranges(steps) {
        if bout.len() >= MIN_GAIT_BOUT_STEPS {
            kept.extend_from_slice(&steps[bout]);
        } else {
            n_left_out += bout.len();
            n_bouts_left_out += 1;
        }
    }
    if 2 * kept.len() < steps.len() {
        return Gait {
            steps: steps.to_vec(),
            n_left_out: 0,
            n_bouts_left_out: 0,
        };
    }
    Gait {
        steps: kept,
        n_left_out,
        n_bouts_left_out,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step(t_start_s: f64, duration_s: f64, ends_bout: bool) -> Step {
        Step {
            t_start_s,
            t_end_s: t_start_s + duration_s,
            t_peak_s: t_start_s + 0.5 * duration_s,
            frequency_hz: 1.0 / duration_s,
            variance_mps2_sq: 1.0,
            a_max_mps2: 11.0,
            a_min_mps2: 8.5,
            ends_bout,
        }
    }

    #[test]
    fn lone_shuffles_between_walks_are_left_out_and_said() {
        // A walk of five steps, a lone step 10 s later, two steps together, a walk of three.
        let mut steps: Vec<Step> = (0..5)
            .map(|i| step(0.6 * f64::from(i), 0.6, i == 4))
            .collect();
        steps.push(step(13.0, 0.6, true));
        steps.push(step(20.0, 0.8, false));
        steps.push(step(20.8, 0.8, true));
        steps.extend((0..3).map(|i| step(30.0 + 0.6 * f64::from(i), 0.6, i == 2)));
        let gait = gait_steps(&steps);
        let kept: Vec<f64> = gait.steps.iter().map(|s| s.t_start_s).collect();
        assert_eq!(kept.len(), 8);
        assert!(kept.iter().all(|&t| !(3.0..30.0).contains(&t)), "{kept:?}");
        assert_eq!((gait.n_left_out, gait.n_bouts_left_out), (3, 2));
        assert_eq!(
            gait.note().as_deref(),
            Some(
                "3 steps in 2 bouts of fewer than 3 steps (feet shifted while standing or turning about) were left out of the track: they are not walking from one place to another."
            )
        );
    }

    #[test]
    fn a_log_of_lone_steps_is_not_a_walk_and_keeps_them_all() {
        // A car's vibrations at 1 Hz: every "step" alone.
        let steps: Vec<Step> = (0..30)
            .map(|i| step(3.0 * f64::from(i), 1.0, true))
            .collect();
        let gait = gait_steps(&steps);
        assert_eq!(gait.steps, steps);
        assert_eq!(gait.note(), None);
    }

    #[test]
    fn a_walk_without_pauses_keeps_every_step() {
        let steps: Vec<Step> = (0..40)
            .map(|i| step(0.55 * f64::from(i), 0.55, i == 39))
            .collect();
        let gait = gait_steps(&steps);
        assert_eq!(gait.steps, steps);
        assert_eq!(gait.note(), None);
    }
}
