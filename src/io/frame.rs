//! The magnetometer's own frame: how an importer made body-axes µT values out of the
//! raw values a log holds, so that a calibration fitted in body axes and µT can be
//! handed back in the sensor's own axes and units.
//!
//! Every importer writes the field as `mag_in_body_ut = body_from_sensor · (u · raw)`:
//! `raw` as written in the log, `u` the µT per raw unit (100 for gauss, 0.1 for milligauss
//! and for MotionCal's `Raw:` counts, 0.001 for nanotesla; 1 for raw counts of a sensor
//! whose sensitivity the log does not give, which are kept as they are, so that every
//! field strength is then in counts), `body_from_sensor` a rotation
//! from the raw values' axes to body axes (x forward, y right, z down). A
//! [`SensorFrame`] records the three, next to where each importer does that
//! conversion; [`crate::fit::export::SensorCalibration`] uses it to turn a body-axes
//! calibration back into the one a device applies to its raw readings.
//!
//! Only the frames below can be made, and each `body_from_sensor` is a proper rotation
//! (a test checks every one), so its inverse is its transpose and a rotation keeps the
//! field's magnitude.

use nalgebra::Matrix3;
use serde::{Serialize, Serializer};

use super::axes::PhoneMount;

/// How the unit of the raw values is known.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum UnitOrigin {
    /// Written in the log (a column name, a unit after the values) or fixed by the
    /// format (MotionCal's counts, Android's µT).
    Stated,
    /// The log gives no unit: guessed from the field's size.
    Guessed,
    /// The log gives no unit and µT was taken, as the format's usual unit.
    Assumed,
}

/// The median magnitudes of magnetometer values without a unit that are taken as raw
/// counts: from 1000, above any µT reading (the Earth's 25-65 µT, a phone's hard iron
/// several hundred µT), to 20,000, below the Earth's field in nT (25,000-65,000 nT). A
/// QMC5883L at ±8 G gives 3000 counts per gauss, so the Earth's field reads 750-2000
/// counts, and hard iron adds thousands.
pub const RAW_COUNT_MAGNITUDES: std::ops::Range<f64> = 1_000.0..20_000.0;

/// MotionCal's `Raw:` magnetometer count in µT (`imuread.h`: `UT_PER_COUNT`).
pub const MOTIONCAL_UT_PER_COUNT: f64 = 0.1;

/// The unit of a magnetometer's raw values as the log writes them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MagUnit {
    /// The unit's name: "µT", "gauss", "mG", "nT", "T", "MotionCal count" or "counts".
    pub name: &'static str,
    /// Microtesla per raw unit; `None` when it is unknown (raw counts of a sensor whose
    /// sensitivity the log does not give). See [`MagUnit::factor`].
    pub ut_per_unit: Option<f64>,
    pub origin: UnitOrigin,
}

impl MagUnit {
    pub const MICROTESLA: MagUnit = MagUnit::stated("µT", 1.0);
    pub const GAUSS: MagUnit = MagUnit::stated("gauss", 100.0);
    pub const MILLIGAUSS: MagUnit = MagUnit::stated("mG", 0.1);
    pub const NANOTESLA: MagUnit = MagUnit::stated("nT", 1e-3);
    pub const TESLA: MagUnit = MagUnit::stated("T", 1e6);
    /// MotionCal's `Raw:` magnetometer count, 0.1 µT.
    pub const MOTIONCAL_COUNT: MagUnit = MagUnit::stated("MotionCal count", MOTIONCAL_UT_PER_COUNT);
    /// Raw counts whose µT per count is unknown, told from the values' size: thousands,
    /// far from the Earth's field (25-65 µT) in µT, gauss or nT. The values are kept as
    /// they are (factor 1), so the fits work in counts and every field strength is in
    /// counts.
    pub const COUNTS: MagUnit = MagUnit {
        name: "counts",
        ut_per_unit: None,
        origin: UnitOrigin::Guessed,
    };

    const fn stated(name: &'static str, ut_per_unit: f64) -> MagUnit {
        MagUnit {
            name,
            ut_per_unit: Some(ut_per_unit),
            origin: UnitOrigin::Stated,
        }
    }

    /// The factor the importer applied to the raw values: µT per unit, or 1 where that
    /// is unknown (the values were kept as they are).
    pub fn factor(&self) -> f64 {
        self.ut_per_unit.unwrap_or(1.0)
    }

    /// The same unit, guessed from the values rather than read.
    pub const fn guessed(self) -> MagUnit {
        MagUnit {
            origin: UnitOrigin::Guessed,
            ..self
        }
    }

    /// µT, taken because the log gives no unit.
    pub const fn assumed_microtesla() -> MagUnit {
        MagUnit {
            origin: UnitOrigin::Assumed,
            ..MagUnit::MICROTESLA
        }
    }

    /// Whether two units scale the same way, however they became known.
    pub fn same_scale(&self, other: &MagUnit) -> bool {
        self.name == other.name && self.ut_per_unit == other.ut_per_unit
    }

    /// The unit for people: "gauss", "MotionCal count (0.1 µT)", "assumed µT (the log
    /// gives no unit)", "gauss (guessed from the field's size)", "counts (µT per unit
    /// unknown: …)".
    pub fn label(&self) -> String {
        let Some(ut_per_unit) = self.ut_per_unit else {
            let origin = match self.origin {
                UnitOrigin::Stated => "",
                UnitOrigin::Guessed | UnitOrigin::Assumed => {
                    ", told from the values' size (far from the Earth's field in µT, gauss or nT)"
                }
            };
            return format!(
                "{} (µT per unit unknown: the values are kept as they are and field strengths \
                 are in {}){origin}",
                self.name, self.name
            );
        };
        let scale = if self.name == "µT" || ut_per_unit == 1.0 {
            String::new()
        } else {
            format!(" ({ut_per_unit} µT)")
        };
        match (self.origin, ut_per_unit == 1.0) {
            (UnitOrigin::Stated, _) => format!("{}{scale}", self.name),
            (_, true) => "assumed µT (the log gives no unit)".to_string(),
            (_, false) => format!("{}{scale}, guessed from the field's size", self.name),
        }
    }
}

/// The serial-line formats' axes: the sensor chip's own, as the sketch prints them.
pub const SENSOR_AXES_AS_PRINTED: &str =
    "the sensor's own x, y, z as printed (z up out of the board)";
/// Android's device axes (phone apps, the Android sensor dump, GetSensorData).
pub const ANDROID_DEVICE_AXES: &str =
    "Android device axes: x right, y towards the top of the screen, z out of the screen";
/// Delimited files whose columns are read as body axes (canonical names, plain x, y, z).
pub const COLUMNS_AS_BODY_AXES: &str =
    "the log's x, y, z columns as written (read as body axes: x forward, y right, z down)";
/// PX4's `sensor_mag` x, y, z: the driver's axes, before the calibration's rotation
/// (`CAL_MAGn_ROT`, or the board's for an internal compass).
pub const PX4_SENSOR_MAG_AXES: &str = "PX4 sensor_mag axes (the driver's)";
/// Body axes themselves, for a calibration that says nothing else.
pub const BODY_AXES: &str = "body axes (x forward, y right, z down)";

/// How the body-axes µT magnetometer values of a recording were made from the log's raw
/// values: `mag_in_body_ut = body_from_sensor · (unit.ut_per_unit · raw)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SensorFrame {
    /// From the raw values' axes to body axes; a proper rotation.
    #[serde(serialize_with = "matrix_rows")]
    pub body_from_sensor: Matrix3<f64>,
    /// The raw values' unit.
    pub unit: MagUnit,
    /// The raw values' axes, for people.
    pub axes: &'static str,
}

impl SensorFrame {
    /// Serial sensor lines: the chip's axes (x forward, y left, z up) to body axes is a
    /// half turn about x, (x, −y, −z) (see [`crate::io::serial_lines::sensor_to_body`]).
    pub fn serial_board(unit: MagUnit) -> SensorFrame {
        SensorFrame {
            body_from_sensor: Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, -1.0, -1.0)),
            unit,
            axes: SENSOR_AXES_AS_PRINTED,
        }
    }

    /// Android device axes turned into body axes by the phone's mount.
    pub fn android_device(mount: PhoneMount, unit: MagUnit) -> SensorFrame {
        SensorFrame {
            body_from_sensor: mount.body_from_device(),
            unit,
            axes: ANDROID_DEVICE_AXES,
        }
    }

    /// Columns read as body axes (the canonical CSV, plain x, y, z): no rotation.
    pub fn columns_as_body(unit: MagUnit) -> SensorFrame {
        SensorFrame {
            body_from_sensor: Matrix3::identity(),
            unit,
            axes: COLUMNS_AS_BODY_AXES,
        }
    }

    /// Body axes and µT: the frame of a calibration that states no other (one saved
    /// before calibrations said their axes, or a recording made in code).
    pub fn body_ut() -> SensorFrame {
        SensorFrame {
            body_from_sensor: Matrix3::identity(),
            unit: MagUnit::MICROTESLA,
            axes: BODY_AXES,
        }
    }

    /// Whether the raw values are body axes in µT already (so a calibration reads the
    /// same in both).
    pub fn is_body_ut(&self) -> bool {
        self.body_from_sensor == Matrix3::identity() && self.unit.ut_per_unit == Some(1.0)
    }

    /// The same rotation and unit, whatever the words or the unit's origin.
    pub fn same_conversion(&self, other: &SensorFrame) -> bool {
        self.body_from_sensor == other.body_from_sensor && self.unit.same_scale(&other.unit)
    }

    /// One sentence for the notes: which axes and unit the magnetometer's raw values are
    /// in, and how they became body axes.
    pub fn describe(&self) -> String {
        let m = &self.body_from_sensor;
        let axis = |row: usize| {
            let terms: Vec<String> = (0..3)
                .filter(|&col| m[(row, col)] != 0.0)
                .map(|col| {
                    let name = ["x", "y", "z"][col];
                    match m[(row, col)] {
                        1.0 => name.to_string(),
                        -1.0 => format!("−{name}"),
                        value => format!("{value:.3}·{name}"),
                    }
                })
                .collect();
            terms.join(" + ")
        };
        format!(
            "magnetometer raw values: {}, in {}; body axes (x forward, y right, z down) = ({}, {}, {})",
            self.axes,
            self.unit.label(),
            axis(0),
            axis(1),
            axis(2)
        )
    }
}

/// A matrix as rows, `[[m00, m01, m02], …]`, the way people read it.
fn matrix_rows<S: Serializer>(matrix: &Matrix3<f64>, serializer: S) -> Result<S::Ok, S::Error> {
    let row = |i: usize| [matrix[(i, 0)], matrix[(i, 1)], matrix[(i, 2)]];
    [row(0), row(1), row(2)].serialize(serializer)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn every_frame_is_a_proper_rotation() {
        let frames = [
            SensorFrame::serial_board(MagUnit::MOTIONCAL_COUNT),
            SensorFrame::android_device(PhoneMount::Flat, MagUnit::MICROTESLA),
            SensorFrame::android_device(PhoneMount::Upright, MagUnit::MICROTESLA),
            SensorFrame::columns_as_body(MagUnit::GAUSS),
            SensorFrame::columns_as_body(MagUnit::COUNTS),
            SensorFrame::body_ut(),
        ];
        for frame in frames {
            let b = frame.body_from_sensor;
            assert!(
                (b.transpose() * b - Matrix3::identity()).amax() < 1e-12,
                "{frame:?}"
            );
            assert!((b.determinant() - 1.0).abs() < 1e-12, "{frame:?}");
        }
    }

    #[test]
    fn the_frames_turn_vectors_as_their_importers_do() {
        let v = Vector3::new(1.0, 2.0, 3.0);
        assert_eq!(
            SensorFrame::serial_board(MagUnit::MICROTESLA).body_from_sensor * v,
            crate::io::serial_lines::sensor_to_body(v)
        );
        for mount in [PhoneMount::Flat, PhoneMount::Upright] {
            assert_eq!(
                SensorFrame::android_device(mount, MagUnit::MICROTESLA).body_from_sensor * v,
                mount.device_to_body(v)
            );
        }
    }

    #[test]
    fn units_say_how_they_are_known() {
        assert_eq!(MagUnit::GAUSS.label(), "gauss (100 µT)");
        assert_eq!(MagUnit::MOTIONCAL_COUNT.label(), "MotionCal count (0.1 µT)");
        assert_eq!(
            MagUnit::assumed_microtesla().label(),
            "assumed µT (the log gives no unit)"
        );
        assert_eq!(
            MagUnit::MICROTESLA.guessed().label(),
            "assumed µT (the log gives no unit)"
        );
        assert_eq!(
            MagUnit::GAUSS.guessed().label(),
            "gauss (100 µT), guessed from the field's size"
        );
        assert!(MagUnit::COUNTS
            .label()
            .starts_with("counts (µT per unit unknown: the values are kept as they are and field strengths are in counts), told from"));
        assert_eq!(MagUnit::COUNTS.factor(), 1.0);
        assert!(!SensorFrame::columns_as_body(MagUnit::COUNTS).is_body_ut());
        let described = SensorFrame::serial_board(MagUnit::MOTIONCAL_COUNT).describe();
        assert!(described.contains("= (x, −y, −z)"), "{described}");
    }
}
