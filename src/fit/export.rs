//! A calibration in the forms other tools read: JSON, a C/Arduino snippet, and the
//! MotionCal calibration packet.
//!
//! The fits work in body axes and µT ([`FieldCalibration`]), but a device applies its
//! calibration to its own raw readings, in its own axes and units. So every export is a
//! [`SensorCalibration`]: the body-axes fit turned back through the importer's
//! [`SensorFrame`] into the axes and unit the log's raw values are written in, and each
//! form says which, with the formula `corrected = soft_iron · (raw − hard_iron)` for raw
//! values as the log writes them: with `B` the frame's rotation and `u` its µT per raw
//! unit, hard iron `Bᵀ·h_b/u` and soft iron `Bᵀ·S_b·B`. The MotionCal packet carries µT
//! (its floats are µT by definition) in the raw values' axes. Raw counts of unknown
//! sensitivity are exported in counts (`u` = 1): the JSON's `ut_per_unit` is null, the
//! snippet declares no `mag_ut_per_unit`, and there is no packet.
//!
//! The MotionCal packet is the one PJRC's MotionCal sends to a board over the serial
//! port, and which Adafruit's `Adafruit_Sensor_Calibration` examples and PJRC's
//! `NXPMotionSense` receive and store. Its layout is `send_calibration()` in MotionCal's
//! `rawdata.c` (IanBUK/MotionCal, commit 0bc48368026da9c8fe436addafb4be0fe96df929; the
//! older upstream PaulStoffregen/MotionCal 1d9800ae sent a 52-byte form without the
//! accelerometer, gyroscope and field values):
//!
//! ```text
//! bytes  0-1   117, 84 ("uT")
//! bytes  2-65  16 little-endian float32:
//!              0-2   accelerometer offsets (written as 0)
//!              3-5   gyroscope offsets (written as 0)
//!              6-8   hard-iron offset V (µT)
//!              9     field strength B (µT)
//!              10-15 inverse soft-iron invW[0][0], [1][1], [2][2], [0][1], [0][2], [1][2]
//! bytes 66-67  CRC-16 of bytes 0-65, little-endian: reflected polynomial 0xA001,
//!              initial value 0xFFFF, no final XOR (CRC-16/MODBUS)
//! ```
//!
//! MotionCal's `invW` is the correction matrix applied after subtracting `V`, exactly
//! this crate's `soft_iron`. A receiver runs the CRC over all 68 bytes and accepts the
//! packet when the result is 0, which is what appending the CRC low byte first gives.
//! The packet holds only six soft-iron entries, so it carries a symmetric matrix. A
//! general correction `D` (the tilt-aided 3D fit's, which also turns the magnetometer's
//! axes onto the accelerometer's) is written as the symmetric factor of its polar
//! decomposition, `P = (DᵀD)^½` with `D = Q·P`: `|P·d| = |D·d|` for every `d`, so the
//! corrected field's magnitude (all MotionCal and the boards' fusion check) is exactly
//! ours, and only the small rotation `Q` is left out.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::fit::model::FieldCalibration;
use crate::io::frame::{SensorFrame, BODY_AXES};

/// The length of a MotionCal calibration packet.
pub const MOTIONCAL_PACKET_LEN: usize = 68;

/// The packet's first two bytes, "uT".
const MOTIONCAL_MAGIC: [u8; 2] = [117, 84];

/// Where the floats start, and their order (indices into the 16 floats).
const FLOATS_OFFSET: usize = 2;
const HARD_IRON_FLOAT_IDX: usize = 6;
const FIELD_FLOAT_IDX: usize = 9;
/// The soft-iron entries (row, column) carried by floats 10 to 15.
const SOFT_IRON_ENTRIES: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];
const SOFT_IRON_FIRST_FLOAT_IDX: usize = 10;
const N_FLOATS: usize = 16;
const CRC_OFFSET: usize = FLOATS_OFFSET + 4 * N_FLOATS;

/// Why a saved calibration could not be read back. Messages say what the user can do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ExportError {
    #[error(
        "a MotionCal calibration packet is {MOTIONCAL_PACKET_LEN} bytes, but this one has \
         {n_bytes}. Save the whole packet, as compass-pdr or MotionCal wrote it."
    )]
    PacketLength { n_bytes: usize },

    #[error(
        "this is not a MotionCal calibration packet: it starts with bytes {found:?} instead \
         of [117, 84] (\"uT\"). Check that you chose the packet file."
    )]
    PacketMagic { found: [u8; 2] },

    #[error(
        "the MotionCal packet is damaged: its checksum is {found:#06x} but its contents give \
         {calculated:#06x}. Export the calibration again."
    )]
    PacketChecksum { calculated: u16, found: u16 },

    #[error(
        "the calibration's {what} is not a finite number. Export the calibration again, or \
         fix the value in the file."
    )]
    NonFinite { what: &'static str },

    #[error(
        "the calibration's field strength is {field_ut} µT; it must be positive. Export the \
         calibration again, or fix field_ut in the file."
    )]
    FieldNotPositive { field_ut: f64 },

    #[error(
        "the calibration's ut_per_unit is {ut_per_unit}; it must be a positive number of µT \
         per unit. Export the calibration again, or fix ut_per_unit in the file."
    )]
    UnitScale { ut_per_unit: f64 },

    #[error(
        "the calibration is in {unit} whose µT per unit is unknown (ut_per_unit is null), so \
         it cannot be turned into µT. Apply it to the raw values as they are, or give the \
         unit when importing the log."
    )]
    UnitUnknown { unit: String },

    #[error(
        "could not read the calibration JSON: {reason}. It should look like {{\"unit\": \"µT\", \
         \"hard_iron\": [x, y, z], \"soft_iron\": [[a, b, c], [d, e, f], [g, h, i]], \
         \"field\": B}}, as compass-pdr writes it."
    )]
    Json { reason: String },
}

/// A calibration in the axes and unit of a magnetometer's raw values, as a device
/// applies it: `corrected = soft_iron · (raw − hard_iron)`, with `raw` as the log writes
/// it. `corrected` comes out in the same axes and unit, of magnitude `field`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorCalibration {
    /// In `frame.unit`, along the raw values' axes.
    pub hard_iron: Vector3<f64>,
    /// Dimensionless.
    pub soft_iron: Matrix3<f64>,
    /// The field strength after correction, in `frame.unit`.
    pub field: f64,
    /// The raw values' axes and unit.
    pub frame: SensorFrame,
}

impl SensorCalibration {
    /// A body-axes µT calibration in the raw values' axes and unit.
    ///
    /// The log's raw values `r` became `m_b = B·u·r` (`B` = `body_from_sensor`, a
    /// rotation, `u` µT per raw unit), and the fit corrects `c_b = S_b·(m_b − h_b)`. Then
    /// `c_b = S_b·(B·u·r − h_b) = u·S_b·B·(r − Bᵀ·h_b/u)`, and the same correction in the
    /// raw axes and unit, `c = Bᵀ·c_b/u`, is `c = Bᵀ·S_b·B·(r − Bᵀ·h_b/u)`: hard iron
    /// `Bᵀ·h_b/u`, soft iron `Bᵀ·S_b·B`, field `F/u` (a rotation keeps the magnitude).
    /// Raw counts of unknown sensitivity were kept as they are (`u` = 1, see
    /// [`crate::io::MagUnit::factor`]): the "µT" fit is then in counts.
    pub fn from_body(body_ut: &FieldCalibration, frame: &SensorFrame) -> SensorCalibration {
        let b = frame.body_from_sensor;
        let u = frame.unit.factor();
        SensorCalibration {
            hard_iron: b.transpose() * body_ut.hard_iron_ut / u,
            soft_iron: b.transpose() * body_ut.soft_iron * b,
            field: body_ut.field_ut / u,
            frame: *frame,
        }
    }

    /// A calibration fitted in the frame's own axes, in µT (the live session fits the
    /// board's readings as printed): only the unit changes.
    pub fn from_frame_ut(cal_ut: &FieldCalibration, frame: &SensorFrame) -> SensorCalibration {
        let u = frame.unit.factor();
        SensorCalibration {
            hard_iron: cal_ut.hard_iron_ut / u,
            soft_iron: cal_ut.soft_iron,
            field: cal_ut.field_ut / u,
            frame: *frame,
        }
    }

    /// The same correction for readings in µT along the same axes (what MotionCal's
    /// packet carries); `None` for raw counts whose µT per count is unknown.
    pub fn in_ut(&self) -> Option<FieldCalibration> {
        let u = self.frame.unit.ut_per_unit?;
        Some(FieldCalibration {
            hard_iron_ut: self.hard_iron * u,
            soft_iron: self.soft_iron,
            field_ut: self.field * u,
        })
    }

    /// A raw reading (as the log writes it) corrected, in the same axes and unit.
    pub fn apply(&self, raw: Vector3<f64>) -> Vector3<f64> {
        self.soft_iron * (raw - self.hard_iron)
    }

    /// How to apply it, in one sentence that names the axes and the unit.
    pub fn formula(&self) -> String {
        let unit = self.frame.unit.label();
        format!(
            "corrected = soft_iron · (raw − hard_iron), with raw the magnetometer's values as \
             the log writes them, in {unit}, along {}; soft_iron row by row, so corrected[i] = \
             Σ_j soft_iron[i][j] · (raw[j] − hard_iron[j]); hard_iron and field are in {}, and \
             corrected comes out in the same unit and axes",
            self.frame.axes, self.frame.unit.name
        )
    }
}

/// Which axes an exported calibration is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExportAxes {
    /// The magnetometer's raw values' own axes, as the log writes them.
    Sensor,
    /// Body axes (x forward, y right, z down): the analysis's own frame, and how a
    /// calibration file without an `axes` key (written before they said) is read.
    #[default]
    Body,
}

/// A calibration as JSON-friendly arrays, with the axes and unit it is in: `soft_iron`
/// row by row, so that `corrected[i] = Σ_j soft_iron[i][j] · (raw[j] − hard_iron[j])`.
///
/// Files written before calibrations stated their axes (`hard_iron_ut`, `field_ut`, no
/// `axes` or `unit`) still read, as body axes and µT.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationExport {
    #[serde(default)]
    pub axes: ExportAxes,
    /// The axes in words.
    #[serde(default = "unstated_axes")]
    pub axes_description: String,
    /// The unit of the raw values, `hard_iron` and `field`: "µT", "gauss", …
    #[serde(default = "microtesla")]
    pub unit: String,
    /// Microtesla per unit; `null` for raw counts whose µT per count is unknown.
    #[serde(default = "one")]
    pub ut_per_unit: Option<f64>,
    /// How the unit is known ("stated", "guessed", "assumed").
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub unit_origin: String,
    /// How to apply it, in words.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub formula: String,
    #[serde(alias = "hard_iron_ut")]
    pub hard_iron: [f64; 3],
    pub soft_iron: [[f64; 3]; 3],
    #[serde(alias = "field_ut")]
    pub field: f64,
}

fn unstated_axes() -> String {
    format!("not stated (read as {BODY_AXES})")
}

fn microtesla() -> String {
    "µT".to_string()
}

#[expect(
    clippy::unnecessary_wraps,
    reason = "serde's default for an Option field must return the Option"
)]
fn one() -> Option<f64> {
    Some(1.0)
}

impl From<&SensorCalibration> for CalibrationExport {
    fn from(cal: &SensorCalibration) -> Self {
        let soft_iron = &cal.soft_iron;
        let row = |i: usize| [soft_iron[(i, 0)], soft_iron[(i, 1)], soft_iron[(i, 2)]];
        let unit = cal.frame.unit;
        CalibrationExport {
            axes: if cal.frame.axes == BODY_AXES {
                ExportAxes::Body
            } else {
                ExportAxes::Sensor
            },
            axes_description: cal.frame.axes.to_string(),
            unit: unit.name.to_string(),
            ut_per_unit: unit.ut_per_unit,
            unit_origin: match unit.origin {
                crate::io::UnitOrigin::Stated => "stated",
                crate::io::UnitOrigin::Guessed => "guessed",
                crate::io::UnitOrigin::Assumed => "assumed",
            }
            .to_string(),
            formula: cal.formula(),
            hard_iron: [cal.hard_iron.x, cal.hard_iron.y, cal.hard_iron.z],
            soft_iron: [row(0), row(1), row(2)],
            field: cal.field,
        }
    }
}

impl CalibrationExport {
    /// A body-axes µT calibration as the analysis itself uses it (`axes: body`).
    pub fn body_ut(cal: &FieldCalibration) -> CalibrationExport {
        CalibrationExport::from(&SensorCalibration::from_body(cal, &SensorFrame::body_ut()))
    }

    /// The correction these arrays describe for readings in µT along the export's axes,
    /// checked: every number finite, the field strength and the unit's scale positive.
    pub fn to_calibration(&self) -> Result<FieldCalibration, ExportError> {
        let Some(u) = self.ut_per_unit else {
            return Err(ExportError::UnitUnknown {
                unit: self.unit.clone(),
            });
        };
        if !(u.is_finite() && u > 0.0) {
            return Err(ExportError::UnitScale { ut_per_unit: u });
        }
        let hard_iron_ut = Vector3::from(self.hard_iron) * u;
        let soft_iron = Matrix3::from_fn(|i, j| self.soft_iron[i][j]);
        checked(hard_iron_ut, soft_iron, self.field * u)
    }
}

/// The JSON-friendly form of `cal`.
pub fn calibration_export(cal: &SensorCalibration) -> CalibrationExport {
    CalibrationExport::from(cal)
}

/// Reads a calibration saved as JSON (a [`CalibrationExport`]; other keys are ignored),
/// as the correction of readings in µT along the file's axes.
///
/// Native builds only: the page reads JSON with the browser's parser and passes the
/// parsed [`CalibrationExport`] to [`CalibrationExport::to_calibration`].
#[cfg(not(target_arch = "wasm32"))]
pub fn calibration_from_json(text: &str) -> Result<FieldCalibration, ExportError> {
    let export: CalibrationExport =
        serde_json::from_str(text).map_err(|error| ExportError::Json {
            reason: error.to_string(),
        })?;
    export.to_calibration()
}

/// The calibration as C (Arduino) declarations, with comments saying which axes and unit
/// it is in and how to apply it. Numbers are written with the shortest digits that give
/// back the same `float`.
pub fn c_snippet(cal: &SensorCalibration) -> String {
    let export = calibration_export(cal);
    let row = |values: &[f64; 3]| {
        format!(
            "{{ {}, {}, {} }}",
            c_float(values[0]),
            c_float(values[1]),
            c_float(values[2])
        )
    };
    let unit = ascii(cal.frame.unit.name);
    // Raw counts of unknown sensitivity have no µT per unit to declare.
    let (per_unit_comment, ut_per_unit) = match export.ut_per_unit {
        Some(ut_per_unit) => (
            format!("mag_ut_per_unit is uT per {unit}"),
            format!("float mag_ut_per_unit = {};\n", c_float(ut_per_unit)),
        ),
        None => (
            format!("the uT per unit ({unit}) is unknown, so there is no mag_ut_per_unit"),
            String::new(),
        ),
    };
    format!(
        "// Magnetometer calibration made by compass-pdr.\n\
         // Axes: {axes}.\n\
         // Unit: {unit_label}, as the log writes the raw values.\n\
         // Apply it to every raw reading exactly as the log writes it (same axes, same unit):\n\
         //   corrected = soft_iron * (raw - hard_iron)\n\
         // that is, for each i: corrected[i] = sum over j of soft_iron[i][j] * (raw[j] - hard_iron[j]).\n\
         // hard_iron and mag_field are in {unit}; corrected comes out in {unit}, in the same axes.\n\
         // mag_field is the field strength after correction; {per_unit_comment}.\n\
         float hard_iron[3] = {hard_iron};\n\
         float soft_iron[3][3] = {{\n  {row_0},\n  {row_1},\n  {row_2}\n}};\n\
         float mag_field = {field};\n\
         {ut_per_unit}",
        axes = ascii(cal.frame.axes),
        unit_label = ascii(&cal.frame.unit.label()),
        hard_iron = row(&export.hard_iron),
        row_0 = row(&export.soft_iron[0]),
        row_1 = row(&export.soft_iron[1]),
        row_2 = row(&export.soft_iron[2]),
        field = c_float(export.field),
    )
}

/// Text for a C comment, in ASCII: µ as u, the minus sign as -, other symbols spelt.
fn ascii(text: &str) -> String {
    text.chars()
        .map(|c| match c {
            'µ' | 'μ' => "u".to_string(),
            '−' | '–' => "-".to_string(),
            '·' => "*".to_string(),
            '²' => "^2".to_string(),
            '°' => " deg".to_string(),
            c if c.is_ascii() => c.to_string(),
            _ => "?".to_string(),
        })
        .collect()
}

/// The symmetric positive factor `P = (DᵀD)^½` of the polar decomposition `D = Q·P`
/// (see the module header); `D` itself when that fails (not finite).
pub fn symmetric_factor(correction: &Matrix3<f64>) -> Matrix3<f64> {
    let gram = correction.transpose() * correction;
    if !gram.iter().all(|v| v.is_finite()) {
        return *correction;
    }
    let eigen = gram.symmetric_eigen();
    let roots = eigen.eigenvalues.map(|value| value.max(0.0).sqrt());
    eigen.eigenvectors * Matrix3::from_diagonal(&roots) * eigen.eigenvectors.transpose()
}

/// The MotionCal calibration packet for `cal` (layout in the module header).
pub fn motioncal_packet(cal: &FieldCalibration) -> [u8; MOTIONCAL_PACKET_LEN] {
    let mut floats = [0.0f32; N_FLOATS];
    for axis_idx in 0..3 {
        floats[HARD_IRON_FLOAT_IDX + axis_idx] = cal.hard_iron_ut[axis_idx] as f32;
    }
    floats[FIELD_FLOAT_IDX] = cal.field_ut as f32;
    let symmetric = symmetric_factor(&cal.soft_iron);
    for (entry_idx, &(row, col)) in SOFT_IRON_ENTRIES.iter().enumerate() {
        let value = 0.5 * (symmetric[(row, col)] + symmetric[(col, row)]);
        floats[SOFT_IRON_FIRST_FLOAT_IDX + entry_idx] = value as f32;
    }

    let mut packet = [0u8; MOTIONCAL_PACKET_LEN];
    packet[..2].copy_from_slice(&MOTIONCAL_MAGIC);
    for (float_idx, value) in floats.iter().enumerate() {
        let at = FLOATS_OFFSET + 4 * float_idx;
        packet[at..at + 4].copy_from_slice(&value.to_le_bytes());
    }
    let crc = crc16_modbus(&packet[..CRC_OFFSET]);
    packet[CRC_OFFSET..].copy_from_slice(&crc.to_le_bytes());
    packet
}

/// Reads a MotionCal calibration packet back: checks its length, its "uT" start and its
/// checksum, then the values. The accelerometer and gyroscope offsets are ignored.
pub fn parse_motioncal_packet(bytes: &[u8]) -> Result<FieldCalibration, ExportError> {
    let packet: &[u8; MOTIONCAL_PACKET_LEN] =
        bytes.try_into().map_err(|_| ExportError::PacketLength {
            n_bytes: bytes.len(),
        })?;
    let found_magic = [packet[0], packet[1]];
    if found_magic != MOTIONCAL_MAGIC {
        return Err(ExportError::PacketMagic { found: found_magic });
    }
    let calculated = crc16_modbus(&packet[..CRC_OFFSET]);
    let found = u16::from_le_bytes([packet[CRC_OFFSET], packet[CRC_OFFSET + 1]]);
    if calculated != found {
        return Err(ExportError::PacketChecksum { calculated, found });
    }

    let float_at = |float_idx: usize| {
        let at = FLOATS_OFFSET + 4 * float_idx;
        f64::from(f32::from_le_bytes([
            packet[at],
            packet[at + 1],
            packet[at + 2],
            packet[at + 3],
        ]))
    };
    let hard_iron_ut = Vector3::from_fn(|axis_idx, _| float_at(HARD_IRON_FLOAT_IDX + axis_idx));
    let mut soft_iron = Matrix3::zeros();
    for (entry_idx, &(row, col)) in SOFT_IRON_ENTRIES.iter().enumerate() {
        let value = float_at(SOFT_IRON_FIRST_FLOAT_IDX + entry_idx);
        soft_iron[(row, col)] = value;
        soft_iron[(col, row)] = value;
    }
    checked(hard_iron_ut, soft_iron, float_at(FIELD_FLOAT_IDX))
}

/// CRC-16/MODBUS: reflected polynomial 0x8005 (0xA001 reflected), initial value 0xFFFF,
/// no final XOR, as MotionCal's `crc16()` and avr-libc's `_crc16_update()` compute it.
pub fn crc16_modbus(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &byte in bytes {
        crc ^= u16::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xA001
            } else {
                crc >> 1
            };
        }
    }
    crc
}

fn checked(
    hard_iron_ut: Vector3<f64>,
    soft_iron: Matrix3<f64>,
    field_ut: f64,
) -> Result<FieldCalibration, ExportError> {
    if !hard_iron_ut.iter().all(|value| value.is_finite()) {
        return Err(ExportError::NonFinite { what: "hard iron" });
    }
    if !soft_iron.iter().all(|value| value.is_finite()) {
        return Err(ExportError::NonFinite { what: "soft iron" });
    }
    if !field_ut.is_finite() {
        return Err(ExportError::NonFinite {
            what: "field strength",
        });
    }
    if field_ut <= 0.0 {
        return Err(ExportError::FieldNotPositive { field_ut });
    }
    Ok(FieldCalibration {
        hard_iron_ut,
        soft_iron,
        field_ut,
    })
}

/// A C `float` literal: the shortest decimal that reads back as the same `f32`.
fn c_float(value: f64) -> String {
    let value = value as f32;
    if value.is_nan() {
        return "NAN".to_owned();
    }
    if value.is_infinite() {
        return if value > 0.0 { "INFINITY" } else { "-INFINITY" }.to_owned();
    }
    // Rust's `Display` for floats never uses an exponent and drops ".0" from whole
    // numbers; C needs a decimal point before the `f` suffix.
    let digits = value.to_string();
    if digits.contains('.') {
        format!("{digits}f")
    } else {
        format!("{digits}.0f")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The calibration whose packet is the golden one below.
    fn known_calibration() -> FieldCalibration {
        FieldCalibration {
            hard_iron_ut: Vector3::new(12.5, -7.25, 30.0),
            soft_iron: Matrix3::new(
                1.02, 0.015, -0.01, //
                0.015, 0.98, 0.005, //
                -0.01, 0.005, 1.01,
            ),
            field_ut: 48.3,
        }
    }

    /// Computed independently in Python 3:
    /// `body = struct.pack('<2s16f', b'uT', 0, 0, 0, 0, 0, 0, 12.5, -7.25, 30.0, 48.3,
    /// 1.02, 0.98, 1.01, 0.015, -0.01, 0.005)`, then `body + struct.pack('<H', crc)`
    /// with a bitwise CRC (init 0xFFFF, `crc = (crc >> 1) ^ 0xA001` when the low bit is
    /// set) that gives 0x4B37 for b"123456789".
    const GOLDEN_PACKET_HEX: &str = "7554000000000000000000000000000000000000000000000000\
                                     000048410000e8c00000f041333341425c8f823f48e17a3fae47\
                                     813f8fc2753c0ad723bc0ad7a33bb572";

    fn hex(bytes: &[u8]) -> String {
        bytes.iter().map(|byte| format!("{byte:02x}")).collect()
    }

    fn assert_close(actual: &FieldCalibration, expected: &FieldCalibration, tolerance: f64) {
        assert!(
            (actual.hard_iron_ut - expected.hard_iron_ut).amax() <= tolerance
                && (actual.soft_iron - expected.soft_iron).amax() <= tolerance
                && (actual.field_ut - expected.field_ut).abs() <= tolerance,
            "{actual:?} differs from {expected:?}"
        );
    }

    #[test]
    fn the_crc_is_crc16_modbus() {
        // The CRC catalogue's check value for CRC-16/MODBUS.
        assert_eq!(crc16_modbus(b"123456789"), 0x4B37);
        assert_eq!(crc16_modbus(b""), 0xFFFF);
    }

    #[test]
    fn the_packet_matches_the_golden_bytes() {
        let packet = motioncal_packet(&known_calibration());
        assert_eq!(hex(&packet), GOLDEN_PACKET_HEX);
        // What the receiving sketches check: the CRC over all 68 bytes is zero.
        assert_eq!(crc16_modbus(&packet), 0);
    }

    #[test]
    fn the_packet_reads_back() {
        let cal = known_calibration();
        let read = parse_motioncal_packet(&motioncal_packet(&cal)).expect("a valid packet");
        // float32 keeps about 7 digits.
        assert_close(&read, &cal, 1e-5);
        // And once in float32, writing it again gives the same bytes.
        assert_eq!(motioncal_packet(&read), motioncal_packet(&cal));
    }

    #[test]
    fn damaged_packets_are_refused() {
        let packet = motioncal_packet(&known_calibration());

        assert_eq!(
            parse_motioncal_packet(&packet[..67]),
            Err(ExportError::PacketLength { n_bytes: 67 })
        );
        assert_eq!(
            parse_motioncal_packet(&[packet.as_slice(), &[0]].concat()),
            Err(ExportError::PacketLength { n_bytes: 69 })
        );
        assert_eq!(
            parse_motioncal_packet(&[]),
            Err(ExportError::PacketLength { n_bytes: 0 })
        );

        let mut wrong_magic = packet;
        wrong_magic[1] = b'X';
        assert_eq!(
            parse_motioncal_packet(&wrong_magic),
            Err(ExportError::PacketMagic { found: [117, 88] })
        );

        // A single flipped bit anywhere after the magic is caught by the checksum.
        for byte_idx in 2..MOTIONCAL_PACKET_LEN {
            for bit in 0..8 {
                let mut damaged = packet;
                damaged[byte_idx] ^= 1 << bit;
                assert!(
                    matches!(
                        parse_motioncal_packet(&damaged),
                        Err(ExportError::PacketChecksum { .. })
                    ),
                    "byte {byte_idx} bit {bit}"
                );
            }
        }
        let message = ExportError::PacketChecksum {
            calculated: 0x72b5,
            found: 0x72b4,
        }
        .to_string();
        assert!(message.contains("0x72b4") && message.contains("Export the calibration again"));
    }

    #[test]
    fn packets_with_impossible_values_are_refused() {
        let mut cal = known_calibration();
        cal.field_ut = f64::NAN;
        assert_eq!(
            parse_motioncal_packet(&motioncal_packet(&cal)),
            Err(ExportError::NonFinite {
                what: "field strength"
            })
        );
        cal.field_ut = 0.0;
        assert_eq!(
            parse_motioncal_packet(&motioncal_packet(&cal)),
            Err(ExportError::FieldNotPositive { field_ut: 0.0 })
        );
    }

    #[test]
    fn a_general_correction_is_written_as_its_symmetric_factor_with_the_same_magnitudes() {
        let mut cal = known_calibration();
        cal.soft_iron[(0, 1)] = 0.05;
        cal.soft_iron[(1, 0)] = -0.03;
        cal.soft_iron[(2, 0)] = 0.04;
        let read = parse_motioncal_packet(&motioncal_packet(&cal)).expect("a valid packet");
        assert_eq!(read.soft_iron, read.soft_iron.transpose());
        for raw in [
            Vector3::new(30.0, -10.0, 40.0),
            Vector3::new(-20.0, 25.0, 5.0),
            Vector3::new(0.0, 0.0, -45.0),
        ] {
            let (ours, packet) = (cal.apply(raw).norm(), read.apply(raw).norm());
            assert!(
                (ours - packet).abs() < 1e-4 * ours,
                "{ours} against {packet}"
            );
        }
    }

    /// A frame of every kind an importer makes.
    fn frames() -> Vec<SensorFrame> {
        use crate::io::axes::PhoneMount;
        use crate::io::MagUnit;
        vec![
            SensorFrame::body_ut(),
            SensorFrame::serial_board(MagUnit::MOTIONCAL_COUNT),
            SensorFrame::serial_board(MagUnit::assumed_microtesla()),
            SensorFrame::android_device(PhoneMount::Flat, MagUnit::MICROTESLA),
            SensorFrame::android_device(PhoneMount::Upright, MagUnit::MICROTESLA),
            SensorFrame::columns_as_body(MagUnit::GAUSS),
            SensorFrame::columns_as_body(MagUnit::NANOTESLA.guessed()),
            SensorFrame::columns_as_body(MagUnit::COUNTS),
        ]
    }

    #[test]
    fn the_sensor_calibration_corrects_raw_values_as_the_body_one_corrects_imported_ones() {
        let body = known_calibration();
        let raw_values = [
            Vector3::new(40.0, -20.0, 10.0),
            Vector3::new(-3.0, 0.25, 61.0),
            Vector3::new(0.0, 0.0, 0.0),
        ];
        for frame in frames() {
            let sensor = SensorCalibration::from_body(&body, &frame);
            let (b, u) = (frame.body_from_sensor, frame.unit.factor());
            for raw in raw_values {
                // What the importer made of the raw value, corrected in body axes and µT…
                let corrected_body_ut = body.apply(b * (raw * u));
                // …is the sensor calibration's correction of the raw value, turned the
                // same way.
                let corrected_raw = sensor.apply(raw);
                assert!(
                    (b * corrected_raw * u - corrected_body_ut).amax() < 1e-9,
                    "{frame:?}"
                );
            }
            assert!((sensor.field * u - body.field_ut).abs() < 1e-9);
            // In µT along the sensor's axes (the MotionCal packet's form).
            let Some(in_ut) = sensor.in_ut() else {
                assert_eq!(frame.unit.ut_per_unit, None);
                continue;
            };
            assert!((in_ut.hard_iron_ut - b.transpose() * body.hard_iron_ut).amax() < 1e-9);
            assert!((in_ut.field_ut - body.field_ut).abs() < 1e-9);
        }
        // The serial board: y and z change sign, so the soft iron's x-y and x-z terms do.
        let board = SensorCalibration::from_body(
            &body,
            &SensorFrame::serial_board(crate::io::MagUnit::MOTIONCAL_COUNT),
        );
        assert!((board.hard_iron - Vector3::new(125.0, 72.5, -300.0)).amax() < 1e-9);
        assert!((board.soft_iron[(0, 1)] + 0.015).abs() < 1e-12);
        assert!((board.soft_iron[(1, 2)] - 0.005).abs() < 1e-12);
    }

    // serde_json is a native-only dependency.
    #[cfg(not(target_arch = "wasm32"))]
    #[test]
    fn json_says_its_axes_and_unit_is_row_major_and_reads_back_in_microtesla() {
        let sensor = SensorCalibration::from_body(
            &known_calibration(),
            &SensorFrame::columns_as_body(crate::io::MagUnit::GAUSS),
        );
        let export = calibration_export(&sensor);
        assert_eq!(export.axes, ExportAxes::Sensor);
        assert_eq!(export.unit, "gauss");
        assert_eq!(export.ut_per_unit, Some(100.0));
        assert_eq!(export.soft_iron[0], [1.02, 0.015, -0.01]);
        assert_eq!(export.soft_iron[2], [-0.01, 0.005, 1.01]);
        assert_eq!(export.hard_iron, [0.125, -0.0725, 0.3]);
        assert!(export
            .formula
            .contains("in gauss (100 µT), along the log's x, y, z columns"));

        let text = serde_json::to_string(&export).expect("serialisable");
        assert!(
            text.starts_with(
                "{\"axes\":\"sensor\",\"axes_description\":\"the log's x, y, z columns"
            ),
            "{text}"
        );
        assert!(
            text.contains("\"unit\":\"gauss\",\"ut_per_unit\":100.0,\"unit_origin\":\"stated\""),
            "{text}"
        );
        let read_back: CalibrationExport = serde_json::from_str(&text).expect("reads back");
        assert_eq!(read_back, export);
        // Read as µT along the file's axes: the body calibration again (no rotation here).
        let in_ut = calibration_from_json(&text).expect("a calibration");
        assert!((in_ut.hard_iron_ut - known_calibration().hard_iron_ut).amax() < 1e-12);
        assert!((in_ut.field_ut - 48.3).abs() < 1e-12);

        // The row-major arrays mean the same correction as the matrix.
        let raw = Vector3::new(0.40, -0.20, 0.10);
        let centred = raw - Vector3::from(export.hard_iron);
        let by_rows = Vector3::from_fn(|i, _| {
            (0..3)
                .map(|j| export.soft_iron[i][j] * centred[j])
                .sum::<f64>()
        });
        assert!((by_rows - sensor.apply(raw)).amax() < 1e-12);
    }

    // serde_json is a native-only dependency.
    #[cfg(not(target_arch = "wasm32"))]
    #[test]
    fn an_old_file_without_axes_or_unit_reads_as_body_axes_and_microtesla() {
        let old = "{\"hard_iron_ut\":[12.5,-7.25,30.0],\"soft_iron\":[[1.02,0.015,-0.01],\
                   [0.015,0.98,0.005],[-0.01,0.005,1.01]],\"field_ut\":48.3}";
        let export: CalibrationExport = serde_json::from_str(old).expect("an old file reads");
        assert_eq!(export.axes, ExportAxes::Body);
        assert_eq!(export.unit, "µT");
        assert_eq!(export.ut_per_unit, Some(1.0));
        assert!(export.axes_description.starts_with("not stated"));
        assert_eq!(calibration_from_json(old), Ok(known_calibration()));
        let body = CalibrationExport::body_ut(&known_calibration());
        assert_eq!(body.axes, ExportAxes::Body);
        assert_eq!(body.hard_iron, [12.5, -7.25, 30.0]);
    }

    // serde_json is a native-only dependency.
    #[cfg(not(target_arch = "wasm32"))]
    #[test]
    fn bad_json_is_refused_with_the_expected_shape() {
        let error = calibration_from_json("{\"hard_iron\": [1, 2]}").expect_err("refused");
        assert!(matches!(error, ExportError::Json { .. }));
        assert!(error.to_string().contains("\"soft_iron\": [[a, b, c]"));
        assert_eq!(
            calibration_from_json(
                "{\"hard_iron_ut\":[0,0,0],\"soft_iron\":[[1,0,0],[0,1,0],[0,0,1]],\
                 \"field_ut\":-3}"
            ),
            Err(ExportError::FieldNotPositive { field_ut: -3.0 })
        );
        assert_eq!(
            calibration_from_json(
                "{\"hard_iron\":[0,0,0],\"soft_iron\":[[1,0,0],[0,1,0],[0,0,1]],\
                 \"field\":0.5,\"unit\":\"gauss\",\"ut_per_unit\":0}"
            ),
            Err(ExportError::UnitScale { ut_per_unit: 0.0 })
        );
        // Extra keys (a summary around the calibration) are ignored.
        assert!(calibration_from_json(
            "{\"method\":\"ellipsoid\",\"hard_iron_ut\":[0,0,0],\
             \"soft_iron\":[[1,0,0],[0,1,0],[0,0,1]],\"field_ut\":50}"
        )
        .is_ok());
    }

    #[test]
    fn the_c_snippet_says_its_axes_and_unit_and_how_to_apply_it() {
        let sensor = SensorCalibration::from_body(
            &known_calibration(),
            &SensorFrame::serial_board(crate::io::MagUnit::MOTIONCAL_COUNT),
        );
        let snippet = c_snippet(&sensor);
        let expected = "\
// Magnetometer calibration made by compass-pdr.
// Axes: the sensor's own x, y, z as printed (z up out of the board).
// Unit: MotionCal count (0.1 uT), as the log writes the raw values.
// Apply it to every raw reading exactly as the log writes it (same axes, same unit):
//   corrected = soft_iron * (raw - hard_iron)
// that is, for each i: corrected[i] = sum over j of soft_iron[i][j] * (raw[j] - hard_iron[j]).
// hard_iron and mag_field are in MotionCal count; corrected comes out in MotionCal count, in the same axes.
// mag_field is the field strength after correction; mag_ut_per_unit is uT per MotionCal count.
float hard_iron[3] = { 125.0f, 72.5f, -300.0f };
float soft_iron[3][3] = {
  { 1.02f, -0.015f, 0.01f },
  { -0.015f, 0.98f, 0.005f },
  { 0.01f, 0.005f, 1.01f }
};
float mag_field = 483.0f;
float mag_ut_per_unit = 0.1f;
";
        assert_eq!(snippet, expected);
        assert!(snippet.is_ascii());
    }

    #[test]
    fn c_floats_read_back_as_the_same_float() {
        for value in [1.0, -0.0, 1e-7, 123456.789, 0.1, -3.0e5, 48.3] {
            let literal = c_float(value);
            assert!(literal.ends_with('f') && literal.contains('.'), "{literal}");
            let read: f32 = literal
                .trim_end_matches('f')
                .parse()
                .expect("a decimal number");
            assert_eq!(read, value as f32, "{literal}");
        }
        assert_eq!(c_float(f64::NAN), "NAN");
        assert_eq!(c_float(f64::NEG_INFINITY), "-INFINITY");
    }
}
