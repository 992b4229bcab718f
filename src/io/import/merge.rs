//! The merge of several files of one recording, each read on its own: a phone app's
//! per-sensor files chosen among first, delimited files in the phone's device axes
//! merged before their axes are converted (so that the mount is judged from all of
//! them), the first magnetometer's frame kept, a file that failed kept as a diagnostic,
//! and the streams sorted by time. Files whose magnetometers cover the same time are
//! not interleaved: the first is used and the others are named in a note.

use super::FileImport;
use crate::io::delimited::{self, RawImport, SensorAxes};
use crate::io::recording::Recording;
use crate::io::sensor_files::{self, SensorImport};
use crate::io::{gpx, Diagnostics, ImportError, ImportReport, SensorFrame};

/// Merges files read one by one (with [`import_files`](super::import_files)'s rules): a file that failed
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
    let (imports, mut choice_notes) = choose_among_sensor_files(imports);
    let mut imports = leave_out_second_magnetometers(imports, &mut choice_notes);
    if imports.is_empty() {
        return Err(failures.into_iter().next().map_or(
            ImportError::Empty {
                file_name: String::new(),
            },
            |(_, error)| error,
        ));
    }
    if imports.len() == 1 && failures.is_empty() {
        let mut report = match imports.remove(0).1 {
            FileImport::Raw(raw) | FileImport::Sensor(SensorImport { raw, .. }) => {
                raw.into_report()
            }
            FileImport::Final(report) => report,
        };
        report.notes.extend(choice_notes);
        return Ok(report);
    }

    let names: Vec<String> = imports.iter().map(|(name, _)| name.clone()).collect();
    let mut merged = ImportReport {
        autopilot: None,
        file_name: names.join(" + "),
        format: "",
        recording: Recording::default(),
        diagnostics: Diagnostics::default(),
        header: None,
        n_data_lines: 0,
        notes: Vec::new(),
        mag_frame: None,
    };
    merged.notes.extend(choice_notes);
    place_tracks(&mut imports, &mut merged.notes);
    // An autopilot log's parameters and compasses go with it (the first one's).
    merged.autopilot = imports.iter_mut().find_map(|(_, import)| match import {
        FileImport::Final(report) => report.autopilot.take(),
        _ => None,
    });
    let (mut formats, mag_frames) = merge_files(&mut merged, imports);
    keep_the_first_mag_frame(&mut merged, &mag_frames);
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

/// The recording a file gives, before it is merged.
fn recording_of(import: &FileImport) -> &Recording {
    match import {
        FileImport::Raw(raw) | FileImport::Sensor(SensorImport { raw, .. }) => {
            &raw.report.recording
        }
        FileImport::Final(report) => &report.recording,
    }
}

/// The time span of a file's magnetometer, if it has one.
fn mag_span_s(import: &FileImport) -> Option<(f64, f64)> {
    let times = &recording_of(import).mag_in_body_ut.t_s;
    Some((*times.first()?, *times.last()?))
}

/// A file whose magnetometer covers the same time as an earlier file's (more than half
/// of the shorter span) is a second recording of the same motion, such as the raw and
/// the filtered export of one calibration: merged by time, the two would interleave
/// into one stream that zigzags between them. The first file is kept, in the order the
/// files came; the others are left out with a note saying how to analyse them.
fn leave_out_second_magnetometers(
    imports: Vec<(String, FileImport)>,
    notes: &mut Vec<String>,
) -> Vec<(String, FileImport)> {
    let mut kept: Vec<(String, FileImport)> = Vec::with_capacity(imports.len());
    for (file_name, import) in imports {
        let overlapping = mag_span_s(&import).and_then(|(start_s, end_s)| {
            kept.iter().find_map(|(kept_name, kept_import)| {
                let (kept_start_s, kept_end_s) = mag_span_s(kept_import)?;
                let overlap_s = end_s.min(kept_end_s) - start_s.max(kept_start_s);
                let shorter_s = (end_s - start_s).min(kept_end_s - kept_start_s);
                (overlap_s > 0.5 * shorter_s && shorter_s > 0.0).then_some(kept_name.clone())
            })
        });
        match overlapping {
            Some(kept_name) => notes.push(format!(
                "{file_name}: not used, {kept_name} already gives a magnetometer over the same time (two recordings \
                 of one motion cannot be merged); drop {file_name} on its own to analyse it"
            )),
            None => kept.push((file_name, import)),
        }
    }
    kept
}

/// Moves every file into `merged`: delimited files with device axes first (their mount
/// is judged together, and their recording converted to body axes once), then
/// everything else. Hands back each file's format, in order, and every magnetometer
/// frame with the name of the file (or files) it came from.
fn merge_files(
    merged: &mut ImportReport,
    imports: Vec<(String, FileImport)>,
) -> (Vec<&'static str>, Vec<(String, SensorFrame)>) {
    let mut formats: Vec<&'static str> = Vec::new();
    let mut device_recording: Option<Recording> = None;
    // The unit of the first device-axes file with a magnetometer: its frame is known
    // once the mount is.
    let mut device_mag_unit = None;
    // Every file's magnetometer frame, in file order, to keep the first and note others.
    let mut mag_frames: Vec<(String, SensorFrame)> = Vec::new();
    for (file_name, import) in imports {
        let (report, in_device_axes) = match import {
            // (Per-sensor files were turned into delimited imports above.)
            FileImport::Raw(raw) | FileImport::Sensor(SensorImport { raw, .. })
                if raw.axes == SensorAxes::AndroidDevice =>
            {
                if device_mag_unit.is_none() && !raw.report.recording.mag_in_body_ut.is_empty() {
                    device_mag_unit = raw.mag_unit;
                }
                (raw.report, true)
            }
            FileImport::Raw(raw) | FileImport::Sensor(SensorImport { raw, .. }) => {
                (raw.into_report(), false)
            }
            FileImport::Final(report) => (report, false),
        };
        if let Some(frame) = report.mag_frame {
            mag_frames.push((file_name.clone(), frame));
        }
        let recording = merge_into_parts(merged, report, &file_name, &mut formats);
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
                autopilot: None,
                recording,
                ..empty_like(merged)
            },
            axes: SensorAxes::AndroidDevice,
            mag_unit: device_mag_unit,
        };
        let converted = raw.into_report();
        merged.notes.extend(converted.notes);
        merged.recording.append(converted.recording);
        if let Some(frame) = converted.mag_frame {
            mag_frames.push(("the phone's files".to_string(), frame));
        }
    }
    (formats, mag_frames)
}

/// The magnetometer's frame survives the merge; a second magnetometer in other axes or
/// units is named, since one calibration cannot be exported for both.
fn keep_the_first_mag_frame(merged: &mut ImportReport, mag_frames: &[(String, SensorFrame)]) {
    if let Some((first_name, first)) = mag_frames.first() {
        merged.mag_frame = Some(*first);
        for (name, frame) in mag_frames.iter().skip(1) {
            if !frame.same_conversion(first) {
                merged.notes.push(format!(
                    "{name} has a magnetometer in other axes or units than {first_name}'s; a \
                     calibration is exported for {first_name}'s ({}, {})",
                    first.axes,
                    first.unit.label()
                ));
            }
        }
    }
}

/// The per-sensor files among the imports chosen among ([`sensor_files::choose`]), in
/// their places, as delimited imports in device axes; with notes on the choices.
fn choose_among_sensor_files(
    imports: Vec<(String, FileImport)>,
) -> (Vec<(String, FileImport)>, Vec<String>) {
    let mut kept: Vec<Option<(String, FileImport)>> = Vec::with_capacity(imports.len());
    let mut sensor: Vec<(String, SensorImport)> = Vec::new();
    let mut sensor_places: Vec<usize> = Vec::new();
    for (file_name, import) in imports {
        match import {
            FileImport::Sensor(sensor_import) => {
                sensor_places.push(kept.len());
                sensor.push((file_name, sensor_import));
                kept.push(None);
            }
            import => kept.push(Some((file_name, import))),
        }
    }
    let (chosen, notes) = sensor_files::choose(sensor);
    for (place, (file_name, raw)) in sensor_places.into_iter().zip(chosen) {
        if let Some(slot) = kept.get_mut(place) {
            *slot = Some((file_name, FileImport::Raw(raw)));
        }
    }
    (kept.into_iter().flatten().collect(), notes)
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
        autopilot: None,
        file_name: report.file_name.clone(),
        format: delimited::FORMAT_NAME,
        recording: Recording::default(),
        diagnostics: Diagnostics::default(),
        header: None,
        n_data_lines: 0,
        notes: Vec::new(),
        mag_frame: None,
    }
}

/// The start (Unix s) of a file's recording, where it is dated.
fn start_of(import: &FileImport) -> Option<f64> {
    match import {
        FileImport::Raw(raw) | FileImport::Sensor(SensorImport { raw, .. }) => {
            raw.report.recording.start_unix_s
        }
        FileImport::Final(report) => report.recording.start_unix_s,
    }
}

fn is_track(import: &FileImport) -> bool {
    matches!(import, FileImport::Final(report) if is_track_report(report))
}

fn is_track_report(report: &ImportReport) -> bool {
    report.format == gpx::GPX || report.format == gpx::KML
}

/// GPX and KML tracks dropped with a sensor log are put on the log's clock by their UTC
/// times; a log that is not dated keeps the track's first point as its own start, and
/// the note says so.
fn place_tracks(imports: &mut [(String, FileImport)], notes: &mut Vec<String>) {
    let log_start = imports
        .iter()
        .filter(|(_, import)| !is_track(import))
        .find_map(|(_, import)| start_of(import));
    let has_log = imports.iter().any(|(_, import)| !is_track(import));
    for (file_name, import) in imports.iter_mut() {
        let FileImport::Final(report) = import else {
            continue;
        };
        if !is_track_report(report) || !has_log {
            continue;
        }
        let recording = &mut report.recording;
        match (log_start, recording.start_unix_s) {
            (Some(log_start), Some(track_start)) => {
                let shift_s = track_start - log_start;
                recording
                    .gnss
                    .t_s
                    .iter_mut()
                    .for_each(|t_s| *t_s += shift_s);
                recording.start_unix_s = Some(log_start);
                notes.push(format!(
                    "{file_name}: placed on the sensor log's clock by its UTC times (its first \
                     point {shift_s:+.1} s after the log's start)"
                ));
            }
            _ => notes.push(format!(
                "{file_name}: the sensor log is not dated, so the track's first point was taken \
                 as the log's start; check that they began together"
            )),
        }
    }
}
