//! Serial sensor lines: what microcontroller sketches print over a serial port.
//!
//! Each line is judged on its own, so a log may mix formats (Adafruit's calibration
//! sketch prints `Raw:`, `Uni:`, `Cal1:` and `Cal2:` lines in turn). The formats:
//!
//! ```text
//! Raw:8192,0,-8192,16,-32,0,300,-150,450           MotionCal Raw: integer counts
//! Uni:0.12,-0.25,9.81,0.0100,-0.0200,0.0000,25.50,-3.25,40.00      Uni: SI values
//! Raw: 0.1200, -0.2500, 9.8100, 0.5730, 0.0000, -1.1459, 25.5000, -3.2500, 40.0000
//! mx:12.5,my:-3.25,mz:40.0     MagX:12.5 MagY:-3.2 MagZ:40     Serial Plotter
//! (12.5, -3.25, 40.0)          Acceleration (m/s^2): (0.100,0.200,9.800)   tuples
//! X:      1.00, Y:      2.00, Z:      3.00 uT      Gyro  X: 0.01, Y: 0.02, Z: 0.0 rad/s
//! 12.5,-3.25,40.0              12.5 -3.25 40.0     plain numbers (3, 6 or 9)
//! Cal1:0.000,0.000,0.000,0.000,0.000,0.000,12.345,-6.789,30.125,48.500
//! Cal2:0.9900,0.0100,-0.0200,0.0100,1.0100,0.0300,-0.0200,0.0300,0.9800
//! ```
//!
//! - **MotionCal `Raw:`** with nine integers `ax,ay,az,gx,gy,gz,mx,my,mz`. MotionCal
//!   (PaulStoffregen/MotionCal `serialdata.c`, `ascii_parse`) reads them as counts of
//!   1/8192 g, 1/16 °/s and 0.1 µT (`imuread.h`: `G_PER_COUNT`,
//!   `DEG_PER_SEC_PER_COUNT`, `UT_PER_COUNT`); Adafruit's sketch makes them that way
//!   (adafruit/Adafruit_AHRS `examples/calibration/calibration.ino`:
//!   `int(accel*8192/9.8)`, `int(gyro*SENSORS_RADS_TO_DPS*16)`, `int(mag*10)`). g is
//!   taken as 9.80665 m/s² (the sketch divides by 9.8: a 0.07 % difference). MotionCal
//!   drops a line with a value outside ±32767 (`(int16_t)ascii_num != ascii_num`);
//!   this reader keeps it, since 16 bits is a limit of MotionCal, not of the sensor.
//! - **`Uni:`** with nine decimals: accelerometer m/s², gyroscope **rad/s** (printed
//!   with 4 decimals), magnetometer µT, the Adafruit Unified Sensor units, as the same
//!   `calibration.ino` prints them right after each `Raw:` line. MotionCal itself never
//!   reads `Uni:` (its parser knows only `Raw:`, `Cal1:` and `Cal2:`). A `Raw:` line
//!   followed directly by a `Uni:` line is one reading printed twice; the more precise
//!   `Uni:` values are kept and the `Raw:` line is not counted as a second sample.
//! - **`Raw:` with decimals** (`Raw: ` and `", "` between values): accelerometer m/s²,
//!   gyroscope **°/s**, magnetometer µT, as Adafruit_AHRS
//!   `examples/calibrated_orientation/calibrated_orientation.ino` prints them (it
//!   converts the gyroscope to °/s for the filter first). A `Raw:` line is read as
//!   counts when all nine values are integers and as this variant as soon as one has
//!   a decimal point or exponent; the choice is made per line.
//! - **Arduino Serial Plotter** `label:value` parts separated by spaces, tabs or commas
//!   (arduino/Arduino `build/shared/ArduinoSerialPlotterProtocol.md`). Labels are
//!   matched without regard to case, `_`, `-` or `.`: a sensor name (`a`, `acc`,
//!   `accel`, `acceleration`; `g`, `gyr`, `gyro`, `w`, `omega`; `m`, `mag`, `magnetic`,
//!   `b`) then the axis (`ax`, `AccX`, `acc_x`, `MagZ`), optionally with a unit
//!   (`mag_x_ut`, `acc_x_mps2`, `gyro_x_dps`); `t`, `temp`, `temperature` are °C.
//!   Bare `x`, `y`, `z` belong to the sensor that a unit after them or a name before
//!   them says (`Accel X: 0.1 Y: 0.2 Z: 9.8 Gyro X: 1 Y: 2 Z: 3`), else to the
//!   magnetometer when they are the line's only three values. Other labels are
//!   ignored and listed once in the notes.
//! - **Tuples** `(x, y, z)`, as CircuitPython prints `sensor.magnetic`: the
//!   magnetometer in µT. Text before the tuple may name the sensor and unit, as in
//!   adafruit/Adafruit_CircuitPython_LSM9DS1 `examples/lsm9ds1_simpletest.py`
//!   (`Acceleration (m/s^2): (…)`, `Magnetometer (gauss): (…)`,
//!   `Gyroscope (degrees/sec): (…)`).
//! - **CircuitPython `X: Y: Z:` with a unit** (adafruit/Adafruit_CircuitPython_LIS3MDL
//!   `examples/lis3mdl_simpletest.py`, `X:{0:10.2f}, Y:…, Z:… uT`, and
//!   `examples/lis3mdl_lsm6ds_test.py`, `Acceleration: X:… m/s^2`, `Gyro X:… rad/s`).
//!   The unit decides the sensor: `uT`, `gauss`, `mG`, `nT`; `m/s^2`, `g`; `rad/s`,
//!   `deg/s`, `dps`. A line that reports a calibration (`Final Calibration: X:…`,
//!   printed by `lis3mdl_calibrator.py`) or a min/max is not a reading and is skipped.
//! - **Plain numbers** separated by commas, semicolons, spaces or tabs: 3 are the
//!   magnetometer (µT), 9 are accelerometer (m/s²), gyroscope (rad/s), magnetometer
//!   (µT). 6 are read as accelerometer then magnetometer, because a compass needs the
//!   magnetometer and an eCompass sketch (accelerometer + magnetometer) prints that;
//!   a sketch that prints accelerometer then gyroscope (an MPU-6050) is caught by the
//!   field-strength check in the notes. 3 numbers followed by a unit take the unit's
//!   sensor.
//! - **`Cal1:` and `Cal2:`**, the calibration the device stored, echoed back: ten
//!   values (accelerometer zero-g offsets in m/s², gyroscope zero-rate offsets in
//!   rad/s, hard iron in µT, field strength in µT) and nine (the soft-iron matrix, row
//!   by row). MotionCal compares them with what it sent (`cal1_data`, `cal2_data`,
//!   tolerance 0.0001 + 3·10⁻⁵·|value|); the layout and units are those of
//!   adafruit/Adafruit_Sensor_Calibration `Adafruit_Sensor_Calibration.cpp`
//!   (`calibrate()`: field = soft_iron · (raw − hard_iron)). They become
//!   [`CalibrationEcho`]s, kept apart from the recording, in the sensor's axes.
//!
//! **Units without a label.** Where a line gives no unit (plotter, tuples, plain
//! numbers), the Adafruit Unified Sensor and CircuitPython units are assumed: m/s²,
//! rad/s, µT. When the file is finished, accelerometer values whose median magnitude
//! is near 1 are taken as g (Arduino's own IMU libraries print g), gyroscope values
//! beyond 35 rad/s (2000 °/s, the widest common range) as °/s, a magnetometer of 1,000
//! to 20,000 as raw counts (kept as they are, its field strengths then in counts), and
//! a magnetometer otherwise far from the Earth's 25-65 µT is reported; each such
//! decision is stated in the notes.
//!
//! **Time.** Serial lines carry no timestamps: the sample number divided by a rate
//! gives `t_s` (files: an assumed 100 Hz, MotionCal's own `SENSORFS` and the 10 ms loop
//! of `calibration.ino`); the live page passes arrival times instead. Lines that each
//! bring a different sensor (CircuitPython's `Acceleration:`, `Gyro`, `Magnetic`
//! lines) are joined into one sample until a sensor repeats.
//!
//! **Axes.** Every format prints the sensor chip's own axes, which are right-handed
//! with z out of the top of the board: a level sensor at rest reads z ≈ +9.8 m/s²
//! (Adafruit Unified Sensor events; MotionCal's NXP fusion, `fusion.c`, expects +1 g
//! on z). With x taken as forward, body axes (x forward, y right, z down) are
//! (x, −y, −z), a half turn about x, for all three sensors ([`sensor_to_body`]).
//! Boards whose magnetometer axes differ from the accelerometer's must be aligned by
//! their firmware.
//!
//! The files: `motioncal.rs` reads the tagged lines of MotionCal and Adafruit's
//! sketches (`Raw:`, `Uni:`, `Cal1:`, `Cal2:`), `labelled.rs` the Serial Plotter's
//! `label:value` pairs and CircuitPython's `X: Y: Z:` with a unit, `tuple.rs` the
//! `(x, y, z)` tuples and `plain.rs` the plain numbers; `units.rs` holds the quantities,
//! units and numbers they share and `names.rs` the sensor names. `reader.rs` joins the
//! lines into samples ([`SerialReader`]) and `finish.rs` ends the input with the unit
//! checks and the notes.

use nalgebra::{Matrix3, Vector3};
use thiserror::Error;

use self::labelled::parse_labelled;
use self::motioncal::{parse_tagged, split_tag};
use self::plain::parse_plain;
use self::tuple::{looks_like_tuple, parse_tuple};
use self::units::number;
use super::lines::decode_all;
use super::{ensure_text, ImportError, ImportReport, MagUnit};

mod finish;
mod labelled;
mod motioncal;
mod names;
mod plain;
mod reader;
mod tuple;
mod units;

pub use self::reader::SerialReader;

pub const FORMAT_NAME: &str = "serial sensor lines";

/// Lines this long or longer are taken as cut (or as several lines run together) and
/// skipped; a sensor line is under 200 bytes. Feed [`SerialReader::read_line`] from a
/// [`LineDecoder`](super::lines::LineDecoder) built with this limit.
pub const MAX_LINE_BYTES: usize = 4096;

/// The sample rate [`read`] assumes, since serial logs have no timestamps.
pub const ASSUMED_FILE_RATE_HZ: f64 = 100.0;

/// More fields than any sensor line has; bounds the work and the stack per line.
const MAX_FIELDS: usize = 32;

/// The line formats this importer reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineFormat {
    /// `Raw:` with nine integer counts (MotionCal).
    MotionCalRaw,
    /// `Uni:` with nine SI values (Adafruit's calibration sketch).
    Uni,
    /// `Raw: ` with nine decimals: m/s², °/s, µT (Adafruit's calibrated_orientation).
    AdafruitRawDecimal,
    /// Arduino Serial Plotter `label:value` pairs.
    SerialPlotter,
    /// `(x, y, z)`, as CircuitPython prints a vector.
    Tuple,
    /// CircuitPython's `X: … Y: … Z: … uT`, where the unit names the sensor.
    CircuitPythonXyz,
    /// 3, 6 or 9 numbers.
    PlainNumbers,
    /// MotionCal's `Cal1:` / `Cal2:` echo of a stored calibration.
    CalibrationEcho,
}

impl LineFormat {
    pub const ALL: [LineFormat; 8] = [
        LineFormat::MotionCalRaw,
        LineFormat::Uni,
        LineFormat::AdafruitRawDecimal,
        LineFormat::SerialPlotter,
        LineFormat::Tuple,
        LineFormat::CircuitPythonXyz,
        LineFormat::PlainNumbers,
        LineFormat::CalibrationEcho,
    ];

    /// The format as the notes name it.
    pub fn describe(self) -> &'static str {
        match self {
            LineFormat::MotionCalRaw => "MotionCal Raw: counts",
            LineFormat::Uni => "Uni: SI values",
            LineFormat::AdafruitRawDecimal => "Raw: with decimals",
            LineFormat::SerialPlotter => "Serial Plotter label:value",
            LineFormat::Tuple => "(x, y, z) tuples",
            LineFormat::CircuitPythonXyz => "X: Y: Z: with a unit",
            LineFormat::PlainNumbers => "plain numbers",
            LineFormat::CalibrationEcho => "Cal1:/Cal2: calibration echoes",
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// One reading, in SI units (µT, m/s², rad/s, °C) and in the **sensor's own axes** as
/// printed; [`sensor_to_body`] turns vectors into body axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorSample {
    pub format: LineFormat,
    pub acc_in_sensor_mps2: Option<Vector3<f64>>,
    pub gyro_in_sensor_radps: Option<Vector3<f64>>,
    pub mag_in_sensor_ut: Option<Vector3<f64>>,
    pub temp_c: Option<f64>,
    /// The line gave no unit for this sensor, so m/s² was assumed.
    pub acc_unit_assumed: bool,
    /// The line gave no unit for this sensor, so rad/s was assumed.
    pub gyro_unit_assumed: bool,
    /// The line gave no unit for this sensor, so µT was assumed.
    pub mag_unit_assumed: bool,
    /// The unit the magnetometer values were written in (before they became µT).
    pub mag_unit: MagUnit,
    /// A MotionCal `Raw:` count outside ±32767 (MotionCal would drop the line).
    pub counts_beyond_16_bits: bool,
    /// Serial Plotter labels that named nothing this importer knows.
    pub n_ignored_labels: usize,
}

impl SensorSample {
    fn empty(format: LineFormat) -> Self {
        Self {
            format,
            acc_in_sensor_mps2: None,
            gyro_in_sensor_radps: None,
            mag_in_sensor_ut: None,
            temp_c: None,
            acc_unit_assumed: false,
            gyro_unit_assumed: false,
            mag_unit_assumed: false,
            mag_unit: MagUnit::MICROTESLA,
            counts_beyond_16_bits: false,
            n_ignored_labels: 0,
        }
    }
}

/// Which of MotionCal's two echo lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EchoKind {
    /// `Cal1:` offsets and field strength.
    Cal1,
    /// `Cal2:` soft-iron matrix.
    Cal2,
}

/// A calibration the device echoes back (`Cal1:` or `Cal2:`), in the sensor's axes and
/// the units of Adafruit_Sensor_Calibration. `Cal1:` fills the offsets and the field
/// strength, `Cal2:` the soft-iron matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationEcho {
    pub kind: EchoKind,
    pub accel_zero_g_in_sensor_mps2: Option<Vector3<f64>>,
    pub gyro_zero_rate_in_sensor_radps: Option<Vector3<f64>>,
    pub mag_hard_iron_in_sensor_ut: Option<Vector3<f64>>,
    pub mag_field_ut: Option<f64>,
    /// Applied as soft_iron · (raw − hard_iron).
    pub mag_soft_iron: Option<Matrix3<f64>>,
}

/// An echo with where it was met.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EchoSeen {
    /// 1-based line number.
    pub line: usize,
    /// The arrival time the caller gave, if any.
    pub arrival_t_s: Option<f64>,
    pub echo: CalibrationEcho,
}

/// What one line holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SerialLine {
    Sample(SensorSample),
    Echo(CalibrationEcho),
}

/// Why a line was not read. The messages are for the user and say what was expected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum LineError {
    #[error("blank line")]
    Blank,
    #[error("longer than {max_bytes} bytes, so not one sensor line")]
    TooLong { max_bytes: usize },
    #[error("more than {max} fields, more than any sensor line has")]
    TooManyFields { max: usize },
    #[error("{tag} line with {found} values; expected {expected} ({layout})")]
    FieldCount {
        tag: &'static str,
        found: usize,
        expected: usize,
        layout: &'static str,
    },
    #[error("value {field} of the {context} line is not a number")]
    NotANumber { context: &'static str, field: usize },
    #[error("value {field} is empty")]
    EmptyField { field: usize },
    #[error("{found} values in parentheses; expected 3, as in (x, y, z)")]
    TupleCount { found: usize },
    #[error(
        "the text before (x, y, z) names no sensor and no unit; expected a name such \
         as Magnetometer or a unit such as (uT)"
    )]
    TupleLabel,
    #[error(
        "{found} numbers; expected 3 (magnetometer, µT), 6 (accelerometer, \
         magnetometer) or 9 (accelerometer, gyroscope, magnetometer)"
    )]
    PlainCount { found: usize },
    #[error("a unit after 6 or 9 numbers does not say which sensor each is; expected 3 numbers before a unit")]
    PlainUnit,
    #[error("the unit {unit} does not fit the {what}")]
    UnitConflict {
        unit: &'static str,
        what: &'static str,
    },
    #[error("the {quantity} has only some of x, y, z")]
    IncompleteVector { quantity: &'static str },
    #[error("the {quantity} {axis} value appears twice")]
    DuplicateLabel { quantity: &'static str, axis: char },
    #[error("label:value pairs mixed with numbers that have no label")]
    MixedPairsAndNumbers,
    #[error("no label names a sensor axis; expected labels such as mx, my, mz, ax, gx or temp")]
    NoKnownLabels,
    #[error("a calibration or min/max summary, not a reading")]
    Summary,
    #[error(
        "not a sensor line; expected Raw:, Uni:, Cal1: or Cal2: values, label:value \
         pairs, (x, y, z), X: Y: Z: with a unit, or 3, 6 or 9 numbers"
    )]
    Unrecognised,
}

/// A vector in the sensor's axes (x forward, y left, z up) in body axes (x forward,
/// y right, z down): a half turn about x, so handedness is kept.
pub fn sensor_to_body(v_in_sensor: Vector3<f64>) -> Vector3<f64> {
    Vector3::new(v_in_sensor.x, -v_in_sensor.y, -v_in_sensor.z)
}

/// Reads one line. Pure; numeric lines are read without allocating.
pub fn parse_line(text: &str) -> Result<SerialLine, LineError> {
    parse_line_with(text, &mut |_| {})
}

/// True when most non-blank lines of the sample are serial sensor lines (or at least
/// two are MotionCal/Adafruit tagged lines, since sketches print a banner first), and
/// the first line is not the header of a delimited file.
pub fn looks_like(sample_lines: &[&str]) -> bool {
    let lines: Vec<&str> = sample_lines
        .iter()
        .map(|line| line.trim_start_matches('\u{feff}').trim())
        .filter(|line| !line.is_empty())
        .collect();
    let Some(first) = lines.first() else {
        return false;
    };
    if is_header_line(first) {
        return false;
    }
    let mut n_read = 0usize;
    let mut n_tagged = 0usize;
    for line in &lines {
        if parse_line(line).is_ok() {
            n_read += 1;
            if split_tag(line).is_some() {
                n_tagged += 1;
            }
        }
    }
    n_read > 0 && (n_read * 2 > lines.len() || n_tagged >= 2)
}

/// Reads a whole log. Fails only when no line holds a sensor reading.
pub fn read(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    let reader = read_all(file_name, bytes)?;
    reader
        .into_report(file_name, true)
        .map(|(report, _)| report)
}

/// Reads a whole log and also returns the calibration echoes (`Cal1:`, `Cal2:`). A log
/// of echoes only is not an error here.
pub fn read_with_echoes(
    file_name: &str,
    bytes: &[u8],
) -> Result<(ImportReport, Vec<EchoSeen>), ImportError> {
    let reader = read_all(file_name, bytes)?;
    reader.into_report(file_name, false)
}

fn read_all(file_name: &str, bytes: &[u8]) -> Result<SerialReader, ImportError> {
    ensure_text(file_name, bytes)?;
    let mut reader = SerialReader::new(ASSUMED_FILE_RATE_HZ);
    decode_all(bytes, MAX_LINE_BYTES, |line| {
        reader.read_line_inner(line.number, &line.text, None, line.truncated);
    });
    Ok(reader)
}

/// A delimited header: the first line splits into two or more names, none a number.
fn is_header_line(line: &str) -> bool {
    if parse_line(line).is_ok() {
        return false;
    }
    let Some(delimiter) = [',', '\t', ';']
        .into_iter()
        .find(|delimiter| line.contains(*delimiter))
    else {
        return false;
    };
    let mut n_fields = 0usize;
    for field in line.split(delimiter) {
        let field = field.trim().trim_matches('"').trim();
        let starts_with_letter = field.chars().next().is_some_and(char::is_alphabetic);
        if !starts_with_letter || number(field).is_some() {
            return false;
        }
        n_fields += 1;
    }
    n_fields >= 2
}

/// [`parse_line`], reporting the labels it ignores.
fn parse_line_with<'a>(
    text: &'a str,
    on_ignored: &mut dyn FnMut(&'a str),
) -> Result<SerialLine, LineError> {
    let text = text.trim_start_matches('\u{feff}').trim();
    if text.is_empty() {
        return Err(LineError::Blank);
    }
    if text.len() >= MAX_LINE_BYTES {
        return Err(LineError::TooLong {
            max_bytes: MAX_LINE_BYTES,
        });
    }
    if let Some((tag, body)) = split_tag(text) {
        return parse_tagged(tag, body);
    }
    if looks_like_tuple(text) {
        return parse_tuple(text).map(SerialLine::Sample);
    }
    if text.contains(':') {
        return parse_labelled(text, on_ignored).map(SerialLine::Sample);
    }
    parse_plain(text).map(SerialLine::Sample)
}

#[cfg(test)]
mod tests;
