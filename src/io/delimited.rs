//! Delimited text with a header line: the canonical CSV and the CSVs that phone apps,
//! data loggers and scripts write.
//!
//! Each header name is resolved to a quantity, an axis and a unit, from the name and
//! the unit written in it, in any of these spellings:
//!
//! ```text
//! mag_x_ut, acc_z_mps2, gyro_y_radps, t_s     canonical: name_axis_unit (body axes)
//! mag_x_gauss, acc_x_g, gyro_x_dps            the same scheme, other units (body axes)
//! "Time (s)","X (µT)","Y (µT)","Z (µT)"       phyphox: the unit says which sensor
//! time,speed,bearing,…,acc_z,acc_y,acc_x,…     Sensor Logger: bare names, no units
//! x,y,z                                        plain: taken as a magnetometer
//! ```
//!
//! Where a name carries no unit, the unit is guessed from the data (the field
//! magnitude tells gauss, mG, nT, T and µT apart; the specific force at rest tells g
//! from m/s²; rotation rates tell deg/s from rad/s), and the guess is stated in the
//! report's notes. Values are converted once, when the file is finished.
//!
//! **Axes.** Names with a unit suffix (`mag_x_ut`, `acc_x_g`) are taken to be in the
//! body frame (x forward, y right, z down), as the canonical CSV defines. Phone apps
//! (phyphox, Sensor Logger) write Android device axes; those are turned into body axes
//! by [`super::axes::PhoneMount`], chosen from the mean specific force once all files
//! of a recording are merged ([`RawImport::into_report`]).
//!
//! Time may be seconds, milli-, micro- or nanoseconds (from the unit, else from the
//! magnitude: epoch times are recognised) or ISO 8601 date-times
//! (`2023-08-09 12:47:45+00:00`); it is made relative to the first sample. A negative
//! speed, course or accuracy (phyphox writes −1) means "invalid" and is dropped.

use nalgebra::{Vector2, Vector3};

use super::axes::PhoneMount;
use super::lines::decode_all;
use super::{ensure_text, shorten, Diagnostics, HeaderInfo, ImportError, ImportReport};
use crate::recording::{Attitude, GnssFix, Recording, Stream};

pub const FORMAT_NAME: &str = "delimited text";

/// Lines longer than this are cut.
const MAX_LINE_BYTES: usize = 64 * 1024;

/// What one column holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Quantity {
    Time,
    Acc,
    Gyro,
    Mag,
    Temp,
    Lat,
    Lon,
    Alt,
    Speed,
    Course,
    HorizontalAccuracy,
    RefHeading,
    RefEast,
    RefNorth,
    Roll,
    Pitch,
    Yaw,
    Pressure,
}

/// A recognised column: quantity, axis (0, 1, 2 for x, y, z) and the factor to this
/// crate's unit, or `None` when it must be guessed from the data.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Column {
    quantity: Quantity,
    axis: usize,
    scale: Option<f64>,
}

/// The axes vector columns are written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SensorAxes {
    /// Body axes (x forward, y right, z down), as the canonical CSV defines.
    Body,
    /// Android device axes (x right, y to the top edge, z out of the screen).
    AndroidDevice,
}

/// A file read with its values in the file's own axes and (possibly unknown) units,
/// ready to be merged with other files of the same recording.
#[derive(Debug, Clone, PartialEq)]
pub struct RawImport {
    pub report: ImportReport,
    pub axes: SensorAxes,
}

/// Reads one delimited file and turns it into body axes and this crate's units.
pub fn read(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    read_raw(file_name, bytes).map(RawImport::into_report)
}

/// Reads one delimited file, leaving vectors in the file's axes (see [`RawImport`]).
pub fn read_raw(file_name: &str, bytes: &[u8]) -> Result<RawImport, ImportError> {
    ensure_text(file_name, bytes)?;
    let file_name = file_name.to_string();
    let mut reader = Reader::default();
    decode_all(bytes, MAX_LINE_BYTES, |line| {
        if line.truncated {
            reader.diagnostics.push(
                Some(line.number),
                format!("line longer than {MAX_LINE_BYTES} bytes; its end was ignored"),
            );
        }
        reader.read_line(line.number, &line.text);
    });
    reader.finish(file_name)
}

/// True when the first non-comment line of a sample reads as a header with at least one
/// recognised column.
pub fn looks_like(sample_lines: &[&str]) -> bool {
    let Some(first) = sample_lines
        .iter()
        .map(|line| line.trim())
        .find(|line| !line.is_empty() && !line.starts_with('#'))
    else {
        return false;
    };
    let header = Header::parse(1, first);
    header.columns.iter().any(Option::is_some) && first.chars().any(|c| c.is_ascii_alphabetic())
}

impl RawImport {
    /// Converts device axes to body axes, choosing the phone mount from the mean
    /// specific force, and says what was done in the notes.
    pub fn into_report(self) -> ImportReport {
        let RawImport { mut report, axes } = self;
        if axes == SensorAxes::AndroidDevice {
            let recording = &mut report.recording;
            let acc = &recording.acc_in_body_mps2.values;
            let mean_acc = acc.iter().fold(Vector3::zeros(), |sum, value| sum + value)
                / (acc.len().max(1) as f64);
            let mount = PhoneMount::detect(mean_acc).unwrap_or_else(|| {
                report.notes.push(
                    "the phone's mount could not be told from the accelerometer; assumed held flat"
                        .to_string(),
                );
                PhoneMount::Flat
            });
            for stream in [
                &mut recording.acc_in_body_mps2,
                &mut recording.gyro_in_body_radps,
                &mut recording.mag_in_body_ut,
            ] {
                for value in &mut stream.values {
                    *value = mount.device_to_body(*value);
                }
            }
            report
                .notes
                .push(format!("Android device axes, {}", mount.describe()));
        } else if !report.recording.mag_in_body_ut.is_empty()
            || !report.recording.acc_in_body_mps2.is_empty()
        {
            report
                .notes
                .push("vectors taken as body axes (x forward, y right, z down)".to_string());
        }
        report
    }
}

#[derive(Default)]
struct Reader {
    header: Option<Header>,
    /// Raw values in the file's units; scaled in `finish`.
    raw: RawStreams,
    diagnostics: Diagnostics,
    n_data_lines: usize,
}

#[derive(Default)]
struct RawStreams {
    time: Vec<f64>,
    acc: Stream<Vector3<f64>>,
    gyro: Stream<Vector3<f64>>,
    mag: Stream<Vector3<f64>>,
    temp: Stream<f64>,
    gnss: Stream<GnssFix>,
    attitude: Stream<(f64, f64, Option<f64>)>,
    pressure: Stream<f64>,
    ref_heading: Stream<f64>,
    ref_position: Stream<Vector2<f64>>,
}

struct Header {
    line: usize,
    delimiter: char,
    names: Vec<String>,
    columns: Vec<Option<Column>>,
    axes: SensorAxes,
    /// The time column, if any: a preferred one (seconds elapsed) wins over others.
    time_field: Option<usize>,
}

impl Reader {
    fn read_line(&mut self, line_number: usize, text: &str) {
        let trimmed = text.trim_start_matches('\u{feff}').trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            return;
        }
        if self.header.is_none() {
            self.header = Some(Header::parse(line_number, trimmed));
            return;
        }
        self.n_data_lines += 1;
        self.read_data_line(line_number, trimmed);
    }

    fn read_data_line(&mut self, line_number: usize, text: &str) {
        let Some(header) = &self.header else { return };
        // One slot per quantity and axis, in the file's units.
        let mut values: [[Option<f64>; 3]; N_QUANTITIES] = [[None; 3]; N_QUANTITIES];
        let mut time: Option<f64> = None;
        let mut problems: Vec<String> = Vec::new();
        let mut n_fields = 0usize;
        for (field_idx, field) in text.split(header.delimiter).enumerate() {
            n_fields += 1;
            let Some(Some(column)) = header.columns.get(field_idx) else {
                continue;
            };
            let field = field.trim().trim_matches('"').trim();
            if field.is_empty() {
                continue;
            }
            let name = header
                .names
                .get(field_idx)
                .map(String::as_str)
                .unwrap_or("?");
            let parsed = match field.parse::<f64>() {
                Ok(value) => Some(value),
                Err(_) if column.quantity == Quantity::Time => parse_datetime_s(field),
                Err(_) => None,
            };
            match parsed {
                Some(value) if value.is_finite() => {
                    if column.quantity == Quantity::Time {
                        if header.time_field == Some(field_idx) {
                            time = Some(value);
                        }
                    } else if let Some(slot) = values
                        .get_mut(column.quantity as usize)
                        .and_then(|axes| axes.get_mut(column.axis))
                    {
                        *slot = Some(value);
                    }
                }
                Some(_) => problems.push(format!("{name} is {field}")),
                None => problems.push(format!("{name} is not a number ({})", shorten(field))),
            }
        }
        if n_fields > header.columns.len() {
            problems.push(format!(
                "{n_fields} fields where the header (line {}) has {}; the extra fields were ignored",
                header.line,
                header.columns.len()
            ));
        }
        let t_raw = match (header.time_field, time) {
            (Some(_), Some(t_raw)) => t_raw,
            (Some(_), None) => {
                problems.push("no time, so the line was skipped".to_string());
                self.diagnostics
                    .push(Some(line_number), problems.join("; "));
                return;
            }
            // Without a time column the sample number stands in for time.
            (None, _) => self.n_data_lines as f64 - 1.0,
        };
        let index = self.raw.time.len() as f64;
        self.raw.time.push(t_raw);
        // Streams hold the sample's index into `time` until `finish` converts it.
        let get = |quantity: Quantity| values[quantity as usize];
        let single = |quantity: Quantity| values[quantity as usize][0];
        let raw = &mut self.raw;
        for (quantity, stream, label) in [
            (Quantity::Acc, &mut raw.acc, "accelerometer"),
            (Quantity::Gyro, &mut raw.gyro, "gyroscope"),
            (Quantity::Mag, &mut raw.mag, "magnetometer"),
        ] {
            match get(quantity) {
                [Some(x), Some(y), Some(z)] => stream.push(index, Vector3::new(x, y, z)),
                [None, None, None] => {}
                _ => problems.push(format!(
                    "{label} has only some of x, y, z; that sample was skipped"
                )),
            }
        }
        if let Some(temp) = single(Quantity::Temp) {
            raw.temp.push(index, temp);
        }
        if let Some(pressure) = single(Quantity::Pressure) {
            raw.pressure.push(index, pressure);
        }
        // A negative speed, course or accuracy is an "invalid" marker (phyphox: −1).
        let non_negative = |value: Option<f64>| value.filter(|value| *value >= 0.0);
        let fix = GnssFix {
            lat_deg: single(Quantity::Lat),
            lon_deg: single(Quantity::Lon),
            alt_m: single(Quantity::Alt),
            speed_mps: non_negative(single(Quantity::Speed)),
            course_rad: non_negative(single(Quantity::Course)),
            hacc_m: non_negative(single(Quantity::HorizontalAccuracy)),
        };
        if fix != GnssFix::default() {
            raw.gnss.push(index, fix);
        }
        if let (Some(roll), Some(pitch)) = (single(Quantity::Roll), single(Quantity::Pitch)) {
            raw.attitude
                .push(index, (roll, pitch, single(Quantity::Yaw)));
        }
        if let Some(heading) = single(Quantity::RefHeading) {
            raw.ref_heading.push(index, heading);
        }
        match (single(Quantity::RefEast), single(Quantity::RefNorth)) {
            (Some(east_m), Some(north_m)) => {
                raw.ref_position.push(index, Vector2::new(east_m, north_m))
            }
            (None, None) => {}
            _ => problems.push("reference position has only one of east and north".to_string()),
        }
        if !problems.is_empty() {
            self.diagnostics
                .push(Some(line_number), problems.join("; "));
        }
    }

    fn finish(mut self, file_name: String) -> Result<RawImport, ImportError> {
        let Some(header) = self.header.take() else {
            return Err(ImportError::NoHeader { file_name });
        };
        if header.columns.iter().all(Option::is_none) {
            return Err(ImportError::UnknownHeader {
                file_name,
                line: header.line,
                found: shorten(&header.names.join(", ")),
            });
        }
        let mut notes = Vec::new();
        let unknown: Vec<&str> = header
            .names
            .iter()
            .zip(&header.columns)
            .filter(|(_, column)| column.is_none())
            .map(|(name, _)| name.as_str())
            .collect();
        // Ignored columns and a missing time are facts about the file, not problems of a
        // line: they are notes.
        if !unknown.is_empty() {
            notes.push(format!(
                "columns ignored (not recognised): {}",
                shorten(&unknown.join(", "))
            ));
        }
        if header.time_field.is_none() {
            notes.push("no time column: the sample number is used as time".to_string());
        }

        let scale_of = |quantity: Quantity| {
            header
                .columns
                .iter()
                .flatten()
                .find(|column| column.quantity == quantity)
                .and_then(|column| column.scale)
        };
        let raw = &self.raw;
        let time_scale = match scale_of(Quantity::Time) {
            Some(scale) => scale,
            None => {
                let (scale, guess) = guess_time_scale(&raw.time);
                if header.time_field.is_some() {
                    notes.push(format!("time unit guessed from the values: {guess}"));
                }
                scale
            }
        };
        // Absolute times (epoch seconds, from date-times or epoch counters) are made
        // relative to the first sample; times that already count from a start are kept,
        // so that times the user quotes from the file still mean the same.
        let first_raw = raw.time.iter().copied().fold(f64::INFINITY, f64::min);
        let t0_raw = if first_raw.is_finite() && first_raw * time_scale > ABSOLUTE_TIME_S {
            first_raw
        } else {
            0.0
        };
        if t0_raw != 0.0 {
            notes.push(format!(
                "absolute times made relative to the first sample ({:.3} s after 1970)",
                t0_raw * time_scale
            ));
        }
        let time_of = |index: f64| {
            raw.time
                .get(index as usize)
                .map_or(0.0, |t_raw| (t_raw - t0_raw) * time_scale)
        };

        let mut recording = Recording::default();
        let (acc_scale, acc_note) =
            unit_or_guess(scale_of(Quantity::Acc), &raw.acc.values, guess_acc_scale);
        let (gyro_scale, gyro_note) =
            unit_or_guess(scale_of(Quantity::Gyro), &raw.gyro.values, guess_gyro_scale);
        let (mag_scale, mag_note) =
            unit_or_guess(scale_of(Quantity::Mag), &raw.mag.values, guess_mag_scale);
        notes.extend([acc_note, gyro_note, mag_note].into_iter().flatten());
        let convert = |stream: &Stream<Vector3<f64>>, scale: f64| Stream {
            t_s: stream.t_s.iter().map(|&index| time_of(index)).collect(),
            values: stream.values.iter().map(|value| value * scale).collect(),
        };
        recording.acc_in_body_mps2 = convert(&raw.acc, acc_scale);
        recording.gyro_in_body_radps = convert(&raw.gyro, gyro_scale);
        recording.mag_in_body_ut = convert(&raw.mag, mag_scale);
        let convert_scalar = |stream: &Stream<f64>, scale: f64| Stream {
            t_s: stream.t_s.iter().map(|&index| time_of(index)).collect(),
            values: stream.values.iter().map(|value| value * scale).collect(),
        };
        recording.temp_c = convert_scalar(&raw.temp, scale_of(Quantity::Temp).unwrap_or(1.0));
        recording.pressure_hpa =
            convert_scalar(&raw.pressure, scale_of(Quantity::Pressure).unwrap_or(1.0));
        recording.ref_heading_rad = convert_scalar(&raw.ref_heading, DEG_TO_RAD);
        let course_scale = scale_of(Quantity::Course).unwrap_or(DEG_TO_RAD);
        recording.gnss = Stream {
            t_s: raw.gnss.t_s.iter().map(|&index| time_of(index)).collect(),
            values: raw
                .gnss
                .values
                .iter()
                .map(|fix| GnssFix {
                    course_rad: fix.course_rad.map(|course| course * course_scale),
                    ..*fix
                })
                .collect(),
        };
        let angle_scale = scale_of(Quantity::Roll).unwrap_or(1.0);
        recording.attitude = Stream {
            t_s: raw
                .attitude
                .t_s
                .iter()
                .map(|&index| time_of(index))
                .collect(),
            values: raw
                .attitude
                .values
                .iter()
                .map(|&(roll, pitch, yaw)| Attitude {
                    roll_rad: roll * angle_scale,
                    pitch_rad: pitch * angle_scale,
                    yaw_rad: yaw.map(|yaw| yaw * angle_scale),
                })
                .collect(),
        };
        recording.ref_position_en_m = Stream {
            t_s: raw
                .ref_position
                .t_s
                .iter()
                .map(|&index| time_of(index))
                .collect(),
            values: raw.ref_position.values.clone(),
        };
        if !recording.attitude.is_empty() && header.axes == SensorAxes::AndroidDevice {
            // The app's orientation angles are in its own conventions, which are not
            // converted yet; they are kept out rather than passed on wrong.
            recording.attitude = Stream::default();
            notes.push("the app's roll/pitch/yaw columns were not used (their axis convention is the app's)".to_string());
        }
        let n_out_of_order = recording.sort_all_by_time();
        if n_out_of_order > 0 {
            self.diagnostics.push(
                Some(header.line),
                format!(
                    "time goes backwards {n_out_of_order} times; the samples were sorted by time"
                ),
            );
        }
        Ok(RawImport {
            report: ImportReport {
                file_name,
                format: FORMAT_NAME,
                recording,
                diagnostics: self.diagnostics,
                header: Some(HeaderInfo {
                    line: header.line,
                    columns: header.names,
                }),
                n_data_lines: self.n_data_lines,
                notes,
            },
            axes: header.axes,
        })
    }
}

/// Times beyond this many seconds (about three years) are taken as absolute (epoch).
const ABSOLUTE_TIME_S: f64 = 1e8;
const N_QUANTITIES: usize = Quantity::Pressure as usize + 1;
const DEG_TO_RAD: f64 = std::f64::consts::PI / 180.0;
/// Standard gravity (CGPM 1901), for accelerometers that report in g.
const STANDARD_GRAVITY_MPS2: f64 = 9.806_65;

impl Header {
    fn parse(line: usize, text: &str) -> Header {
        let delimiter = if text.contains(',') {
            ','
        } else if text.contains('\t') {
            '\t'
        } else if text.contains(';') {
            ';'
        } else {
            ','
        };
        let names: Vec<String> = text
            .split(delimiter)
            .map(|name| name.trim().trim_matches('"').trim().to_string())
            .collect();
        let resolved: Vec<Option<(Column, Naming)>> =
            names.iter().map(|name| resolve(name)).collect();
        let axes = if resolved
            .iter()
            .flatten()
            .any(|(_, naming)| *naming == Naming::PhoneApp)
        {
            SensorAxes::AndroidDevice
        } else {
            SensorAxes::Body
        };
        // Prefer "seconds elapsed" over an absolute time when a file has both.
        let time_fields: Vec<(usize, Naming)> = resolved
            .iter()
            .enumerate()
            .filter_map(|(idx, column)| {
                column
                    .filter(|(column, _)| column.quantity == Quantity::Time)
                    .map(|(_, naming)| (idx, naming))
            })
            .collect();
        let time_field = time_fields
            .iter()
            .find(|(_, naming)| *naming == Naming::Elapsed)
            .or(time_fields.first())
            .map(|(idx, _)| *idx);
        let columns = resolved
            .into_iter()
            .map(|column| column.map(|(column, _)| column))
            .collect();
        Header {
            line,
            delimiter,
            names,
            columns,
            axes,
            time_field,
        }
    }
}

/// How a column was named, which tells the axes it is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Naming {
    /// `name_axis_unit`, or a plain name: body axes.
    Suffixed,
    /// A phone app's own names (phyphox's "X (µT)", Sensor Logger's bare `acc_x`).
    PhoneApp,
    /// A time column counting seconds from the start of the recording.
    Elapsed,
}

/// Resolves one header name to a column.
fn resolve(raw_name: &str) -> Option<(Column, Naming)> {
    let lower = raw_name.trim().trim_matches('"').to_lowercase();
    // "X (µT)": a name and a unit in parentheses.
    let (name, paren_unit) = match (lower.find('('), lower.rfind(')')) {
        (Some(open), Some(close)) if close > open => (
            lower[..open].trim().to_string(),
            Some(lower[open + 1..close].trim().to_string()),
        ),
        _ => (lower.clone(), None),
    };
    let name = name.replace([' ', '-', '.'], "_");
    let tokens: Vec<&str> = name.split('_').filter(|token| !token.is_empty()).collect();
    // A trailing unit token: "mag_x_gauss", "t_s", "temp_c".
    let (base_tokens, suffix_unit) = match tokens.split_last() {
        Some((last, rest)) if !rest.is_empty() && unit_scale(last).is_some() => {
            (rest.to_vec(), Some(last.to_string()))
        }
        _ => (tokens.clone(), None),
    };
    let unit = paren_unit.clone().or(suffix_unit.clone());
    let scale = unit.as_deref().and_then(unit_scale);
    let base = base_tokens.join("_");
    let column = |quantity: Quantity, axis: usize, scale: Option<f64>| Column {
        quantity,
        axis,
        scale,
    };

    // A vector component: a sensor prefix and an axis letter, or an axis letter whose
    // unit says the sensor (phyphox).
    let axis_of = |token: &str| match token {
        "x" => Some(0),
        "y" => Some(1),
        "z" => Some(2),
        _ => None,
    };
    let sensor_of = |token: &str| match token {
        "acc" | "accel" | "accelerometer" | "acceleration" | "a" => Some(Quantity::Acc),
        "gyro" | "gyroscope" | "gyr" | "rot" | "rate" | "g" => Some(Quantity::Gyro),
        "mag" | "magnetometer" | "magnetic" | "magn" | "compass" | "m" | "b" => Some(Quantity::Mag),
        _ => None,
    };
    let naming = if suffix_unit.is_some() {
        Naming::Suffixed
    } else if paren_unit.is_some() {
        Naming::PhoneApp
    } else {
        Naming::Suffixed
    };
    match base_tokens.as_slice() {
        [sensor, axis] if sensor_of(sensor).is_some() && axis_of(axis).is_some() => {
            let quantity = sensor_of(sensor)?;
            let axis = axis_of(axis)?;
            // Sensor Logger writes bare `acc_x`, `mag_z`: device axes, no units.
            let naming = if unit.is_none() {
                Naming::PhoneApp
            } else {
                naming
            };
            return Some((
                column(
                    quantity,
                    axis,
                    scale.filter(|_| unit_matches(quantity, unit.as_deref())),
                ),
                naming,
            ));
        }
        [compact]
            if compact.len() == 2
                && sensor_of(&compact[..1]).is_some()
                && axis_of(&compact[1..]).is_some() =>
        {
            // "mx", "ax", "gz".
            let quantity = sensor_of(&compact[..1])?;
            return Some((
                column(quantity, axis_of(&compact[1..])?, scale),
                Naming::Suffixed,
            ));
        }
        [axis] if axis_of(axis).is_some() => {
            let axis = axis_of(axis)?;
            let quantity = match unit.as_deref() {
                Some(unit) => quantity_of_unit(unit)?,
                None => Quantity::Mag,
            };
            return Some((
                column(quantity, axis, scale),
                if paren_unit.is_some() {
                    Naming::PhoneApp
                } else {
                    Naming::Suffixed
                },
            ));
        }
        _ => {}
    }
    let quantity = match base.as_str() {
        "t" | "time" | "timestamp" | "unix_time" | "epoch" => Quantity::Time,
        "seconds_elapsed" | "elapsed" | "elapsed_time" => {
            return Some((column(Quantity::Time, 0, Some(1.0)), Naming::Elapsed));
        }
        "temp" | "temperature" => Quantity::Temp,
        "lat" | "latitude" => Quantity::Lat,
        "lon" | "lng" | "long" | "longitude" => Quantity::Lon,
        "alt" | "altitude" | "height" => Quantity::Alt,
        "speed" | "velocity" | "gps_speed" => Quantity::Speed,
        "bearing" | "course" | "direction" | "gps_course" | "cog" => Quantity::Course,
        "hacc" | "horizontalaccuracy" | "horizontal_accuracy" | "gps_hacc" | "accuracy" => {
            Quantity::HorizontalAccuracy
        }
        "ref_heading" | "true_heading" | "reference_heading" => Quantity::RefHeading,
        "ref_e" | "ref_east" => Quantity::RefEast,
        "ref_n" | "ref_north" => Quantity::RefNorth,
        "roll" => Quantity::Roll,
        "pitch" => Quantity::Pitch,
        "yaw" | "azimuth" => Quantity::Yaw,
        "pressure" | "baro" => Quantity::Pressure,
        _ => return None,
    };
    let scale = match (quantity, scale) {
        (Quantity::Time, None) if unit.is_none() && base == "t" => None,
        (_, scale) => scale,
    };
    Some((column(quantity, 0, scale), naming))
}

/// Whether a unit fits a quantity (so that "acc_x_s" is not read as seconds).
fn unit_matches(quantity: Quantity, unit: Option<&str>) -> bool {
    match unit {
        None => true,
        Some(unit) => quantity_of_unit(unit) == Some(quantity),
    }
}

/// The quantity a unit measures, for columns named only by an axis.
fn quantity_of_unit(unit: &str) -> Option<Quantity> {
    match unit {
        "µt" | "ut" | "μt" | "gauss" | "mg" | "milligauss" | "nt" | "t" | "microtesla" => {
            Some(Quantity::Mag)
        }
        "m/s^2" | "m/s²" | "mps2" | "g" => Some(Quantity::Acc),
        "rad/s" | "radps" | "deg/s" | "dps" | "°/s" | "degps" => Some(Quantity::Gyro),
        _ => None,
    }
}

/// The factor from a unit to this crate's unit of its quantity.
fn unit_scale(unit: &str) -> Option<f64> {
    let scale = match unit {
        "s" | "sec" | "secs" | "seconds" => 1.0,
        "ms" => 1e-3,
        "us" | "µs" => 1e-6,
        "ns" => 1e-9,
        "µt" | "ut" | "μt" | "microtesla" => 1.0,
        "gauss" => 100.0,
        "mg" | "milligauss" => 0.1,
        "nt" => 1e-3,
        "t" => 1e6,
        "m/s^2" | "m/s²" | "mps2" => 1.0,
        "g" => STANDARD_GRAVITY_MPS2,
        "rad/s" | "radps" => 1.0,
        "deg/s" | "dps" | "°/s" | "degps" => DEG_TO_RAD,
        "deg" | "°" | "degrees" => DEG_TO_RAD,
        "rad" => 1.0,
        "c" | "°c" | "degc" => 1.0,
        "m" => 1.0,
        "mps" | "m/s" => 1.0,
        "hpa" | "mbar" => 1.0,
        "pa" => 0.01,
        "kpa" => 10.0,
        _ => return None,
    };
    Some(scale)
}

/// A known unit's scale, or a guess from the data with a note saying so.
fn unit_or_guess(
    known: Option<f64>,
    values: &[Vector3<f64>],
    guess: fn(f64) -> (f64, &'static str),
) -> (f64, Option<String>) {
    if let Some(scale) = known {
        return (scale, None);
    }
    if values.is_empty() {
        return (1.0, None);
    }
    let mut norms: Vec<f64> = values
        .iter()
        .map(|value| value.norm())
        .filter(|norm| norm.is_finite())
        .collect();
    norms.sort_by(f64::total_cmp);
    let median = norms.get(norms.len() / 2).copied().unwrap_or(0.0);
    let (scale, description) = guess(median);
    (
        scale,
        Some(format!(
            "{description} (median magnitude {median:.3}); override the unit if this is wrong"
        )),
    )
}

/// Magnetometer unit from the median field magnitude. Earth's field is 25-65 µT; hard
/// iron can multiply a raw reading several times, so the bands are wide.
fn guess_mag_scale(median: f64) -> (f64, &'static str) {
    if median < 1e-3 {
        (1e6, "magnetometer unit guessed as tesla")
    } else if median < 5.0 {
        (100.0, "magnetometer unit guessed as gauss")
    } else if median < 5_000.0 {
        (1.0, "magnetometer unit guessed as µT")
    } else {
        (1e-3, "magnetometer unit guessed as nT")
    }
}

/// Accelerometer unit from the median specific force: about 1 in g, 9.8 in m/s².
fn guess_acc_scale(median: f64) -> (f64, &'static str) {
    if median < 3.0 {
        (STANDARD_GRAVITY_MPS2, "accelerometer unit guessed as g")
    } else {
        (1.0, "accelerometer unit guessed as m/s²")
    }
}

/// Gyroscope unit from the median rate: a median above 1.5 would be 86°/s in rad/s,
/// more than a walk or a drive turns for most of the time.
fn guess_gyro_scale(median: f64) -> (f64, &'static str) {
    if median > 1.5 {
        (DEG_TO_RAD, "gyroscope unit guessed as deg/s")
    } else {
        (1.0, "gyroscope unit guessed as rad/s")
    }
}

/// Time unit from the values: epoch nanoseconds, microseconds, milliseconds or
/// seconds, told apart by magnitude.
fn guess_time_scale(times: &[f64]) -> (f64, &'static str) {
    let largest = times
        .iter()
        .copied()
        .filter(|t| t.is_finite())
        .fold(0.0f64, |a, b| a.max(b.abs()));
    if largest > 1e17 {
        (1e-9, "nanoseconds")
    } else if largest > 1e14 {
        (1e-6, "microseconds")
    } else if largest > 1e11 {
        (1e-3, "milliseconds")
    } else {
        (1.0, "seconds")
    }
}

/// Seconds since 1970 of an ISO 8601 date-time such as `2023-08-09 12:47:45+00:00`,
/// `2023-08-09T12:47:45.250Z` or `2023-08-09 12:47:45` (taken as UTC).
pub fn parse_datetime_s(text: &str) -> Option<f64> {
    let text = text.trim();
    let date = text.get(..10)?;
    let mut date_parts = date.split('-');
    let year: i64 = date_parts.next()?.parse().ok()?;
    let month: i64 = date_parts.next()?.parse().ok()?;
    let day: i64 = date_parts.next()?.parse().ok()?;
    if !(1..=12).contains(&month) || !(1..=31).contains(&day) {
        return None;
    }
    let rest = text.get(10..)?.trim_start_matches(['T', ' ']);
    // Split off a zone: "Z", "+hh:mm", "-hh:mm" after the time.
    let (clock, offset_s) = if let Some(clock) = rest.strip_suffix('Z') {
        (clock, 0.0)
    } else if let Some(sign_idx) = rest.rfind(['+', '-']).filter(|&idx| idx >= 5) {
        let (clock, zone) = rest.split_at(sign_idx);
        let sign = if zone.starts_with('-') { -1.0 } else { 1.0 };
        let zone = zone.get(1..)?.replace(':', "");
        let hours: f64 = zone.get(..2)?.parse().ok()?;
        let minutes: f64 = zone
            .get(2..)
            .filter(|m| !m.is_empty())
            .map_or(Some(0.0), |m| m.parse().ok())?;
        (clock, sign * (hours * 3600.0 + minutes * 60.0))
    } else {
        (rest, 0.0)
    };
    let mut clock_parts = clock.split(':');
    let hours: f64 = clock_parts.next()?.parse().ok()?;
    let minutes: f64 = clock_parts.next()?.parse().ok()?;
    let seconds: f64 = clock_parts.next().map_or(Some(0.0), |s| s.parse().ok())?;
    // Days from the civil date (Howard Hinnant's algorithm, public domain).
    let (y, m) = if month <= 2 {
        (year - 1, month + 9)
    } else {
        (year, month - 3)
    };
    let era = y.div_euclid(400);
    let year_of_era = y - era * 400;
    let day_of_year = (153 * m + 2) / 5 + day - 1;
    let day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
    let days = era * 146_097 + day_of_era - 719_468;
    Some(days as f64 * 86_400.0 + hours * 3600.0 + minutes * 60.0 + seconds - offset_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_text(text: &str) -> ImportReport {
        read("test.csv", text.as_bytes()).expect("readable")
    }

    #[test]
    fn iso_datetimes_become_epoch_seconds() {
        assert_eq!(parse_datetime_s("1970-01-01 00:00:00+00:00"), Some(0.0));
        assert_eq!(
            parse_datetime_s("2023-08-09 12:47:45+00:00"),
            Some(1_691_585_265.0)
        );
        assert_eq!(
            parse_datetime_s("2023-08-09T14:47:45.5+02:00"),
            Some(1_691_585_265.5)
        );
        assert_eq!(
            parse_datetime_s("2023-08-09T12:47:45Z"),
            Some(1_691_585_265.0)
        );
        assert_eq!(parse_datetime_s("not a date"), None);
        assert_eq!(parse_datetime_s("2023-13-09 00:00:00"), None);
    }

    #[test]
    fn phyphox_headers_say_the_sensor_by_their_unit() {
        let report = read_text("\"Time (s)\",\"X (µT)\",\"Y (µT)\",\"Z (µT)\"\n1.0E-2,1.8E1,3.5E0,-3.5E1\n2.0E-2,1.9E1,3.6E0,-3.6E1\n");
        let mag = &report.recording.mag_in_body_ut;
        assert_eq!(mag.len(), 2);
        // Device axes, flat by default (no accelerometer): body = (y, x, −z).
        assert_eq!(mag.values[0], Vector3::new(3.5, 18.0, 35.0));
        assert!(
            (mag.t_s[1] - 0.02).abs() < 1e-12,
            "times counted from a start are kept"
        );
        assert!(report
            .notes
            .iter()
            .any(|note| note.contains("Android device axes")));
    }

    #[test]
    fn units_in_suffixes_are_converted() {
        let report = read_text("t_s,mag_x_gauss,mag_y_gauss,mag_z_gauss,acc_x_g,acc_y_g,acc_z_g,gyro_x_dps,gyro_y_dps,gyro_z_dps\n0,0.25,-0.3,-0.4,0,0,-1,90,0,0\n");
        let recording = &report.recording;
        assert!(
            (recording.mag_in_body_ut.values[0] - Vector3::new(25.0, -30.0, -40.0)).norm() < 1e-9
        );
        assert!((recording.acc_in_body_mps2.values[0].z + STANDARD_GRAVITY_MPS2).abs() < 1e-9);
        assert!(
            (recording.gyro_in_body_radps.values[0].x - std::f64::consts::FRAC_PI_2).abs() < 1e-12
        );
        assert!(report.notes.iter().any(|note| note.contains("body axes")));
    }

    #[test]
    fn missing_units_are_guessed_and_said() {
        let report = read_text("x,y,z\n0.2,0.1,-0.4\n0.25,0.1,-0.4\n");
        assert!((report.recording.mag_in_body_ut.values[0].x - 20.0).abs() < 1e-9);
        assert!(
            report
                .notes
                .iter()
                .any(|note| note.contains("guessed as gauss")),
            "{:?}",
            report.notes
        );
    }

    #[test]
    fn sensor_logger_columns_and_datetimes() {
        let text = "time,speed,bearing,horizontalAccuracy,latitude,longitude,acc_z,acc_y,acc_x,mag_z,mag_y,mag_x\n\
                    2023-08-09 12:47:45+00:00,0.0,0.0,6.2,40.04,-75.22,-0.05,9.77,-0.07,-30.0,10.0,20.0\n\
                    2023-08-09 12:47:46+00:00,,,,,,-0.03,9.76,-0.06,-31.0,10.0,20.0\n";
        let report = read_text(text);
        let recording = &report.recording;
        assert_eq!(recording.mag_in_body_ut.t_s, vec![0.0, 1.0]);
        // Upright in a mount: body = (−z, x, −y), gravity along device y.
        assert!(
            report.notes.iter().any(|note| note.contains("upright")),
            "{:?}",
            report.notes
        );
        assert_eq!(
            recording.mag_in_body_ut.values[0],
            Vector3::new(30.0, 20.0, -10.0)
        );
        assert!((recording.acc_in_body_mps2.values[0].z + 9.77).abs() < 1e-9);
        assert_eq!(recording.gnss.len(), 1, "the second row has no fix");
    }

    #[test]
    fn phyphox_invalid_markers_are_dropped() {
        let report = read_text("\"Time (s)\",\"Latitude (°)\",\"Longitude (°)\",\"Velocity (m/s)\",\"Direction (°)\",\"Horizontal Accuracy (m)\"\n0.1,43.5,1.39,-1,-1,669.0\n");
        let fix = report.recording.gnss.values[0];
        assert_eq!((fix.speed_mps, fix.course_rad), (None, None));
        assert_eq!(fix.hacc_m, Some(669.0));
        assert_eq!(fix.lat_deg, Some(43.5));
    }

    #[test]
    fn headers_that_name_nothing_known_are_refused() {
        assert!(matches!(
            read("a.csv", b"foo,bar\n1,2\n"),
            Err(ImportError::UnknownHeader { .. })
        ));
        assert!(looks_like(&["t_s,mag_x_ut,mag_y_ut,mag_z_ut"]));
        assert!(!looks_like(&["$GPGGA,123519,4807.038,N"]));
        assert!(!looks_like(&["1,2,3"]));
    }
}
