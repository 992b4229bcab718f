//! Autopilot logs: what ArduPilot's DataFlash logs and PX4's ULog files hold beyond the
//! streams of a [`Recording`](crate::recording::Recording): the autopilot's parameters
//! in force, and every compass it logged, both as logged (after the autopilot's own
//! calibration) and raw (that calibration undone), so that a new calibration can be
//! fitted on the raw field and compared with the one in force.
//!
//! The readers are `dataflash/` (binary `.bin` and text `.log`) and `ulog/`; both fill
//! an [`AutopilotLog`] and put their primary compass's raw field in the recording.

pub mod ardupilot;
pub mod px4;

use nalgebra::Vector3;

use crate::recording::Stream;

/// Which autopilot wrote the log: it decides how a calibration is applied and written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Autopilot {
    ArduPilot,
    Px4,
}

impl Autopilot {
    pub fn name(self) -> &'static str {
        match self {
            Autopilot::ArduPilot => "ArduPilot",
            Autopilot::Px4 => "PX4",
        }
    }
}

/// One compass of an autopilot log.
#[derive(Debug, Clone, PartialEq)]
pub struct CompassLog {
    /// The autopilot's compass instance, from 0 (ArduPilot's `MAG`/`MAG2`/`MAG3` or `I`
    /// column, PX4's multi id).
    pub instance: usize,
    /// Where it was read from ("MAG2", "sensor_mag 1").
    pub source: String,
    /// The field as logged, body axes (x forward, y right, z down), µT: after the
    /// calibration in force, where the autopilot logs it so.
    pub logged_in_body_ut: Stream<Vector3<f64>>,
    /// The raw field, the calibration in force undone, body axes, µT; `None` where the
    /// log does not hold what is needed to undo it.
    pub raw_in_body_ut: Option<Stream<Vector3<f64>>>,
    /// How the raw field was made from the logged one, or why it could not be.
    pub how_raw: String,
    /// PX4's calibration slot (`CAL_MAGn_*`) and the rotation from the raw values' axes
    /// to body axes; `None` for ArduPilot, which logs in body axes and numbers its
    /// compasses by instance.
    pub px4_slot: Option<(usize, nalgebra::Matrix3<f64>)>,
}

/// What an autopilot log holds besides its streams.
#[derive(Debug, Clone, PartialEq)]
pub struct AutopilotLog {
    pub autopilot: Autopilot,
    /// The firmware and board as the log names them.
    pub firmware: Option<String>,
    /// The parameters in force: the first value logged of each, in the log's order.
    pub params: Vec<(String, f64)>,
    /// Parameters whose value changed during the log, with their last value.
    pub params_changed: Vec<(String, f64)>,
    pub compasses: Vec<CompassLog>,
    /// The compass (an index into `compasses`) whose raw field is the recording's
    /// magnetometer; `None` when the recording holds no compass's raw field.
    pub main_compass: Option<usize>,
    /// The battery current (A), for the motor-interference fit; empty where not logged.
    pub current_a: Stream<f64>,
}

/// The value of `name` in a list of parameters (a log's, or a parameter file's).
pub fn param_in(params: &[(String, f64)], name: &str) -> Option<f64> {
    params
        .iter()
        .find(|(param, _)| param == name)
        .map(|&(_, value)| value)
}

impl AutopilotLog {
    /// A parameter's value in force, where the log has it.
    pub fn param(&self, name: &str) -> Option<f64> {
        param_in(&self.params, name)
    }
}
