//! A causal attitude filter: the gyroscope carries the attitude, the accelerometer
//! corrects its tilt and the calibrated magnetometer its heading, each only when it can
//! be trusted.
//!
//! Both papers point here: the 2007 network takes a gyro heading as an input, and the
//! PDR paper (Chen et al.) smooths the compass's residual error with a Kalman filter.
//! What phones and autopilots run is a gyro-propagated attitude corrected by gravity and
//! the field (Android's rotation vector, xioTechnologies' Fusion AHRS, PX4's EKF2); this
//! is one, an error-state Kalman filter ([`eskf`]) with its gates ([`gates`]):
//!
//! - the **gyroscope's bias** is a state, learnt from the field's heading and from the
//!   rate itself while the body is at rest; gravity does not move it (it is fused with
//!   the bias as a *considered* state, Schmidt's filter): a bias learnt from a walking
//!   body's accelerations turned the heading by tens of degrees in two minutes on the
//!   shared attitude trials. How far the bias may be from zero at the start is what
//!   the log says of the gyroscope ([`AttitudeOptions::for_gyro`]): a raw one's up to
//!   about 0.6°/s, which the field then learns (the independent generator's walks drift
//!   1.2 % of their length over a ten-minute outage without that learning, 0.8 % with);
//!   one whose bias the OS removed (Android's `TYPE_GYROSCOPE`) only about 0.1°/s, so
//!   that a disturbed field passing the gates cannot teach it a false one;
//! - the **accelerometer** corrects the tilt with a noise that grows with the body's own
//!   acceleration (how far the specific force's magnitude is from gravity's), and not at
//!   all when its direction is further from the predicted down than that noise allows;
//! - the **magnetometer** corrects the yaw alone, and only while the field's magnitude
//!   and dip are the undisturbed field's ([`gates::MagneticGate`]) and its direction in
//!   the navigation frame holds over a second and a half ([`gates::QuasiStaticField`]):
//!   iron passed while walking turns it; a heading that the
//!   field contradicts for longer than [`RECOVERY_S`] while it looks undisturbed is
//!   re-aimed at it (the filter, not the field, was wrong); a yaw seeded by a field the
//!   gate calls disturbed is unknown, so the first field it passes sets it;
//! - every output carries the yaw's 1σ, which grows while the field is refused, with
//!   the error that a field passing the gates still carries added
//!   ([`gates::FieldErrorLevel`]: the filter's own variance counts each field sample's
//!   error as independent of the next, which a disturbance's is not).
//!
//! It runs sample by sample in time order ([`filter::AttitudeFilter`]), so the same code
//! serves a file ([`estimate_attitude`]) and a live stream; nothing in it looks ahead.
//! From a file, only the field's sample interval and the gyroscope's gap limit are read
//! off the whole log ([`StreamTiming::of`]); a live caller states them.

pub mod compass_heading;
pub mod down;
pub mod eskf;
pub mod filter;
pub mod gates;
pub mod smoother;
pub mod tilt;

use nalgebra::Vector3;
use serde::Serialize;

use crate::io::recording::{GyroBias, Stream};
use eskf::NoiseModel;
pub use filter::{AttitudeFilter, StreamTiming};
use gates::FieldReference;

/// A heading the field contradicts (beyond the gate) for this long (s), while its
/// magnitude and dip look undisturbed, is re-aimed at the field.
pub const RECOVERY_S: f64 = 5.0;
/// Gyroscope samples further apart than this (s), or than three of the log's typical
/// intervals where that is longer (a log of per-second means), are a gap: the turn
/// across it is not integrated, and the yaw's variance grows by [`GAP_RATE_RADPS`] over
/// it.
pub const MAX_GYRO_GAP_S: f64 = 0.5;
/// Accelerometer samples within this time (s) of a block's first are fused as one.
pub const GRAVITY_BLOCK_S: f64 = 0.02;
/// The rate assumed unseen across a gap, for the variance only (rad/s).
pub const GAP_RATE_RADPS: f64 = 1.0;

/// The filter's tuning. The defaults are those of a phone-grade MEMS unit with the
/// errors a hand-held device adds (see each field).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeOptions {
    pub noise: NoiseModel,
    /// The magnetic heading's noise density (rad·√s): one sample's 1σ is this over the
    /// root of the field's sample interval, so that a second of field corrects as much
    /// at 10 Hz as at 100 Hz. The field's errors (a calibration's residue, iron passed
    /// too weakly to trip the gate) are not independent from sample to sample, so this
    /// is far above the sensor's noise: it makes the heading follow the field over tens
    /// of seconds and the gyroscope within them.
    pub heading_noise_rad_sqrt_s: f64,
    /// 1σ of the specific force's direction as gravity's (rad) when the body does not
    /// accelerate; the acceleration's share is added to it.
    pub gravity_sigma_rad: f64,
    /// Initial 1σ of the gyroscope's bias (rad/s).
    pub initial_bias_sigma_radps: f64,
    /// Whether the field's heading corrects the bias (else only rest does, and the field
    /// fuses the bias as a considered state).
    pub field_corrects_bias: bool,
    /// The body counts as at rest while its bias-corrected rate stays under this (rad/s)
    /// and its specific force within [`AttitudeOptions::rest_acceleration_mps2`] of
    /// gravity for [`AttitudeOptions::rest_hold_s`].
    pub rest_rate_radps: f64,
    pub rest_acceleration_mps2: f64,
    pub rest_hold_s: f64,
}

impl Default for AttitudeOptions {
    fn default() -> Self {
        AttitudeOptions {
            noise: NoiseModel {
                // 0.3°/√s: far above a phone gyroscope's noise (about 0.01°/√s), for the
                // errors of timing and of g-sensitivity a hand adds.
                gyro_arw_rad_per_sqrt_s: 0.005,
                // 1 % of the rate: a MEMS gyroscope's scale factor and axis misalignment.
                gyro_scale_error: 0.01,
                // The bias wanders by about 0.2°/s over an hour of warming up.
                bias_walk_radps_per_sqrt_s: 1e-5,
            },
            heading_noise_rad_sqrt_s: 0.05,
            gravity_sigma_rad: 0.02,
            initial_bias_sigma_radps: RAW_BIAS_SIGMA_RADPS,
            field_corrects_bias: true,
            rest_rate_radps: 0.02,
            rest_acceleration_mps2: 0.15,
            rest_hold_s: 0.5,
        }
    }
}

/// Initial 1σ of a raw gyroscope's bias (rad/s, about 0.6°/s): a MEMS gyroscope's
/// turn-on bias, which rest and the field then learn.
pub const RAW_BIAS_SIGMA_RADPS: f64 = 0.01;

/// Initial 1σ of the bias left once the OS has removed its own estimate (rad/s, about
/// 0.1°/s). A prior this tight keeps the field from teaching the filter a bias that is
/// the disturbance's: on the shared attitude trials (already bias-free) the raw prior
/// turned 4.5° of heading error into 16.6° in a pocket walked past iron.
pub const REMOVED_BIAS_SIGMA_RADPS: f64 = 0.002;

impl AttitudeOptions {
    /// The defaults, with the bias prior of a gyroscope as the log says it is.
    pub fn for_gyro(gyro_bias: GyroBias) -> AttitudeOptions {
        AttitudeOptions {
            initial_bias_sigma_radps: match gyro_bias {
                GyroBias::Unknown => RAW_BIAS_SIGMA_RADPS,
                GyroBias::RemovedByDevice => REMOVED_BIAS_SIGMA_RADPS,
            },
            ..AttitudeOptions::default()
        }
    }
}

/// The attitude after one gyroscope sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AttitudeEstimate {
    /// Body x-forward, y-right, z-down relative to north-east-down (ZYX Euler angles).
    pub roll_rad: f64,
    pub pitch_rad: f64,
    /// Clockwise from magnetic north, in (−π, π].
    pub yaw_rad: f64,
    pub yaw_sigma_rad: f64,
    /// Whether the last magnetometer sample corrected the heading.
    pub field_used: bool,
}

/// What the filter did over a log.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AttitudeSummary {
    pub n_gyro_samples: usize,
    pub n_gyro_gaps: usize,
    pub n_gravity_fused: usize,
    pub n_gravity_refused: usize,
    pub n_field_fused: usize,
    /// Field samples refused because their magnitude or dip said "disturbed" (or the
    /// gate still held them back after a disturbance).
    pub n_field_disturbed: usize,
    /// Field samples within the gate's tolerances whose direction in the navigation
    /// frame was turning (the quasi-static test).
    pub n_field_turning: usize,
    /// Field samples that looked undisturbed but contradicted the heading.
    pub n_field_contradicting: usize,
    pub n_recoveries: usize,
    /// Tilts re-levelled on gravity after [`RECOVERY_S`] of contradicting it.
    pub n_tilt_recoveries: usize,
    pub n_rest_updates: usize,
    /// The prior 1σ of the gyroscope's bias (rad/s): [`AttitudeOptions::initial_bias_sigma_radps`].
    pub initial_gyro_bias_sigma_radps: f64,
    /// The gyroscope's bias at the end (rad/s, body axes).
    pub final_gyro_bias_radps: [f64; 3],
    /// Its 1σ (rad/s, body axes).
    pub final_gyro_bias_sigma_radps: [f64; 3],
    pub field_reference: Option<FieldReference>,
}

/// An attitude per gyroscope sample, and what the filter did.
#[derive(Debug, Clone, PartialEq)]
pub struct AttitudeTrack {
    pub attitude: Stream<AttitudeEstimate>,
    pub summary: AttitudeSummary,
}

/// Why there is no attitude.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum AttitudeError {
    #[error("the log has no gyroscope: an attitude filter needs one (record the gyroscope too)")]
    NoGyroscope,
    #[error(
        "the log has no accelerometer: the filter cannot tell down (record the accelerometer too)"
    )]
    NoAccelerometer,
}

/// The sensor streams the filter reads, in body axes: specific force (m/s²), rate
/// (rad/s) and the **calibrated** field (µT; empty for a relative heading).
#[derive(Debug, Clone, Copy)]
pub struct Sensors<'a> {
    pub acc_in_body_mps2: &'a Stream<Vector3<f64>>,
    pub gyro_in_body_radps: &'a Stream<Vector3<f64>>,
    pub field_in_body_ut: &'a Stream<Vector3<f64>>,
}

/// Runs the filter over the streams in time order. Without a field (or a reference for
/// it) the yaw is relative to the first sample's and its σ grows without bound.
pub fn estimate_attitude(
    sensors: Sensors<'_>,
    reference: Option<FieldReference>,
    options: &AttitudeOptions,
) -> Result<AttitudeTrack, AttitudeError> {
    if sensors.gyro_in_body_radps.is_empty() {
        return Err(AttitudeError::NoGyroscope);
    }
    if sensors.acc_in_body_mps2.is_empty() {
        return Err(AttitudeError::NoAccelerometer);
    }
    let mut filter = AttitudeFilter::new(reference, StreamTiming::of(&sensors), options);
    let n_gyro = sensors.gyro_in_body_radps.len();
    let mut attitude = Stream {
        t_s: Vec::with_capacity(n_gyro),
        values: Vec::with_capacity(n_gyro),
    };
    let mut cursors = [0usize; 3];
    while let Some((which, t_s)) = next(&sensors, &cursors) {
        match which {
            Next::Gyro => {
                let rate = sensors.gyro_in_body_radps.values[cursors[0]];
                cursors[0] += 1;
                if let Some(estimate) = filter.gyro(t_s, rate) {
                    attitude.push(t_s, estimate);
                }
            }
            Next::Acc => {
                let force = sensors.acc_in_body_mps2.values[cursors[1]];
                cursors[1] += 1;
                filter.acc(t_s, force);
            }
            Next::Field => {
                let field = sensors.field_in_body_ut.values[cursors[2]];
                cursors[2] += 1;
                filter.field(t_s, field);
            }
        }
    }
    Ok(AttitudeTrack {
        attitude,
        summary: filter.summary(),
    })
}

/// Which stream the next sample comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Next {
    Gyro,
    Acc,
    Field,
}

/// The earliest unread sample, gyroscope first at equal times (the attitude is carried
/// to a time before it is corrected there).
fn next(sensors: &Sensors<'_>, cursors: &[usize; 3]) -> Option<(Next, f64)> {
    let times = [
        (Next::Gyro, &sensors.gyro_in_body_radps.t_s),
        (Next::Acc, &sensors.acc_in_body_mps2.t_s),
        (Next::Field, &sensors.field_in_body_ut.t_s),
    ];
    let mut best: Option<(Next, f64)> = None;
    for (idx, (which, t_s)) in times.into_iter().enumerate() {
        if let Some(&t) = t_s.get(cursors[idx]) {
            if best.is_none_or(|(_, best_t)| t < best_t) {
                best = Some((which, t));
            }
        }
    }
    best
}
