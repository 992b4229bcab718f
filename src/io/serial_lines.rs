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
//! beyond 35 rad/s (2000 °/s, the widest common range) as °/s, and a magnetometer far
//! from the Earth's 25-65 µT is reported; each such decision is stated in the notes.
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

use std::f64::consts::PI;

use nalgebra::{Matrix3, Vector3};
use thiserror::Error;

use super::lines::decode_all;
use super::{
    ensure_text, shorten, Diagnostics, ImportError, ImportReport, MagUnit, SensorFrame, UnitOrigin,
    STANDARD_GRAVITY_MPS2,
};
use crate::recording::Recording;

pub const FORMAT_NAME: &str = "serial sensor lines";

/// Lines this long or longer are taken as cut (or as several lines run together) and
/// skipped; a sensor line is under 200 bytes. Feed [`SerialReader::read_line`] from a
/// [`LineDecoder`](super::lines::LineDecoder) built with this limit.
pub const MAX_LINE_BYTES: usize = 4096;

/// The sample rate [`read`] assumes, since serial logs have no timestamps.
pub const ASSUMED_FILE_RATE_HZ: f64 = 100.0;

/// MotionCal's scale factors (`imuread.h`).
const MOTIONCAL_G_PER_COUNT: f64 = 1.0 / 8192.0;
const MOTIONCAL_DPS_PER_COUNT: f64 = 1.0 / 16.0;
use super::frame::{MOTIONCAL_UT_PER_COUNT, RAW_COUNT_MAGNITUDES};
/// The widest common gyroscope range, 2000 °/s, in rad/s.
const MAX_PLAUSIBLE_RATE_RADPS: f64 = 35.0;

/// More fields than any sensor line has; bounds the work and the stack per line.
const MAX_FIELDS: usize = 32;
/// How many ignored label names the notes list.
const MAX_IGNORED_LABELS_LISTED: usize = 20;

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

/// Lines that each bring some sensors, collected until a sensor repeats.
#[derive(Debug, Clone, Copy)]
struct Frame {
    t_s: f64,
    acc: Option<(Vector3<f64>, bool)>,
    gyro: Option<(Vector3<f64>, bool)>,
    mag: Option<(Vector3<f64>, bool, MagUnit)>,
    temp_c: Option<f64>,
    /// The frame is one MotionCal `Raw:` line, so a `Uni:` line right after it is the
    /// same reading.
    is_one_motioncal_raw: bool,
    n_lines: usize,
}

impl Frame {
    fn collides(&self, sample: &SensorSample) -> bool {
        (self.acc.is_some() && sample.acc_in_sensor_mps2.is_some())
            || (self.gyro.is_some() && sample.gyro_in_sensor_radps.is_some())
            || (self.mag.is_some() && sample.mag_in_sensor_ut.is_some())
            || (self.temp_c.is_some() && sample.temp_c.is_some())
    }

    fn take(&mut self, sample: &SensorSample) {
        if let Some(acc) = sample.acc_in_sensor_mps2 {
            self.acc = Some((acc, sample.acc_unit_assumed));
        }
        if let Some(gyro) = sample.gyro_in_sensor_radps {
            self.gyro = Some((gyro, sample.gyro_unit_assumed));
        }
        if let Some(mag) = sample.mag_in_sensor_ut {
            self.mag = Some((mag, sample.mag_unit_assumed, sample.mag_unit));
        }
        if let Some(temp_c) = sample.temp_c {
            self.temp_c = Some(temp_c);
        }
    }
}

/// The streaming reader: the live page feeds it lines as they arrive, files feed it
/// every line, and [`SerialReader::finish`] makes the report.
#[derive(Debug, Clone)]
pub struct SerialReader {
    sample_rate_hz: f64,
    rate_was_invalid: bool,
    recording: Recording,
    /// For each sample of each stream: whether its unit was assumed (SI) rather than
    /// given, so that `finish` can check the assumption.
    acc_unit_assumed: Vec<bool>,
    gyro_unit_assumed: Vec<bool>,
    mag_unit_assumed: Vec<bool>,
    /// How many magnetometer samples came in each unit, in the order first met.
    mag_units: Vec<(MagUnit, usize)>,
    diagnostics: Diagnostics,
    echoes: Vec<EchoSeen>,
    frame: Option<Frame>,
    n_frames: usize,
    n_joined_frames: usize,
    n_arrival_times: usize,
    n_data_lines: usize,
    n_lines: usize,
    lines_per_format: [usize; LineFormat::ALL.len()],
    n_raw_replaced_by_uni: usize,
    n_wide_count_lines: usize,
    n_six_value_lines: usize,
    ignored_labels: Vec<String>,
    first_problem: Option<(usize, String)>,
}

impl SerialReader {
    /// A reader that spaces samples without an arrival time at `sample_rate_hz` (100 Hz
    /// if the rate given is not a positive number).
    pub fn new(sample_rate_hz: f64) -> Self {
        let rate_is_valid = sample_rate_hz.is_finite() && sample_rate_hz > 0.0;
        Self {
            sample_rate_hz: if rate_is_valid {
                sample_rate_hz
            } else {
                ASSUMED_FILE_RATE_HZ
            },
            rate_was_invalid: !rate_is_valid,
            recording: Recording::default(),
            acc_unit_assumed: Vec::new(),
            gyro_unit_assumed: Vec::new(),
            mag_unit_assumed: Vec::new(),
            mag_units: Vec::new(),
            diagnostics: Diagnostics::default(),
            echoes: Vec::new(),
            frame: None,
            n_frames: 0,
            n_joined_frames: 0,
            n_arrival_times: 0,
            n_data_lines: 0,
            n_lines: 0,
            lines_per_format: [0; LineFormat::ALL.len()],
            n_raw_replaced_by_uni: 0,
            n_wide_count_lines: 0,
            n_six_value_lines: 0,
            ignored_labels: Vec::new(),
            first_problem: None,
        }
    }

    /// Reads one line (1-based `line_number`). The live page passes the arrival time of
    /// the line; files pass `None`. A line of [`MAX_LINE_BYTES`] or more is skipped.
    pub fn read_line(&mut self, line_number: usize, text: &str, arrival_t_s: Option<f64>) {
        let truncated = text.len() >= MAX_LINE_BYTES;
        self.read_line_inner(line_number, text, arrival_t_s, truncated);
    }

    /// The samples read so far (the last one may still be waiting for the rest of its
    /// lines), in body axes and SI units, before the unit checks of `finish`.
    pub fn recording(&self) -> &Recording {
        &self.recording
    }

    /// The calibration echoes read so far.
    pub fn echoes(&self) -> &[EchoSeen] {
        &self.echoes
    }

    /// The stream ended (a serial port closed): the reading still waiting for the rest of
    /// its lines is taken as it is, as `finish` would take it.
    pub fn end_of_stream(&mut self) {
        self.flush_frame();
    }

    /// The lines skipped so far, with their line numbers and reasons.
    pub fn diagnostics(&self) -> &Diagnostics {
        &self.diagnostics
    }

    /// The line format read most often so far (echo lines aside), for telling the user
    /// what the stream was taken for; `None` before the first reading.
    pub fn main_format(&self) -> Option<LineFormat> {
        LineFormat::ALL
            .iter()
            .copied()
            .filter(|format| *format != LineFormat::CalibrationEcho)
            .map(|format| (format, self.lines_per_format[format.index()]))
            .filter(|(_, n_lines)| *n_lines > 0)
            .max_by_key(|(_, n_lines)| *n_lines)
            .map(|(format, _)| format)
    }

    /// The report. Fails when no line held a sensor reading.
    pub fn finish(self, file_name: &str) -> Result<ImportReport, ImportError> {
        self.into_report(file_name, true).map(|(report, _)| report)
    }

    /// The report and the calibration echoes. Fails only when no line held a reading
    /// or an echo.
    pub fn finish_with_echoes(
        self,
        file_name: &str,
    ) -> Result<(ImportReport, Vec<EchoSeen>), ImportError> {
        self.into_report(file_name, false)
    }

    fn read_line_inner(
        &mut self,
        line_number: usize,
        text: &str,
        arrival_t_s: Option<f64>,
        truncated: bool,
    ) {
        self.n_lines = self.n_lines.max(line_number);
        let trimmed = text.trim_start_matches('\u{feff}').trim();
        if trimmed.is_empty() {
            return;
        }
        self.n_data_lines += 1;
        if truncated {
            self.skip(
                line_number,
                trimmed,
                LineError::TooLong {
                    max_bytes: MAX_LINE_BYTES,
                },
            );
            return;
        }
        let arrival_t_s = arrival_t_s.filter(|t_s| t_s.is_finite());
        let mut ignored: [&str; 8] = [""; 8];
        let mut n_ignored = 0usize;
        let parsed = parse_line_with(trimmed, &mut |label| {
            if let Some(slot) = ignored.get_mut(n_ignored) {
                *slot = label;
                n_ignored += 1;
            }
        });
        match parsed {
            Ok(SerialLine::Sample(sample)) => {
                for label in ignored.iter().take(n_ignored) {
                    self.note_ignored_label(label);
                }
                self.add_sample(sample, arrival_t_s);
            }
            Ok(SerialLine::Echo(echo)) => {
                self.count_format(LineFormat::CalibrationEcho);
                self.echoes.push(EchoSeen {
                    line: line_number,
                    arrival_t_s,
                    echo,
                });
            }
            Err(LineError::Blank) => {}
            Err(error) => self.skip(line_number, trimmed, error),
        }
    }

    fn count_format(&mut self, format: LineFormat) {
        if let Some(count) = self.lines_per_format.get_mut(format.index()) {
            *count += 1;
        }
    }

    fn skip(&mut self, line_number: usize, text: &str, error: LineError) {
        let reason = error.to_string();
        self.diagnostics.push(
            Some(line_number),
            format!("\"{}\": {reason}", shorten(text)),
        );
        if self.first_problem.is_none() {
            self.first_problem = Some((line_number, reason));
        }
    }

    fn note_ignored_label(&mut self, label: &str) {
        let label = if label.is_empty() { "(empty)" } else { label };
        let is_known = self
            .ignored_labels
            .iter()
            .any(|known| known.eq_ignore_ascii_case(label));
        if !is_known && self.ignored_labels.len() < MAX_IGNORED_LABELS_LISTED {
            self.ignored_labels.push(shorten(label));
        }
    }

    fn add_sample(&mut self, sample: SensorSample, arrival_t_s: Option<f64>) {
        self.count_format(sample.format);
        if sample.counts_beyond_16_bits {
            self.n_wide_count_lines += 1;
        }
        let is_six_values = sample.format == LineFormat::PlainNumbers
            && sample.acc_in_sensor_mps2.is_some()
            && sample.mag_in_sensor_ut.is_some();
        if is_six_values {
            self.n_six_value_lines += 1;
        }
        if let Some(frame) = self.frame.as_mut() {
            if sample.format == LineFormat::Uni && frame.is_one_motioncal_raw {
                // The same reading as the Raw: line before it, with more digits.
                frame.take(&sample);
                frame.is_one_motioncal_raw = false;
                self.n_raw_replaced_by_uni += 1;
                return;
            }
            if frame.collides(&sample) {
                self.flush_frame();
            }
        }
        if self.frame.is_none() {
            let t_s = match arrival_t_s {
                Some(t_s) => {
                    self.n_arrival_times += 1;
                    t_s
                }
                None => self.n_frames as f64 / self.sample_rate_hz,
            };
            self.frame = Some(Frame {
                t_s,
                acc: None,
                gyro: None,
                mag: None,
                temp_c: None,
                is_one_motioncal_raw: sample.format == LineFormat::MotionCalRaw,
                n_lines: 0,
            });
        } else if let Some(frame) = self.frame.as_mut() {
            frame.is_one_motioncal_raw = false;
        }
        if let Some(frame) = self.frame.as_mut() {
            frame.take(&sample);
            frame.n_lines += 1;
        }
    }

    fn flush_frame(&mut self) {
        let Some(frame) = self.frame.take() else {
            return;
        };
        let t_s = frame.t_s;
        let recording = &mut self.recording;
        if let Some((acc, assumed)) = frame.acc {
            recording.acc_in_body_mps2.push(t_s, sensor_to_body(acc));
            self.acc_unit_assumed.push(assumed);
        }
        if let Some((gyro, assumed)) = frame.gyro {
            recording.gyro_in_body_radps.push(t_s, sensor_to_body(gyro));
            self.gyro_unit_assumed.push(assumed);
        }
        if let Some((mag, assumed, unit)) = frame.mag {
            recording.mag_in_body_ut.push(t_s, sensor_to_body(mag));
            self.mag_unit_assumed.push(assumed);
            match self.mag_units.iter_mut().find(|(seen, _)| *seen == unit) {
                Some((_, count)) => *count += 1,
                None => self.mag_units.push((unit, 1)),
            }
        }
        if let Some(temp_c) = frame.temp_c {
            recording.temp_c.push(t_s, temp_c);
        }
        self.n_frames += 1;
        if frame.n_lines > 1 {
            self.n_joined_frames += 1;
        }
    }

    fn into_report(
        mut self,
        file_name: &str,
        require_samples: bool,
    ) -> Result<(ImportReport, Vec<EchoSeen>), ImportError> {
        self.flush_frame();
        let has_samples = self.n_frames > 0;
        if !has_samples && (require_samples || self.echoes.is_empty()) {
            let first_problem = match (&self.first_problem, self.echoes.first()) {
                (_, Some(echo)) => format!(
                    " (line {}: only calibration echoes (Cal1:, Cal2:), no sensor readings)",
                    echo.line
                ),
                (Some((line, reason)), None) => format!(" (line {line}: {reason})"),
                (None, None) => String::new(),
            };
            return Err(ImportError::NothingRecognised {
                file_name: file_name.to_string(),
                format: FORMAT_NAME,
                n_lines: self.n_lines,
                first_problem,
            });
        }

        let mut notes = Vec::new();
        if self.n_arrival_times < self.n_frames {
            let rate_hz = self.sample_rate_hz;
            notes.push(format!(
                "no timestamps: samples are spaced at an assumed {rate_hz} Hz"
            ));
        }
        if self.rate_was_invalid {
            notes.push(
                "the sample rate given was not a positive number; 100 Hz was used".to_string(),
            );
        }
        if self.n_arrival_times > 0 {
            notes.push(format!(
                "{} samples are timed by the arrival of their first line",
                self.n_arrival_times
            ));
        }
        let seen: Vec<String> = LineFormat::ALL
            .iter()
            .zip(self.lines_per_format)
            .filter(|(_, count)| *count > 0)
            .map(|(format, count)| format!("{} ({count})", format.describe()))
            .collect();
        notes.push(format!("line formats seen: {}", seen.join(", ")));
        self.push_unit_notes(&mut notes);
        if has_samples {
            notes.push(
                "axes: the sensor's own x, y, z as printed, z up out of the board (a level \
                 sensor at rest reads z ≈ +9.8 m/s²); body axes (x forward, y right, z \
                 down) = (x, −y, −z)"
                    .to_string(),
            );
        }
        self.check_assumed_units(&mut notes);
        self.check_gravity_direction(&mut notes);
        let mag_frame = self.mag_frame(&mut notes);
        if self.n_raw_replaced_by_uni > 0 {
            notes.push(format!(
                "{} Raw: lines were each followed by a Uni: line of the same reading; the \
                 Uni: values (more digits) were used",
                self.n_raw_replaced_by_uni
            ));
        }
        if self.n_joined_frames > 0 {
            notes.push(format!(
                "{} samples were joined from consecutive lines that each brought a \
                 different sensor",
                self.n_joined_frames
            ));
        }
        if !self.ignored_labels.is_empty() {
            notes.push(format!(
                "labels ignored (no sensor axis this tool knows): {}",
                self.ignored_labels.join(", ")
            ));
        }
        if !self.echoes.is_empty() {
            notes.push(format!(
                "{} calibration echoes (Cal1:, Cal2:) were read apart from the recording",
                self.echoes.len()
            ));
        }

        if self.n_arrival_times > 0 {
            let recording = &mut self.recording;
            let n_out_of_order = recording.acc_in_body_mps2.sort_by_time()
                + recording.gyro_in_body_radps.sort_by_time()
                + recording.mag_in_body_ut.sort_by_time()
                + recording.temp_c.sort_by_time();
            if n_out_of_order > 0 {
                self.diagnostics.push(
                    None,
                    format!(
                        "arrival times go backwards {n_out_of_order} times; the samples were sorted by time"
                    ),
                );
            }
        }

        let report = ImportReport {
            file_name: file_name.to_string(),
            format: FORMAT_NAME,
            recording: self.recording,
            diagnostics: self.diagnostics,
            header: None,
            n_data_lines: self.n_data_lines,
            notes,
            mag_frame,
        };
        Ok((report, self.echoes))
    }

    /// The magnetometer's frame: the board's axes as printed ([`sensor_to_body`] turned
    /// them into body axes) and the unit most of its values were written in; a note when
    /// they came in several.
    fn mag_frame(&self, notes: &mut Vec<String>) -> Option<SensorFrame> {
        let (unit, _) = self
            .mag_units
            .iter()
            .copied()
            .max_by_key(|&(_, count)| count)?;
        if self.mag_units.len() > 1 {
            let counts: Vec<String> = self
                .mag_units
                .iter()
                .map(|(unit, count)| format!("{count} in {}", unit.label()))
                .collect();
            notes.push(format!(
                "magnetometer values came in several units ({}); a calibration is exported for \
                 values in {}, the most common",
                counts.join(", "),
                unit.label()
            ));
        }
        Some(SensorFrame::serial_board(unit))
    }

    fn format_count(&self, format: LineFormat) -> usize {
        self.lines_per_format
            .get(format.index())
            .copied()
            .unwrap_or(0)
    }

    fn push_unit_notes(&self, notes: &mut Vec<String>) {
        if self.format_count(LineFormat::MotionCalRaw) > 0 {
            notes.push(
                "Raw: counts read as MotionCal reads them: accelerometer 1/8192 g (g = \
                 9.80665 m/s²), gyroscope 1/16 °/s, magnetometer 0.1 µT per count"
                    .to_string(),
            );
        }
        if self.n_wide_count_lines > 0 {
            notes.push(format!(
                "{} Raw: lines have counts beyond ±32767; MotionCal would drop them, they \
                 were kept",
                self.n_wide_count_lines
            ));
        }
        if self.format_count(LineFormat::Uni) > 0 {
            notes.push(
                "Uni: accelerometer m/s², gyroscope rad/s, magnetometer µT (Adafruit's \
                 calibration sketch)"
                    .to_string(),
            );
        }
        if self.format_count(LineFormat::AdafruitRawDecimal) > 0 {
            notes.push(
                "Raw: with decimals: accelerometer m/s², gyroscope °/s, magnetometer µT \
                 (Adafruit's calibrated_orientation sketch)"
                    .to_string(),
            );
        }
        let unitless = [
            LineFormat::SerialPlotter,
            LineFormat::Tuple,
            LineFormat::PlainNumbers,
        ];
        if unitless.iter().any(|&format| self.format_count(format) > 0) {
            notes.push(
                "values without a unit: accelerometer m/s², gyroscope rad/s, magnetometer \
                 µT (Adafruit Unified Sensor and CircuitPython units); a line of 3 numbers \
                 or a lone (x, y, z) is the magnetometer"
                    .to_string(),
            );
        }
        if self.n_six_value_lines > 0 {
            notes.push(format!(
                "{} lines of 6 numbers were read as accelerometer (m/s²) then magnetometer \
                 (µT); if the sketch prints accelerometer then gyroscope, the magnetometer \
                 stream is wrong",
                self.n_six_value_lines
            ));
        }
    }

    /// Checks the SI units assumed where lines gave none against the data's size, and
    /// rescales where the data leaves no doubt.
    fn check_assumed_units(&mut self, notes: &mut Vec<String>) {
        let acc = &mut self.recording.acc_in_body_mps2.values;
        let acc_norms: Vec<f64> = acc
            .iter()
            .zip(&self.acc_unit_assumed)
            .filter(|(_, assumed)| **assumed)
            .map(|(value, _)| value.norm())
            .collect();
        if let Some(median) = median(acc_norms) {
            if (0.3..3.0).contains(&median) {
                // At rest or walking, specific force is about 1 g; near 1 the unit is g.
                for (value, _) in acc
                    .iter_mut()
                    .zip(&self.acc_unit_assumed)
                    .filter(|(_, assumed)| **assumed)
                {
                    *value *= STANDARD_GRAVITY_MPS2;
                }
                notes.push(format!(
                    "accelerometer values without a unit have a median magnitude of \
                     {median:.2}: read as g, not m/s²"
                ));
            } else if !(5.0..30.0).contains(&median) {
                notes.push(format!(
                    "accelerometer values without a unit have a median magnitude of \
                     {median:.2}, neither about 1 g nor 9.8 m/s²: check the unit"
                ));
            }
        }

        let gyro = &mut self.recording.gyro_in_body_radps.values;
        let max_rate = gyro
            .iter()
            .zip(&self.gyro_unit_assumed)
            .filter(|(_, assumed)| **assumed)
            .map(|(value, _)| value.norm())
            .fold(None, |max: Option<f64>, norm| {
                Some(max.map_or(norm, |max| max.max(norm)))
            });
        if let Some(max_rate) = max_rate {
            if max_rate > MAX_PLAUSIBLE_RATE_RADPS {
                for (value, _) in gyro
                    .iter_mut()
                    .zip(&self.gyro_unit_assumed)
                    .filter(|(_, assumed)| **assumed)
                {
                    *value *= PI / 180.0;
                }
                notes.push(format!(
                    "gyroscope values without a unit reach {max_rate:.0}, beyond any \
                     gyroscope's range in rad/s: read as °/s"
                ));
            }
        }

        let mag_norms: Vec<f64> = self
            .recording
            .mag_in_body_ut
            .values
            .iter()
            .zip(&self.mag_unit_assumed)
            .filter(|(_, assumed)| **assumed)
            .map(|value| value.0.norm())
            .collect();
        if let Some(median) = median(mag_norms) {
            if RAW_COUNT_MAGNITUDES.contains(&median) {
                // Far from the Earth's field in any unit: raw counts, kept as they are.
                for (unit, _) in &mut self.mag_units {
                    if unit.origin == UnitOrigin::Assumed {
                        *unit = MagUnit::COUNTS;
                    }
                }
                notes.push(format!(
                    "magnetometer values without a unit have a median magnitude of \
                     {median:.0}, far from the Earth's field in µT, gauss or nT: read as raw \
                     counts, kept as they are (the µT per count is unknown, so field strengths \
                     are in counts)"
                ));
            } else if !(10.0..=200.0).contains(&median) {
                notes.push(format!(
                    "magnetometer values without a unit have a median magnitude of \
                     {median:.3} µT, far from the Earth's 25-65 µT: check the unit (gauss \
                     would be 100× larger) or whether these are magnetometer values"
                ));
            }
        }
    }

    /// A level device at rest reads z ≈ −9.8 m/s² in body axes; a clearly positive mean
    /// means it was upside down or its firmware already prints z down.
    fn check_gravity_direction(&self, notes: &mut Vec<String>) {
        let acc = &self.recording.acc_in_body_mps2.values;
        if acc.is_empty() {
            return;
        }
        let mean_z = acc.iter().map(|value| value.z).sum::<f64>() / acc.len() as f64;
        if mean_z > 3.0 {
            notes.push(format!(
                "the mean body z specific force is +{mean_z:.1} m/s² (a level device at \
                 rest reads −9.8): the sensor was mostly upside down, or its firmware \
                 already prints z down"
            ));
        }
    }
}

fn median(mut values: Vec<f64>) -> Option<f64> {
    values.retain(|value| value.is_finite());
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied()
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

// ---------------------------------------------------------------------------------
// Line parsing
// ---------------------------------------------------------------------------------

/// The quantities a line can carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Quantity {
    Acc,
    Gyro,
    Mag,
    Temp,
}

impl Quantity {
    fn name(self) -> &'static str {
        match self {
            Quantity::Acc => "accelerometer",
            Quantity::Gyro => "gyroscope",
            Quantity::Mag => "magnetometer",
            Quantity::Temp => "temperature",
        }
    }
}

/// A unit: the quantity it measures and its factor to this crate's unit.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Unit {
    quantity: Quantity,
    to_si: f64,
    name: &'static str,
}

const MICROTESLA: Unit = Unit {
    quantity: Quantity::Mag,
    to_si: 1.0,
    name: "µT",
};
const GAUSS: Unit = Unit {
    quantity: Quantity::Mag,
    to_si: 100.0,
    name: "gauss",
};
const MILLIGAUSS: Unit = Unit {
    quantity: Quantity::Mag,
    to_si: 0.1,
    name: "mG",
};
const NANOTESLA: Unit = Unit {
    quantity: Quantity::Mag,
    to_si: 0.001,
    name: "nT",
};
const MPS2: Unit = Unit {
    quantity: Quantity::Acc,
    to_si: 1.0,
    name: "m/s²",
};
const GRAVITY: Unit = Unit {
    quantity: Quantity::Acc,
    to_si: STANDARD_GRAVITY_MPS2,
    name: "g",
};
const RADPS: Unit = Unit {
    quantity: Quantity::Gyro,
    to_si: 1.0,
    name: "rad/s",
};
const DEGPS: Unit = Unit {
    quantity: Quantity::Gyro,
    to_si: PI / 180.0,
    name: "°/s",
};
const CELSIUS: Unit = Unit {
    quantity: Quantity::Temp,
    to_si: 1.0,
    name: "°C",
};

/// Unit spellings, compared without regard to ASCII case.
const UNIT_SPELLINGS: [(&str, Unit); 31] = [
    ("uT", MICROTESLA),
    ("µT", MICROTESLA),
    ("μT", MICROTESLA),
    ("microtesla", MICROTESLA),
    ("gauss", GAUSS),
    ("nT", NANOTESLA),
    ("milligauss", MILLIGAUSS),
    ("m/s^2", MPS2),
    ("m/s²", MPS2),
    ("m/s2", MPS2),
    ("m/s/s", MPS2),
    ("mps2", MPS2),
    ("ms^-2", MPS2),
    ("rad/s", RADPS),
    ("rad/sec", RADPS),
    ("rads", RADPS),
    ("radps", RADPS),
    ("deg/s", DEGPS),
    ("deg/sec", DEGPS),
    ("degrees/s", DEGPS),
    ("degrees/sec", DEGPS),
    ("degree/s", DEGPS),
    ("°/s", DEGPS),
    ("°/sec", DEGPS),
    ("dps", DEGPS),
    ("degps", DEGPS),
    ("C", CELSIUS),
    ("°C", CELSIUS),
    ("degC", CELSIUS),
    ("celsius", CELSIUS),
    ("ºC", CELSIUS),
];

/// The unit a word names, if any; brackets around it are ignored.
fn unit_of(word: &str) -> Option<Unit> {
    let word = word
        .trim_end_matches(':')
        .trim_matches(|c| matches!(c, '(' | ')' | '[' | ']'));
    // Case matters for these few: g is gravity, G gauss, mG milligauss.
    match word {
        "g" => return Some(GRAVITY),
        "G" | "Gs" => return Some(GAUSS),
        "mG" => return Some(MILLIGAUSS),
        _ => {}
    }
    UNIT_SPELLINGS
        .iter()
        .find(|(spelling, _)| spelling.eq_ignore_ascii_case(word))
        .map(|&(_, unit)| unit)
}

/// A finite number, or `None`.
fn number(text: &str) -> Option<f64> {
    text.parse::<f64>().ok().filter(|value| value.is_finite())
}

/// A number with a unit written right after it (`25.000C`, `12.5uT`).
fn number_with_unit(word: &str) -> Option<(f64, Unit)> {
    // Bounded so that a long run of garbage costs little.
    if word.len() > 40 {
        return None;
    }
    word.char_indices()
        .skip(1)
        .find_map(|(idx, _)| Some((number(word.get(..idx)?)?, unit_of(word.get(idx..)?)?)))
}

/// Whether a field is written as an integer (MotionCal counts).
fn is_integer_text(field: &str) -> bool {
    let digits = field.strip_prefix(['-', '+']).unwrap_or(field);
    !digits.is_empty() && digits.bytes().all(|byte| byte.is_ascii_digit())
}

/// The tags of MotionCal and Adafruit's sketches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tag {
    Raw,
    Uni,
    Cal1,
    Cal2,
}

const TAGS: [(&str, Tag); 4] = [
    ("Raw:", Tag::Raw),
    ("Uni:", Tag::Uni),
    ("Cal1:", Tag::Cal1),
    ("Cal2:", Tag::Cal2),
];

/// The tag at the start of the line and the text after it. Digits before the tag are
/// skipped: some sketches print `millis()` right before `Raw:` (SensESP's copy of the
/// Adafruit sketch does), and MotionCal skips text before the tag too.
fn split_tag(text: &str) -> Option<(Tag, &str)> {
    let rest = text
        .trim_start_matches(|c: char| c.is_ascii_digit())
        .trim_start();
    TAGS.iter().find_map(|&(tag_text, tag)| {
        let head = rest.get(..tag_text.len())?;
        if head.eq_ignore_ascii_case(tag_text) {
            Some((tag, rest.get(tag_text.len()..).unwrap_or("")))
        } else {
            None
        }
    })
}

/// The comma-separated numbers after a tag.
struct Fields {
    values: [f64; MAX_FIELDS],
    n: usize,
    all_integers: bool,
    beyond_16_bits: bool,
}

impl Fields {
    fn vector(&self, start: usize, scale: f64) -> Option<Vector3<f64>> {
        match self.values.get(start..start + 3)? {
            &[x, y, z] => Some(Vector3::new(x, y, z) * scale),
            _ => None,
        }
    }

    fn value(&self, idx: usize) -> Option<f64> {
        self.values.get(idx).copied()
    }
}

fn comma_numbers(body: &str, context: &'static str) -> Result<Fields, LineError> {
    let mut fields = Fields {
        values: [0.0; MAX_FIELDS],
        n: 0,
        all_integers: true,
        beyond_16_bits: false,
    };
    let mut parts = body.split(',').enumerate().peekable();
    while let Some((idx, part)) = parts.next() {
        let part = part.trim();
        if part.is_empty() {
            // A comma after the last value (some sketches print one) adds no value.
            if parts.peek().is_none() && idx > 0 {
                continue;
            }
            return Err(LineError::EmptyField { field: idx + 1 });
        }
        let value = number(part).ok_or(LineError::NotANumber {
            context,
            field: idx + 1,
        })?;
        let Some(slot) = fields.values.get_mut(fields.n) else {
            return Err(LineError::TooManyFields { max: MAX_FIELDS });
        };
        *slot = value;
        fields.n += 1;
        fields.all_integers &= is_integer_text(part);
        fields.beyond_16_bits |= !(-32768.0..=32767.0).contains(&value);
    }
    Ok(fields)
}

const NINE_LAYOUT: &str = "ax,ay,az,gx,gy,gz,mx,my,mz";

fn expect_count(
    fields: &Fields,
    tag: &'static str,
    expected: usize,
    layout: &'static str,
) -> Result<(), LineError> {
    if fields.n == expected {
        Ok(())
    } else {
        Err(LineError::FieldCount {
            tag,
            found: fields.n,
            expected,
            layout,
        })
    }
}

fn parse_tagged(tag: Tag, body: &str) -> Result<SerialLine, LineError> {
    match tag {
        Tag::Raw => {
            let fields = comma_numbers(body, "Raw:")?;
            expect_count(&fields, "Raw:", 9, NINE_LAYOUT)?;
            let sample = if fields.all_integers {
                SensorSample {
                    acc_in_sensor_mps2: fields
                        .vector(0, MOTIONCAL_G_PER_COUNT * STANDARD_GRAVITY_MPS2),
                    gyro_in_sensor_radps: fields.vector(3, MOTIONCAL_DPS_PER_COUNT.to_radians()),
                    mag_in_sensor_ut: fields.vector(6, MOTIONCAL_UT_PER_COUNT),
                    mag_unit: MagUnit::MOTIONCAL_COUNT,
                    counts_beyond_16_bits: fields.beyond_16_bits,
                    ..SensorSample::empty(LineFormat::MotionCalRaw)
                }
            } else {
                SensorSample {
                    acc_in_sensor_mps2: fields.vector(0, 1.0),
                    gyro_in_sensor_radps: fields.vector(3, PI / 180.0),
                    mag_in_sensor_ut: fields.vector(6, 1.0),
                    ..SensorSample::empty(LineFormat::AdafruitRawDecimal)
                }
            };
            Ok(SerialLine::Sample(sample))
        }
        Tag::Uni => {
            let fields = comma_numbers(body, "Uni:")?;
            expect_count(&fields, "Uni:", 9, NINE_LAYOUT)?;
            Ok(SerialLine::Sample(SensorSample {
                acc_in_sensor_mps2: fields.vector(0, 1.0),
                gyro_in_sensor_radps: fields.vector(3, 1.0),
                mag_in_sensor_ut: fields.vector(6, 1.0),
                ..SensorSample::empty(LineFormat::Uni)
            }))
        }
        Tag::Cal1 => {
            let fields = comma_numbers(body, "Cal1:")?;
            expect_count(
                &fields,
                "Cal1:",
                10,
                "3 accelerometer offsets, 3 gyroscope offsets, 3 hard-iron offsets, field strength",
            )?;
            Ok(SerialLine::Echo(CalibrationEcho {
                kind: EchoKind::Cal1,
                accel_zero_g_in_sensor_mps2: fields.vector(0, 1.0),
                gyro_zero_rate_in_sensor_radps: fields.vector(3, 1.0),
                mag_hard_iron_in_sensor_ut: fields.vector(6, 1.0),
                mag_field_ut: fields.value(9),
                mag_soft_iron: None,
            }))
        }
        Tag::Cal2 => {
            let fields = comma_numbers(body, "Cal2:")?;
            expect_count(&fields, "Cal2:", 9, "the soft-iron matrix, row by row")?;
            let soft_iron = fields.values.get(..9).map(Matrix3::from_row_slice);
            Ok(SerialLine::Echo(CalibrationEcho {
                kind: EchoKind::Cal2,
                accel_zero_g_in_sensor_mps2: None,
                gyro_zero_rate_in_sensor_radps: None,
                mag_hard_iron_in_sensor_ut: None,
                mag_field_ut: None,
                mag_soft_iron: soft_iron,
            }))
        }
    }
}

/// Sets the vector of `quantity` in `sample`, scaled to SI.
fn set_vector(sample: &mut SensorSample, quantity: Quantity, v: Vector3<f64>, unit: Option<Unit>) {
    let scaled = v * unit.map_or(1.0, |unit| unit.to_si);
    let assumed = unit.is_none();
    match quantity {
        Quantity::Acc => {
            sample.acc_in_sensor_mps2 = Some(scaled);
            sample.acc_unit_assumed = assumed;
        }
        Quantity::Gyro => {
            sample.gyro_in_sensor_radps = Some(scaled);
            sample.gyro_unit_assumed = assumed;
        }
        Quantity::Mag => {
            sample.mag_in_sensor_ut = Some(scaled);
            sample.mag_unit_assumed = assumed;
            sample.mag_unit = match unit {
                Some(unit) => MagUnit {
                    name: unit.name,
                    ut_per_unit: Some(unit.to_si),
                    origin: UnitOrigin::Stated,
                },
                None => MagUnit::assumed_microtesla(),
            };
        }
        // Callers never pass a temperature as a vector.
        Quantity::Temp => {}
    }
}

/// Label and prefix words, lower-cased with punctuation dropped, on the stack.
struct Normalized {
    bytes: [u8; 32],
    len: usize,
}

impl Normalized {
    /// `None` for non-ASCII text or names longer than 32 letters and digits.
    fn new(text: &str) -> Option<Self> {
        let mut normalized = Normalized {
            bytes: [0; 32],
            len: 0,
        };
        for c in text.chars() {
            if c.is_ascii_alphanumeric() {
                *normalized.bytes.get_mut(normalized.len)? = c.to_ascii_lowercase() as u8;
                normalized.len += 1;
            } else if !c.is_ascii() {
                return None;
            }
        }
        Some(normalized)
    }

    fn as_str(&self) -> &str {
        std::str::from_utf8(self.bytes.get(..self.len).unwrap_or_default()).unwrap_or("")
    }
}

const ACC_NAMES: [&str; 4] = ["acc", "accel", "acceleration", "accelerometer"];
const GYRO_NAMES: [&str; 4] = ["gyr", "gyro", "gyroscope", "omega"];
const MAG_NAMES: [&str; 6] = [
    "mag",
    "magn",
    "magnet",
    "magnetic",
    "magnetometer",
    "magneticfield",
];
const TEMP_NAMES: [&str; 4] = ["t", "temp", "temperature", "tmp"];
/// Words that mark a summary (a calibration result, a min/max), not a reading.
const SUMMARY_WORDS: [&str; 9] = [
    "calibration",
    "offset",
    "offsets",
    "bias",
    "min",
    "max",
    "minimum",
    "maximum",
    "range",
];

/// The quantity a (normalized) name gives; one-letter names only for labels.
fn quantity_of_name(name: &str, allow_one_letter: bool) -> Option<Quantity> {
    if allow_one_letter {
        match name {
            "a" => return Some(Quantity::Acc),
            "g" | "w" => return Some(Quantity::Gyro),
            "m" | "b" => return Some(Quantity::Mag),
            _ => {}
        }
    }
    if ACC_NAMES.contains(&name) {
        Some(Quantity::Acc)
    } else if GYRO_NAMES.contains(&name) {
        Some(Quantity::Gyro)
    } else if MAG_NAMES.contains(&name) {
        Some(Quantity::Mag)
    } else if TEMP_NAMES.contains(&name) && name.len() > 1 {
        Some(Quantity::Temp)
    } else {
        None
    }
}

/// What a Serial Plotter label names.
#[derive(Debug, Clone, Copy, PartialEq)]
enum LabelKind {
    /// An axis of a sensor (`None`: a bare `x`, `y` or `z`), with the unit the label
    /// itself carries (`mag_x_ut`).
    Axis {
        quantity: Option<Quantity>,
        axis: usize,
        unit: Option<Unit>,
    },
    Temp {
        unit: Option<Unit>,
    },
    Unknown,
}

/// Units written as label suffixes, longest first so that `mps2` wins over `ms2`.
const LABEL_UNIT_SUFFIXES: [(&str, Unit); 10] = [
    ("gauss", GAUSS),
    ("radps", RADPS),
    ("degps", DEGPS),
    ("mps2", MPS2),
    ("rads", RADPS),
    ("degs", DEGPS),
    ("ms2", MPS2),
    ("dps", DEGPS),
    ("ut", MICROTESLA),
    ("nt", NANOTESLA),
];

fn classify_label(label: &str) -> LabelKind {
    let Some(normalized) = Normalized::new(label) else {
        return LabelKind::Unknown;
    };
    let name = normalized.as_str();
    for (suffix, unit) in [("", None), ("degc", Some(CELSIUS)), ("c", Some(CELSIUS))] {
        if let Some(stem) = name.strip_suffix(suffix) {
            if TEMP_NAMES.contains(&stem) {
                return LabelKind::Temp { unit };
            }
        }
    }
    let (stem, unit) = LABEL_UNIT_SUFFIXES
        .iter()
        .find_map(|&(suffix, unit)| {
            let stem = name.strip_suffix(suffix)?;
            stem.ends_with(['x', 'y', 'z'])
                .then_some((stem, Some(unit)))
        })
        .unwrap_or((name, None));
    let axis = match stem.bytes().last() {
        Some(b'x') => 0,
        Some(b'y') => 1,
        Some(b'z') => 2,
        _ => return LabelKind::Unknown,
    };
    let sensor_name = stem.get(..stem.len() - 1).unwrap_or("");
    if sensor_name.is_empty() {
        return LabelKind::Axis {
            quantity: None,
            axis,
            unit,
        };
    }
    match quantity_of_name(sensor_name, true) {
        Some(Quantity::Temp) | None => LabelKind::Unknown,
        Some(quantity) => LabelKind::Axis {
            quantity: Some(quantity),
            axis,
            unit,
        },
    }
}

/// One part of a labelled line.
#[derive(Debug, Clone, Copy)]
enum Item<'a> {
    Pair {
        label: &'a str,
        value: f64,
        unit: Option<Unit>,
    },
    /// `label:` with no number after it (a prefix such as `Acceleration:`).
    Label(&'a str),
    /// A number without a label; only its presence matters (it makes the line
    /// ambiguous).
    Number,
    Word(&'a str),
}

fn is_separator(byte: u8) -> bool {
    matches!(byte, b',' | b';' | b' ' | b'\t')
}

/// Splits a labelled line into items. Separators are commas, semicolons, spaces and
/// tabs; spaces may stand around the colon (`Label : Value` in Arduino's description).
fn scan_items<'a>(text: &'a str, items: &mut [Item<'a>; MAX_FIELDS]) -> Result<usize, LineError> {
    let bytes = text.as_bytes();
    let mut n_items = 0usize;
    let mut idx = 0usize;
    let skip_blanks = |mut at: usize| {
        while matches!(bytes.get(at), Some(b' ' | b'\t')) {
            at += 1;
        }
        at
    };
    let word_end = |mut at: usize| {
        while let Some(&byte) = bytes.get(at) {
            if is_separator(byte) || byte == b':' {
                break;
            }
            at += 1;
        }
        at
    };
    loop {
        while bytes.get(idx).is_some_and(|&byte| is_separator(byte)) {
            idx += 1;
        }
        if idx >= bytes.len() {
            break;
        }
        let start = idx;
        let end = word_end(start);
        let word = text.get(start..end).unwrap_or("");
        let after_blanks = skip_blanks(end);
        let item = if bytes.get(after_blanks) == Some(&b':') {
            let value_start = skip_blanks(after_blanks + 1);
            let value_end = word_end(value_start);
            let value_word = text.get(value_start..value_end).unwrap_or("");
            let value = number(value_word)
                .map(|value| (value, None))
                .or_else(|| number_with_unit(value_word).map(|(value, unit)| (value, Some(unit))));
            match value {
                Some((value, unit)) => {
                    idx = value_end;
                    Item::Pair {
                        label: word,
                        value,
                        unit,
                    }
                }
                None => {
                    idx = after_blanks + 1;
                    Item::Label(word)
                }
            }
        } else {
            idx = end;
            match number(word) {
                Some(_) => Item::Number,
                None => {
                    // A unit right after a value belongs to that value (`X: 1.0 uT`).
                    let previous = n_items.checked_sub(1).and_then(|last| items.get_mut(last));
                    if let (
                        Some(Item::Pair {
                            unit: unit @ None, ..
                        }),
                        Some(found),
                    ) = (previous, unit_of(word))
                    {
                        *unit = Some(found);
                        continue;
                    }
                    Item::Word(word)
                }
            }
        };
        let Some(slot) = items.get_mut(n_items) else {
            return Err(LineError::TooManyFields { max: MAX_FIELDS });
        };
        *slot = item;
        n_items += 1;
    }
    Ok(n_items)
}

/// Adds `unit` to a pool that must hold one unit only.
fn pool_unit(pool: &mut Option<Unit>, unit: Unit, what: &'static str) -> Result<(), LineError> {
    match pool {
        Some(existing) if existing.to_si != unit.to_si || existing.quantity != unit.quantity => {
            Err(LineError::UnitConflict {
                unit: unit.name,
                what,
            })
        }
        Some(_) => Ok(()),
        None => {
            *pool = Some(unit);
            Ok(())
        }
    }
}

fn quantity_slot(quantity: Quantity) -> Option<usize> {
    match quantity {
        Quantity::Acc => Some(0),
        Quantity::Gyro => Some(1),
        Quantity::Mag => Some(2),
        Quantity::Temp => None,
    }
}

const VECTOR_QUANTITIES: [Quantity; 3] = [Quantity::Acc, Quantity::Gyro, Quantity::Mag];

/// A run of pairs after a sensor name: `Gyro X: 1 Y: 2 Z: 3 rad/s`. Bare `x`, `y`, `z`
/// take their sensor from the run they are in.
#[derive(Debug, Clone, Copy, Default)]
struct Group {
    /// The sensor a word before the run names.
    hint: Option<Quantity>,
    hint_is_ambiguous: bool,
    /// The unit written for the bare axes of the run.
    unit: Option<Unit>,
    n_bare: usize,
}

/// More runs than a line has; later ones merge into the last.
const MAX_GROUPS: usize = 8;

/// Serial Plotter pairs and CircuitPython's `X: Y: Z: unit`.
fn parse_labelled<'a>(
    text: &'a str,
    on_ignored: &mut dyn FnMut(&'a str),
) -> Result<SensorSample, LineError> {
    let mut items = [Item::Number; MAX_FIELDS];
    let n_items = scan_items(text, &mut items)?;
    let items = items.get(..n_items).unwrap_or_default();
    if items.iter().any(|item| matches!(item, Item::Number))
        && items.iter().any(|item| matches!(item, Item::Pair { .. }))
    {
        return Err(LineError::MixedPairsAndNumbers);
    }

    // The words around the pairs: a sensor name starts a new run, a unit belongs to
    // the run it is in, and a summary word means the line is no reading.
    let mut groups = [Group::default(); MAX_GROUPS];
    let mut group_of_item = [0usize; MAX_FIELDS];
    let mut current = 0usize;
    let mut n_pairs_in_current = 0usize;
    let mut n_pairs = 0usize;
    for (idx, item) in items.iter().enumerate() {
        match *item {
            Item::Word(word) | Item::Label(word) => {
                if let Some(unit) = unit_of(word) {
                    if let Some(group) = groups.get_mut(current) {
                        pool_unit(&mut group.unit, unit, "x, y, z values")?;
                    }
                } else if let Some(normalized) = Normalized::new(word) {
                    let name = normalized.as_str();
                    if SUMMARY_WORDS.contains(&name) {
                        return Err(LineError::Summary);
                    }
                    if let Some(quantity) = quantity_of_name(name, false) {
                        if n_pairs_in_current > 0 {
                            current = (current + 1).min(MAX_GROUPS - 1);
                            n_pairs_in_current = 0;
                        }
                        if let Some(group) = groups.get_mut(current) {
                            if group.hint.is_some_and(|hint| hint != quantity) {
                                group.hint_is_ambiguous = true;
                            }
                            group.hint = Some(quantity);
                        }
                    }
                }
            }
            Item::Pair { .. } => {
                n_pairs += 1;
                n_pairs_in_current += 1;
            }
            Item::Number => {}
        }
        if let Some(slot) = group_of_item.get_mut(idx) {
            *slot = current;
        }
    }
    if n_pairs == 0 {
        return Err(LineError::Unrecognised);
    }

    // Units per quantity, from label suffixes and units written after values.
    let mut pools: [Option<Unit>; 3] = [None; 3];
    let mut n_named_axes = 0usize;
    for (idx, item) in items.iter().enumerate() {
        let Item::Pair { label, unit, .. } = *item else {
            continue;
        };
        match classify_label(label) {
            LabelKind::Axis {
                quantity: Some(quantity),
                unit: suffix_unit,
                ..
            } => {
                n_named_axes += 1;
                if let Some(unit) = suffix_unit.or(unit) {
                    if unit.quantity != quantity {
                        return Err(LineError::UnitConflict {
                            unit: unit.name,
                            what: quantity.name(),
                        });
                    }
                    if let Some(pool) = quantity_slot(quantity).and_then(|slot| pools.get_mut(slot))
                    {
                        pool_unit(pool, unit, quantity.name())?;
                    }
                }
            }
            LabelKind::Axis {
                quantity: None,
                unit: suffix_unit,
                ..
            } => {
                let group = group_of_item
                    .get(idx)
                    .and_then(|&group| groups.get_mut(group));
                if let Some(group) = group {
                    group.n_bare += 1;
                    if let Some(unit) = suffix_unit.or(unit) {
                        pool_unit(&mut group.unit, unit, "x, y, z values")?;
                    }
                }
            }
            LabelKind::Temp { unit: suffix_unit } => {
                if let Some(unit) = suffix_unit.or(unit) {
                    if unit.quantity != Quantity::Temp {
                        return Err(LineError::UnitConflict {
                            unit: unit.name,
                            what: Quantity::Temp.name(),
                        });
                    }
                }
            }
            LabelKind::Unknown => {}
        }
    }

    // Bare x, y, z of a run: the unit says the sensor, else the name before the run,
    // else they are the magnetometer when they are the line's only values.
    let mut bare_quantities: [Option<Quantity>; MAX_GROUPS] = [None; MAX_GROUPS];
    let mut all_bare_have_units = true;
    for (group, bare_quantity) in groups.iter().zip(bare_quantities.iter_mut()) {
        if group.n_bare == 0 {
            continue;
        }
        let hint = group
            .hint
            .filter(|hint| !group.hint_is_ambiguous && *hint != Quantity::Temp);
        *bare_quantity = if let Some(unit) = group.unit {
            if unit.quantity == Quantity::Temp {
                return Err(LineError::UnitConflict {
                    unit: unit.name,
                    what: "x, y, z values",
                });
            }
            if let Some(hint) = hint.filter(|hint| *hint != unit.quantity) {
                return Err(LineError::UnitConflict {
                    unit: unit.name,
                    what: hint.name(),
                });
            }
            Some(unit.quantity)
        } else if hint.is_some() {
            hint
        } else if n_pairs == 3 && group.n_bare == 3 {
            Some(Quantity::Mag)
        } else {
            None
        };
        all_bare_have_units &= group.unit.is_some() && bare_quantity.is_some();
        if let (Some(quantity), Some(unit)) = (*bare_quantity, group.unit) {
            if let Some(pool) = quantity_slot(quantity).and_then(|slot| pools.get_mut(slot)) {
                pool_unit(pool, unit, quantity.name())?;
            }
        }
    }
    let n_bare: usize = groups.iter().map(|group| group.n_bare).sum();

    let mut values: [[Option<f64>; 3]; 3] = [[None; 3]; 3];
    let mut sample = SensorSample::empty(LineFormat::SerialPlotter);
    for (idx, item) in items.iter().enumerate() {
        let Item::Pair { label, value, unit } = *item else {
            continue;
        };
        match classify_label(label) {
            LabelKind::Axis { quantity, axis, .. } => {
                let bare_quantity = group_of_item
                    .get(idx)
                    .and_then(|&group| bare_quantities.get(group))
                    .copied()
                    .flatten();
                let Some(quantity) = quantity.or(bare_quantity) else {
                    on_ignored(label);
                    sample.n_ignored_labels += 1;
                    continue;
                };
                let slot = quantity_slot(quantity)
                    .and_then(|slot| values.get_mut(slot))
                    .and_then(|axes| axes.get_mut(axis));
                if let Some(slot) = slot {
                    if slot.is_some() {
                        return Err(LineError::DuplicateLabel {
                            quantity: quantity.name(),
                            axis: ['x', 'y', 'z'].get(axis).copied().unwrap_or('?'),
                        });
                    }
                    *slot = Some(value);
                }
            }
            LabelKind::Temp { unit: suffix_unit } => {
                if sample.temp_c.is_some() {
                    return Err(LineError::DuplicateLabel {
                        quantity: Quantity::Temp.name(),
                        axis: ' ',
                    });
                }
                let to_si = suffix_unit.or(unit).map_or(1.0, |unit| unit.to_si);
                sample.temp_c = Some(value * to_si);
            }
            LabelKind::Unknown => {
                on_ignored(label);
                sample.n_ignored_labels += 1;
            }
        }
    }

    for (quantity, (axes, pool)) in VECTOR_QUANTITIES.iter().zip(values.iter().zip(pools)) {
        match *axes {
            [Some(x), Some(y), Some(z)] => {
                set_vector(&mut sample, *quantity, Vector3::new(x, y, z), pool);
            }
            [None, None, None] => {}
            _ => {
                return Err(LineError::IncompleteVector {
                    quantity: quantity.name(),
                })
            }
        }
    }
    let has_values = sample.acc_in_sensor_mps2.is_some()
        || sample.gyro_in_sensor_radps.is_some()
        || sample.mag_in_sensor_ut.is_some()
        || sample.temp_c.is_some();
    if !has_values {
        return Err(LineError::NoKnownLabels);
    }
    if n_bare > 0 && all_bare_have_units && n_named_axes == 0 {
        sample.format = LineFormat::CircuitPythonXyz;
    }
    Ok(sample)
}

/// Whether the line ends with a parenthesised list that starts with a number.
fn looks_like_tuple(text: &str) -> bool {
    let Some(body) = text.strip_suffix(')') else {
        return false;
    };
    let Some(open) = body.rfind('(') else {
        return false;
    };
    let inner = body.get(open + 1..).unwrap_or("");
    inner
        .split(',')
        .next()
        .is_some_and(|first| number(first.trim()).is_some())
}

/// `(x, y, z)`, perhaps after a name and a unit (`Magnetometer (gauss): (…)`).
fn parse_tuple(text: &str) -> Result<SensorSample, LineError> {
    let body = text.strip_suffix(')').unwrap_or(text);
    let open = body.rfind('(').ok_or(LineError::Unrecognised)?;
    let inner = body.get(open + 1..).unwrap_or("");
    let prefix = body.get(..open).unwrap_or("");
    let mut v = [0.0f64; 3];
    let mut n = 0usize;
    for (idx, field) in inner.split(',').enumerate() {
        let value = number(field.trim()).ok_or(LineError::NotANumber {
            context: "(x, y, z)",
            field: idx + 1,
        })?;
        if let Some(slot) = v.get_mut(n) {
            *slot = value;
        }
        n += 1;
    }
    if n != 3 {
        return Err(LineError::TupleCount { found: n });
    }

    let mut quantity: Option<Quantity> = None;
    let mut unit: Option<Unit> = None;
    let mut has_words = false;
    for word in prefix.split(|c: char| c.is_whitespace() || c == ',') {
        if word.trim_matches(|c: char| !c.is_alphanumeric()).is_empty() {
            continue;
        }
        has_words = true;
        if let Some(found) = unit_of(word) {
            unit = Some(found);
            continue;
        }
        let Some(normalized) = Normalized::new(word) else {
            continue;
        };
        let name = normalized.as_str();
        if SUMMARY_WORDS.contains(&name) {
            return Err(LineError::Summary);
        }
        if let Some(found) = quantity_of_name(name, false) {
            quantity.get_or_insert(found);
        }
    }
    let (quantity, unit) = match (quantity, unit) {
        (Some(quantity), Some(unit)) if unit.quantity == quantity => (quantity, Some(unit)),
        (Some(quantity), Some(unit)) => {
            return Err(LineError::UnitConflict {
                unit: unit.name,
                what: quantity.name(),
            })
        }
        (None, Some(unit)) => (unit.quantity, Some(unit)),
        (Some(quantity), None) => (quantity, None),
        (None, None) if has_words => return Err(LineError::TupleLabel),
        (None, None) => (Quantity::Mag, None),
    };
    if quantity == Quantity::Temp {
        return Err(LineError::TupleLabel);
    }
    let mut sample = SensorSample::empty(LineFormat::Tuple);
    set_vector(&mut sample, quantity, Vector3::new(v[0], v[1], v[2]), unit);
    Ok(sample)
}

/// 3, 6 or 9 numbers; 3 may be followed by a unit.
fn parse_plain(text: &str) -> Result<SensorSample, LineError> {
    // An empty field between delimiters is a missing value, which must not shift the
    // values after it into the wrong sensor.
    if let Some(delimiter) = [',', ';'].into_iter().find(|d| text.contains(*d)) {
        let mut fields = text.split(delimiter).enumerate().peekable();
        while let Some((idx, field)) = fields.next() {
            if field.trim().is_empty() && fields.peek().is_some() {
                return Err(LineError::EmptyField { field: idx + 1 });
            }
        }
    }
    let mut values = [0.0f64; 9];
    let mut n = 0usize;
    let mut unit: Option<Unit> = None;
    let mut tokens = text
        .split([',', ';', ' ', '\t'])
        .filter(|token| !token.is_empty())
        .peekable();
    while let Some(token) = tokens.next() {
        if let Some(value) = number(token) {
            if let Some(slot) = values.get_mut(n) {
                *slot = value;
            }
            n += 1;
            continue;
        }
        if tokens.peek().is_none() && n > 0 {
            if let Some(found) = unit_of(token) {
                unit = Some(found);
                continue;
            }
        }
        return Err(LineError::Unrecognised);
    }
    let vector = |start: usize| match values.get(start..start + 3) {
        Some(&[x, y, z]) => Vector3::new(x, y, z),
        _ => Vector3::zeros(),
    };
    let mut sample = SensorSample::empty(LineFormat::PlainNumbers);
    match (n, unit) {
        (3, Some(unit)) if unit.quantity == Quantity::Temp => {
            return Err(LineError::UnitConflict {
                unit: unit.name,
                what: "x, y, z values",
            })
        }
        (3, Some(unit)) => set_vector(&mut sample, unit.quantity, vector(0), Some(unit)),
        (3, None) => set_vector(&mut sample, Quantity::Mag, vector(0), None),
        (6 | 9, Some(_)) => return Err(LineError::PlainUnit),
        (6, None) => {
            set_vector(&mut sample, Quantity::Acc, vector(0), None);
            set_vector(&mut sample, Quantity::Mag, vector(3), None);
        }
        (9, None) => {
            set_vector(&mut sample, Quantity::Acc, vector(0), None);
            set_vector(&mut sample, Quantity::Gyro, vector(3), None);
            set_vector(&mut sample, Quantity::Mag, vector(6), None);
        }
        (found, _) => return Err(LineError::PlainCount { found }),
    }
    Ok(sample)
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
mod tests {
    use super::*;
    use crate::io::lines::LineDecoder;

    fn sample(text: &str) -> SensorSample {
        match parse_line(text) {
            Ok(SerialLine::Sample(sample)) => sample,
            other => panic!("{text:?} gave {other:?}"),
        }
    }

    fn assert_close(got: Option<Vector3<f64>>, want: [f64; 3], what: &str) {
        let got = got.unwrap_or_else(|| panic!("{what}: no vector"));
        let want = Vector3::from(want);
        assert!(
            (got - want).norm() < 1e-9,
            "{what}: got {got:?}, want {want:?}"
        );
    }

    fn read_text(text: &str) -> Result<ImportReport, ImportError> {
        read("serial.txt", text.as_bytes())
    }

    #[test]
    fn the_magnetometer_frame_is_the_board_s_axes_in_the_unit_the_lines_use() {
        let frame_of = |text: &str| {
            read_text(text)
                .ok()
                .and_then(|report| report.mag_frame)
                .map(|frame| (frame.body_from_sensor, frame.unit))
        };
        let board = SensorFrame::serial_board(MagUnit::MICROTESLA).body_from_sensor;
        assert_eq!(
            frame_of("Raw:0,0,8192,0,0,0,300,-150,450\nRaw:0,0,8192,0,0,0,301,-150,450\n"),
            Some((board, MagUnit::MOTIONCAL_COUNT))
        );
        // A Raw: line followed by its Uni: line is read in µT.
        assert_eq!(
            frame_of("Raw:0,0,8192,0,0,0,300,-150,450\nUni:0,0,9.8,0,0,0,30.01,-15.0,45.0\n"),
            Some((board, MagUnit::MICROTESLA))
        );
        assert_eq!(
            frame_of("Magnetometer (gauss): (0.25, -0.1, 0.4)\n"),
            Some((board, MagUnit::GAUSS))
        );
        assert_eq!(
            frame_of("12.5,-3.25,40.0\n12.6,-3.25,40.0\n"),
            Some((board, MagUnit::assumed_microtesla()))
        );
        // Mixed units: the most common one, and a note.
        let report =
            read_text("X:1.0 Y:2.0 Z:3.0 uT\nRaw:0,0,8192,0,0,0,1,2,3\nRaw:0,0,8192,0,0,0,1,2,3\n")
                .expect("readable");
        assert_eq!(
            report.mag_frame.map(|frame| frame.unit),
            Some(MagUnit::MOTIONCAL_COUNT)
        );
        assert!(
            report
                .notes
                .iter()
                .any(|note| note.contains("several units") && note.contains("1 in µT")),
            "{:?}",
            report.notes
        );
        // Accelerometer only: no magnetometer frame.
        assert_eq!(frame_of("Accel X: 0.1 Y: 0.2 Z: 9.8 m/s^2\n"), None);
    }

    #[test]
    fn golden_motioncal_raw_counts() {
        let s = sample("Raw:8192,0,-8192,16,-32,0,300,-150,450");
        assert_eq!(s.format, LineFormat::MotionCalRaw);
        assert_close(s.acc_in_sensor_mps2, [9.80665, 0.0, -9.80665], "acc");
        assert_close(
            s.gyro_in_sensor_radps,
            [1f64.to_radians(), -2f64.to_radians(), 0.0],
            "gyro",
        );
        assert_close(s.mag_in_sensor_ut, [30.0, -15.0, 45.0], "mag");
        assert!(!s.counts_beyond_16_bits);
        // The millis() some sketches print before the tag is skipped.
        assert_eq!(
            sample("123456Raw:0,0,8192,0,0,0,1,2,3").format,
            LineFormat::MotionCalRaw
        );
    }

    #[test]
    fn motioncal_raw_beyond_16_bits_is_kept() {
        let s = sample("Raw:0,0,8192,0,0,0,40000,-40000,100");
        assert!(s.counts_beyond_16_bits);
        assert_close(s.mag_in_sensor_ut, [4000.0, -4000.0, 10.0], "mag");

        let report = read_text("Raw:0,0,8192,0,0,0,40000,-40000,100\n").expect("readable");
        assert_eq!(report.recording.mag_in_body_ut.len(), 1);
        assert_close(
            report.recording.mag_in_body_ut.values.first().copied(),
            [4000.0, 40000.0 * 0.1, -10.0],
            "mag in body axes",
        );
        assert!(
            report
                .notes
                .iter()
                .any(|note| note.contains("beyond ±32767")),
            "{:?}",
            report.notes
        );
    }

    #[test]
    fn golden_uni_line() {
        let s = sample("Uni:0.12,-0.25,9.81,0.0100,-0.0200,0.0000,25.50,-3.25,40.00");
        assert_eq!(s.format, LineFormat::Uni);
        assert_close(s.acc_in_sensor_mps2, [0.12, -0.25, 9.81], "acc");
        assert_close(s.gyro_in_sensor_radps, [0.01, -0.02, 0.0], "gyro rad/s");
        assert_close(s.mag_in_sensor_ut, [25.5, -3.25, 40.0], "mag");
    }

    #[test]
    fn golden_adafruit_raw_with_decimals() {
        let s = sample(
            "Raw: 0.1200, -0.2500, 9.8100, 57.2958, 0.0000, -5.0000, 25.5000, -3.2500, 40.0000",
        );
        assert_eq!(s.format, LineFormat::AdafruitRawDecimal);
        assert_close(s.acc_in_sensor_mps2, [0.12, -0.25, 9.81], "acc");
        assert_close(
            s.gyro_in_sensor_radps,
            [57.2958f64.to_radians(), 0.0, -5f64.to_radians()],
            "gyro °/s",
        );
        assert_close(s.mag_in_sensor_ut, [25.5, -3.25, 40.0], "mag");
    }

    #[test]
    fn golden_serial_plotter_pairs() {
        let s = sample("mx:12.5,my:-3.25,mz:40.0");
        assert_eq!(s.format, LineFormat::SerialPlotter);
        assert_close(s.mag_in_sensor_ut, [12.5, -3.25, 40.0], "mag");

        let s = sample("MagX:12.5 MagY:-3.2 MagZ:40");
        assert_close(s.mag_in_sensor_ut, [12.5, -3.2, 40.0], "mag");

        let s = sample("AccX:0.1\tAccY:0.2\tAccZ:9.8\tgyro_x:0.01\tgyro_y:0.02\tgyro_z:0.03\tmag_x:1\tmag_y:2\tmag_z:3\ttemp:25.5\tloop:7");
        assert_close(s.acc_in_sensor_mps2, [0.1, 0.2, 9.8], "acc");
        assert_close(s.gyro_in_sensor_radps, [0.01, 0.02, 0.03], "gyro");
        assert_close(s.mag_in_sensor_ut, [1.0, 2.0, 3.0], "mag");
        assert_eq!(s.temp_c, Some(25.5));
        assert_eq!(s.n_ignored_labels, 1);

        // Units in the labels, and spaces around the colon.
        let s = sample("gyro_x_dps : 90, gyro_y_dps : 0, gyro_z_dps : -90, mag_x_gauss:0.5 mag_y_gauss:0 mag_z_gauss:-0.25");
        assert_close(s.gyro_in_sensor_radps, [PI / 2.0, 0.0, -PI / 2.0], "gyro");
        assert_close(s.mag_in_sensor_ut, [50.0, 0.0, -25.0], "mag");
        assert!(!s.gyro_unit_assumed && !s.mag_unit_assumed);

        // Bare x, y, z are the magnetometer when they are the only values.
        let s = sample("x:1 y:2 z:3");
        assert_close(s.mag_in_sensor_ut, [1.0, 2.0, 3.0], "bare mag");
        assert!(s.mag_unit_assumed);

        assert_eq!(
            parse_line("mx:1 my:2"),
            Err(LineError::IncompleteVector {
                quantity: "magnetometer"
            })
        );
        assert_eq!(parse_line("heading:123.4"), Err(LineError::NoKnownLabels));
        assert_eq!(
            parse_line("Orientation: 12.0, 3.0, 4.0"),
            Err(LineError::MixedPairsAndNumbers)
        );
    }

    #[test]
    fn golden_tuples() {
        let s = sample("(12.5, -3.25, 40.0)");
        assert_eq!(s.format, LineFormat::Tuple);
        assert_close(s.mag_in_sensor_ut, [12.5, -3.25, 40.0], "mag");

        let s = sample("Acceleration (m/s^2): (0.100,0.200,9.800)");
        assert_close(s.acc_in_sensor_mps2, [0.1, 0.2, 9.8], "acc");
        let s = sample("Magnetometer (gauss): (0.250,-0.100,0.400)");
        assert_close(s.mag_in_sensor_ut, [25.0, -10.0, 40.0], "mag in gauss");
        let s = sample("Gyroscope (degrees/sec): (180.000,0.000,-90.000)");
        assert_close(s.gyro_in_sensor_radps, [PI, 0.0, -PI / 2.0], "gyro");

        assert_eq!(
            parse_line("(1, 2)"),
            Err(LineError::TupleCount { found: 2 })
        );
        assert_eq!(
            parse_line("Orientation: (1, 2, 3)"),
            Err(LineError::TupleLabel)
        );
    }

    #[test]
    fn golden_circuitpython_xyz_with_units() {
        let s = sample("X:      1.00, Y:      2.00, Z:      3.00 uT");
        assert_eq!(s.format, LineFormat::CircuitPythonXyz);
        assert_close(s.mag_in_sensor_ut, [1.0, 2.0, 3.0], "mag");
        assert!(!s.mag_unit_assumed);

        assert_close(
            sample("X:1.00 Y:2.00 Z:3.00 uT").mag_in_sensor_ut,
            [1.0, 2.0, 3.0],
            "mag",
        );
        let s = sample("Acceleration: X:   0.10, Y:  -0.20, Z:   9.80 m/s^2");
        assert_close(s.acc_in_sensor_mps2, [0.1, -0.2, 9.8], "acc");
        let s = sample("Gyro          X:   0.01, Y:   0.02, Z:  -0.03 rad/s");
        assert_close(s.gyro_in_sensor_radps, [0.01, 0.02, -0.03], "gyro");
        let s = sample("X: 90 Y: 0 Z: -180 deg/s");
        assert_close(s.gyro_in_sensor_radps, [PI / 2.0, 0.0, -PI], "gyro °/s");
        let s = sample("X: 0.5 Y: 0.1 Z: -0.2 gauss");
        assert_close(s.mag_in_sensor_ut, [50.0, 10.0, -20.0], "gauss");
        let s = sample("X: 20000 Y: -5000 Z: 40000 nT");
        assert_close(s.mag_in_sensor_ut, [20.0, -5.0, 40.0], "nT");
        let s = sample("Accel X: 0.1 Y: 0.2 Z: 9.8 m/s^2 Gyro X: 90 Y: 0 Z: 0 deg/s");
        assert_eq!(s.format, LineFormat::CircuitPythonXyz);
        assert_close(s.acc_in_sensor_mps2, [0.1, 0.2, 9.8], "acc run");
        assert_close(s.gyro_in_sensor_radps, [PI / 2.0, 0.0, 0.0], "gyro run");
        let s = sample("Accel X: 0.1 Y: 0.2 Z: 9.8 Mag X: 20 Y: 0 Z: -40");
        assert_eq!(s.format, LineFormat::SerialPlotter);
        assert_close(s.mag_in_sensor_ut, [20.0, 0.0, -40.0], "mag run");
        assert!(s.acc_unit_assumed && s.mag_unit_assumed);
        let s = sample("Temperature: 25.000C");
        assert_eq!(s.temp_c, Some(25.0));

        assert_eq!(
            parse_line("  Final Calibration: X:  1.00 Y:  2.00 Z:  3.00 uT"),
            Err(LineError::Summary)
        );
        assert!(matches!(
            parse_line("Magnetic X: 1 Y: 2 Z: 3 m/s^2"),
            Err(LineError::UnitConflict { .. })
        ));
    }

    #[test]
    fn golden_plain_numbers() {
        for text in [
            "12.5,-3.25,40",
            "12.5 -3.25 40",
            "12.5\t-3.25\t40",
            "12.5; -3.25; 40",
        ] {
            let s = sample(text);
            assert_eq!(s.format, LineFormat::PlainNumbers, "{text}");
            assert_close(s.mag_in_sensor_ut, [12.5, -3.25, 40.0], text);
        }
        let s = sample("0.1,0.2,9.8,0.01,0.02,0.03,20,-5,40");
        assert_close(s.acc_in_sensor_mps2, [0.1, 0.2, 9.8], "acc");
        assert_close(s.gyro_in_sensor_radps, [0.01, 0.02, 0.03], "gyro");
        assert_close(s.mag_in_sensor_ut, [20.0, -5.0, 40.0], "mag");

        let s = sample("0.1 0.2 9.8 20 -5 40");
        assert_close(s.acc_in_sensor_mps2, [0.1, 0.2, 9.8], "six: acc");
        assert_close(s.mag_in_sensor_ut, [20.0, -5.0, 40.0], "six: mag");
        assert!(s.gyro_in_sensor_radps.is_none());

        let s = sample("0.1 0.2 1.0 g");
        assert_close(
            s.acc_in_sensor_mps2,
            [0.1 * 9.80665, 0.2 * 9.80665, 9.80665],
            "g",
        );

        assert_eq!(
            parse_line("1,2,3,4"),
            Err(LineError::PlainCount { found: 4 })
        );
        assert_eq!(parse_line("1,,3"), Err(LineError::EmptyField { field: 2 }));
        assert_eq!(
            parse_line("Wrote calibration"),
            Err(LineError::Unrecognised)
        );
    }

    #[test]
    fn calibration_echoes_are_parsed_and_kept_apart() {
        let Ok(SerialLine::Echo(cal1)) =
            parse_line("Cal1:0.100,-0.200,0.300,0.010,-0.020,0.030,12.345,-6.789,30.125,48.500")
        else {
            panic!("Cal1 not read");
        };
        assert_eq!(cal1.kind, EchoKind::Cal1);
        assert_close(
            cal1.accel_zero_g_in_sensor_mps2,
            [0.1, -0.2, 0.3],
            "accel offsets",
        );
        assert_close(
            cal1.gyro_zero_rate_in_sensor_radps,
            [0.01, -0.02, 0.03],
            "gyro offsets",
        );
        assert_close(
            cal1.mag_hard_iron_in_sensor_ut,
            [12.345, -6.789, 30.125],
            "hard iron",
        );
        assert_eq!(cal1.mag_field_ut, Some(48.5));
        assert_eq!(cal1.mag_soft_iron, None);

        let Ok(SerialLine::Echo(cal2)) =
            parse_line("Cal2:0.9900,0.0100,-0.0200,0.0100,1.0100,0.0300,-0.0200,0.0300,0.9800")
        else {
            panic!("Cal2 not read");
        };
        assert_eq!(cal2.kind, EchoKind::Cal2);
        let soft_iron = cal2.mag_soft_iron.expect("soft iron");
        assert_eq!(soft_iron[(0, 1)], 0.01);
        assert_eq!(soft_iron[(1, 2)], 0.03);
        assert_eq!(soft_iron[(2, 0)], -0.02);
        assert_eq!(soft_iron[(2, 2)], 0.98);

        assert!(matches!(
            parse_line("Cal2:1,0,0,0,1,0,0,0"),
            Err(LineError::FieldCount {
                found: 8,
                expected: 9,
                ..
            })
        ));

        let text = "Raw:0,0,8192,0,0,0,200,0,-400\n\
                    Cal1:0.000,0.000,0.000,0.000,0.000,0.000,1.000,2.000,3.000,45.000\n\
                    Cal2:1.0000,0.0000,0.0000,0.0000,1.0000,0.0000,0.0000,0.0000,1.0000\n";
        let (report, echoes) = read_with_echoes("cal.txt", text.as_bytes()).expect("readable");
        assert_eq!(report.recording.mag_in_body_ut.len(), 1);
        let lines: Vec<usize> = echoes.iter().map(|echo| echo.line).collect();
        assert_eq!(lines, vec![2, 3]);
        assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);

        // Echoes alone are a result for read_with_echoes, but no recording for read.
        let only_echoes = "Cal1:0,0,0,0,0,0,1,2,3,45\n";
        assert!(read_with_echoes("cal.txt", only_echoes.as_bytes()).is_ok());
        assert!(matches!(
            read("cal.txt", only_echoes.as_bytes()),
            Err(ImportError::NothingRecognised { .. })
        ));
    }

    #[test]
    fn mixed_formats_in_one_file() {
        let text = "Adafruit AHRS - IMU Calibration!\n\
                    Raw:0,0,8192,0,0,0,200,-100,-400\n\
                    Uni:0.00,0.00,9.81,0.0000,0.0000,0.0000,20.03,-10.01,-40.02\n\
                    Cal1:0.000,0.000,0.000,0.000,0.000,0.000,0.000,0.000,0.000,50.000\n\
                    mx:21 my:-11 mz:-41\n\
                    (22.0, -12.0, -42.0)\n\
                    X: 23.00, Y: -13.00, Z: -43.00 uT\n\
                    24,-14,-44\n\
                    Orientation: 1.0, 2.0, 3.0\n";
        let report = read_text(text).expect("readable");
        let mag = &report.recording.mag_in_body_ut;
        let mag_x: Vec<f64> = mag.values.iter().map(|v| v.x).collect();
        assert_eq!(mag_x, vec![20.03, 21.0, 22.0, 23.0, 24.0]);
        assert_close(
            mag.values.first().copied(),
            [20.03, 10.01, 40.02],
            "Uni in body axes",
        );
        assert_eq!(mag.t_s, vec![0.0, 0.01, 0.02, 0.03, 0.04]);
        assert_eq!(report.n_data_lines, 9);
        let lines: Vec<Option<usize>> = report.diagnostics.kept.iter().map(|d| d.line).collect();
        assert_eq!(lines, vec![Some(1), Some(9)]);
        assert!(report.diagnostics.kept[1].message.contains("Orientation"));
        assert_eq!(report.format, FORMAT_NAME);
        assert_eq!(report.header, None);
        let notes = report.notes.join("\n");
        assert!(
            notes.contains("no timestamps: samples are spaced at an assumed 100 Hz"),
            "{notes}"
        );
        assert!(notes.contains("MotionCal Raw: counts (1)"), "{notes}");
        assert!(notes.contains("Uni: SI values (1)"), "{notes}");
        assert!(notes.contains("X: Y: Z: with a unit (1)"), "{notes}");
        assert!(
            notes.contains("Cal1:/Cal2: calibration echoes (1)"),
            "{notes}"
        );
        assert!(notes.contains("(x, −y, −z)"), "{notes}");
        assert!(
            notes.contains("the Uni: values (more digits) were used"),
            "{notes}"
        );
    }

    #[test]
    fn a_level_sensor_at_rest_reads_minus_g_on_body_z() {
        let report = read_text("Uni:0.00,0.00,9.81,0.0000,0.0000,0.0500,20.00,0.00,-40.00\n")
            .expect("readable");
        let acc = report.recording.acc_in_body_mps2.values.first().copied();
        assert_close(acc, [0.0, 0.0, -9.81], "acc body");
        assert_close(
            report.recording.gyro_in_body_radps.values.first().copied(),
            [0.0, 0.0, -0.05],
            "gyro body",
        );
        let columns = [Vector3::x(), Vector3::y(), Vector3::z()].map(sensor_to_body);
        assert!((Matrix3::from_columns(&columns).determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn lines_of_different_sensors_are_joined_into_one_sample() {
        let text = "Acceleration: X:   0.00, Y:   0.00, Z:   9.80 m/s^2\n\
                    Gyro          X:   0.00, Y:   0.00, Z:   0.00 rad/s\n\
                    Magnetic      X:  20.00, Y:   0.00, Z: -40.00 uT\n\
                    \n\
                    Acceleration: X:   0.00, Y:   0.00, Z:   9.80 m/s^2\n\
                    Gyro          X:   0.00, Y:   0.00, Z:   0.00 rad/s\n\
                    Magnetic      X:  21.00, Y:   0.00, Z: -40.00 uT\n";
        let report = read_text(text).expect("readable");
        assert_eq!(report.recording.mag_in_body_ut.t_s, vec![0.0, 0.01]);
        assert_eq!(report.recording.acc_in_body_mps2.t_s, vec![0.0, 0.01]);
        assert!(
            report
                .notes
                .iter()
                .any(|note| note.contains("2 samples were joined")),
            "{:?}",
            report.notes
        );
    }

    #[test]
    fn unitless_accelerometer_in_g_is_rescaled() {
        let text: String = (0..10)
            .map(|i| format!("ax:0.0{i} ay:0.0 az:1.0 mx:20 my:0 mz:40\n"))
            .collect();
        let report = read_text(&text).expect("readable");
        let acc = report.recording.acc_in_body_mps2.values.first().copied();
        assert_close(acc, [0.0, 0.0, -9.80665], "acc in g");
        assert!(
            report.notes.iter().any(|note| note.contains("read as g")),
            "{:?}",
            report.notes
        );
    }

    #[test]
    fn unknown_labels_are_listed_once() {
        let text = "mx:1 my:2 mz:3 loop:1\nmx:1 my:2 mz:3 loop:2 LOOP2:5\n";
        let report = read_text(text).expect("readable");
        let note = report
            .notes
            .iter()
            .find(|note| note.starts_with("labels ignored"))
            .expect("note");
        assert_eq!(
            note,
            "labels ignored (no sensor axis this tool knows): loop, LOOP2"
        );
    }

    fn read_in_chunks(bytes: &[u8], splits: &[usize]) -> Result<ImportReport, ImportError> {
        let mut reader = SerialReader::new(ASSUMED_FILE_RATE_HZ);
        let mut decoder = LineDecoder::new(MAX_LINE_BYTES);
        let mut start = 0;
        for &split in splits.iter().chain(std::iter::once(&bytes.len())) {
            decoder.feed(&bytes[start..split], |line| {
                reader.read_line(line.number, &line.text, None)
            });
            start = split;
        }
        decoder.finish(|line| reader.read_line(line.number, &line.text, None));
        reader.finish("serial.txt")
    }

    #[test]
    fn line_endings_and_chunking_do_not_matter() {
        let lf = "Raw:0,0,8192,0,0,0,200,0,-400\nmx:1 my:2 mz:3\n(4, 5, 6)\n7 8 9\n";
        let crlf = lf.replace('\n', "\r\n");
        let cr = lf.replace('\n', "\r");
        let whole = read_text(lf).expect("readable");
        assert_eq!(whole.recording.mag_in_body_ut.len(), 4);
        for text in [&crlf, &cr] {
            assert_eq!(read_text(text).expect("readable"), whole);
        }
        let bytes = crlf.as_bytes();
        for split in 0..=bytes.len() {
            assert_eq!(
                read_in_chunks(bytes, &[split]).expect("readable"),
                whole,
                "split at {split}"
            );
        }
    }

    #[test]
    fn the_live_reader_uses_arrival_times() {
        let mut reader = SerialReader::new(50.0);
        reader.read_line(1, "mx:1 my:2 mz:3", Some(10.0));
        reader.read_line(2, "mx:1 my:2 mz:4", Some(10.25));
        reader.read_line(3, "Cal1:0,0,0,0,0,0,1,2,3,45", Some(10.3));
        assert_eq!(reader.echoes().len(), 1);
        let (report, echoes) = reader.finish_with_echoes("port").expect("readable");
        assert_eq!(report.recording.mag_in_body_ut.t_s, vec![10.0, 10.25]);
        assert_eq!(echoes.first().and_then(|echo| echo.arrival_t_s), Some(10.3));
        assert!(!report
            .notes
            .iter()
            .any(|note| note.contains("no timestamps")));
    }

    #[test]
    fn garbage_is_nothing_recognised_with_a_line_number() {
        let error = read_text("\nhello world\nmore text\n").unwrap_err();
        let ImportError::NothingRecognised {
            n_lines,
            first_problem,
            format,
            ..
        } = &error
        else {
            panic!("{error:?}");
        };
        assert_eq!(*format, FORMAT_NAME);
        assert_eq!(*n_lines, 3);
        assert!(
            first_problem.starts_with(" (line 2: not a sensor line"),
            "{first_problem}"
        );
        assert!(
            error
                .to_string()
                .starts_with("serial.txt: none of its 3 lines"),
            "{error}"
        );
    }

    #[test]
    fn binary_and_empty_files_are_refused() {
        assert!(matches!(
            read("x.bin", b"\x00\x01\x02Raw:1,2,3"),
            Err(ImportError::NotText { .. })
        ));
        assert!(matches!(read("x.txt", b""), Err(ImportError::Empty { .. })));
        assert!(matches!(
            read("x.txt", b" \r\n\n"),
            Err(ImportError::Empty { .. })
        ));
    }

    #[test]
    fn long_lines_are_skipped_with_a_diagnostic() {
        let text = format!("mx:1 my:2 mz:3\n{}\n", "1,".repeat(MAX_LINE_BYTES));
        let report = read_text(&text).expect("readable");
        assert_eq!(report.recording.mag_in_body_ut.len(), 1);
        assert_eq!(
            report.diagnostics.kept.first().and_then(|d| d.line),
            Some(2)
        );
    }

    #[test]
    fn detection_takes_serial_lines_but_not_delimited_files() {
        assert!(looks_like(&[
            "Raw:0,0,8192,0,0,0,200,0,-400",
            "Uni:0,0,9.8,0,0,0,20,0,-40"
        ]));
        assert!(looks_like(&["mx:1 my:2 mz:3", "mx:1 my:2 mz:3"]));
        assert!(looks_like(&["(1.0, 2.0, 3.0)", "junk", "(1.0, 2.0, 3.0)"]));
        assert!(looks_like(&[
            "Sensor: LSM6DS",
            "Type: Acceleration",
            "Max Value: 156",
            "Raw:0,0,8192,0,0,0,1,2,3",
            "Uni:0,0,9.8,0,0,0,0.1,0.2,0.3"
        ]));
        assert!(!looks_like(&[
            "t_s,mag_x_ut,mag_y_ut,mag_z_ut",
            "0,1,2,3",
            "1,1,2,3"
        ]));
        assert!(!looks_like(&["mag_x,mag_y,mag_z", "1,2,3", "1,2,3"]));
        assert!(!looks_like(&[
            "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47"
        ]));
        assert!(!looks_like(&[]));
    }

    #[test]
    fn pseudo_random_bytes_never_panic() {
        let mut state: u64 = 0x2545_f491_4f6c_dd1d;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) as u8
        };
        let alphabet = b"0123456789-+.,;: \t\r\n()eERawUniCal12xyzXYZmagutG/s^";
        for round in 0..400 {
            let len = usize::from(next()) % 120;
            let bytes: Vec<u8> = (0..len)
                .map(|_| {
                    let byte = next();
                    if round % 2 == 0 {
                        alphabet[usize::from(byte) % alphabet.len()]
                    } else {
                        byte
                    }
                })
                .collect();
            let _ = read("fuzz.txt", &bytes);
            let _ = read_with_echoes("fuzz.txt", &bytes);
            let text = String::from_utf8_lossy(&bytes);
            for line in text.lines() {
                let _ = parse_line(line);
            }
            let _ = looks_like(&text.lines().collect::<Vec<_>>());
        }
    }
}
