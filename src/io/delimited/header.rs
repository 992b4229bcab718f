//! The header of delimited text ([`super`]): each name resolved to a quantity, an axis
//! and a unit, in the spellings the module's header lists (canonical `mag_x_ut`, the
//! same scheme in other units, phyphox's `"X (µT)"`, Sensor Logger's bare `acc_x`,
//! plain `x,y,z`, a per-sensor file's `x,y,z`); the delimiter; a first line of only
//! numbers read as columns `column 1`, `column 2`, …; and the `key,value` settings lines
//! a data logger writes before the header (`Fs,50.00`).

use super::mapping::{ColumnMapping, IGNORE};
use super::{SensorAxes, XyzColumns};
use crate::io::number::parse_f64;
use crate::io::STANDARD_GRAVITY_MPS2;

/// What one column holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Quantity {
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
pub(super) struct Column {
    pub(super) quantity: Quantity,
    pub(super) axis: usize,
    pub(super) scale: Option<f64>,
}

/// A `key,value` line before the header, such as `Fs,50.00` or `Initialization time,60`:
/// a data logger's settings.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Setting {
    pub(super) key: String,
    pub(super) value: f64,
    /// The line as written, for the notes.
    pub(super) text: String,
}

impl Setting {
    /// The sample rate in Hz, where the key names one (`Fs`, `sample rate`, `ODR`, …)
    /// and the value is a plausible rate.
    pub(super) fn sample_rate_hz(&self) -> Option<f64> {
        let key: String = self
            .key
            .to_lowercase()
            .chars()
            .filter(char::is_ascii_alphanumeric)
            .collect();
        let key = key.strip_suffix("hz").unwrap_or(&key);
        let names_a_rate = matches!(
            key,
            "fs" | "samplerate"
                | "samplingrate"
                | "samplefrequency"
                | "samplingfrequency"
                | "rate"
                | "frequency"
                | "odr"
                | "outputdatarate"
                | "datarate"
        );
        (names_a_rate && self.value > 0.0 && self.value <= MAX_SAMPLE_RATE_HZ).then_some(self.value)
    }
}

/// The highest sample rate a settings line is believed to give.
const MAX_SAMPLE_RATE_HZ: f64 = 100_000.0;

/// A settings line (`key,value` before the header): two fields, a key with a letter that
/// names no column, and a number. `None` for any other line.
pub(super) fn setting_of(text: &str, mapping: Option<&ColumnMapping>) -> Option<Setting> {
    let delimiter = [',', ';', '\t'].into_iter().find(|&c| text.contains(c))?;
    let mut fields = text
        .split(delimiter)
        .map(|field| field.trim().trim_matches('"').trim());
    let (key, value, None) = (fields.next()?, fields.next()?, fields.next()) else {
        return None;
    };
    let value = parse_f64(value).filter(|value| value.is_finite())?;
    let names_a_column =
        mapping.is_some_and(|mapping| mapping.target_of(key).is_some()) || resolve(key).is_some();
    (key.chars().any(char::is_alphabetic) && !names_a_column).then(|| Setting {
        key: key.to_string(),
        value,
        text: text.to_string(),
    })
}

/// Whether a line is only numbers (and so no header).
pub(super) fn is_number_line(text: &str) -> bool {
    number_line_delimiter(text).is_some()
}

/// How a line of only numbers splits into them: as a header would, else on white space
/// (`0.5  20.1\t-40` mixes spaces and a tab); `None` when it is not only numbers.
fn number_line_delimiter(text: &str) -> Option<char> {
    let all_numbers = |delimiter: char| {
        let fields = split_fields(text, delimiter);
        !fields.is_empty()
            && fields
                .iter()
                .all(|field| parse_f64(field.trim().trim_matches('"').trim()).is_some())
    };
    [delimiter_of(text), WHITESPACE]
        .into_iter()
        .find(|&delimiter| all_numbers(delimiter))
}

pub(super) const N_QUANTITIES: usize = Quantity::Pressure as usize + 1;
pub(super) const DEG_TO_RAD: f64 = std::f64::consts::PI / 180.0;

/// The delimiter that stands for "runs of spaces and tabs" (a line with no comma, tab
/// or semicolon, split on white space).
pub(super) const WHITESPACE: char = ' ';

/// How a header (or a first line) is split: comma, else tab, else semicolon, else white
/// space where that gives several fields.
fn delimiter_of(text: &str) -> char {
    if text.contains(',') {
        ','
    } else if text.contains('\t') {
        '\t'
    } else if text.contains(';') {
        ';'
    } else if text.split_ascii_whitespace().nth(1).is_some() {
        WHITESPACE
    } else {
        ','
    }
}

/// A line's fields, split by `delimiter` ([`WHITESPACE`]: runs of spaces and tabs).
pub(super) fn split_fields(text: &str, delimiter: char) -> Vec<&str> {
    if delimiter == WHITESPACE {
        text.split_ascii_whitespace().collect()
    } else {
        text.split(delimiter).collect()
    }
}

/// The header line, resolved.
#[derive(Debug, Clone)]
pub(super) struct Header {
    pub(super) line: usize,
    pub(super) delimiter: char,
    pub(super) names: Vec<String>,
    pub(super) columns: Vec<Option<Column>>,
    pub(super) axes: SensorAxes,
    /// The time column, if any: a preferred one (seconds elapsed) wins over others.
    pub(super) time_field: Option<usize>,
    /// The file has no header line: `line` is its first data line, and the columns are
    /// named "column 1", "column 2", ….
    pub(super) headerless: bool,
}

impl Header {
    /// The header from the first line that is not a comment or a setting: the line
    /// itself, or, when it is only numbers, columns named "column 1", "column 2", …
    /// (the file has no header line, and that line is data).
    pub(super) fn of_first_line(
        line: usize,
        text: &str,
        mapping: Option<&ColumnMapping>,
        xyz_columns: Option<XyzColumns>,
    ) -> Header {
        if let Some(delimiter) = number_line_delimiter(text) {
            let n_columns = split_fields(text, delimiter).len();
            let names = (1..=n_columns).map(|idx| format!("column {idx}")).collect();
            Header {
                headerless: true,
                ..Header::of_names(line, delimiter, names, mapping, None)
            }
        } else {
            let delimiter = delimiter_of(text);
            let names = split_fields(text, delimiter)
                .into_iter()
                .map(|name| name.trim().trim_matches('"').trim().to_string())
                .collect();
            Header::of_names(line, delimiter, names, mapping, xyz_columns)
        }
    }

    fn of_names(
        line: usize,
        delimiter: char,
        names: Vec<String>,
        mapping: Option<&ColumnMapping>,
        xyz_columns: Option<XyzColumns>,
    ) -> Header {
        let resolved: Vec<Option<(Column, Naming)>> = names
            .iter()
            .map(
                |name| match mapping.and_then(|mapping| mapping.target_of(name)) {
                    Some(target) if target.eq_ignore_ascii_case(IGNORE) => None,
                    Some(target) => resolve(target),
                    None => match xyz_columns {
                        Some(sensor) => resolve_xyz(name, sensor).or_else(|| resolve(name)),
                        None => resolve(name),
                    },
                },
            )
            .collect();
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
            headerless: false,
        }
    }
}

/// A bare `x`, `y` or `z` column of a phone app's per-sensor file: that sensor, in
/// Android device axes and the app's unit (m/s², rad/s, µT: factor 1).
fn resolve_xyz(raw_name: &str, sensor: XyzColumns) -> Option<(Column, Naming)> {
    let axis = match raw_name.trim().trim_matches('"').to_lowercase().as_str() {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        _ => return None,
    };
    let quantity = match sensor {
        XyzColumns::Accelerometer => Quantity::Acc,
        XyzColumns::Gyroscope => Quantity::Gyro,
        XyzColumns::Magnetometer => Quantity::Mag,
    };
    Some((
        Column {
            quantity,
            axis,
            scale: Some(1.0),
        },
        Naming::PhoneApp,
    ))
}

/// How a column was named, which tells the axes it is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Naming {
    /// `name_axis_unit`, or a plain name: body axes.
    Suffixed,
    /// A phone app's own names (phyphox's "X (µT)", Sensor Logger's bare `acc_x`).
    PhoneApp,
    /// A time column counting seconds from the start of the recording.
    Elapsed,
}

/// Resolves one header name to a column.
pub(super) fn resolve(raw_name: &str) -> Option<(Column, Naming)> {
    let NameParts {
        base_tokens,
        paren_unit,
        suffix_unit,
    } = NameParts::of(raw_name);
    let unit = paren_unit.clone().or(suffix_unit.clone());
    let scale = unit.as_deref().and_then(unit_scale);
    let naming = if suffix_unit.is_some() {
        Naming::Suffixed
    } else if paren_unit.is_some() {
        Naming::PhoneApp
    } else {
        Naming::Suffixed
    };
    let tokens: Vec<&str> = base_tokens.iter().map(String::as_str).collect();
    // A vector component: a sensor prefix and an axis letter, or an axis letter whose
    // unit says the sensor (phyphox).
    match tokens.as_slice() {
        [sensor, axis] if sensor_of(sensor).is_some() && axis_of(axis).is_some() => {
            let quantity = sensor_of(sensor)?;
            let axis = axis_of(axis)?;
            // Sensor Logger writes bare `acc_x`, `mag_z`: device axes, no units.
            let naming = if unit.is_none() {
                Naming::PhoneApp
            } else {
                naming
            };
            Some((
                column(
                    quantity,
                    axis,
                    scale.filter(|_| unit_matches(quantity, unit.as_deref())),
                ),
                naming,
            ))
        }
        [compact]
            if compact.len() == 2
                && compact.get(..1).and_then(sensor_of).is_some()
                && compact.get(1..).and_then(axis_of).is_some() =>
        {
            // "mx", "ax", "gz". `get` and not indexing: a two-byte name may be one
            // character ("À"), and slicing inside it would panic.
            let quantity = compact.get(..1).and_then(sensor_of)?;
            Some((
                column(quantity, compact.get(1..).and_then(axis_of)?, scale),
                Naming::Suffixed,
            ))
        }
        [axis] if axis_of(axis).is_some() => {
            let axis = axis_of(axis)?;
            let quantity = match unit.as_deref() {
                Some(unit) => quantity_of_unit(unit)?,
                None => Quantity::Mag,
            };
            Some((
                column(quantity, axis, scale),
                if paren_unit.is_some() {
                    Naming::PhoneApp
                } else {
                    Naming::Suffixed
                },
            ))
        }
        _ => scalar_column(&tokens.join("_"), unit.as_deref(), scale, naming),
    }
}

/// A header name taken apart: its tokens without a trailing unit, and its unit in
/// parentheses or as its last token.
struct NameParts {
    base_tokens: Vec<String>,
    paren_unit: Option<String>,
    suffix_unit: Option<String>,
}

impl NameParts {
    /// `raw_name` without quotes, in lower case, split at `_`, spaces, `-` and `.`.
    fn of(raw_name: &str) -> NameParts {
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
        NameParts {
            base_tokens: base_tokens.into_iter().map(str::to_string).collect(),
            paren_unit,
            suffix_unit,
        }
    }
}

/// A column of `quantity`'s component `axis` (0 for a scalar), with its unit's factor.
fn column(quantity: Quantity, axis: usize, scale: Option<f64>) -> Column {
    Column {
        quantity,
        axis,
        scale,
    }
}

/// The axis an axis letter names: 0, 1, 2 for x, y, z.
fn axis_of(token: &str) -> Option<usize> {
    match token {
        "x" => Some(0),
        "y" => Some(1),
        "z" => Some(2),
        _ => None,
    }
}

/// The sensor a name's prefix names ("acc", "gyro", "mag", or their one letters).
fn sensor_of(token: &str) -> Option<Quantity> {
    match token {
        "acc" | "accel" | "accelerometer" | "acceleration" | "a" => Some(Quantity::Acc),
        "gyro" | "gyroscope" | "gyr" | "rot" | "rate" | "g" => Some(Quantity::Gyro),
        "mag" | "magnetometer" | "magnetic" | "magn" | "compass" | "m" | "b" => Some(Quantity::Mag),
        _ => None,
    }
}

/// A column of one value (time, temperature, position, ...) by its name without the
/// unit, `base`; `None` for a name this reader does not know.
fn scalar_column(
    base: &str,
    unit: Option<&str>,
    scale: Option<f64>,
    naming: Naming,
) -> Option<(Column, Naming)> {
    let quantity = match base {
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
