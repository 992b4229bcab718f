//! The calibration models every fit produces, and how they correct a sample.
//!
//! Moafipoor et al. (2007), Eq. 2-3 and 5: a measured field `m = S·b + h` is the true
//! field `b` (body frame) seen through a soft-iron matrix `S` (symmetric, near the
//! identity: axis scale factors on the diagonal, cross-coupling off it) plus a hard-iron
//! offset `h`. The correction is its inverse, `b = A·(m − h)` with `A = S⁻¹`.

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use serde::Serialize;

/// A full 3D calibration: `corrected = soft_iron · (raw − hard_iron)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FieldCalibration {
    pub hard_iron_ut: Vector3<f64>,
    /// The correction matrix `A = S⁻¹`, symmetric.
    pub soft_iron: Matrix3<f64>,
    /// The field magnitude after correction (the corrected sphere's radius).
    pub field_ut: f64,
}

impl FieldCalibration {
    pub fn apply(&self, raw_ut: Vector3<f64>) -> Vector3<f64> {
        self.soft_iron * (raw_ut - self.hard_iron_ut)
    }
}

/// A calibration of the levelled horizontal field: `corrected = transform · (level −
/// center)`. Min/max has a diagonal transform; a general conic fit has a full one, which
/// also removes in-plane cross-axis soft iron.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlaneCalibration {
    pub center_ut: Vector2<f64>,
    pub transform: Matrix2<f64>,
    /// The corrected circle's radius.
    pub radius_ut: f64,
}

impl PlaneCalibration {
    pub fn apply(&self, level_ut: Vector2<f64>) -> Vector2<f64> {
        self.transform * (level_ut - self.center_ut)
    }
}
