//! PX4's compass calibration, applied and undone.
//!
//! PX4 corrects a magnetometer as `corrected = R · S · (raw − offset)`
//! (`src/lib/sensor_calibration/Magnetometer.hpp`, `Correct`; ignoring the power
//! compensation `CAL_MAGn_COMP*`): `offset` = `CAL_MAGn_XOFF/YOFF/ZOFF` (gauss), `S` the
//! symmetric matrix with `CAL_MAGn_XSCALE/YSCALE/ZSCALE` on its diagonal and
//! `CAL_MAGn_XODIAG/YODIAG/ZODIAG` off it (`Magnetometer.cpp`, `set_offdiagonal`:
//! `S = [[xs, xod, yod], [xod, ys, zod], [yod, zod, zs]]`), and `R` the rotation
//! `CAL_MAGn_ROT` of an external compass, or for an internal one (`ROT` −1) the
//! board's, `SENS_BOARD_ROT` (`Utilities.cpp`, `GetBoardRotationMatrix`, which leaves
//! the level trim `SENS_BOARD_X/Y/Z_OFF` out). `n` is the slot whose `CAL_MAGn_ID` is
//! the sensor's device id.

use crate::io::autopilot::px4::Px4Compass;
use nalgebra::{Matrix3, Rotation3, Vector3};

/// PX4's `rot_lookup` (`src/lib/conversion/rotation.h`): roll, pitch, yaw in degrees of
/// each `enum Rotation` entry, from board (or sensor) axes to airframe axes.
const ROT_LOOKUP_DEG: [[f64; 3]; 48] = [
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 45.0],
    [0.0, 0.0, 90.0],
    [0.0, 0.0, 135.0],
    [0.0, 0.0, 180.0],
    [0.0, 0.0, 225.0],
    [0.0, 0.0, 270.0],
    [0.0, 0.0, 315.0],
    [180.0, 0.0, 0.0],
    [180.0, 0.0, 45.0],
    [180.0, 0.0, 90.0],
    [180.0, 0.0, 135.0],
    [0.0, 180.0, 0.0],
    [180.0, 0.0, 225.0],
    [180.0, 0.0, 270.0],
    [180.0, 0.0, 315.0],
    [90.0, 0.0, 0.0],
    [90.0, 0.0, 45.0],
    [90.0, 0.0, 90.0],
    [90.0, 0.0, 135.0],
    [270.0, 0.0, 0.0],
    [270.0, 0.0, 45.0],
    [270.0, 0.0, 90.0],
    [270.0, 0.0, 135.0],
    [0.0, 90.0, 0.0],
    [0.0, 270.0, 0.0],
    [0.0, 180.0, 90.0],
    [0.0, 180.0, 270.0],
    [90.0, 90.0, 0.0],
    [180.0, 90.0, 0.0],
    [270.0, 90.0, 0.0],
    [90.0, 180.0, 0.0],
    [270.0, 180.0, 0.0],
    [90.0, 270.0, 0.0],
    [180.0, 270.0, 0.0],
    [270.0, 270.0, 0.0],
    [90.0, 180.0, 90.0],
    [90.0, 0.0, 270.0],
    [90.0, 68.0, 293.0],
    [0.0, 315.0, 0.0],
    [90.0, 315.0, 0.0],
    [270.0, 0.0, 180.0],
    [270.0, 0.0, 270.0],
    [0.0, 90.0, 180.0],
    [0.0, 9.0, 180.0],
    [0.0, 45.0, 0.0],
    [270.0, 0.0, 225.0],
    [270.0, 0.0, 315.0],
];

/// Euler ZYX (roll, pitch, yaw in degrees) as a matrix, as PX4's `Dcmf(Eulerf(..))`.
fn euler_deg(roll_deg: f64, pitch_deg: f64, yaw_deg: f64) -> Matrix3<f64> {
    Rotation3::from_euler_angles(
        roll_deg.to_radians(),
        pitch_deg.to_radians(),
        yaw_deg.to_radians(),
    )
    .into_inner()
}

/// The matrix of PX4's rotation `code` (`get_rot_matrix`), from sensor (or board)
/// axes to body axes; `None` for a code PX4 does not define.
pub fn px4_rotation(code: i32) -> Option<Matrix3<f64>> {
    let [roll_deg, pitch_deg, yaw_deg] = *ROT_LOOKUP_DEG.get(usize::try_from(code).ok()?)?;
    let matrix = euler_deg(roll_deg, pitch_deg, yaw_deg);
    // Products of quarter and eighth turns: clean the 1e-16 rounding to exact values.
    Some(matrix.map(|value| {
        let rounded = (value * 1e12).round() / 1e12;
        if rounded == 0.0 {
            0.0
        } else {
            rounded
        }
    }))
}

/// One compass's calibration in force, from the parameters.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Calibration {
    pub slot: usize,
    /// `None` when the rotation code is unknown.
    pub body_from_sensor: Option<Matrix3<f64>>,
    pub scale: Matrix3<f64>,
    pub offset_ga: Vector3<f64>,
    /// How `R` was chosen, for people.
    pub rotation_source: String,
}

/// The calibration slot of `device_id` and what it holds; `None` when no
/// `CAL_MAGn_ID` names the device.
pub(super) fn calibration(
    param: &dyn Fn(&str) -> Option<f64>,
    device_id: u32,
) -> Option<Calibration> {
    let slot = (0..8).find(|slot| param(&format!("CAL_MAG{slot}_ID")) == Some(device_id as f64))?;
    let get =
        |suffix: &str, default: f64| param(&format!("CAL_MAG{slot}_{suffix}")).unwrap_or(default);
    let rotation_code = get("ROT", -1.0) as i32;
    let (body_from_sensor, rotation_source) = if rotation_code >= 0 {
        (
            px4_rotation(rotation_code),
            format!("CAL_MAG{slot}_ROT {rotation_code} (external)"),
        )
    } else {
        let board_code = param("SENS_BOARD_ROT").unwrap_or(0.0) as i32;
        (
            px4_rotation(board_code),
            format!("internal: SENS_BOARD_ROT {board_code}"),
        )
    };
    // The offsets and scales as PX4 stores them: one reading, `Px4Compass`'s.
    let px4 = Px4Compass::from_params(param, slot, Matrix3::identity());
    Some(Calibration {
        slot,
        body_from_sensor,
        scale: px4.scale,
        offset_ga: px4.offset_ga,
        rotation_source,
    })
}

impl Calibration {
    /// `R · S · (raw − offset)`, gauss.
    pub(super) fn apply(
        &self,
        body_from_sensor: &Matrix3<f64>,
        raw_ga: &Vector3<f64>,
    ) -> Vector3<f64> {
        body_from_sensor * (self.scale * (raw_ga - self.offset_ga))
    }

    /// The inverse, from a corrected (body axes) field to the raw one in body axes:
    /// `R · (S⁻¹ · Rᵀ · corrected + offset)`; `None` for a singular `S`.
    pub(super) fn undo_into_body(
        &self,
        body_from_sensor: &Matrix3<f64>,
    ) -> Option<impl Fn(&Vector3<f64>) -> Vector3<f64>> {
        let scale_inverse = self.scale.try_inverse()?;
        let rotation = *body_from_sensor;
        let offset_ga = self.offset_ga;
        Some(move |corrected_ga: &Vector3<f64>| {
            rotation * (scale_inverse * (rotation.transpose() * corrected_ga) + offset_ga)
        })
    }
}
