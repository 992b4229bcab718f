//! Autopilot logs: what ArduPilot's DataFlash logs and PX4's ULog files hold beyond the
//! streams of a [`Recording`](crate::io::recording::Recording): the autopilot's parameters
//! in force, and every compass it logged, both as logged (after the autopilot's own
//! calibration) and raw (that calibration undone), so that a new calibration can be
//! fitted on the raw field and compared with the one in force.
//!
//! The readers are `dataflash/` (binary `.bin` and text `.log`) and `ulog/`; both fill
//! an [`AutopilotLog`] and put their primary compass's raw field in the recording.

pub mod ardupilot;
pub mod px4;

use nalgebra::Vector3;

use crate::io::recording::Stream;

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

    /// The declination (degrees, east positive) the autopilot's heading was made with,
    /// and the parameter it was read from, where the log says: ArduPilot's
    /// `COMPASS_DEC` (radians) when set by hand (`COMPASS_AUTODEC` 0) or learnt and
    /// saved (not 0); PX4's saved `EKF2_MAG_DECL`, else `ATT_MAG_DECL` (degrees), when
    /// not 0. A 0 with the automatic declination on is no answer: it was never set.
    pub fn declination_deg(&self) -> Option<(f64, &'static str)> {
        let finite = |name: &str| self.param(name).filter(|value| value.is_finite());
        match self.autopilot {
            Autopilot::ArduPilot => {
                let declination_rad = finite("COMPASS_DEC")?;
                let by_hand = finite("COMPASS_AUTODEC") == Some(0.0);
                (by_hand || declination_rad != 0.0)
                    .then(|| (declination_rad.to_degrees(), "COMPASS_DEC"))
            }
            Autopilot::Px4 => ["EKF2_MAG_DECL", "ATT_MAG_DECL"]
                .into_iter()
                .find_map(|name| Some((finite(name).filter(|&deg| deg != 0.0)?, name))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log(autopilot: Autopilot, params: &[(&str, f64)]) -> AutopilotLog {
        AutopilotLog {
            autopilot,
            firmware: None,
            params: params
                .iter()
                .map(|&(name, value)| (name.to_string(), value))
                .collect(),
            params_changed: Vec::new(),
            compasses: Vec::new(),
            main_compass: None,
            current_a: Stream::default(),
        }
    }

    #[test]
    fn the_autopilot_s_own_declination_is_read_where_it_was_ever_set() {
        let ardupilot =
            |params: &[(&str, f64)]| log(Autopilot::ArduPilot, params).declination_deg();
        // Set by hand, even to 0; learnt and saved; never set (log171, nan.log).
        let by_hand = ardupilot(&[("COMPASS_DEC", 0.2), ("COMPASS_AUTODEC", 0.0)]).unwrap();
        assert!((by_hand.0 - 0.2f64.to_degrees()).abs() < 1e-12 && by_hand.1 == "COMPASS_DEC");
        assert_eq!(
            ardupilot(&[("COMPASS_DEC", 0.0), ("COMPASS_AUTODEC", 0.0)]),
            Some((0.0, "COMPASS_DEC"))
        );
        assert!(ardupilot(&[("COMPASS_DEC", -0.1), ("COMPASS_AUTODEC", 1.0)]).is_some());
        assert_eq!(
            ardupilot(&[("COMPASS_DEC", 0.0), ("COMPASS_AUTODEC", 1.0)]),
            None
        );
        assert_eq!(
            ardupilot(&[("COMPASS_DEC", f64::NAN), ("COMPASS_AUTODEC", 0.0)]),
            None
        );
        assert_eq!(ardupilot(&[]), None);
        let px4 = |params: &[(&str, f64)]| log(Autopilot::Px4, params).declination_deg();
        // sample_log_small.ulg's saved EKF2_MAG_DECL; sample.ulg's ATT_MAG_DECL 0.
        assert_eq!(
            px4(&[("EKF2_MAG_DECL", 3.99)]),
            Some((3.99, "EKF2_MAG_DECL"))
        );
        assert_eq!(px4(&[("ATT_MAG_DECL", 0.0), ("ATT_MAG_DECL_A", 1.0)]), None);
        assert_eq!(
            px4(&[("EKF2_MAG_DECL", 0.0), ("ATT_MAG_DECL", -2.5)]),
            Some((-2.5, "ATT_MAG_DECL"))
        );
    }
}
