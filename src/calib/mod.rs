//! Magnetometer calibration and the heading it gives.
//!
//! One algorithm per file: [`tilt`] levels the field (Eq. 4 of Moafipoor et al. 2007),
//! [`heading`] turns levelled components into a heading (Eq. 1), [`minmax`] is the
//! min/max autocalibration (Eq. 6-7, after Caruso 1997), [`plane`] the tilt-aware
//! level-plane fit for circle-only data, [`ellipsoid`] the 3D fit of Eq. 5, [`refls`]
//! the reference-heading least squares of Eq. 8; [`model`] holds what they produce,
//! [`wmm`] the expected field, [`export`] the formats a device takes.

pub mod acceptance;
pub mod attitude_aided;
pub mod ellipsoid;
pub mod export;
pub mod gravity;
pub mod heading;
pub mod inertial;
pub mod minmax;
pub mod model;
mod normal_lm;
pub mod plane;
pub mod plane_isotropic;
pub mod refls;
pub mod sphere_coverage;
pub mod tilt;
pub mod wmm;

use thiserror::Error;

/// Why a calibration could not be fitted. Messages say what the user can do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CalibError {
    #[error("too few magnetometer samples ({n_samples}; at least {min} are needed). Record longer, turning through a full circle.")]
    TooFewSamples { n_samples: usize, min: usize },

    #[error(
        "sample {sample_idx} is not a finite number. Remove NaN or infinite values from the input."
    )]
    NonFinite { sample_idx: usize },

    #[error(
        "the horizontal field hardly changes along {axis} (range {range_ut:.2} µT), so there is \
         no turn to calibrate from. Turn the device through a full circle while holding it level."
    )]
    NoTurn { axis: &'static str, range_ut: f64 },

    #[error(
        "the horizontal field along {axis} spans only {range_ut:.2} µT, under {min_noise_multiple:.0} \
         times the sensor's own noise ({noise_ut:.2} µT): the device hardly turned, so the \
         extremes are noise, not the field. Turn the device through a full circle while \
         holding it level."
    )]
    NoTurnAboveNoise {
        axis: &'static str,
        range_ut: f64,
        noise_ut: f64,
        min_noise_multiple: f64,
    },
}
