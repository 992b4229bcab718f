//! The one metric every autopilot compass calibration is judged by, the parameters in
//! force and new ones alike: the corrected field against the Earth's field seen through
//! the autopilot's attitude.
//!
//! For each sample `i`, with `c_i` the corrected field (body axes, mG), `R_i` the
//! attitude of the axes the compass is logged in (ArduPilot's `ATT` turned by
//! `AHRS_TRIM`, PX4's `vehicle_attitude`) and `B` the Earth's field in north-east-down
//! axes (the World Magnetic Model's at the log's position and date):
//!
//! - **vector error**: RMS of `|c_i − R_iᵀ·B|` (mG), the figure MAGFit (ArduPilot
//!   WebTools) fits and ranks by, and ArduPilot's own pre-arm check compares;
//! - **heading error**: RMS (and mean) of the tilt-compensated heading of `c_i` plus the
//!   declination, against the autopilot's yaw; a constant error counts in full, it is not
//!   taken out;
//! - **|B| spread**: the standard deviation of `|c_i|` over its mean (%).
//!
//! Without a position there is no model field: `B` is then the field the correction
//! itself sees on the part of the log it is fitted on, `mean(R_i·c_i)`, and the figures
//! say so ([`EarthField::Fitted`]).

use nalgebra::Vector3;
use serde::Serialize;

use super::AidedSample;
use crate::base::angle::wrap_to_pi;

/// Where the Earth's field the corrections are judged against comes from.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum EarthField {
    /// The World Magnetic Model's, north-east-down, mG.
    Model {
        ned_mg: [f64; 3],
        /// "WMM2020 on 2015-11-21 (extrapolated 4.1 years back)".
        source: String,
    },
    /// No position and date for the model: each correction's own mean field on the part
    /// of the log it was fitted on.
    Fitted,
}

impl EarthField {
    pub fn model_ned_mg(&self) -> Option<Vector3<f64>> {
        match self {
            EarthField::Model { ned_mg, .. } => Some(Vector3::from(*ned_mg)),
            EarthField::Fitted => None,
        }
    }

    /// The same in as few words as a phone's first screen allows.
    pub fn short(&self) -> String {
        match self {
            EarthField::Model { ned_mg, .. } => format!(
                "the World Magnetic Model's {:.0} mG field",
                Vector3::from(*ned_mg).norm()
            ),
            EarthField::Fitted => {
                "the field it sees itself (no position for the model)".to_string()
            }
        }
    }

    /// What the vector error is measured against, in a few words.
    pub fn describe(&self) -> String {
        match self {
            EarthField::Model { ned_mg, source } => format!(
                "the {source} field of {:.0} mG seen through the autopilot's attitude",
                Vector3::from(*ned_mg).norm()
            ),
            EarthField::Fitted => {
                "the field each calibration sees on the first half of the log (no position for \
                 the World Magnetic Model), seen through the autopilot's attitude"
                    .to_string()
            }
        }
    }
}

/// How one correction agrees with the Earth's field over some samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Score {
    /// RMS of `|corrected − R_iᵀ·B|`, mG.
    pub vector_rms_mg: f64,
    /// RMS and mean of the heading (plus the declination) against the autopilot's yaw;
    /// `None` without a declination.
    pub heading_rms_deg: Option<f64>,
    pub heading_mean_deg: Option<f64>,
    /// The corrected field's magnitude: its standard deviation over its mean (%), and
    /// its mean (mG).
    pub spread_pct: f64,
    pub mean_field_mg: f64,
    pub n_samples: usize,
}

/// The field a correction sees in the Earth's frame, averaged over `samples`.
pub fn field_seen_ned(
    samples: &[AidedSample],
    correct: &dyn Fn(Vector3<f64>, f64) -> Vector3<f64>,
) -> Option<Vector3<f64>> {
    if samples.is_empty() {
        return None;
    }
    let sum: Vector3<f64> = samples
        .iter()
        .map(|s| s.body_to_ned * correct(s.raw, s.current_a))
        .sum();
    let mean = sum / samples.len() as f64;
    mean.iter().all(|v| v.is_finite()).then_some(mean)
}

/// The score of `correct(raw, current_a)` over `samples` against `earth_ned_mg`, with the
/// heading compared where `declination_rad` is known; `None` without samples or with a
/// correction that is not finite.
pub fn score(
    samples: &[AidedSample],
    earth_ned_mg: &Vector3<f64>,
    declination_rad: Option<f64>,
    correct: &dyn Fn(Vector3<f64>, f64) -> Vector3<f64>,
) -> Option<Score> {
    if samples.is_empty() {
        return None;
    }
    let n = samples.len() as f64;
    let (mut sum_squared_mg2, mut sum_heading, mut sum_heading_sq) = (0.0, 0.0, 0.0);
    let mut magnitudes = Vec::with_capacity(samples.len());
    for sample in samples {
        let corrected = correct(sample.raw, sample.current_a);
        let expected = sample.body_to_ned.inverse() * earth_ned_mg;
        sum_squared_mg2 += (corrected - expected).norm_squared();
        magnitudes.push(corrected.norm());
        if let Some(declination_rad) = declination_rad {
            // The corrected field in north-east-down axes: its azimuth is the
            // declination when the heading agrees with the yaw, and every radian it
            // turns east is a radian the compass's heading reads less.
            let ned = sample.body_to_ned * corrected;
            let error = wrap_to_pi(declination_rad - ned.y.atan2(ned.x));
            sum_heading += error;
            sum_heading_sq += error * error;
        }
    }
    let vector_rms_mg = (sum_squared_mg2 / n).sqrt();
    let mean_field_mg = magnitudes.iter().sum::<f64>() / n;
    let finite = vector_rms_mg.is_finite() && mean_field_mg.is_finite();
    finite.then(|| Score {
        vector_rms_mg,
        heading_rms_deg: declination_rad.map(|_| (sum_heading_sq / n).sqrt().to_degrees()),
        heading_mean_deg: declination_rad.map(|_| (sum_heading / n).to_degrees()),
        spread_pct: crate::base::stats::spread_pct(magnitudes.iter().copied()).unwrap_or(0.0),
        mean_field_mg,
        n_samples: samples.len(),
    })
}

/// How far a reference error could favour a change of correction: the change
/// `d_i = c_new,i − c_in_force,i` seen in the Earth's frame and averaged over stretches
/// of [`REFERENCE_STRETCH_S`], `|mean(R_i·d_i)|`, averaged over the stretches (mG).
///
/// The reference's error is steady in the Earth's frame over such a stretch: the model's
/// field against the local one does not change over a flight, and the autopilot's yaw
/// and tilt errors wander over tens of seconds. Over a stretch where it is a constant `ε`,
/// `mean(ρ_i·d_i) = ε·mean(R_i·d_i)`: a change the vehicle turns with in the body (new
/// iron, offsets on a turning flight) averages out there, while a change that stays put
/// in the Earth's frame (offsets on one heading) looks exactly like the reference's own
/// error.
pub fn change_seen_by_reference_mg(
    samples: &[AidedSample],
    new: &dyn Fn(Vector3<f64>, f64) -> Vector3<f64>,
    in_force: &dyn Fn(Vector3<f64>, f64) -> Vector3<f64>,
) -> Option<f64> {
    let first_s = samples.first()?.t_s;
    let mut sum = 0.0;
    for stretch in samples.chunk_by(|a, b| {
        ((a.t_s - first_s) / REFERENCE_STRETCH_S).floor()
            == ((b.t_s - first_s) / REFERENCE_STRETCH_S).floor()
    }) {
        let mean_ned = stretch
            .iter()
            .map(|s| s.body_to_ned * (new(s.raw, s.current_a) - in_force(s.raw, s.current_a)))
            .sum::<Vector3<f64>>()
            / stretch.len() as f64;
        sum += mean_ned.norm() * stretch.len() as f64;
    }
    let mean = sum / samples.len() as f64;
    mean.is_finite().then_some(mean)
}

/// How long (s) the reference's error is taken as steady.
pub const REFERENCE_STRETCH_S: f64 = 20.0;

/// Whether a new correction's gain over the one in force, measured against a reference
/// that is itself off the truth by up to `reference_error_mg`, is a real gain.
///
/// With `r_X = c_X − e` the measured errors, `e = t + ρ` the reference (`t` the truth,
/// `ρ` its error) and `d = c_new − c_in_force`, the true gain in mean square is
/// `mean|c_in − t|² − mean|c_new − t|² = (rms_in² − rms_new²) + 2·mean(ρ·d)`. With `ρ`
/// steady over each stretch and no longer than `reference_error_mg`, `|mean(ρ·d)|` is at
/// most `reference_error_mg` times [`change_seen_by_reference_mg`]. So the gain is real
/// whatever the reference's error does when `rms_in² − rms_new²` exceeds twice that.
pub fn gain_is_real(
    in_force_rms_mg: f64,
    new_rms_mg: f64,
    change_seen_mg: f64,
    reference_error_mg: f64,
) -> bool {
    in_force_rms_mg.powi(2) - new_rms_mg.powi(2) > 2.0 * reference_error_mg * change_seen_mg
}

/// The median, over `samples`, of the corrected field's horizontal and vertical
/// differences from `earth_ned_mg` in the Earth's frame (mG): what ArduPilot's pre-arm
/// check compares with `ARMING_MAGTHRESH`.
pub fn median_ned_difference_mg(
    samples: &[AidedSample],
    earth_ned_mg: &Vector3<f64>,
    correct: &dyn Fn(Vector3<f64>, f64) -> Vector3<f64>,
) -> Option<(f64, f64)> {
    let (mut horizontal, mut vertical): (Vec<f64>, Vec<f64>) = samples
        .iter()
        .map(|s| {
            let difference = s.body_to_ned * correct(s.raw, s.current_a) - earth_ned_mg;
            (difference.x.hypot(difference.y), difference.z.abs())
        })
        .filter(|(h, v)| h.is_finite() && v.is_finite())
        .unzip();
    let median = crate::base::stats::median;
    Some((median(&mut horizontal)?, median(&mut vertical)?))
}

#[cfg(test)]
mod tests {
    use nalgebra::Rotation3;

    use super::*;

    #[test]
    fn a_constant_heading_error_counts_in_full_and_the_vector_error_sees_it() {
        let earth: Vector3<f64> = Vector3::new(230.0, 50.0, -530.0);
        let declination = earth.y.atan2(earth.x);
        let samples: Vec<AidedSample> = (0..360)
            .map(|i| {
                let body_to_ned = Rotation3::from_euler_angles(
                    0.1 * (i as f64 * 0.1).sin(),
                    0.05,
                    (i as f64).to_radians(),
                );
                AidedSample {
                    // A full turn in 18 s: within one of the reference's stretches.
                    t_s: i as f64 * 0.05,
                    raw: body_to_ned.inverse() * earth,
                    body_to_ned,
                    current_a: 0.0,
                }
            })
            .collect();
        let exact = score(&samples, &earth, Some(declination), &|raw, _| raw).unwrap();
        assert!(exact.vector_rms_mg < 1e-9 && exact.heading_rms_deg.unwrap() < 1e-9);
        // The field turned 5° about the body's z axis: the heading reads 5° less.
        let turn = Rotation3::from_euler_angles(0.0, 0.0, 5f64.to_radians());
        let turned = score(&samples, &earth, Some(declination), &|raw, _| turn * raw).unwrap();
        assert!(
            (turned.heading_rms_deg.unwrap() - 5.0).abs() < 0.3,
            "{turned:?}"
        );
        assert!(
            (turned.heading_mean_deg.unwrap() + 5.0).abs() < 0.3,
            "{turned:?}"
        );
        assert!(turned.vector_rms_mg > 20.0 && turned.spread_pct < 1e-9);
        let seen = field_seen_ned(&samples, &|raw, _| raw).unwrap();
        assert!((seen - earth).amax() < 1e-9);
        let (horizontal, vertical) =
            median_ned_difference_mg(&samples, &earth, &|raw, _| raw * 1.1).unwrap();
        assert!((horizontal - 0.1 * earth.xy().norm()).abs() < 1e-6);
        assert!((vertical - 53.0).abs() < 1e-6);
        assert!(score(&[], &earth, None, &|raw, _| raw).is_none());
        // A 20 mG change on one heading, measured as a gain of 20 mG: real only where the
        // reference is known to better than half of it.
        let one_heading: Vec<AidedSample> = vec![samples[0]; 50];
        let shifted = |raw: Vector3<f64>, _| raw + Vector3::new(20.0, 0.0, 0.0);
        let seen = change_seen_by_reference_mg(&one_heading, &shifted, &|raw, _| raw).unwrap();
        assert!((seen - 20.0).abs() < 1e-9);
        assert!(gain_is_real(20.0, 0.0, seen, 9.0));
        assert!(!gain_is_real(20.0, 0.0, seen, 11.0));
        // Turning through a circle every stretch, the same change averages out.
        let seen = change_seen_by_reference_mg(&samples, &shifted, &|raw, _| raw).unwrap();
        assert!(seen < 2.0, "{seen}");
    }
}
