//! Format detection and multi-file import: the one door every log comes through.
//!
//! The format is told from the content (the first lines), not from the file name:
//! NMEA sentences, the Android sensor dump, GetSensorData logs, delimited text with a
//! header, or serial sensor lines. Several files dropped together (phyphox writes one
//! file per sensor) are read one by one and merged into one recording; a file that
//! cannot be read becomes a diagnostic of the merge, and the rest is still used.

use super::delimited::{self, RawImport, SensorAxes};
use super::lines::decode_all;
use super::summary::{summarize, StreamSummary};
use super::{
    ensure_text, nmea, serial_lines, tagged_lines, Diagnostics, ImportError, ImportReport,
};
use crate::recording::{Recording, Stream};

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

/// One file as read, before merging.
enum FileImport {
    /// Delimited text still in its own axes: merged before the axes are converted, so
    /// that a phone's mount is judged from its accelerometer file.
    Raw(RawImport),
    Final(ImportReport),
}

fn import_one(file_name: &str, bytes: &[u8]) -> Result<FileImport, ImportError> {
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
        Some(Format::Delimited) | None => FileImport::Raw(delimited::read_raw(file_name, bytes)?),
    })
}

/// Reads one file, whatever its format.
pub fn import(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    import_files(&[(file_name, bytes)])
}

/// Reads several files of one recording and merges them. Fails only when no file could
/// be read; then the error is the first file's.
pub fn import_files(files: &[(&str, &[u8])]) -> Result<ImportReport, ImportError> {
    let mut imports: Vec<(String, FileImport)> = Vec::new();
    let mut failures: Vec<(String, ImportError)> = Vec::new();
    for &(file_name, bytes) in files {
        match import_one(file_name, bytes) {
            Ok(import) => imports.push((file_name.to_string(), import)),
            Err(error) => failures.push((file_name.to_string(), error)),
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
        append_recording(target, recording);
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
        append_recording(&mut merged.recording, converted.recording);
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

fn append<T>(into: &mut Stream<T>, from: Stream<T>) {
    into.t_s.extend(from.t_s);
    into.values.extend(from.values);
}

/// Appends every stream of `from` to `into` (sorting is the caller's).
fn append_recording(into: &mut Recording, from: Recording) {
    append(&mut into.acc_in_body_mps2, from.acc_in_body_mps2);
    append(&mut into.gyro_in_body_radps, from.gyro_in_body_radps);
    append(&mut into.mag_in_body_ut, from.mag_in_body_ut);
    append(&mut into.mag_bias_in_body_ut, from.mag_bias_in_body_ut);
    append(&mut into.temp_c, from.temp_c);
    append(&mut into.pressure_hpa, from.pressure_hpa);
    append(&mut into.gnss, from.gnss);
    append(&mut into.attitude, from.attitude);
    append(&mut into.device_heading, from.device_heading);
    append(&mut into.ref_heading_rad, from.ref_heading_rad);
    append(&mut into.ref_position_en_m, from.ref_position_en_m);
    append(
        &mut into.ref_position_lat_lon_deg,
        from.ref_position_lat_lon_deg,
    );
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
