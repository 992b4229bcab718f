//! The calibration fits, one model per file, each named for the [`Method`] that runs it
//! where there is one.
//!
//! [`minmax`] is the min/max autocalibration (Moafipoor et al. 2007, Eq. 6-7, after
//! Caruso 1997); [`ellipse`] the tilt-aware level-plane fit for circle-only data (with
//! [`ellipse_isotropic`] its fallback); [`ellipsoid`] the 3D fit of Eq. 5 with the dip and
//! gravity; [`ref_ls`] the reference-heading least squares of Eq. 8; [`autopilot_aided`]
//! the fit levelled by an autopilot's own attitude; [`streaming_ellipsoid`] the live
//! panel's power-sum fit, refitted at any time. [`model`] holds what they produce,
//! [`quality`] the bounds a calibration must meet to be written to a device, [`coverage`]
//! MotionCal's 100 regions of the sphere of directions, and [`export`] the formats a
//! device takes. `normal_lm` is the Levenberg-Marquardt on the normal equations that
//! the ellipse fits share.
//!
//! Each fit cites its paper and equation in its header and has its own error type,
//! whose messages say what the user can do. A folder's `mod.rs` holds its public types
//! and entry point and re-exports what other modules import, so that paths stay
//! `fit::<fit>::<item>`; its other files are `pub(super)` rooms.
//!
//! [`Method`]: crate::analysis::calibration::Method

pub mod autopilot_aided;
pub mod coverage;
pub mod ellipse;
pub mod ellipse_isotropic;
pub mod ellipsoid;
pub mod export;
pub mod minmax;
pub mod model;
mod normal_lm;
pub mod quality;
pub mod ref_ls;
pub mod streaming_ellipsoid;

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
