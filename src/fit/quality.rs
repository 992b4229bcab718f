//! The bounds a calibration must lie inside to be written to a device (sent to a board
//! live, or exported as JSON, a C snippet or MotionCal's packet), whatever the data say
//! of it: numbers a sensor's correction cannot have (not finite, a mirror, an axis
//! stretched beyond any real sensor's) and a field strength that is not the Earth's.
//! In figures: finite, the soft iron positive definite with its axes within 3:1, the
//! field 0.35-1.65 × the World Magnetic Model's (10-150 µT without a position); each
//! constant says where its figure comes from. An autopilot's own bounds are
//! `analysis::calibration::autopilot::acceptance`.
//!
//! And the one field verdict ([`field_verdict`]): whether a fit of a board turned in the
//! hand (live, or a dropped file without a reference heading) is good enough, by its
//! samples, MotionCal's gap rule, the corrected field's spread and the World Magnetic
//! Model's field.

use nalgebra::SymmetricEigen;
use serde::Serialize;

use crate::fit::coverage::{SphereCoverage, MAX_GOOD_GAP_PCT};
use crate::fit::model::FieldCalibration;

/// The largest ratio of the soft iron's largest to smallest eigenvalue accepted. Real
/// boards fitted by `compass-pdr calibrate`: the HMC5883L of `hmc5883l-sphere` 1.23, the
/// QMC5883L of `qmc5883l-calibration` 2.25 (its axes' gains differ that much: its
/// author's own calibration gives 2.18). 3 accepts both with a third to spare; a fit of
/// a partial turn or of a moving magnet stretches far more.
pub const MAX_SOFT_IRON_AXIS_RATIO: f64 = 3.0;

/// The fitted field strength as a multiple of the World Magnetic Model's, when the page
/// knows the position: ArduPilot's arming check (185-875 mG around 530 mG), a sensor's
/// scale error or a nearby magnet beyond it.
pub const MIN_FIELD_RATIO_TO_MODEL: f64 = 0.35;
pub const MAX_FIELD_RATIO_TO_MODEL: f64 = 1.65;

/// The fitted field strength without a position (µT): the Earth's is 22-67 µT
/// everywhere; this leaves a factor of two for a sensor's scale error and refuses
/// counts read as µT (thousands) or gauss read as µT (under one).
pub const MIN_FIELD_UT: f64 = 10.0;
pub const MAX_FIELD_UT: f64 = 150.0;

/// Why `calibration` is outside the bounds a device accepts (each says what to do);
/// empty when it is inside them.
pub fn acceptance_reasons(
    calibration: &FieldCalibration,
    expected_field_ut: Option<f64>,
) -> Vec<String> {
    let mut reasons = shape_reasons(calibration);
    if reasons.is_empty() {
        reasons.extend(field_reasons(calibration.field_ut, expected_field_ut));
    }
    reasons
}

/// [`acceptance_reasons`] without the field strength's: for a calibration fitted in
/// counts of unknown sensitivity, whose field is not in µT.
pub fn shape_reasons(calibration: &FieldCalibration) -> Vec<String> {
    let finite = calibration.hard_iron_ut.iter().all(|v| v.is_finite())
        && calibration.soft_iron.iter().all(|v| v.is_finite())
        && calibration.field_ut.is_finite();
    if !finite {
        return vec![
            "the calibration has numbers that are not finite: it cannot be sent. Keep turning the \
             device for a new fit"
                .to_string(),
        ];
    }
    let mut reasons = Vec::new();
    // The packet carries the symmetric part (MotionCal's six soft-iron floats).
    let symmetric = (calibration.soft_iron + calibration.soft_iron.transpose()) * 0.5;
    let eigenvalues = SymmetricEigen::new(symmetric).eigenvalues;
    let (smallest, largest) = (eigenvalues.min(), eigenvalues.max());
    if smallest <= 0.0 {
        reasons.push(format!(
            "the soft-iron matrix is not positive definite (smallest eigenvalue \
             {smallest:.3}): it would mirror or flatten the field. Record again away from moving \
             iron, turning the device through every direction"
        ));
    } else if largest / smallest > MAX_SOFT_IRON_AXIS_RATIO {
        reasons.push(format!(
            "the soft iron stretches one axis {:.1} times another (at most \
             {MAX_SOFT_IRON_AXIS_RATIO:.0} is accepted; real sensors need up to 2.3): that is a \
             failed fit, not a sensor's distortion. Record again away from moving iron, turning \
             the device through every direction",
            largest / smallest
        ));
    }
    reasons
}

/// Why a fitted field strength (µT) is not the Earth's: against the World Magnetic
/// Model's where the position is known, else against the Earth's range.
fn field_reasons(field_ut: f64, expected_field_ut: Option<f64>) -> Vec<String> {
    let mut reasons = Vec::new();
    match expected_field_ut {
        Some(expected_ut) => {
            let ratio = field_ut / expected_ut;
            if !(MIN_FIELD_RATIO_TO_MODEL..=MAX_FIELD_RATIO_TO_MODEL).contains(&ratio) {
                reasons.push(format!(
                    "the fitted field is {field_ut:.1} µT, {ratio:.2} × the {expected_ut:.1} µT \
                     the World Magnetic Model gives here \
                     ({MIN_FIELD_RATIO_TO_MODEL}-{MAX_FIELD_RATIO_TO_MODEL} × is accepted): check \
                     the sensor's range and units, and move away from magnetic objects"
                ));
            }
        }
        None => {
            if !(MIN_FIELD_UT..=MAX_FIELD_UT).contains(&field_ut) {
                reasons.push(format!(
                    "the fitted field is {field_ut:.1} µT, outside the \
                     {MIN_FIELD_UT:.0}-{MAX_FIELD_UT:.0} µT accepted (the Earth's is 22-67 µT): \
                     check the sensor's range and units"
                ));
            }
        }
    }
    reasons
}

/// Good enough to send: fewer samples than this are not.
pub const GOOD_MIN_SAMPLES: usize = 300;
/// Good enough: the corrected field's magnitude varies by less than this (standard
/// deviation over mean, percent). A good fit of a MEMS magnetometer leaves about 1 %.
pub const GOOD_MAX_SPREAD_PCT: f64 = 3.0;
/// Good enough: the fitted field within this of the World Magnetic Model's, when the
/// position is known (percent). Further off, the sensor's scale is wrong or something
/// magnetic is near.
pub const GOOD_MAX_FIELD_DIFFERENCE_PCT: f64 = 15.0;

/// A field fit judged: good enough to send (or to trust without a reference heading), or
/// the reasons it is not, each saying what to do.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FieldVerdict {
    pub good_enough: bool,
    /// The corrected field still varies by [`GOOD_MAX_SPREAD_PCT`] or more, or the fitted
    /// field is [`GOOD_MAX_FIELD_DIFFERENCE_PCT`] or more from the World Magnetic Model's:
    /// the calibration itself is off, not only the data short.
    pub far_off: bool,
    pub reasons: Vec<String>,
}

/// The verdict on a fit: each unmet condition is a reason that says what to do. A
/// dropped file without a reference heading is judged by it too ([`crate::present::verdict`]).
pub fn field_verdict(
    n_samples: usize,
    coverage: &SphereCoverage,
    field_spread_pct: f64,
    expected_field_ut: Option<f64>,
    field_ut: f64,
) -> FieldVerdict {
    let mut reasons = Vec::new();
    if n_samples < GOOD_MIN_SAMPLES {
        reasons.push(format!(
            "only {n_samples} samples; at least {GOOD_MIN_SAMPLES} are needed. Keep turning the device."
        ));
    }
    if coverage.gaps_too_large() {
        let advice = coverage
            .largest_gap
            .map_or(String::new(), |gap| format!(": {}", gap.advice()));
        reasons.push(format!(
            "{:.0} % of the sphere of directions is still missing (under {MAX_GOOD_GAP_PCT:.0} % is needed){advice}",
            coverage.gap_pct
        ));
    }
    // NaN (no spread measured) is not good enough either.
    if field_spread_pct.is_nan() || field_spread_pct >= GOOD_MAX_SPREAD_PCT {
        reasons.push(format!(
            "the corrected field still varies by {field_spread_pct:.1} % (under {GOOD_MAX_SPREAD_PCT:.0} % is needed): \
             move away from metal and magnets, and turn the device slowly"
        ));
    }
    let mut far_off = field_spread_pct >= GOOD_MAX_SPREAD_PCT;
    if let Some(expected_ut) = expected_field_ut {
        let difference_pct = 100.0 * (field_ut - expected_ut) / expected_ut;
        far_off |= difference_pct.abs() >= GOOD_MAX_FIELD_DIFFERENCE_PCT;
        if difference_pct.is_nan() || difference_pct.abs() >= GOOD_MAX_FIELD_DIFFERENCE_PCT {
            reasons.push(format!(
                "the fitted field is {field_ut:.1} µT, {difference_pct:+.0} % from the {expected_ut:.1} µT the World \
                 Magnetic Model gives here: check the sensor's range and units, and move away from magnetic objects"
            ));
        }
    }
    FieldVerdict {
        good_enough: reasons.is_empty(),
        far_off,
        reasons,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    fn calibration(soft_iron: Matrix3<f64>, field_ut: f64) -> FieldCalibration {
        FieldCalibration {
            hard_iron_ut: Vector3::new(12.0, -7.5, 30.0),
            soft_iron,
            field_ut,
        }
    }

    /// The QMC5883L of `qmc5883l-calibration` as `compass-pdr calibrate` fits it.
    fn qmc5883l() -> Matrix3<f64> {
        Matrix3::new(
            1.1609, -0.0337, -0.0073, -0.0337, 1.7618, -0.0510, -0.0073, -0.0510, 0.7881,
        )
    }

    #[test]
    fn real_sensors_soft_iron_is_accepted_and_an_absurd_one_is_not() {
        assert!(acceptance_reasons(&calibration(qmc5883l(), 48.0), Some(48.6)).is_empty());
        let stretched = Matrix3::from_diagonal(&Vector3::new(0.5, 1.0, 2.0));
        let reasons = acceptance_reasons(&calibration(stretched, 48.0), None);
        assert!(
            reasons.len() == 1 && reasons[0].contains("stretches one axis 4.0 times another"),
            "{reasons:?}"
        );
        let mirrored = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
        let reasons = acceptance_reasons(&calibration(mirrored, 48.0), None);
        assert!(reasons[0].contains("not positive definite"), "{reasons:?}");
        let reasons = acceptance_reasons(&calibration(Matrix3::identity(), f64::NAN), None);
        assert!(reasons[0].contains("not finite"), "{reasons:?}");
    }

    #[test]
    fn the_field_is_the_earth_s_within_ardupilot_s_arming_range_or_10_to_150_ut() {
        let at = |field_ut, expected_ut| {
            acceptance_reasons(&calibration(Matrix3::identity(), field_ut), expected_ut)
        };
        assert!(at(48.0, Some(48.6)).is_empty());
        assert!(at(17.5, Some(48.6)).is_empty(), "0.36 ×");
        assert!(at(16.5, Some(48.6))[0].contains("0.34 × the 48.6 µT"));
        assert!(at(81.0, Some(48.6))[0].contains("1.67 ×"));
        assert!(at(120.0, None).is_empty());
        assert!(at(7401.5, None)[0].contains("outside the 10-150 µT"));
        assert!(at(0.45, None)[0].contains("0.5 µT"));
    }
}
