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
//!   re-aimed at it (the filter, not the field, was wrong);
//! - every output carries the yaw's 1σ, which grows while the field is refused.
//!
//! It runs sample by sample in time order, so the same code serves a file and a live
//! stream; nothing here looks ahead.

pub mod eskf;
pub mod gates;
pub mod track;

use nalgebra::Vector3;
use serde::Serialize;

use crate::recording::{GyroBias, Stream};
use eskf::{Eskf, Fused, NoiseModel};
use gates::{dip_of, AccelerationLevel, FieldReference, MagneticGate, QuasiStaticField};

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
    /// Field samples refused because their magnitude or dip said "disturbed".
    pub n_field_disturbed: usize,
    /// Field samples that looked undisturbed but contradicted the heading.
    pub n_field_contradicting: usize,
    pub n_recoveries: usize,
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
    let mut run = Run::new(sensors, reference, *options);
    run.all();
    Ok(AttitudeTrack {
        attitude: run.output,
        summary: run.summary,
    })
}

/// Which stream the next sample comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Next {
    Gyro,
    Acc,
    Field,
}

/// One pass of the filter: the streams' cursors, the filter, its gates and its output.
struct Run<'a> {
    sensors: Sensors<'a>,
    options: AttitudeOptions,
    filter: Option<Eskf>,
    gate: Option<MagneticGate>,
    quasi_static: QuasiStaticField,
    acceleration: AccelerationLevel,
    /// The latest specific force and field, for the initial attitude.
    last_force: Option<Vector3<f64>>,
    last_field: Option<Vector3<f64>>,
    last_gyro_t_s: Option<f64>,
    /// Since when the body has looked at rest, and since when the field has contradicted
    /// the heading while looking undisturbed.
    rest_since_s: Option<f64>,
    contradicting_since_s: Option<f64>,
    field_used: bool,
    /// The accelerometer samples not fused yet: the first one's time, the sum of their
    /// unit directions in the navigation frame, how many, the largest acceleration level.
    gravity_block: Option<(f64, Vector3<f64>, usize, f64)>,
    cursors: [usize; 3],
    /// One field sample's 1σ (rad), from the noise density and the field's interval.
    heading_sigma_rad: f64,
    /// The longest gyroscope interval integrated (s).
    max_gyro_gap_s: f64,
    output: Stream<AttitudeEstimate>,
    summary: AttitudeSummary,
}

impl<'a> Run<'a> {
    fn new(
        sensors: Sensors<'a>,
        reference: Option<FieldReference>,
        options: AttitudeOptions,
    ) -> Run<'a> {
        let n_gyro = sensors.gyro_in_body_radps.len();
        Run {
            sensors,
            options,
            filter: None,
            gate: reference.map(MagneticGate::new),
            quasi_static: QuasiStaticField::default(),
            acceleration: AccelerationLevel::new(),
            last_force: None,
            last_field: None,
            last_gyro_t_s: None,
            rest_since_s: None,
            contradicting_since_s: None,
            field_used: false,
            gravity_block: None,
            cursors: [0; 3],
            heading_sigma_rad: options.heading_noise_rad_sqrt_s
                / sensors
                    .field_in_body_ut
                    .median_interval_s()
                    .unwrap_or(0.02)
                    .sqrt(),
            max_gyro_gap_s: sensors.gyro_in_body_radps.gap_limit_s(MAX_GYRO_GAP_S),
            output: Stream {
                t_s: Vec::with_capacity(n_gyro),
                values: Vec::with_capacity(n_gyro),
            },
            summary: AttitudeSummary {
                n_gyro_samples: 0,
                n_gyro_gaps: 0,
                n_gravity_fused: 0,
                n_gravity_refused: 0,
                n_field_fused: 0,
                n_field_disturbed: 0,
                n_field_contradicting: 0,
                n_recoveries: 0,
                n_rest_updates: 0,
                initial_gyro_bias_sigma_radps: options.initial_bias_sigma_radps,
                final_gyro_bias_radps: [0.0; 3],
                final_gyro_bias_sigma_radps: [0.0; 3],
                field_reference: reference,
            },
        }
    }

    /// The earliest unread sample, gyroscope first at equal times (the attitude is
    /// carried to a time before it is corrected there).
    fn next(&self) -> Option<(Next, f64)> {
        let times = [
            (Next::Gyro, &self.sensors.gyro_in_body_radps.t_s),
            (Next::Acc, &self.sensors.acc_in_body_mps2.t_s),
            (Next::Field, &self.sensors.field_in_body_ut.t_s),
        ];
        let mut best: Option<(Next, f64)> = None;
        for (idx, (which, t_s)) in times.into_iter().enumerate() {
            if let Some(&t) = t_s.get(self.cursors[idx]) {
                if best.is_none_or(|(_, best_t)| t < best_t) {
                    best = Some((which, t));
                }
            }
        }
        best
    }

    fn all(&mut self) {
        while let Some((which, t_s)) = self.next() {
            match which {
                Next::Gyro => {
                    let rate = self.sensors.gyro_in_body_radps.values[self.cursors[0]];
                    self.cursors[0] += 1;
                    self.gyro(t_s, rate);
                }
                Next::Acc => {
                    let force = self.sensors.acc_in_body_mps2.values[self.cursors[1]];
                    self.cursors[1] += 1;
                    self.acc(t_s, force);
                }
                Next::Field => {
                    let field = self.sensors.field_in_body_ut.values[self.cursors[2]];
                    self.cursors[2] += 1;
                    self.field(t_s, field);
                }
            }
        }
        if let Some(filter) = &self.filter {
            self.summary.final_gyro_bias_radps = filter.gyro_bias_radps.into();
            self.summary.final_gyro_bias_sigma_radps =
                std::array::from_fn(|axis| filter.covariance[(3 + axis, 3 + axis)].sqrt());
        }
    }

    /// The filter, started at the first gyroscope sample after a specific force (and a
    /// field, when the log has one and a reference for it) was seen.
    fn start(&mut self) {
        if self.filter.is_none() {
            let Some(force) = self.last_force else {
                return;
            };
            let wants_field = self.gate.is_some() && !self.sensors.field_in_body_ut.is_empty();
            if wants_field && self.last_field.is_none() {
                return;
            }
            let field = self.last_field.filter(|_| wants_field);
            let yaw_sigma_rad = if field.is_some() {
                0.2
            } else {
                std::f64::consts::PI
            };
            self.filter = Some(Eskf::new(
                eskf::attitude_from(force, field),
                (0.05, yaw_sigma_rad, self.options.initial_bias_sigma_radps),
                self.options.noise,
            ));
        }
    }

    fn gyro(&mut self, t_s: f64, rate_radps: Vector3<f64>) {
        if !rate_radps.iter().all(|v| v.is_finite()) {
            return;
        }
        let dt_s = self.last_gyro_t_s.map(|last_s| t_s - last_s);
        self.last_gyro_t_s = Some(t_s);
        let options = self.options;
        self.start();
        let Some(filter) = self.filter.as_mut() else {
            return;
        };
        match dt_s {
            Some(dt_s) if dt_s > 0.0 && dt_s <= self.max_gyro_gap_s => {
                filter.propagate(rate_radps, dt_s)
            }
            Some(dt_s) if dt_s > self.max_gyro_gap_s => {
                filter.inflate_yaw(
                    (GAP_RATE_RADPS * dt_s)
                        .powi(2)
                        .min(std::f64::consts::PI.powi(2)),
                );
                self.summary.n_gyro_gaps += 1;
            }
            _ => {}
        }
        // At rest the gyroscope reads its bias.
        let corrected = rate_radps - filter.gyro_bias_radps;
        if corrected.norm() < options.rest_rate_radps {
            let since_s = *self.rest_since_s.get_or_insert(t_s);
            if t_s - since_s >= options.rest_hold_s {
                filter.fuse_zero_rate(rate_radps, options.rest_rate_radps);
                self.summary.n_rest_updates += 1;
            }
        } else {
            self.rest_since_s = None;
        }
        let (roll_rad, pitch_rad, yaw_rad) = filter.roll_pitch_yaw_rad();
        let estimate = AttitudeEstimate {
            roll_rad,
            pitch_rad,
            yaw_rad,
            yaw_sigma_rad: filter.yaw_sigma_rad(),
            field_used: self.field_used,
        };
        self.output.push(t_s, estimate);
        self.summary.n_gyro_samples += 1;
    }

    fn acc(&mut self, t_s: f64, force_mps2: Vector3<f64>) {
        let magnitude = force_mps2.norm();
        if !magnitude.is_finite() {
            return;
        }
        self.last_force = Some(force_mps2);
        let acceleration_mps2 =
            self.acceleration
                .add(t_s, magnitude, crate::io::STANDARD_GRAVITY_MPS2);
        if acceleration_mps2 > self.options.rest_acceleration_mps2 {
            self.rest_since_s = None;
        }
        let Some(filter) = self.filter.as_ref() else {
            return;
        };
        // Samples closer than GRAVITY_BLOCK_S are fused as one: their directions turned
        // into the navigation frame by the attitude at each are averaged (a fast
        // accelerometer then costs the filter no more than a 50 Hz one). The sensor's
        // share of the noise averages down; the body's acceleration, correlated over a
        // block, does not.
        let in_nav = filter.nav_from_body * (force_mps2 / magnitude);
        let block = self
            .gravity_block
            .get_or_insert((t_s, Vector3::zeros(), 0, 0.0));
        block.1 += in_nav;
        block.2 += 1;
        block.3 = block.3.max(acceleration_mps2);
        if t_s - block.0 < GRAVITY_BLOCK_S && t_s >= block.0 {
            return;
        }
        let (_, sum, n, acceleration_mps2) = *block;
        self.gravity_block = None;
        let mean = sum / n as f64;
        let sigma_rad = (self.options.gravity_sigma_rad / (n as f64).sqrt())
            .hypot(acceleration_mps2 / crate::io::STANDARD_GRAVITY_MPS2);
        let Some(filter) = self.filter.as_mut() else {
            return;
        };
        // 99.9 % of a χ² with 2 degrees of freedom.
        match filter.fuse_gravity_in_nav(nalgebra::Vector2::new(mean.x, mean.y), sigma_rad, 13.8) {
            Fused::Applied { .. } => self.summary.n_gravity_fused += n,
            _ => self.summary.n_gravity_refused += n,
        }
    }

    fn field(&mut self, t_s: f64, field_ut: Vector3<f64>) {
        if !field_ut.iter().all(|v| v.is_finite()) {
            return;
        }
        self.last_field = Some(field_ut);
        let heading_sigma_rad = self.heading_sigma_rad;
        let (Some(filter), Some(gate)) = (self.filter.as_mut(), self.gate.as_mut()) else {
            return;
        };
        let down_in_body = filter.nav_from_body.inverse() * Vector3::z();
        let Some(dip_rad) = dip_of(field_ut, down_in_body) else {
            return;
        };
        let steady = filter
            .magnetic_heading_error(field_ut)
            .is_some_and(|direction_rad| self.quasi_static.steady(t_s, direction_rad));
        let undisturbed = gate.open(t_s, field_ut.norm(), dip_rad);
        if !(undisturbed && steady) {
            self.summary.n_field_disturbed += 1;
            self.contradicting_since_s = None;
            self.field_used = false;
            return;
        }
        // 99.7 % of a χ² with one degree of freedom (3σ).
        let corrects_bias = self.options.field_corrects_bias;
        match filter.fuse_magnetic_heading(field_ut, heading_sigma_rad, 9.0, corrects_bias) {
            Fused::Applied { .. } => {
                self.summary.n_field_fused += 1;
                self.contradicting_since_s = None;
                self.field_used = true;
            }
            Fused::Gated { .. } => {
                self.summary.n_field_contradicting += 1;
                self.field_used = false;
                let since_s = *self.contradicting_since_s.get_or_insert(t_s);
                if t_s - since_s >= RECOVERY_S {
                    filter.reset_yaw_to(field_ut, heading_sigma_rad);
                    self.summary.n_recoveries += 1;
                    self.contradicting_since_s = None;
                }
            }
            Fused::Degenerate => self.field_used = false,
        }
    }
}
