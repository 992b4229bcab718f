//! Each compass sample paired with the attitude and the battery current at its time, and
//! a compass's calibration (in force, or as a parameter file sets it) in one form; and
//! `InForce`, the heading the vehicle flies with, for the heading comparison's row.

use nalgebra::{Matrix3, Rotation3, Vector3};

use crate::fit::autopilot_aided::AidedSample;
use crate::io::autopilot::ardupilot::ArduPilotCompass;
use crate::io::autopilot::px4::Px4Compass;
use crate::io::autopilot::{Autopilot, AutopilotLog, CompassLog};
use crate::io::recording::{Attitude, Stream};

/// ArduPilot's compass unit, mG, in µT.
pub(super) const UT_PER_MG: f64 = 0.1;
/// The longest time (s) between a compass sample and the attitude it is paired with.
const MAX_ATTITUDE_GAP_S: f64 = 0.1;
/// The longest time (s) between a compass sample and the current it is paired with.
const MAX_CURRENT_GAP_S: f64 = 0.5;

/// The index of the sample of `times` nearest to `t_s`, within `max_gap_s`.
pub(super) fn nearest(times: &[f64], t_s: f64, max_gap_s: f64) -> Option<usize> {
    let after = times.partition_point(|&t| t < t_s);
    [after.checked_sub(1), Some(after)]
        .into_iter()
        .flatten()
        .filter(|&idx| idx < times.len())
        .min_by(|&a, &b| (times[a] - t_s).abs().total_cmp(&(times[b] - t_s).abs()))
        .filter(|&idx| (times[idx] - t_s).abs() <= max_gap_s)
}

/// Pairs each raw sample with the attitude nearest in time (within 0.1 s) and the
/// battery current (within 0.5 s, else 0).
pub(super) fn aided_samples(
    raw_ut: &Stream<Vector3<f64>>,
    attitude: &Stream<Attitude>,
    current_a: &Stream<f64>,
) -> Vec<AidedSample> {
    let mut samples = Vec::with_capacity(raw_ut.len());
    for (&t_s, raw) in raw_ut.t_s.iter().zip(&raw_ut.values) {
        let Some(idx) = nearest(&attitude.t_s, t_s, MAX_ATTITUDE_GAP_S) else {
            continue;
        };
        let Attitude {
            roll_rad,
            pitch_rad,
            yaw_rad: Some(yaw_rad),
        } = attitude.values[idx]
        else {
            continue;
        };
        let current_a = nearest(&current_a.t_s, t_s, MAX_CURRENT_GAP_S)
            .map_or(0.0, |idx| current_a.values[idx]);
        samples.push(AidedSample {
            t_s,
            raw: raw / UT_PER_MG,
            body_to_ned: Rotation3::from_euler_angles(roll_rad, pitch_rad, yaw_rad),
            current_a,
        });
    }
    samples
}

/// A correction in ArduPilot's form with nothing in force: the raw field.
pub(super) fn identity(instance: usize) -> ArduPilotCompass {
    ArduPilotCompass {
        instance,
        offsets_mg: Vector3::zeros(),
        soft_iron: Matrix3::identity(),
        scale: 1.0,
        motor_mg_per_a: Vector3::zeros(),
    }
}

/// A compass's calibration in `params`, in body axes and ArduPilot's form (PX4's turned
/// into it, [`Px4Compass::body_form`]); `None` without the offsets (ArduPilot).
pub(super) fn in_body_form(
    compass: &CompassLog,
    params: &dyn Fn(&str) -> Option<f64>,
) -> Option<ArduPilotCompass> {
    match compass.px4_slot {
        Some((slot, rotation)) => {
            let (soft_iron, offsets_mg) =
                Px4Compass::from_params(params, slot, rotation).body_form();
            Some(ArduPilotCompass {
                instance: compass.instance,
                offsets_mg,
                soft_iron,
                scale: 1.0,
                motor_mg_per_a: Vector3::zeros(),
            })
        }
        None => ArduPilotCompass::from_params(params, compass.instance),
    }
}

/// The calibration in force of the compass whose raw field is a recording's
/// magnetometer, applied as the autopilot applies it (the motor compensation at the
/// battery current of each sample): the field the vehicle's own heading is made from.
pub struct InForce<'a> {
    autopilot: Autopilot,
    correction: ArduPilotCompass,
    current_a: &'a Stream<f64>,
}

impl<'a> InForce<'a> {
    /// The main compass's calibration in force, where `mag_in_body_ut` is that
    /// compass's raw field (not, say, several logs' fields merged) and the log has its
    /// parameters.
    pub fn of(log: &'a AutopilotLog, mag_in_body_ut: &Stream<Vector3<f64>>) -> Option<InForce<'a>> {
        let compass = log.compasses.get(log.main_compass?)?;
        // The same samples bit for bit (a NaN equals itself here).
        let raw = compass.raw_in_body_ut.as_ref()?;
        fn bits(stream: &Stream<Vector3<f64>>) -> impl Iterator<Item = u64> + '_ {
            let values = stream.values.iter().flat_map(|value| value.iter());
            stream.t_s.iter().chain(values).map(|value| value.to_bits())
        }
        if raw.len() != mag_in_body_ut.len() || !bits(raw).eq(bits(mag_in_body_ut)) {
            return None;
        }
        let lookup = |name: &str| log.param(name).filter(|value| value.is_finite());
        Some(InForce {
            autopilot: log.autopilot,
            correction: in_body_form(compass, &lookup)?,
            current_a: &log.current_a,
        })
    }

    /// "ArduPilot" or "PX4".
    pub fn autopilot(&self) -> &'static str {
        self.autopilot.name()
    }

    /// The corrected field (body axes, µT) of a raw sample at `t_s`.
    pub fn corrected_ut(&self, t_s: f64, raw_ut: Vector3<f64>) -> Vector3<f64> {
        let current_a = nearest(&self.current_a.t_s, t_s, MAX_CURRENT_GAP_S)
            .map_or(0.0, |idx| self.current_a.values[idx]);
        self.correction.apply(raw_ut / UT_PER_MG, current_a) * UT_PER_MG
    }
}
