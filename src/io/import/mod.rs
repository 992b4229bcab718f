//! Format detection and multi-file import: the one door every log comes through.
//!
//! The format is told from the content, not from the file name: the binary autopilot
//! logs (DataFlash, ULog) by their first bytes, then, once the file is known to be text
//! ([`super::ensure_text`]), by its first lines: DataFlash text, GPX or KML, NMEA
//! sentences, the Android sensor dump, GetSensorData logs, delimited text with a header,
//! or serial sensor lines; a file that starts with `{` is JSON (a map or a track a
//! logger keeps beside its log) and is refused as such. The file name counts only for a
//! phone app's per-sensor files ([`super::sensor_files`]), and only together with their
//! content. Lines of only numbers go to the delimited reader when the user has mapped
//! their columns. Several files dropped together (phyphox writes one file per sensor)
//! are read one by one and merged into one recording; a file that cannot be read
//! becomes a diagnostic of the merge, and the rest is still used.
//!
//! The files: here the entry points, the detection and [`Inspection`] (the report with
//! each stream's summary; a magnetometer in raw counts is summarised in counts);
//! `merge.rs` the merge of several files' imports; `chunked.rs` [`ChunkedImport`], a
//! file fed in chunks.

mod chunked;
mod merge;

pub use self::chunked::ChunkedImport;
pub use self::merge::merge;

use super::delimited::{self, ColumnMapping, RawImport};
use super::lines::decode_all;
use super::sensor_files::{self, SensorImport};
use super::summary::{summarize, StreamSummary};
use super::{
    dataflash, ensure_text, gpx, nmea, serial_lines, tagged_lines, ulog, Diagnostics, ImportError,
    ImportReport, SensorFrame,
};

/// How many leading lines detection looks at.
const N_SAMPLE_LINES: usize = 60;
/// How many leading bytes detection decodes.
const SAMPLE_BYTES: usize = 16 * 1024;

/// The formats this tool reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Nmea,
    AndroidDump,
    GetSensorData,
    Delimited,
    SerialLines,
    DataflashText,
    /// A GPX or KML track.
    Track,
}

/// The first non-blank lines of a file's first bytes, trimmed, for telling its format.
fn sample_lines(bytes: &[u8]) -> Vec<String> {
    let mut sample_lines: Vec<String> = Vec::new();
    decode_all(&bytes[..bytes.len().min(SAMPLE_BYTES)], 4096, |line| {
        if sample_lines.len() < N_SAMPLE_LINES && !line.text.trim().is_empty() {
            sample_lines.push(line.text.trim().to_string());
        }
    });
    sample_lines
}

/// Refuses a file whose first lines are JSON (its first character `{`): no format read
/// here starts so, and a delimited header of a JSON line would name thousands of
/// "columns" (a GeoJSON floor plan is one line of 100 kB). Both import paths ask this.
fn refuse_json(file_name: &str, sample: &[&str]) -> Result<(), ImportError> {
    let json = sample
        .iter()
        .map(|line| line.trim_start_matches('\u{feff}').trim_start())
        .find(|line| !line.is_empty())
        .is_some_and(|line| line.starts_with('{'));
    if json {
        Err(ImportError::Json {
            file_name: file_name.to_string(),
        })
    } else {
        Ok(())
    }
}

/// The format of a file, told from its first lines; `None` when nothing fits.
pub fn detect(bytes: &[u8]) -> Option<Format> {
    let sample_lines = sample_lines(bytes);
    let sample: Vec<&str> = sample_lines.iter().map(String::as_str).collect();
    detect_lines(&sample)
}

/// The format to read a file as: [`detect`]'s, except that delimited numbers without a
/// header line are read as delimited text when the user mapped their columns.
fn format_for(sample: &[&str], mapping: Option<&ColumnMapping>) -> Option<Format> {
    let format = detect_lines(sample);
    let mapped_numbers = mapping.is_some() && delimited::looks_headerless(sample);
    match format {
        Some(Format::SerialLines) | None if mapped_numbers => Some(Format::Delimited),
        format => format,
    }
}

fn detect_lines(sample: &[&str]) -> Option<Format> {
    if dataflash::looks_like_text(sample) {
        Some(Format::DataflashText)
    } else if gpx::looks_like(sample) {
        Some(Format::Track)
    } else if nmea::looks_like(sample) {
        Some(Format::Nmea)
    } else if tagged_lines::looks_like_android_dump(sample) {
        Some(Format::AndroidDump)
    } else if tagged_lines::looks_like_get_sensor_data(sample) {
        Some(Format::GetSensorData)
    } else if delimited::looks_like(sample) {
        Some(Format::Delimited)
    } else if serial_lines::looks_like(sample) {
        Some(Format::SerialLines)
    } else {
        None
    }
}

/// The header of a delimited file, as a key under which a column mapping can be
/// remembered: its column names, lower-cased, in order. `None` for other formats.
pub fn header_signature(prefix: &[u8]) -> Option<String> {
    let sample_lines = sample_lines(prefix);
    let sample: Vec<&str> = sample_lines.iter().map(String::as_str).collect();
    if matches!(detect(prefix), Some(Format::Delimited) | None) {
        let columns = delimited::header_columns(&sample)?;
        Some(
            columns
                .iter()
                .map(|name| name.to_lowercase())
                .collect::<Vec<_>>()
                .join(","),
        )
    } else {
        None
    }
}

/// One file as read, before merging (see [`merge`]).
pub enum FileImport {
    /// Delimited text still in its own axes: merged before the axes are converted, so
    /// that a phone's mount is judged from its accelerometer file.
    Raw(RawImport),
    Final(ImportReport),
    /// A phone app's per-sensor file, in device axes, with what it gives the recording
    /// (the merge chooses among alternatives: see [`sensor_files::choose`]).
    Sensor(SensorImport),
}

/// One whole file in memory (a file mapped by the CLI), read as [`import_files_mapped`]
/// reads each, for [`merge`]: the importers' whole-file paths, which size the streams
/// once and read a large delimited file on every core ([`crate::base::par`]).
pub fn import_file(
    file_name: &str,
    bytes: &[u8],
    mapping: Option<&ColumnMapping>,
) -> Result<FileImport, ImportError> {
    if dataflash::looks_like_binary(bytes) {
        return Ok(FileImport::Final(dataflash::read_binary(file_name, bytes)?));
    }
    if ulog::looks_like(bytes) {
        return Ok(FileImport::Final(ulog::read(file_name, bytes)?));
    }
    ensure_text(file_name, bytes)?;
    let sample_lines = sample_lines(bytes);
    let sample: Vec<&str> = sample_lines.iter().map(String::as_str).collect();
    refuse_json(file_name, &sample)?;
    if sensor_files::recognise(file_name, &sample).is_some() {
        // The readers a file read in chunks uses, fed the whole file at once.
        let mut chunked = ChunkedImport::new(file_name, Some(bytes.len()));
        chunked.feed(bytes)?;
        return chunked.finish();
    }
    Ok(match format_for(&sample, mapping) {
        Some(Format::Nmea) => FileImport::Final(nmea::read(file_name, bytes)?),
        Some(Format::AndroidDump) => {
            FileImport::Final(tagged_lines::read_android_dump(file_name, bytes)?)
        }
        Some(Format::GetSensorData) => {
            FileImport::Final(tagged_lines::read_get_sensor_data(file_name, bytes)?)
        }
        Some(Format::SerialLines) => FileImport::Final(serial_lines::read(file_name, bytes)?),
        Some(Format::DataflashText) => FileImport::Final(dataflash::read_text(file_name, bytes)?),
        Some(Format::Track) => FileImport::Final(gpx::read(file_name, bytes)?),
        // Delimited text, or nothing recognisable: the delimited reader's error says
        // which header it found and what names it expects.
        Some(Format::Delimited) | None => {
            FileImport::Raw(delimited::read_raw_mapped(file_name, bytes, mapping)?)
        }
    })
}

/// Reads one file, whatever its format.
pub fn import(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    import_files(&[(file_name, bytes)])
}

/// Reads several files of one recording and merges them. Fails only when no file could
/// be read; then the error is the first file's.
pub fn import_files(files: &[(&str, &[u8])]) -> Result<ImportReport, ImportError> {
    import_files_mapped(files, None)
}

/// [`import_files`] with the user's column mapping for delimited files.
pub fn import_files_mapped(
    files: &[(&str, &[u8])],
    mapping: Option<&ColumnMapping>,
) -> Result<ImportReport, ImportError> {
    merge(
        files
            .iter()
            .map(|&(file_name, bytes)| {
                (
                    file_name.to_string(),
                    import_file(file_name, bytes, mapping),
                )
            })
            .collect(),
    )
}

/// An import with its stream summaries: what `compass-pdr inspect` prints and the page
/// shows.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Inspection {
    pub file_name: String,
    pub format: &'static str,
    pub n_data_lines: usize,
    pub streams: Vec<StreamSummary>,
    pub notes: Vec<String>,
    pub diagnostics: Diagnostics,
    /// The magnetometer's raw axes and unit, where the log has a magnetometer.
    pub mag_frame: Option<SensorFrame>,
    /// An autopilot log's compass parameters in force (`COMPASS_*`, `CAL_MAG*`), in the
    /// log's order; what the binary log's `n_data_lines` counts are messages.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compass_params: Option<Vec<(String, f64)>>,
}

impl Inspection {
    pub fn of(report: &ImportReport) -> Inspection {
        let mut streams = summarize(&report.recording);
        // Raw counts of unknown sensitivity were kept as they are: their magnitudes are
        // counts, not µT.
        if let Some(unit) = report
            .mag_frame
            .map(|frame| frame.unit)
            .filter(|unit| unit.ut_per_unit.is_none())
        {
            for summary in &mut streams {
                if summary.stream.starts_with("magnetometer") {
                    summary.unit = unit.name;
                }
            }
        }
        Inspection {
            file_name: report.file_name.clone(),
            format: report.format,
            n_data_lines: report.n_data_lines,
            streams,
            notes: report.notes.clone(),
            diagnostics: report.diagnostics.clone(),
            mag_frame: report.mag_frame,
            compass_params: report.autopilot.as_ref().map(|log| {
                log.params
                    .iter()
                    .filter(|(name, _)| name.starts_with("COMPASS_") || name.starts_with("CAL_MAG"))
                    .cloned()
                    .collect()
            }),
        }
    }
}

// Native only: proptest is a native dev-dependency.
#[cfg(all(test, not(target_arch = "wasm32")))]
mod tests;
