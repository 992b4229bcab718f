//! Device axes to body axes, in one place.
//!
//! Android phones (and apps that export their sensors as they come: phyphox, Sensor
//! Logger, the Android sensor dump) report vectors in the *device* frame: x to the
//! right of the screen, y up along the screen towards its top edge, z out of the
//! screen. Accelerometers report specific force, so a phone lying face up reads
//! z ≈ +9.81 m/s².
//!
//! This crate's body frame is x forward, y right, z down, and which device axis is
//! "forward" depends on how the phone is carried:
//!
//! - **held flat**, screen up, top edge forward (walking with the phone in hand):
//!   body = (y, x, −z);
//! - **upright** in a mount, screen towards the user, back facing forward (a car
//!   mount): body = (−z, x, −y).
//!
//! Both are proper rotations (determinant +1), so the field's handedness is kept.
//! [`PhoneMount::detect`] chooses between them from the mean specific force.

use nalgebra::Vector3;
use serde::Serialize;

/// How a phone is carried, which fixes its forward axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PhoneMount {
    /// Screen up, top edge forward.
    Flat,
    /// Screen towards the user, back facing forward.
    Upright,
}

impl PhoneMount {
    /// A vector in Android device axes, in body axes.
    pub fn device_to_body(self, v_in_device: Vector3<f64>) -> Vector3<f64> {
        match self {
            PhoneMount::Flat => Vector3::new(v_in_device.y, v_in_device.x, -v_in_device.z),
            PhoneMount::Upright => Vector3::new(-v_in_device.z, v_in_device.x, -v_in_device.y),
        }
    }

    /// The matrix of [`PhoneMount::device_to_body`]: body = M · device.
    pub fn body_from_device(self) -> nalgebra::Matrix3<f64> {
        nalgebra::Matrix3::from_columns(
            &[Vector3::x(), Vector3::y(), Vector3::z()].map(|axis| self.device_to_body(axis)),
        )
    }

    /// The mount whose "up" axis carries most of the mean specific force (device
    /// axes): z for a flat phone, y for an upright one. `None` without a clear answer
    /// (no data, or the force mostly along x: a phone on its side).
    pub fn detect(mean_specific_force_in_device: Vector3<f64>) -> Option<PhoneMount> {
        let f = mean_specific_force_in_device;
        let norm = f.norm();
        if !(norm.is_finite() && norm > 2.0) {
            return None;
        }
        if f.z.abs() >= f.y.abs() && f.z.abs() >= f.x.abs() {
            Some(PhoneMount::Flat)
        } else if f.y.abs() > f.x.abs() {
            Some(PhoneMount::Upright)
        } else {
            None
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            PhoneMount::Flat => "phone held flat, top edge forward: body x = device y, y = device x, z = −device z",
            PhoneMount::Upright => {
                "phone upright, back facing forward: body x = −device z, y = device x, z = −device y"
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::STANDARD_GRAVITY_MPS2;

    #[test]
    fn gravity_reads_down_in_body_axes_for_both_mounts() {
        // At rest the specific force points up: +z (device) when flat, +y when upright.
        let flat = PhoneMount::Flat.device_to_body(Vector3::new(0.0, 0.0, STANDARD_GRAVITY_MPS2));
        let upright =
            PhoneMount::Upright.device_to_body(Vector3::new(0.0, STANDARD_GRAVITY_MPS2, 0.0));
        assert_eq!(flat, Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2));
        assert_eq!(upright, Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2));
    }

    #[test]
    fn the_mappings_are_proper_rotations() {
        for mount in [PhoneMount::Flat, PhoneMount::Upright] {
            let columns =
                [Vector3::x(), Vector3::y(), Vector3::z()].map(|axis| mount.device_to_body(axis));
            let matrix = nalgebra::Matrix3::from_columns(&columns);
            assert!((matrix.determinant() - 1.0).abs() < 1e-12, "{mount:?}");
        }
    }

    #[test]
    fn the_mount_is_detected_from_gravity() {
        assert_eq!(
            PhoneMount::detect(Vector3::new(0.3, 1.0, 9.7)),
            Some(PhoneMount::Flat)
        );
        assert_eq!(
            PhoneMount::detect(Vector3::new(-0.05, 9.77, -0.07)),
            Some(PhoneMount::Upright)
        );
        assert_eq!(PhoneMount::detect(Vector3::new(9.8, 0.1, 0.1)), None);
        assert_eq!(PhoneMount::detect(Vector3::zeros()), None);
    }
}
