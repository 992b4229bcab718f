//! What an autopilot accepts as a compass calibration: parameters nobody should write
//! whatever a fit says, because the autopilot (or its own calibration tool) would refuse
//! them or a real compass cannot need them.
//!
//! - **ArduPilot**, as MAGFit (ArduPilot WebTools, `MAGFit/magfit.js`, `params_valid`)
//!   checks a fit before it offers it: each offset within ±1500 mG, each `COMPASS_DIA`
//!   within 0.8-1.2, each `COMPASS_ODI` within ±0.2, `COMPASS_SCALE` within 0.8-1.2; and
//!   the offsets' length within `COMPASS_OFFS_MAX` where the log has it (`AP_Compass`'s
//!   pre-arm "Compass offsets too high").
//! - **PX4**, as its calibration (`commander/mag_calibration.cpp`,
//!   `check_calibration_result`) checks it: every value finite, the scales positive, each
//!   offset within 1.3 gauss (`MAG_MAX_OFFSET_LEN`: beyond it the sensor saturates); the
//!   iron within MAGFit's ranges as well, which no real compass needs to leave.
//! - **The corrected field's strength**, as the pre-arm checks take it: ArduPilot's
//!   `AP_Arming::compass_checks` refuses a field outside 185-875 mG
//!   (`AP_ARMING_COMPASS_MAGFIELD_MIN/MAX`, 0.35-1.65 × 530 mG) and, where the firmware
//!   has `ARMING_MAGTHRESH` (default 100 mG, 0 turns it off), a field whose horizontal or
//!   vertical (2×) part differs from the World Magnetic Model's by more; PX4's EKF2
//!   refuses a strength further than `EKF2_MAG_CHK_STR` (default 0.2 gauss) from the
//!   model's. Here the median over the log stands for the vehicle at arming.

use nalgebra::{Matrix3, Vector3};

use crate::io::autopilot::Autopilot;

/// MAGFit's ranges (mG; factors).
const ARDUPILOT_OFFSET_MAX_MG: f64 = 1500.0;
const DIAGONAL_RANGE: (f64, f64) = (0.8, 1.2);
const OFF_DIAGONAL_MAX: f64 = 0.2;
const SCALE_RANGE: (f64, f64) = (0.8, 1.2);
/// `COMPASS_MOT_*`'s range in ArduPilot's parameter table (mG per A).
const MOTOR_MAX_MG_PER_A: f64 = 1000.0;
/// PX4's `MAG_MAX_OFFSET_LEN`, 1.3 gauss.
const PX4_OFFSET_MAX_MG: f64 = 1300.0;
/// ArduPilot's pre-arm field strength range (mG).
const FIELD_RANGE_MG: (f64, f64) = (185.0, 875.0);
/// PX4's `EKF2_MAG_CHK_STR` default: 0.2 gauss.
const PX4_STRENGTH_TOLERANCE_MG: f64 = 200.0;

/// A calibration in ArduPilot's form, in body axes and mG: what is checked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    pub offsets_mg: Vector3<f64>,
    /// `M`, the iron (its scale apart).
    pub soft_iron: Matrix3<f64>,
    pub scale: f64,
    pub motor_mg_per_a: Vector3<f64>,
}

/// How the corrected field looks over the log: its median strength (mG) and, where the
/// model's field is known, its median horizontal and vertical differences from it in the
/// Earth's frame (mG), and the model's strength.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldSeen {
    pub median_strength_mg: f64,
    pub model: Option<ModelDifference>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelDifference {
    pub horizontal_mg: f64,
    pub vertical_mg: f64,
    pub model_strength_mg: f64,
}

/// The parameters of the log that set an autopilot's own limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    pub autopilot: Autopilot,
    /// ArduPilot's `COMPASS_OFFS_MAX`, where the firmware has it.
    pub offsets_length_max_mg: Option<f64>,
    /// ArduPilot's `ARMING_MAGTHRESH` (mG) where the firmware has it and it is on.
    pub arming_mag_threshold_mg: Option<f64>,
    /// PX4's `EKF2_MAG_CHK_STR` (mG).
    pub px4_strength_tolerance_mg: f64,
}

impl Limits {
    /// The limits a log's parameters set (`param` gives a finite value where it has one).
    pub fn of(autopilot: Autopilot, param: &dyn Fn(&str) -> Option<f64>) -> Limits {
        Limits {
            autopilot,
            offsets_length_max_mg: param("COMPASS_OFFS_MAX").filter(|&max| max > 0.0),
            arming_mag_threshold_mg: param("ARMING_MAGTHRESH").filter(|&max| max > 0.0),
            px4_strength_tolerance_mg: param("EKF2_MAG_CHK_STR")
                .filter(|&tolerance| tolerance > 0.0)
                .map_or(PX4_STRENGTH_TOLERANCE_MG, |gauss| gauss * 1000.0),
        }
    }

    /// Every reason the autopilot would refuse `candidate`, each a sentence naming the
    /// value and the range; empty when it is accepted.
    pub fn refusals(&self, candidate: &Candidate, field: Option<&FieldSeen>) -> Vec<String> {
        let mut reasons = Vec::new();
        let values = candidate
            .offsets_mg
            .iter()
            .chain(candidate.soft_iron.iter())
            .chain(candidate.motor_mg_per_a.iter())
            .chain(std::iter::once(&candidate.scale));
        if values.clone().any(|v| !v.is_finite()) {
            reasons.push("a parameter is not a finite number".to_string());
            return reasons;
        }
        let (offset_max_mg, name) = match self.autopilot {
            Autopilot::ArduPilot => (ARDUPILOT_OFFSET_MAX_MG, "ArduPilot's (MAGFit's)"),
            Autopilot::Px4 => (PX4_OFFSET_MAX_MG, "PX4's"),
        };
        for (axis, offset) in ["x", "y", "z"].iter().zip(candidate.offsets_mg.iter()) {
            if offset.abs() >= offset_max_mg {
                reasons.push(format!(
                    "the {axis} offset, {offset:.0} mG, is outside {name} ±{offset_max_mg:.0} mG"
                ));
            }
        }
        if let Some(max_mg) = self.offsets_length_max_mg {
            let length = candidate.offsets_mg.norm();
            if length > max_mg {
                reasons.push(format!(
                    "the offsets' length, {length:.0} mG, is over COMPASS_OFFS_MAX ({max_mg:.0} mG)"
                ));
            }
        }
        let m = &candidate.soft_iron;
        for (axis, idx) in ["x", "y", "z"].iter().zip(0..3) {
            let diagonal = m[(idx, idx)];
            if !(DIAGONAL_RANGE.0 < diagonal && diagonal < DIAGONAL_RANGE.1) {
                reasons.push(format!(
                    "the iron's {axis} diagonal, {diagonal:.3}, is outside {:.1}-{:.1}",
                    DIAGONAL_RANGE.0, DIAGONAL_RANGE.1
                ));
            }
        }
        for (pair, (row, col)) in ["xy", "xz", "yz"].iter().zip([(0, 1), (0, 2), (1, 2)]) {
            let off = m[(row, col)];
            if off.abs() >= OFF_DIAGONAL_MAX {
                reasons.push(format!(
                    "the iron's {pair} off-diagonal, {off:.3}, is outside ±{OFF_DIAGONAL_MAX:.1}"
                ));
            }
        }
        let scale = candidate.scale;
        if !(SCALE_RANGE.0 < scale && scale < SCALE_RANGE.1) {
            reasons.push(format!(
                "the scale, {scale:.3}, is outside {:.1}-{:.1}",
                SCALE_RANGE.0, SCALE_RANGE.1
            ));
        }
        if candidate.motor_mg_per_a.amax() > MOTOR_MAX_MG_PER_A {
            reasons.push(format!(
                "the motor compensation, up to {:.0} mG/A, is outside ±{MOTOR_MAX_MG_PER_A:.0}",
                candidate.motor_mg_per_a.amax()
            ));
        }
        if let Some(field) = field {
            reasons.extend(self.field_refusals(field));
        }
        reasons
    }

    /// The pre-arm checks of the corrected field's strength.
    fn field_refusals(&self, field: &FieldSeen) -> Vec<String> {
        let mut reasons = Vec::new();
        let strength = field.median_strength_mg;
        match (self.autopilot, field.model) {
            (Autopilot::Px4, Some(model)) => {
                let difference = strength - model.model_strength_mg;
                if difference.abs() > self.px4_strength_tolerance_mg {
                    reasons.push(format!(
                        "the corrected field's strength, {strength:.0} mG, is {difference:+.0} mG from \
                         the World Magnetic Model's {:.0} mG, more than PX4's EKF2_MAG_CHK_STR \
                         ({:.0} mG) allows",
                        model.model_strength_mg, self.px4_strength_tolerance_mg
                    ));
                }
            }
            _ => {
                if !(FIELD_RANGE_MG.0..=FIELD_RANGE_MG.1).contains(&strength) {
                    reasons.push(format!(
                        "the corrected field's strength, {strength:.0} mG, is outside the pre-arm \
                         check's {:.0}-{:.0} mG",
                        FIELD_RANGE_MG.0, FIELD_RANGE_MG.1
                    ));
                }
            }
        }
        if let (Autopilot::ArduPilot, Some(model), Some(threshold)) =
            (self.autopilot, field.model, self.arming_mag_threshold_mg)
        {
            if model.horizontal_mg > threshold || model.vertical_mg > 2.0 * threshold {
                reasons.push(format!(
                    "the corrected field differs from the World Magnetic Model's by {:.0} mG \
                     horizontally and {:.0} mG vertically, more than ARMING_MAGTHRESH ({threshold:.0} \
                     mG; twice that vertically) allows",
                    model.horizontal_mg, model.vertical_mg
                ));
            }
        }
        reasons
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn candidate(offsets: [f64; 3], diagonal: [f64; 3], scale: f64) -> Candidate {
        Candidate {
            offsets_mg: Vector3::from(offsets),
            soft_iron: Matrix3::from_diagonal(&Vector3::from(diagonal)),
            scale,
            motor_mg_per_a: Vector3::zeros(),
        }
    }

    fn field(strength: f64) -> FieldSeen {
        FieldSeen {
            median_strength_mg: strength,
            model: None,
        }
    }

    #[test]
    fn the_issue_s_degenerate_parameters_are_refused_and_sound_ones_accepted() {
        let ardupilot = Limits::of(Autopilot::ArduPilot, &|_| None);
        let sound = candidate([-97.8, 118.1, 213.2], [0.996, 1.008, 1.003], 1.0);
        assert!(ardupilot.refusals(&sound, Some(&field(560.0))).is_empty());
        // DIA 0.35/0.56/2.09 and a corrected field of 146 mG: refused for each.
        let degenerate = candidate([300.0, -20.0, 80.0], [0.35, 0.56, 2.09], 1.0);
        let reasons = ardupilot.refusals(&degenerate, Some(&field(146.0)));
        assert_eq!(reasons.len(), 4, "{reasons:?}");
        assert!(reasons[3].contains("146 mG") && reasons[3].contains("185-875"));
        let far = candidate([1600.0, 0.0, 0.0], [1.0; 3], 1.25);
        assert_eq!(ardupilot.refusals(&far, None).len(), 2);
        // COMPASS_OFFS_MAX where the log has it; ARMING_MAGTHRESH against the model.
        let params = |name: &str| match name {
            "COMPASS_OFFS_MAX" => Some(200.0),
            "ARMING_MAGTHRESH" => Some(100.0),
            _ => None,
        };
        let newer = Limits::of(Autopilot::ArduPilot, &params);
        let off_model = FieldSeen {
            median_strength_mg: 560.0,
            model: Some(ModelDifference {
                horizontal_mg: 130.0,
                vertical_mg: 20.0,
                model_strength_mg: 580.0,
            }),
        };
        let reasons = newer.refusals(&sound, Some(&off_model));
        assert_eq!(reasons.len(), 2, "{reasons:?}");
        assert!(reasons[0].contains("COMPASS_OFFS_MAX") && reasons[1].contains("ARMING_MAGTHRESH"));
    }

    #[test]
    fn px4_takes_its_own_offset_limit_and_strength_tolerance() {
        let px4 = Limits::of(Autopilot::Px4, &|_| None);
        let big = candidate([1400.0, 0.0, 0.0], [1.0; 3], 1.0);
        assert!(px4.refusals(&big, None)[0].contains("PX4's ±1300"));
        let weak = FieldSeen {
            median_strength_mg: 300.0,
            model: Some(ModelDifference {
                horizontal_mg: 0.0,
                vertical_mg: 0.0,
                model_strength_mg: 550.0,
            }),
        };
        let sound = candidate([10.0, 0.0, 0.0], [1.0; 3], 1.0);
        assert!(px4.refusals(&sound, Some(&weak))[0].contains("EKF2_MAG_CHK_STR"));
        assert!(px4.refusals(&sound, Some(&field(300.0))).is_empty());
        let not_finite = candidate([f64::NAN, 0.0, 0.0], [1.0; 3], 1.0);
        assert_eq!(px4.refusals(&not_finite, None).len(), 1);
    }
}
