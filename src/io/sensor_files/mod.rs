//! Per-sensor files of phone apps, told by their file name *and* their first lines (a
//! name alone never decides: phyphox also writes `Accelerometer.csv`), and the choices
//! made when several of them are merged into one recording.
//!
//! The formats, each in a file whose header shows its files and cites its source: Sensor
//! Logger's per-sensor CSVs (`sensor_logger.rs`) and the TYREX attitude benchmark's
//! headerless per-sensor text (`headerless.rs`). `merge.rs` makes the choices among the
//! files of one recording; `tests.rs` tests whole folders through the import.
//!
//! Device axes become body axes in [`super::delimited::RawImport::into_report`], through
//! [`super::axes::PhoneMount`], once all files are merged.

use self::headerless::{headerless_import, numbers_of, properties_import, HeaderlessStreams};
use self::sensor_logger::{metadata_notes, recognise_logger};
use super::delimited::{RawImport, SensorAxes};
use super::lines::Line;
use super::{Diagnostics, ImportError, ImportReport};
use crate::io::recording::Recording;

mod headerless;
mod merge;
mod sensor_logger;

pub use self::headerless::HeaderlessFile;
pub use self::merge::choose;
pub use self::sensor_logger::{finish_logger, logger_reader, LoggerFile};

/// The format name of Sensor Logger's per-sensor CSVs.
pub const SENSOR_LOGGER: &str = "Sensor Logger CSV";
/// The format name of headerless per-sensor text.
pub const HEADERLESS_TEXT: &str = "headerless per-sensor text";

/// A per-sensor file recognised by its name and first lines.
#[derive(Debug, Clone, PartialEq)]
pub enum SensorFile {
    /// One of Sensor Logger's CSVs, with the recording's start told by its first row.
    SensorLogger {
        kind: LoggerFile,
        start_unix_s: Option<f64>,
    },
    /// A headerless whitespace-separated sensor file.
    Headerless(HeaderlessFile),
    /// The benchmark's `record.properties`.
    RecordProperties,
}

/// What a per-sensor file gives the recording, for the choices of the merge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Specific force, gravity included; an alternative is used only without the other.
    Accelerometer {
        alternative: bool,
    },
    /// An alternative is used only without the other.
    Gyroscope {
        alternative: bool,
    },
    /// The raw field: the magnetometer to calibrate.
    RawMagnetometer,
    /// The OS-calibrated field: the magnetometer only when there is no raw one.
    CalibratedMagnetometer,
    Other,
}

/// A per-sensor file as read, in Android device axes, with what it gives.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorImport {
    pub raw: RawImport,
    pub role: Role,
}

/// The file's name without its folders.
fn base_name(file_name: &str) -> &str {
    file_name.rsplit(['/', '\\']).next().unwrap_or(file_name)
}

/// The per-sensor file `file_name` is, judged from its name and its first non-blank
/// lines (trimmed); `None` when either does not fit.
pub fn recognise(file_name: &str, sample_lines: &[&str]) -> Option<SensorFile> {
    let name = base_name(file_name);
    if let Some(kind) = LoggerFile::ALL
        .iter()
        .find(|(_, known)| known.eq_ignore_ascii_case(name))
        .map(|(kind, _)| *kind)
    {
        return recognise_logger(kind, sample_lines);
    }
    if let Some(kind) = HeaderlessFile::ALL
        .iter()
        .find(|(_, known)| known.eq_ignore_ascii_case(name))
        .map(|(kind, _)| *kind)
    {
        let first = sample_lines.first()?;
        let n_numbers = numbers_of(first)?.len();
        let (fewest, most) = kind.n_numbers();
        return (fewest..=most)
            .contains(&n_numbers)
            .then_some(SensorFile::Headerless(kind));
    }
    let is_properties = name.eq_ignore_ascii_case("record.properties")
        && sample_lines.iter().any(|line| {
            line.starts_with("[Device]") || line.starts_with("[Time]") || line.contains("StartTime")
        });
    is_properties.then_some(SensorFile::RecordProperties)
}

/// An import that gives only notes (a file that is recognised and not used, or one of
/// metadata).
fn notes_only(
    file_name: &str,
    format: &'static str,
    notes: Vec<String>,
    n_lines: usize,
) -> SensorImport {
    SensorImport {
        raw: RawImport {
            report: ImportReport {
                autopilot: None,
                file_name: file_name.to_string(),
                format,
                recording: Recording::default(),
                diagnostics: Diagnostics::default(),
                header: None,
                n_data_lines: n_lines,
                notes,
                mag_frame: None,
            },
            axes: SensorAxes::AndroidDevice,
            mag_unit: None,
        },
        role: Role::Other,
    }
}

/// The reader of a per-sensor file that the delimited reader does not read: lines are
/// counted (a file that is not used), kept (metadata, properties) or read as numbers
/// (headerless files).
pub struct SensorFileReader {
    file: SensorFile,
    n_lines: usize,
    /// The first lines, for the files read as metadata.
    kept_lines: Vec<String>,
    headerless: HeaderlessStreams,
}

/// How many lines of a metadata file are kept.
const MAX_KEPT_LINES: usize = 64;

impl SensorFileReader {
    pub fn new(file: SensorFile) -> SensorFileReader {
        SensorFileReader {
            file,
            n_lines: 0,
            kept_lines: Vec::new(),
            headerless: HeaderlessStreams::default(),
        }
    }

    pub fn read_line(&mut self, line: &Line<'_>) {
        self.n_lines = self.n_lines.max(line.number);
        let text = line.text.trim_start_matches('\u{feff}').trim();
        if text.is_empty() {
            return;
        }
        match self.file {
            SensorFile::Headerless(kind) if kind.not_used().is_none() => {
                self.read_numbers(kind, line.number, text, line.truncated);
            }
            SensorFile::SensorLogger {
                kind: LoggerFile::Metadata,
                ..
            }
            | SensorFile::RecordProperties
                if self.kept_lines.len() < MAX_KEPT_LINES =>
            {
                self.kept_lines.push(text.to_string());
            }
            _ => {}
        }
    }

    pub fn finish(self, file_name: &str) -> Result<SensorImport, ImportError> {
        match self.file {
            SensorFile::SensorLogger { kind, .. } => {
                let notes = match kind.not_used() {
                    Some(reason) => vec![format!("Sensor Logger: {reason}")],
                    None => metadata_notes(&self.kept_lines),
                };
                Ok(notes_only(file_name, SENSOR_LOGGER, notes, self.n_lines))
            }
            SensorFile::RecordProperties => {
                Ok(properties_import(file_name, &self.kept_lines, self.n_lines))
            }
            SensorFile::Headerless(kind) => match kind.not_used() {
                Some(reason) => Ok(notes_only(
                    file_name,
                    HEADERLESS_TEXT,
                    vec![reason.to_string()],
                    self.n_lines,
                )),
                None => headerless_import(file_name, kind, self.headerless, self.n_lines),
            },
        }
    }
}

#[cfg(test)]
mod tests;
