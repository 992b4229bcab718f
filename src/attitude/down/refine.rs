//! Down again without the gyroscope's bias: the bias its turns show against the
//! two-pass down ([`super::gyro_bias`]), removed, and down followed over a longer time
//! constant, which averages a swinging arm's or a walker's periodic accelerations away
//! (the accelerometer's mean over whole swings is gravity's: the body's velocity comes
//! back to itself). [`super::estimate_gravity`] keeps it where the two passes then
//! agree clearly better.

use nalgebra::Vector3;

use super::gyro_bias::gyro_bias_radps;
use super::{fuse_passes, pass, Direction, Motion};
use crate::io::recording::Stream;

/// Down followed the gyroscope for this many times the asked time constant once the
/// gyroscope's bias is removed ([`refine_without_gyro_bias`]): on the independent
/// generator's swinging phone, 10 s took the exported calibration from 5 to 14 seeds of
/// 20 within 1.3 × the true one's heading error (18 once the bias was seen over 15 s
/// windows), the phone held in front from 17 to 19 and moved by the hand from 17 to 18
/// (`tests/independent.rs`); 3 s and 30 s did less for the swing (10 and 12 of 20, with
/// 3 s windows).
pub(super) const LONG_TAU_FACTOR: f64 = 10.0;

/// How much lower the passes' median disagreement must be for the refined down to be
/// kept, as for a setting other than the plain one in [`super::best_setting`].
pub(super) const CLEARLY_BETTER: f64 = 2.0;

/// Rounds of estimating the bias from down and down again without it.
const BIAS_ROUNDS: usize = 3;

/// How down was smoothed: the time constant, and the gyroscope's bias removed first.
pub(super) struct Smoothing {
    pub(super) tau_s: f64,
    pub(super) gyro_bias_radps: Option<[f64; 3]>,
}

/// Down again with the gyroscope's bias removed and the time constant `long_tau_s`.
pub(super) struct Refined {
    pub(super) smoothing: Smoothing,
    pub(super) specific_force_mps2: Stream<Vector3<f64>>,
    pub(super) tilt_sigma_rad: Stream<f64>,
}

/// Down without the gyroscope's bias: the bias the gyroscope's turns show against
/// `fused` ([`gyro_bias_radps`]), down again by two passes with it removed and the time
/// constant `long_tau_s`, and again, [`BIAS_ROUNDS`] times (each down is a better
/// reference for the bias than the last). `None` where the turns show no bias.
pub(super) fn refine_without_gyro_bias(
    (acc, gyro): (&Stream<Vector3<f64>>, &Stream<Vector3<f64>>),
    (gyro_scale, long_tau_s): (f64, f64),
    motion: &Motion,
    fused: &Stream<Vector3<f64>>,
) -> Option<Refined> {
    let mut bias = Vector3::zeros();
    let mut refined: Option<Refined> = None;
    for _ in 0..BIAS_ROUNDS {
        let reference = refined
            .as_ref()
            .map_or(fused, |refined| &refined.specific_force_mps2);
        bias += gyro_bias_radps(reference, gyro, gyro_scale, bias)?;
        let run = |direction| {
            pass(
                acc,
                gyro,
                (gyro_scale, bias, long_tau_s),
                direction,
                motion,
                f64::INFINITY,
            )
            .map(|(downs, _)| downs)
            .unwrap_or_default()
        };
        let (specific_force_mps2, tilt_sigma_rad) = fuse_passes(
            &acc.t_s,
            (&run(Direction::Forward), &run(Direction::Backward)),
        );
        if specific_force_mps2.is_empty() {
            return None;
        }
        refined = Some(Refined {
            smoothing: Smoothing {
                tau_s: long_tau_s,
                gyro_bias_radps: Some(bias.into()),
            },
            specific_force_mps2,
            tilt_sigma_rad,
        });
    }
    refined
}
