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
//! magnitude tells gauss, mG, nT, T and µT apart, and a magnetometer of 1,000 to 20,000
//! is raw counts, kept as they are; the specific force at rest tells g from m/s²;
//! rotation rates tell deg/s from rad/s), and the guess is stated in the report's notes.
//! Values are stored in the file's units, one pass per line, and converted once, in
//! place, when the file is finished.
//!
//! A first line of only numbers (split on the delimiter, else on white space) is read as
//! columns `column 1`, `column 2`, …: an error ([`super::ImportError::NoHeaderLine`])
//! until the user's [`ColumnMapping`] names them. A mapping renames a file's columns
//! before they are resolved.
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
//!
//! The reader's parts: `header.rs` resolves the header (names, units, delimiter, the
//! settings lines before it), `mapping.rs` holds the user's column mapping, `reader.rs`
//! reads the data lines, `sinks.rs` says where their samples go, `finish.rs` converts
//! times and units once the file is read, and `parallel.rs` reads large files on every
//! thread.

use nalgebra::Vector3;

use self::header::{is_number_line, setting_of, split_fields, Header, WHITESPACE};
use super::axes::PhoneMount;
use super::lines::{decode_all, LineDecoder};
use super::number::parse_f64;
use super::{ensure_text, ImportError, ImportReport, MagUnit, SensorFrame, MAX_LINE_BYTES};

mod finish;
mod header;
mod mapping;
#[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
mod parallel;
mod reader;
mod sinks;
#[cfg(test)]
mod tests;

pub use self::mapping::{suggested_target, ColumnMapping, MappingError, MAPPING_TARGETS};
pub use self::reader::{parse_datetime_s, DelimitedReader};

pub const FORMAT_NAME: &str = "delimited text";

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
    /// The unit the magnetometer columns were written in (already converted to µT in the
    /// report); `None` without magnetometer samples.
    pub mag_unit: Option<MagUnit>,
}

/// What the x, y, z columns of a phone app's per-sensor file hold, told from its file
/// name (see `io::sensor_files`): that sensor, in Android device axes and the app's own
/// unit (m/s², rad/s, µT).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum XyzColumns {
    Accelerometer,
    Gyroscope,
    Magnetometer,
}

/// The header and first data line of delimited text, for a mapping dialog.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Preview {
    pub columns: Vec<String>,
    /// The first data line's fields, one per column ("" where it has none).
    pub first_values: Vec<String>,
}

/// A preview of delimited text from its first lines (settings lines before the header
/// skipped); `None` when there is no line at all. A file without a header line (its
/// first line is numbers) shows its columns as "column 1", "column 2", … with that
/// line's values.
pub fn preview(sample_lines: &[&str]) -> Option<Preview> {
    let mut lines = sample_lines
        .iter()
        .map(|line| line.trim())
        .filter(|line| !line.is_empty() && !line.starts_with('#'))
        .skip_while(|line| setting_of(line, None).is_some())
        .peekable();
    let first = *lines.peek()?;
    let header = Header::of_first_line(1, first, None, None);
    if !header.headerless {
        lines.next();
    }
    let first_values: Vec<String> = match lines.next() {
        Some(line) => split_fields(line, header.delimiter)
            .into_iter()
            .map(|field| field.trim().trim_matches('"').to_string())
            .collect(),
        None => Vec::new(),
    };
    let first_values = (0..header.names.len())
        .map(|idx| first_values.get(idx).cloned().unwrap_or_default())
        .collect();
    Some(Preview {
        columns: header.names,
        first_values,
    })
}

/// The header's column names, as written, of delimited text (its first non-comment
/// line after any settings lines), for a mapping dialog and for remembering mappings by
/// header. `None` without a header line (a file whose first line is numbers: its
/// "column N" names say nothing about it).
pub fn header_columns(sample_lines: &[&str]) -> Option<Vec<String>> {
    let header = Header::of_first_line(1, header_line(sample_lines)?, None, None);
    (!header.headerless).then_some(header.names)
}

/// The first line that is neither blank, a comment nor a settings line (`Fs,50.00`):
/// the header, where there is one.
fn header_line<'a>(sample_lines: &[&'a str]) -> Option<&'a str> {
    sample_lines
        .iter()
        .map(|line| line.trim())
        .filter(|line| !line.is_empty() && !line.starts_with('#'))
        .find(|line| setting_of(line, None).is_none())
}

/// Whether the first lines are delimited numbers without a header line (the first line
/// after any settings is numbers): read as delimited text when the user maps its
/// columns.
pub fn looks_headerless(sample_lines: &[&str]) -> bool {
    header_line(sample_lines).is_some_and(is_number_line)
}

/// Reads one delimited file and turns it into body axes and this crate's units.
pub fn read(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    read_raw(file_name, bytes).map(RawImport::into_report)
}

/// Reads one delimited file, leaving vectors in the file's axes (see [`RawImport`]).
pub fn read_raw(file_name: &str, bytes: &[u8]) -> Result<RawImport, ImportError> {
    read_raw_mapped(file_name, bytes, None)
}

/// [`read_raw`] with the user's column mapping applied to the header.
pub fn read_raw_mapped(
    file_name: &str,
    bytes: &[u8],
    mapping: Option<&ColumnMapping>,
) -> Result<RawImport, ImportError> {
    ensure_text(file_name, bytes)?;
    #[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
    if let Some(raw) = parallel::read_raw(file_name, bytes, mapping) {
        return raw;
    }
    if let Some((mut reader, data_offset, n_header_lines)) =
        read_up_to_header(bytes, mapping, Some(bytes.len()))
    {
        reader.read_data_bytes(bytes.get(data_offset..).unwrap_or_default(), n_header_lines);
        return reader.finish(file_name);
    }
    let mut reader = DelimitedReader::new(Some(bytes.len())).with_mapping(mapping.cloned());
    decode_all(bytes, MAX_LINE_BYTES, |line| reader.read_line(&line));
    reader.finish(file_name)
}

/// Reads lines up to and including the header: the reader, the offset of the first byte
/// after the header's line ending, and the number of lines read. `None` when no line
/// ending follows the header (the caller then reads line by line).
pub(crate) fn read_up_to_header(
    bytes: &[u8],
    mapping: Option<&ColumnMapping>,
    size_hint_bytes: Option<usize>,
) -> Option<(DelimitedReader, usize, usize)> {
    read_up_to_header_with(
        DelimitedReader::new(size_hint_bytes).with_mapping(mapping.cloned()),
        bytes,
    )
}

/// [`read_up_to_header`] with a reader made beforehand.
pub(crate) fn read_up_to_header_with(
    mut reader: DelimitedReader,
    bytes: &[u8],
) -> Option<(DelimitedReader, usize, usize)> {
    let mut decoder = LineDecoder::new(MAX_LINE_BYTES);
    let mut offset = 0usize;
    while reader.header.is_none() {
        let line_end = offset + memchr::memchr(b'\n', bytes.get(offset..)?)? + 1;
        decoder.feed(bytes.get(offset..line_end)?, |line| reader.read_line(&line));
        offset = line_end;
    }
    Some((reader, offset, decoder.n_lines()))
}

/// True when the first non-comment line of a sample reads as a header with at least one
/// recognised column.
pub fn looks_like(sample_lines: &[&str]) -> bool {
    let Some(first) = header_line(sample_lines) else {
        return false;
    };
    let header = Header::of_first_line(1, first, None, None);
    let n_recognised = header.columns.iter().flatten().count();
    // Names split on white space must all be names: "x 1.5" is a serial line.
    let plausible = header.delimiter != WHITESPACE
        || (n_recognised >= 2 && header.names.iter().all(|name| parse_f64(name).is_none()));
    !header.headerless
        && n_recognised > 0
        && plausible
        && first.chars().any(|c| c.is_ascii_alphabetic())
}

impl RawImport {
    /// Converts device axes to body axes, choosing the phone mount from the mean
    /// specific force, and says what was done in the notes.
    pub fn into_report(self) -> ImportReport {
        let RawImport {
            mut report,
            axes,
            mag_unit,
        } = self;
        let has_mag = !report.recording.mag_in_body_ut.is_empty();
        let recording = &report.recording;
        let has_vectors = !(recording.acc_in_body_mps2.is_empty()
            && recording.gyro_in_body_radps.is_empty()
            && recording.mag_in_body_ut.is_empty()
            && recording.mag_bias_in_body_ut.is_empty());
        // A file with no vector (positions, pressure, notes) has no axes to turn.
        if axes == SensorAxes::AndroidDevice && has_vectors {
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
                &mut recording.mag_bias_in_body_ut,
            ] {
                for value in &mut stream.values {
                    *value = mount.device_to_body(*value);
                }
            }
            report
                .notes
                .push(format!("Android device axes, {}", mount.describe()));
            report.mag_frame = mag_unit
                .filter(|_| has_mag)
                .map(|unit| SensorFrame::android_device(mount, unit));
        } else if !report.recording.mag_in_body_ut.is_empty()
            || !report.recording.acc_in_body_mps2.is_empty()
        {
            report
                .notes
                .push("vectors taken as body axes (x forward, y right, z down)".to_string());
        }
        if axes == SensorAxes::Body {
            report.mag_frame = mag_unit
                .filter(|_| has_mag)
                .map(SensorFrame::columns_as_body);
        }
        report
    }
}
