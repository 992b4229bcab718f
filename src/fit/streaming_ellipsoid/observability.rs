//! What the samples' geometry lets a 3D fit see (step 6 of the method in [`super`]): the
//! frame the fits are solved in ([`Geometry`]: the power sums moved to the mean and
//! scaled by the RMS radius); the refusal of data that did not turn, that lie along a
//! line or within ±[`MIN_TILT_SPAN_DEG`] of a plane; the band's tilt span
//! `atan(√3·σ₃ / √(σ₁² + σ₂²))` from the principal spreads; and the fallback to the band
//! model on a band narrower than ±[`MIN_FULL_TILT_SPAN_DEG`], whose thresholds the
//! `band_sweep` test measured (no paper: the band model is this crate's own).

use nalgebra::{Matrix3, Vector3};

use super::*;

/// A spread below this (µT, RMS about the mean) means the device did not turn: a
/// still magnetometer spreads by its noise, well under 1 µT, and any turn by tens.
const MIN_SPREAD_UT: f64 = 2.0;

/// Samples whose second principal axis is this small a fraction of the first lie on a
/// line (a field that grows and shrinks along one direction), not on a surface.
const MIN_WIDTH_FRACTION: f64 = 0.05;

/// Samples within this tilt span (±degrees, see [`Observability::tilt_span_deg`]) of a
/// plane are refused. Such a band is mostly noise (a level ring at 0.6 µT of noise
/// already spans 3°), and just above it, at 5°, every 3D model leaves 3.5° RMS of
/// heading error (worst 5-7°): any narrower would be a confident wrong answer.
const MIN_TILT_SPAN_DEG: f64 = 4.0;

/// A narrow band falls back to the band model only when the band model's RMS residual
/// exceeds the full model's by a systematic part under this fraction of the full
/// model's RMS (the RMS grows by under 0.5 %); see [`prefers_band`].
const BAND_EXCESS_OF_NOISE: f64 = 0.1;

/// The power sums in the frame the fits are solved in, `u = (m − mean) / scale`, and
/// what they say about the data's shape.
#[derive(Debug, Clone)]
pub(super) struct Geometry {
    pub(super) n_samples: f64,
    pub(super) mean_ut: Vector3<f64>,
    pub(super) scale_ut: f64,
    pub(super) normalised: [f64; N_MOMENTS],
    pub(super) principal_spread_ut: [f64; 3],
    /// Unit principal directions of the samples, as columns, by falling spread.
    pub(super) principal_axes: Matrix3<f64>,
    pub(super) tilt_span_deg: f64,
}

impl EllipsoidAccumulator {
    /// Checks the data and moves the sums to a well-conditioned frame.
    pub(super) fn geometry(&self) -> Result<Geometry, EllipsoidError> {
        if let Some(error) = &self.first_rejected {
            return Err(error.clone());
        }
        let n_finite = self.moments[0];
        let origin_ut = match self.origin_ut {
            Some(origin_ut) if self.n_seen >= MIN_SAMPLES => origin_ut,
            _ => {
                return Err(EllipsoidError::TooFewSamples {
                    n_samples: self.n_seen,
                    min: MIN_SAMPLES,
                })
            }
        };
        let mean_offset_ut =
            Vector3::new(self.moments[1], self.moments[2], self.moments[3]) / n_finite;
        let centred = shift_and_scale(&self.moments, -mean_offset_ut, 1.0);
        let second = |a: usize, b: usize, c: usize| centred[MOMENT_INDEX[a][b][c]] / n_finite;
        let covariance_ut2 = Matrix3::new(
            second(2, 0, 0),
            second(1, 1, 0),
            second(1, 0, 1),
            second(1, 1, 0),
            second(0, 2, 0),
            second(0, 1, 1),
            second(1, 0, 1),
            second(0, 1, 1),
            second(0, 0, 2),
        );
        let spread_ut = covariance_ut2.trace().max(0.0).sqrt();
        if spread_ut.is_nan() || spread_ut < MIN_SPREAD_UT {
            return Err(EllipsoidError::NoRotation { spread_ut });
        }
        let Some(eigen) = symmetric_eigen(covariance_ut2) else {
            return Err(EllipsoidError::NoRotation { spread_ut });
        };
        let mut axes: [(f64, Vector3<f64>); 3] = std::array::from_fn(|axis_idx| {
            (
                eigen.eigenvalues[axis_idx].max(0.0).sqrt(),
                eigen.eigenvectors.column(axis_idx).into_owned(),
            )
        });
        crate::base::sort::sort_by_key(&mut axes, |axis| -axis.0);
        let principal_spread_ut = [axes[0].0, axes[1].0, axes[2].0];
        if principal_spread_ut[1] < MIN_WIDTH_FRACTION * principal_spread_ut[0] {
            return Err(EllipsoidError::Line {
                length_ut: principal_spread_ut[0],
                width_ut: principal_spread_ut[1],
            });
        }
        let in_plane_ut = principal_spread_ut[0].hypot(principal_spread_ut[1]);
        let tilt_span_deg = (3f64.sqrt() * principal_spread_ut[2] / in_plane_ut)
            .atan()
            .to_degrees();
        if tilt_span_deg < MIN_TILT_SPAN_DEG {
            return Err(EllipsoidError::Plane { tilt_span_deg });
        }
        let scale_ut = spread_ut;
        Ok(Geometry {
            n_samples: n_finite,
            mean_ut: origin_ut + mean_offset_ut,
            scale_ut,
            normalised: shift_and_scale(&centred, Vector3::zeros(), scale_ut),
            principal_spread_ut,
            principal_axes: Matrix3::from_columns(&[axes[0].1, axes[1].1, axes[2].1]),
            tilt_span_deg,
        })
    }
}

impl Geometry {
    pub(super) fn observability(&self, calibration: &FieldCalibration) -> Observability {
        Observability {
            principal_spread_ut: self.principal_spread_ut,
            least_spread_axis: self.principal_axes.column(2).into_owned(),
            tilt_span_deg: self.tilt_span_deg,
            axis_ratio: axis_ratio(&calibration.soft_iron),
            hard_iron_std_ut: None,
        }
    }
}

/// Longest over shortest semi-axis of the raw ellipsoid that `A` maps to a sphere.
pub(super) fn axis_ratio(soft_iron: &Matrix3<f64>) -> f64 {
    let Some(eigen) = symmetric_eigen(*soft_iron) else {
        return f64::INFINITY;
    };
    let (min, max) = (eigen.eigenvalues.min(), eigen.eigenvalues.max());
    if min > 0.0 {
        max / min
    } else {
        f64::INFINITY
    }
}

/// The body axis nearest a direction, for messages.
fn nearest_axis_name(direction: &Vector3<f64>) -> &'static str {
    let abs = direction.abs();
    if abs.x >= abs.y && abs.x >= abs.z {
        "x"
    } else if abs.y >= abs.z {
        "y"
    } else {
        "z"
    }
}

/// Whether a narrow band of data should fall back to the band model: when the band
/// model fits as well as the full one, the data cannot tell the scale along the
/// band's axis from the hard iron along it. Rings give no excess at all (the full fit
/// there is often worse, its refinement rejected as drifting); caps of the sphere,
/// which look narrow to the tilt span but do see that scale, give 0.2-0.7 of the
/// noise where the band model would cost degrees of heading.
pub(super) fn prefers_band(geometry: &Geometry, band_rms_ut: f64, full_rms_ut: f64) -> bool {
    let excess_ut = (band_rms_ut.powi(2) - full_rms_ut.powi(2)).max(0.0).sqrt();
    geometry.tilt_span_deg < MIN_FULL_TILT_SPAN_DEG
        && excess_ut <= BAND_EXCESS_OF_NOISE * full_rms_ut
}

/// The sentence that says why a fit fell back to the band model.
pub(super) fn band_fallback_sentence(geometry: &Geometry) -> String {
    format!(
        "the data span only ±{:.0}° of tilt about the body {} axis (a full or diagonal \
         fit needs ±{:.0}°), so the scale along that axis cannot be told from the hard \
         iron along it; fell back to the band model (that scale tied to the other two), \
         whose hard iron along that axis is a guess from the band's curvature. Tilt the \
         device through more orientations for a full fit.",
        geometry.tilt_span_deg,
        nearest_axis_name(&geometry.principal_axes.column(2).into_owned()),
        MIN_FULL_TILT_SPAN_DEG,
    )
}
