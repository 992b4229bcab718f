//! Format detection and multi-file import: the one door every log comes through.
//!
//! The format is told from the content (the first lines), not from the file name:
//! NMEA sentences, the Android sensor dump, GetSensorData logs, delimited text with a
//! header, or serial sensor lines. Several files dropped together (phyphox writes one
//! file per sensor) are read one by one and merged into one recording; a file that
//! cannot be read becomes a diagnostic of the merge, and the rest is still used.

use super::delimited::{self, ColumnMapping, DelimitedReader, RawImport, SensorAxes};
use super::lines::{decode_all, Line, LineDecoder};
use super::summary::{summarize, StreamSummary};
use super::tagged_lines::LineReader as _;
use super::{
    ensure_text, first_binary_offset, nmea, serial_lines, tagged_lines, Diagnostics, ImportError,
    ImportReport,
};
use crate::recording::Recording;

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
}

/// The format of a file, told from its first lines; `None` when nothing fits.
pub fn detect(bytes: &[u8]) -> Option<Format> {
    let mut sample_lines: Vec<String> = Vec::new();
    decode_all(&bytes[..bytes.len().min(SAMPLE_BYTES)], 4096, |line| {
        if sample_lines.len() < N_SAMPLE_LINES && !line.text.trim().is_empty() {
            sample_lines.push(line.text.trim().to_string());
        }
    });
    let sample: Vec<&str> = sample_lines.iter().map(String::as_str).collect();
    if nmea::looks_like(&sample) {
        Some(Format::Nmea)
    } else if tagged_lines::looks_like_android_dump(&sample) {
        Some(Format::AndroidDump)
    } else if tagged_lines::looks_like_get_sensor_data(&sample) {
        Some(Format::GetSensorData)
    } else if delimited::looks_like(&sample) {
        Some(Format::Delimited)
    } else if serial_lines::looks_like(&sample) {
        Some(Format::SerialLines)
    } else {
        None
    }
}

/// The header of a delimited file, as a key under which a column mapping can be
/// remembered: its column names, lower-cased, in order. `None` for other formats.
pub fn header_signature(prefix: &[u8]) -> Option<String> {
    let mut sample_lines: Vec<String> = Vec::new();
    decode_all(&prefix[..prefix.len().min(SAMPLE_BYTES)], 4096, |line| {
        if sample_lines.len() < N_SAMPLE_LINES && !line.text.trim().is_empty() {
            sample_lines.push(line.text.trim().to_string());
        }
    });
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
}

fn import_one(
    file_name: &str,
    bytes: &[u8],
    mapping: Option<&ColumnMapping>,
) -> Result<FileImport, ImportError> {
    ensure_text(file_name, bytes)?;
    Ok(match detect(bytes) {
        Some(Format::Nmea) => FileImport::Final(nmea::read(file_name, bytes)?),
        Some(Format::AndroidDump) => {
            FileImport::Final(tagged_lines::read_android_dump(file_name, bytes)?)
        }
        Some(Format::GetSensorData) => {
            FileImport::Final(tagged_lines::read_get_sensor_data(file_name, bytes)?)
        }
        Some(Format::SerialLines) => FileImport::Final(serial_lines::read(file_name, bytes)?),
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
                (file_name.to_string(), import_one(file_name, bytes, mapping))
            })
            .collect(),
    )
}

/// Merges files read one by one (with [`import_files`]'s rules): a file that failed
/// becomes a diagnostic, unless every file failed.
pub fn merge(
    results: Vec<(String, Result<FileImport, ImportError>)>,
) -> Result<ImportReport, ImportError> {
    let mut imports: Vec<(String, FileImport)> = Vec::new();
    let mut failures: Vec<(String, ImportError)> = Vec::new();
    for (file_name, result) in results {
        match result {
            Ok(import) => imports.push((file_name, import)),
            Err(error) => failures.push((file_name, error)),
        }
    }
    if imports.is_empty() {
        return Err(failures
            .into_iter()
            .next()
            .map(|(_, error)| error)
            .unwrap_or(ImportError::Empty {
                file_name: String::new(),
            }));
    }
    if imports.len() == 1 && failures.is_empty() {
        return Ok(match imports.remove(0).1 {
            FileImport::Raw(raw) => raw.into_report(),
            FileImport::Final(report) => report,
        });
    }

    // Merge: delimited files with device axes first (their mount is judged together),
    // then everything else.
    let names: Vec<String> = imports.iter().map(|(name, _)| name.clone()).collect();
    let mut merged = ImportReport {
        file_name: names.join(" + "),
        format: "",
        recording: Recording::default(),
        diagnostics: Diagnostics::default(),
        header: None,
        n_data_lines: 0,
        notes: Vec::new(),
    };
    let mut formats: Vec<&'static str> = Vec::new();
    let mut device_recording: Option<Recording> = None;
    for (file_name, import) in imports {
        let (report, in_device_axes) = match import {
            FileImport::Raw(raw) if raw.axes == SensorAxes::AndroidDevice => (raw.report, true),
            FileImport::Raw(raw) => (raw.into_report(), false),
            FileImport::Final(report) => (report, false),
        };
        let recording = merge_into_parts(&mut merged, report, &file_name, &mut formats);
        let target = if in_device_axes {
            device_recording.get_or_insert_with(Recording::default)
        } else {
            &mut merged.recording
        };
        target.append(recording);
    }
    if let Some(recording) = device_recording {
        let raw = RawImport {
            report: ImportReport {
                recording,
                ..empty_like(&merged)
            },
            axes: SensorAxes::AndroidDevice,
        };
        let converted = raw.into_report();
        merged.notes.extend(converted.notes);
        merged.recording.append(converted.recording);
    }
    for (file_name, error) in failures {
        merged.diagnostics.absorb(
            {
                let mut diagnostics = Diagnostics::default();
                diagnostics.push(None, format!("{error} (this file was left out)"));
                diagnostics
            },
            &file_name,
        );
    }
    let n_out_of_order = merged.recording.sort_all_by_time();
    if n_out_of_order > 0 {
        merged
            .notes
            .push("streams from several files were merged by time".to_string());
    }
    formats.dedup();
    merged.format = if formats.len() == 1 {
        formats[0]
    } else {
        "several formats"
    };
    Ok(merged)
}

/// Moves a file's diagnostics, notes and counts into the merged report and hands back
/// its recording.
fn merge_into_parts(
    merged: &mut ImportReport,
    report: ImportReport,
    file_name: &str,
    formats: &mut Vec<&'static str>,
) -> Recording {
    merged.diagnostics.absorb(report.diagnostics, file_name);
    merged.n_data_lines += report.n_data_lines;
    merged.notes.extend(
        report
            .notes
            .into_iter()
            .map(|note| format!("{file_name}: {note}")),
    );
    formats.push(report.format);
    if merged.header.is_none() {
        merged.header = report.header;
    }
    report.recording
}

fn empty_like(report: &ImportReport) -> ImportReport {
    ImportReport {
        file_name: report.file_name.clone(),
        format: delimited::FORMAT_NAME,
        recording: Recording::default(),
        diagnostics: Diagnostics::default(),
        header: None,
        n_data_lines: 0,
        notes: Vec::new(),
    }
}

/// How many leading bytes a chunked import holds back to tell the format.
const SNIFF_BYTES: usize = SAMPLE_BYTES;

/// A file read in chunks (from disk, or from a `File` in the browser), so that memory
/// holds the samples and one chunk, never the whole text. The format is told from the
/// first 16 KiB; from then on every chunk goes through the line decoder into that
/// format's reader. Feeding the same bytes in any chunks gives the same result.
pub struct ChunkedImport {
    file_name: String,
    size_hint_bytes: Option<usize>,
    /// The first bytes, held until the format is known.
    prefix: Vec<u8>,
    reader: Option<(LineDecoder, FormatReader)>,
    saw_text: bool,
    n_bytes_read: usize,
    mapping: Option<ColumnMapping>,
}

enum FormatReader {
    Delimited(DelimitedReader),
    Nmea(nmea::NmeaReader),
    Serial(serial_lines::SerialReader),
    Android(tagged_lines::AndroidReader),
    GetSensorData(tagged_lines::GetSensorDataReader),
}

impl FormatReader {
    fn read_line(&mut self, line: &Line<'_>) {
        match self {
            FormatReader::Delimited(reader) => reader.read_line(line),
            FormatReader::Nmea(reader) => reader.read_decoded(line),
            FormatReader::Serial(reader) => reader.read_line(line.number, &line.text, None),
            FormatReader::Android(reader) => {
                reader.read_line(line.number, &line.text, line.truncated)
            }
            FormatReader::GetSensorData(reader) => {
                reader.read_line(line.number, &line.text, line.truncated)
            }
        }
    }

    fn finish(self, file_name: &str) -> Result<FileImport, ImportError> {
        Ok(match self {
            FormatReader::Delimited(reader) => FileImport::Raw(reader.finish(file_name)?),
            FormatReader::Nmea(reader) => FileImport::Final(reader.finish(file_name)?),
            FormatReader::Serial(reader) => FileImport::Final(reader.finish(file_name)?),
            FormatReader::Android(reader) => {
                FileImport::Final(reader.finish(file_name.to_string())?)
            }
            FormatReader::GetSensorData(reader) => {
                FileImport::Final(reader.finish(file_name.to_string())?)
            }
        })
    }
}

impl ChunkedImport {
    /// `size_hint_bytes`, the file's size where known, lets readers reserve room once.
    pub fn new(file_name: &str, size_hint_bytes: Option<usize>) -> Self {
        ChunkedImport {
            file_name: file_name.to_string(),
            size_hint_bytes,
            prefix: Vec::new(),
            reader: None,
            saw_text: false,
            n_bytes_read: 0,
            mapping: None,
        }
    }

    /// Reads a delimited file's header through the user's mapping.
    pub fn with_mapping(mut self, mapping: Option<ColumnMapping>) -> Self {
        self.mapping = mapping;
        self
    }

    /// Bytes fed so far, for progress.
    pub fn n_bytes_read(&self) -> usize {
        self.n_bytes_read
    }

    /// Feeds the next chunk. Fails only when the first bytes show the file is not text.
    pub fn feed(&mut self, chunk: &[u8]) -> Result<(), ImportError> {
        self.n_bytes_read += chunk.len();
        if !self.saw_text {
            self.saw_text = chunk.iter().any(|byte| !byte.is_ascii_whitespace());
        }
        match &mut self.reader {
            Some((decoder, reader)) => decoder.feed(chunk, |line| reader.read_line(&line)),
            None => {
                self.prefix.extend_from_slice(chunk);
                if self.prefix.len() >= SNIFF_BYTES {
                    self.start_reading()?;
                }
            }
        }
        Ok(())
    }

    /// Tells the format from the held-back prefix and replays it into the reader.
    fn start_reading(&mut self) -> Result<(), ImportError> {
        if let Some(byte_offset) = first_binary_offset(&self.prefix) {
            return Err(ImportError::NotText {
                file_name: self.file_name.clone(),
                byte_offset,
            });
        }
        let mut reader = match detect(&self.prefix) {
            Some(Format::Nmea) => FormatReader::Nmea(nmea::NmeaReader::new()),
            Some(Format::AndroidDump) => {
                FormatReader::Android(tagged_lines::AndroidReader::default())
            }
            Some(Format::GetSensorData) => {
                FormatReader::GetSensorData(tagged_lines::GetSensorDataReader::default())
            }
            Some(Format::SerialLines) => FormatReader::Serial(serial_lines::SerialReader::new(
                serial_lines::ASSUMED_FILE_RATE_HZ,
            )),
            Some(Format::Delimited) | None => FormatReader::Delimited(
                DelimitedReader::new(self.size_hint_bytes).with_mapping(self.mapping.clone()),
            ),
        };
        let mut decoder = LineDecoder::new(MAX_LINE_BYTES);
        decoder.feed(&self.prefix, |line| reader.read_line(&line));
        self.prefix = Vec::new();
        self.reader = Some((decoder, reader));
        Ok(())
    }

    /// Ends the file and hands over what was read, for [`merge`].
    pub fn finish(mut self) -> Result<FileImport, ImportError> {
        if !self.saw_text {
            return Err(ImportError::Empty {
                file_name: self.file_name,
            });
        }
        if self.reader.is_none() {
            self.start_reading()?;
        }
        let Some((mut decoder, mut reader)) = self.reader.take() else {
            return Err(ImportError::Empty {
                file_name: self.file_name,
            });
        };
        decoder.finish(|line| reader.read_line(&line));
        reader.finish(&self.file_name)
    }
}

/// Lines longer than this are cut by the chunked reader (the readers report it).
const MAX_LINE_BYTES: usize = 64 * 1024;

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
}

impl Inspection {
    pub fn of(report: &ImportReport) -> Inspection {
        Inspection {
            file_name: report.file_name.clone(),
            format: report.format,
            n_data_lines: report.n_data_lines,
            streams: summarize(&report.recording),
            notes: report.notes.clone(),
            diagnostics: report.diagnostics.clone(),
        }
    }
}
