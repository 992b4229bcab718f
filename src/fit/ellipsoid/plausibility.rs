//! Whether a solution is a calibration at all: a correction that mirrors the field or,
//! for a sensor read in µT, an overall gain far from one ([`degeneracy`], for either
//! model); and, for the full model, a shape no material gives or a dip far from the
//! model's ([`implausibility`]). Such solutions come from a changing field or a wrong
//! tilt; [`super::fit_inertial`] sets them aside, and falls back to the isotropic model
//! when no full one is left.

use super::*;

/// Why a solution of either model is no calibration at all, if it is not: a correction
/// that mirrors the field, or, for a sensor read in µT (whose factory gain is known), an
/// overall gain beyond [`MAX_OVERALL_GAIN`] either way: the fit shrank a sphere onto a
/// patch of the samples (a hard iron among them and a gain of hundreds), which a band of
/// data with a changing field allows.
pub(super) fn degeneracy(state: &State, options: &InertialOptions) -> Option<String> {
    let det = state.correction.determinant();
    if det.is_nan() || det <= 0.0 {
        return Some("the fitted correction mirrors the field".to_string());
    }
    let gain = det.cbrt();
    if options.gain_known && !(1.0 / MAX_OVERALL_GAIN..=MAX_OVERALL_GAIN).contains(&gain) {
        return Some(format!(
            "the fit would scale the sensor's µT by {gain:.2}, a sphere shrunk onto part of the samples"
        ));
    }
    None
}

/// Why a full-model solution is not a magnetometer's distortion, if it is not: a shape
/// no material gives (axis gains beyond 0.5-2× their mean, cross-axis terms beyond
/// ±[`MAX_CROSS_AXIS`], a rotation beyond [`MAX_ROTATION_RAD`]), or, where the tilt is
/// trusted (`tilt_trusted`: at least half on average), a dip far from the model's. Such
/// solutions come from fitting a changing field or a wrong tilt with the soft iron,
/// typically on a band of data (a car's drive). Where the tilt is mostly not trusted (a
/// phone swinging at the arm's end) the fitted dip says only that, and the soft iron,
/// held symmetric there, is decided by the field's shape.
pub(super) fn implausibility(
    state: &State,
    options: &InertialOptions,
    tilt_trusted: bool,
) -> Option<String> {
    if let Some(reason) = degeneracy(state, options) {
        return Some(reason);
    }
    let det = state.correction.determinant();
    let shape = state.correction / det.cbrt();
    for axis in 0..3 {
        let gain = shape[(axis, axis)];
        if !(MIN_AXIS_GAIN..=MAX_AXIS_GAIN).contains(&gain) {
            return Some(format!(
                "a full soft iron would scale one axis by {gain:.2} of the mean"
            ));
        }
    }
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let symmetric = 0.5 * (shape[(a, b)] + shape[(b, a)]);
        let antisymmetric = 0.5 * (shape[(a, b)] - shape[(b, a)]);
        if symmetric.abs() > MAX_CROSS_AXIS {
            return Some(format!(
                "a full soft iron would couple two axes by {symmetric:.2}"
            ));
        }
        if antisymmetric.abs() > MAX_ROTATION_RAD {
            return Some(format!(
                "a full soft iron would turn the axes by {:.0}°",
                antisymmetric.abs().to_degrees()
            ));
        }
    }
    if let Some(prior) = options.field.filter(|_| tilt_trusted) {
        let dip_deg = (state.vertical_ut / state.field_ut)
            .clamp(-1.0, 1.0)
            .asin()
            .to_degrees();
        if (dip_deg - prior.inclination_deg).abs() > MAX_DIP_OFF_PRIOR_DEG
            && state.vertical_ut != 0.0
        {
            return Some(format!(
                "a full soft iron would put the dip at {dip_deg:.0}° where the model has {:.0}°",
                prior.inclination_deg
            ));
        }
    }
    None
}
