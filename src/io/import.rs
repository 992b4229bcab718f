//! Format detection and multi-file import: the one door every log comes through.
//!
//! The format is told from the content (the first lines), not from the file name:
//! NMEA sentences, the Android sensor dump, GetSensorData logs, delimited text with a
//! header, or serial sensor lines. Several files dropped together (phyphox writes one
//! file per sensor) are read one by one and merged into one recording; a file that
//! cannot be read becomes a diagnostic of the merge, and the rest is still used.

use super::delimited::{self, ColumnMapping, DelimitedReader, RawImport, SensorAxes};
use super::lines::{decode_all, Line, LineDecoder};
use super::sensor_files::{self, SensorFile, SensorFileReader, SensorImport};
use super::summary::{summarize, StreamSummary};
use super::tagged_lines::LineReader as _;
use super::{
    ensure_text, first_binary_offset, nmea, serial_lines, tagged_lines, Diagnostics, ImportError,
    ImportReport, SensorFrame, MAX_LINE_BYTES,
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
    if nmea::looks_like(sample) {
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

fn import_one(
    file_name: &str,
    bytes: &[u8],
    mapping: Option<&ColumnMapping>,
) -> Result<FileImport, ImportError> {
    ensure_text(file_name, bytes)?;
    let sample_lines = sample_lines(bytes);
    let sample: Vec<&str> = sample_lines.iter().map(String::as_str).collect();
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
    let (mut imports, choice_notes) = choose_among_sensor_files(imports);
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
        let mut report = match imports.remove(0).1 {
            FileImport::Raw(raw) | FileImport::Sensor(SensorImport { raw, .. }) => {
                raw.into_report()
            }
            FileImport::Final(report) => report,
        };
        report.notes.extend(choice_notes);
        return Ok(report);
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
        mag_frame: None,
    };
    let mut formats: Vec<&'static str> = Vec::new();
    let mut device_recording: Option<Recording> = None;
    // The unit of the first device-axes file with a magnetometer: its frame is known
    // once the mount is.
    let mut device_mag_unit = None;
    // Every file's magnetometer frame, in file order, to keep the first and note others.
    let mut mag_frames: Vec<(String, SensorFrame)> = Vec::new();
    merged.notes.extend(choice_notes);
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
            mag_unit: device_mag_unit,
        };
        let converted = raw.into_report();
        merged.notes.extend(converted.notes);
        merged.recording.append(converted.recording);
        if let Some(frame) = converted.mag_frame {
            mag_frames.push(("the phone's files".to_string(), frame));
        }
    }
    // The magnetometer's frame survives the merge; a second magnetometer in other axes
    // or units is named, since one calibration cannot be exported for both.
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

/// How many leading bytes a chunked import holds back to tell the format.
const SNIFF_BYTES: usize = SAMPLE_BYTES;

/// A file read in chunks (from disk, or from a `File` in the browser), so that memory
/// holds the samples and one chunk, never the whole text. The format is told from the
/// first 16 KiB. From then on, delimited data lines and NMEA sentences are read in
/// blocks of whole lines where they lie in the chunk, by the same code and with the same
/// result as reading the file whole (only a chunk's unfinished last line is kept for
/// the next); every other format, and a header that does not end in the first 16 KiB,
/// goes line by line through the line decoder. Feeding the same bytes in any chunks
/// gives the same result.
pub struct ChunkedImport {
    file_name: String,
    size_hint_bytes: Option<usize>,
    /// The first bytes, held until the format is known.
    prefix: Vec<u8>,
    reader: Option<Reading>,
    saw_text: bool,
    n_bytes_read: usize,
    mapping: Option<ColumnMapping>,
    /// The phone app's per-sensor file this is, told from its name and first lines.
    sensor_file: Option<SensorFile>,
}

/// How a chunked import reads, once the format is known.
enum Reading {
    Lines(LineDecoder, FormatReader),
    Blocks {
        reader: BlockReader,
        /// The unfinished line at the end of the last chunk.
        carry: Vec<u8>,
        /// Lines read so far (the header's included).
        n_lines: usize,
    },
}

/// An unfinished line longer than this goes to the line decoder (which bounds the
/// memory a line takes), with the rest of the file.
const MAX_CARRY_BYTES: usize = 1 << 20;

/// The readers that take blocks of whole lines.
enum BlockReader {
    Delimited(DelimitedReader),
    Nmea(nmea::NmeaReader),
}

impl BlockReader {
    fn read(&mut self, lines: &[u8], n_lines_before: usize) -> usize {
        match self {
            BlockReader::Delimited(reader) => reader.read_lines_block(lines, n_lines_before),
            BlockReader::Nmea(reader) => reader.read_lines_block(lines, n_lines_before),
        }
    }

    fn into_line_reader(self) -> FormatReader {
        match self {
            BlockReader::Delimited(reader) => FormatReader::Delimited(reader),
            BlockReader::Nmea(reader) => FormatReader::Nmea(reader),
        }
    }
}

impl Reading {
    fn feed(&mut self, chunk: &[u8]) {
        match self {
            Reading::Lines(decoder, reader) => decoder.feed(chunk, |line| reader.read_line(&line)),
            Reading::Blocks {
                reader,
                carry,
                n_lines,
            } => {
                let Some(last_newline) = memchr::memrchr(b'\n', chunk) else {
                    carry.extend_from_slice(chunk);
                    return;
                };
                let (mut lines, rest) = chunk.split_at(last_newline + 1);
                if !carry.is_empty() {
                    // Finish the carried line; read the rest of the chunk where it lies.
                    let first_end =
                        memchr::memchr(b'\n', lines).map_or(lines.len(), |newline| newline + 1);
                    let (first_rest, after) = lines.split_at(first_end);
                    carry.extend_from_slice(first_rest);
                    *n_lines += reader.read(carry, *n_lines);
                    carry.clear();
                    lines = after;
                }
                if !lines.is_empty() {
                    *n_lines += reader.read(lines, *n_lines);
                }
                carry.extend_from_slice(rest);
            }
        }
    }

    /// Whether the unfinished line has grown too long to keep whole.
    fn carries_too_much(&self) -> bool {
        matches!(self, Reading::Blocks { carry, .. } if carry.len() > MAX_CARRY_BYTES)
    }

    /// Goes on line by line through the line decoder, from the carried line on.
    fn into_lines(self) -> Reading {
        match self {
            Reading::Blocks {
                reader,
                carry,
                n_lines,
            } => {
                let mut decoder = LineDecoder::continuing(MAX_LINE_BYTES, n_lines);
                let mut reader = reader.into_line_reader();
                decoder.feed(&carry, |line| reader.read_line(&line));
                Reading::Lines(decoder, reader)
            }
            lines @ Reading::Lines(..) => lines,
        }
    }

    fn finish(self, file_name: &str) -> Result<FileImport, ImportError> {
        match self {
            Reading::Lines(mut decoder, mut reader) => {
                decoder.finish(|line| reader.read_line(&line));
                reader.finish(file_name)
            }
            Reading::Blocks {
                mut reader,
                carry,
                n_lines,
            } => {
                if !carry.is_empty() {
                    reader.read(&carry, n_lines);
                }
                reader.into_line_reader().finish(file_name)
            }
        }
    }
}

enum FormatReader {
    Delimited(DelimitedReader),
    SensorFile(SensorFileReader),
    Nmea(nmea::NmeaReader),
    Serial(serial_lines::SerialReader),
    Android(tagged_lines::AndroidReader),
    GetSensorData(tagged_lines::GetSensorDataReader),
}

impl FormatReader {
    fn read_line(&mut self, line: &Line<'_>) {
        match self {
            FormatReader::Delimited(reader) => reader.read_line(line),
            FormatReader::SensorFile(reader) => reader.read_line(line),
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
            FormatReader::SensorFile(reader) => FileImport::Sensor(reader.finish(file_name)?),
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
            sensor_file: None,
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
            Some(reading) => {
                reading.feed(chunk);
                if reading.carries_too_much() {
                    self.reader = self.reader.take().map(Reading::into_lines);
                }
            }
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
        let sample_lines = sample_lines(&self.prefix);
        let sample: Vec<&str> = sample_lines.iter().map(String::as_str).collect();
        if let Some(sensor_file) = sensor_files::recognise(&self.file_name, &sample) {
            self.start_reading_sensor_file(sensor_file);
            return Ok(());
        }
        let format = format_for(&sample, self.mapping.as_ref());
        if let Some((mut reading, data_start)) = self.blocks_for(format) {
            let prefix = std::mem::take(&mut self.prefix);
            reading.feed(prefix.get(data_start..).unwrap_or_default());
            self.reader = Some(reading);
            return Ok(());
        }
        let mut reader = match format {
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
        self.reader = Some(Reading::Lines(decoder, reader));
        Ok(())
    }

    /// A phone app's per-sensor file: Sensor Logger's CSVs that are read go through the
    /// delimited reader (in blocks, as other delimited text), every other one through
    /// [`SensorFileReader`], line by line.
    fn start_reading_sensor_file(&mut self, sensor_file: SensorFile) {
        let prefix = std::mem::take(&mut self.prefix);
        let logger_reader = || match &sensor_file {
            SensorFile::SensorLogger { kind, .. } => {
                sensor_files::logger_reader(*kind, self.size_hint_bytes)
            }
            _ => None,
        };
        let reading = match logger_reader() {
            Some(reader) => match delimited::read_up_to_header_with(reader, &prefix) {
                Some((reader, data_start, n_lines)) => {
                    let mut reading = Reading::Blocks {
                        reader: BlockReader::Delimited(reader),
                        carry: Vec::new(),
                        n_lines,
                    };
                    reading.feed(prefix.get(data_start..).unwrap_or_default());
                    reading
                }
                // No line ending after the header yet: line by line.
                None => {
                    let reader = logger_reader().map_or_else(
                        || FormatReader::SensorFile(SensorFileReader::new(sensor_file.clone())),
                        FormatReader::Delimited,
                    );
                    self.lines_of(reader, &prefix)
                }
            },
            None => self.lines_of(
                FormatReader::SensorFile(SensorFileReader::new(sensor_file.clone())),
                &prefix,
            ),
        };
        self.reader = Some(reading);
        self.sensor_file = Some(sensor_file);
    }

    /// Line-by-line reading with `reader`, the prefix already fed.
    fn lines_of(&self, mut reader: FormatReader, prefix: &[u8]) -> Reading {
        let mut decoder = LineDecoder::new(MAX_LINE_BYTES);
        decoder.feed(prefix, |line| reader.read_line(&line));
        Reading::Lines(decoder, reader)
    }

    /// Block reading for NMEA, and for delimited text whose header ends in the prefix
    /// (the header is read here), with where the data starts in the prefix.
    fn blocks_for(&self, format: Option<Format>) -> Option<(Reading, usize)> {
        let (reader, data_start, n_lines) = match format? {
            Format::Nmea => (BlockReader::Nmea(nmea::NmeaReader::new()), 0, 0),
            Format::Delimited => {
                let (reader, data_start, n_lines) = delimited::read_up_to_header(
                    &self.prefix,
                    self.mapping.as_ref(),
                    self.size_hint_bytes,
                )?;
                (BlockReader::Delimited(reader), data_start, n_lines)
            }
            Format::AndroidDump | Format::GetSensorData | Format::SerialLines => return None,
        };
        let reading = Reading::Blocks {
            reader,
            carry: Vec::new(),
            n_lines,
        };
        Some((reading, data_start))
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
        let Some(reading) = self.reader.take() else {
            return Err(ImportError::Empty {
                file_name: self.file_name,
            });
        };
        let import = reading.finish(&self.file_name)?;
        Ok(match (self.sensor_file, import) {
            (Some(SensorFile::SensorLogger { kind, start_unix_s }), FileImport::Raw(raw)) => {
                FileImport::Sensor(sensor_files::finish_logger(kind, start_unix_s, raw))
            }
            (_, import) => import,
        })
    }
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
        }
    }
}

// Native only: proptest is a native dev-dependency.
#[cfg(all(test, not(target_arch = "wasm32")))]
mod tests {
    use proptest::prelude::*;

    use super::*;

    fn sentence(body: &str) -> String {
        let checksum = body.bytes().fold(0u8, |acc, byte| acc ^ byte);
        format!("${body}*{checksum:02X}")
    }

    /// A canonical CSV with what a block must get right: comments and a blank line among
    /// the data, a quoted field, bad numbers, a short row, a time that goes back, a lone
    /// CR, CRLF endings, bytes that are not UTF-8, and a last line without its ending.
    fn tricky_csv() -> Vec<u8> {
        let mut text = b"# comment\nt_s,mag_x_ut,mag_y_ut,mag_z_ut,acc_x_mps2,acc_y_mps2,acc_z_mps2,lat_deg,lon_deg\n".to_vec();
        for row in 0..1500u32 {
            let t = f64::from(row) * 0.01;
            let line = match row % 57 {
                3 => format!("{t:.2},abc,1,2,0,0,-9.8,,\n"),
                7 => format!("{t:.2},\"20.5\",1,2,0,0,-9.8,48.1,11.5\r\n"),
                11 => "\n".to_string(),
                13 => format!("{t:.2},20\n"),
                17 => format!("{:.2},21,2,3,0,0,-9.8,,\n", t - 1.0),
                19 => format!("{t:.2},22,1,2\r0,0,-9.8,,\n"),
                23 => format!("# note {row}\r\n"),
                _ => format!("{t:.2},{},{},-40,0.1,0.2,-9.8,,\n", 20 + row % 5, row % 3),
            };
            text.extend_from_slice(line.as_bytes());
            if row == 700 {
                text.extend_from_slice(b"1.5,\xff\xfe,1,2,0,0,-9.8,,\n");
            }
        }
        text.extend_from_slice(b"99.99,20,1,2,0,0,-9.8,,");
        text
    }

    /// NMEA with a midnight, untimed sentences, every line ending, a bad checksum, an
    /// unknown address, bytes that are not UTF-8, blank lines, an overlong line and a
    /// last line without its ending.
    fn tricky_nmea() -> Vec<u8> {
        let mut text = sentence("HEHDT,10.0,T").into_bytes();
        text.extend_from_slice(b"\r\n");
        for epoch in 0..600u32 {
            let seconds = 235_950 + epoch;
            let hhmmss = format!(
                "{:02}{:02}{:02}",
                (seconds / 3600) % 24,
                (seconds / 60) % 60,
                seconds % 60
            );
            let date = if seconds / 3600 >= 24 {
                "030124"
            } else {
                "020124"
            };
            let lines = [
                sentence(&format!(
                    "GPRMC,{hhmmss}.00,A,4807.038,N,01131.000,E,1.5,{:.1},{date},,,A",
                    f64::from(epoch % 360)
                )),
                sentence(&format!(
                    "GPGGA,{hhmmss}.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,47.0,M,,"
                )),
                sentence("GPVTG,54.7,T,,M,5.5,N,10.2,K,A"),
                sentence("HCHDG,101.1,,,7.1,W"),
                sentence("PTNTHPR,85.9,N,-0.9,N,0.8,N"),
            ];
            for (idx, line) in lines.iter().enumerate() {
                let ending: &[u8] = match (epoch as usize + idx) % 3 {
                    0 => b"\r\n",
                    1 => b"\n",
                    _ => b"\r",
                };
                if epoch % 41 == 5 && idx == 1 {
                    text.extend_from_slice(b"$GPGGA,bad*00\n");
                }
                if epoch % 53 == 7 && idx == 2 {
                    text.extend_from_slice(b"$GPXYZ,1,2,3\n\xff\xfe garbage\n\n");
                }
                text.extend_from_slice(line.as_bytes());
                text.extend_from_slice(ending);
            }
        }
        text.extend_from_slice(&[b'x'; 5000]);
        text.extend_from_slice(b"\n");
        text.extend_from_slice(sentence("HEHDT,12.0,T").as_bytes());
        text
    }

    fn read_in_chunks(
        name: &str,
        bytes: &[u8],
        chunk_ends: &[usize],
    ) -> Result<ImportReport, ImportError> {
        let mut chunked = ChunkedImport::new(name, Some(bytes.len()));
        let mut start = 0;
        for &end in chunk_ends.iter().chain(std::iter::once(&bytes.len())) {
            let end = end.clamp(start, bytes.len());
            chunked.feed(&bytes[start..end])?;
            start = end;
        }
        merge(vec![(name.to_string(), chunked.finish())])
    }

    #[test]
    fn the_magnetometer_frame_survives_a_merge_with_the_mount_of_the_phone_s_files() {
        use crate::io::axes::PhoneMount;
        use crate::io::MagUnit;
        // phyphox: one file per sensor, held upright (gravity along device y).
        let acc = "\"Time (s)\",\"X (m/s^2)\",\"Y (m/s^2)\",\"Z (m/s^2)\"\n0.0,0.1,9.8,0.2\n0.1,0.1,9.8,0.2\n";
        let mag = "\"Time (s)\",\"X (µT)\",\"Y (µT)\",\"Z (µT)\"\n0.0,10,-20,30\n0.1,11,-20,30\n";
        let temp = "t_s,temp_c\n0,20\n";
        for files in [
            vec![("Accelerometer.csv", acc), ("Magnetometer.csv", mag)],
            vec![
                ("Magnetometer.csv", mag),
                ("t.csv", temp),
                ("Accelerometer.csv", acc),
            ],
        ] {
            let files: Vec<(&str, &[u8])> = files
                .iter()
                .map(|(name, text)| (*name, text.as_bytes()))
                .collect();
            let report = import_files(&files).expect("merged");
            let frame = report.mag_frame.expect("the magnetometer's frame");
            assert_eq!(
                frame,
                SensorFrame::android_device(PhoneMount::Upright, MagUnit::MICROTESLA)
            );
            assert_eq!(
                frame.body_from_sensor * nalgebra::Vector3::new(10.0, -20.0, 30.0),
                report.recording.mag_in_body_ut.values[0]
            );
        }
        // A second magnetometer in other axes is named in the notes.
        let serial = "Raw:0,0,8192,0,0,0,300,-150,450\nRaw:0,0,8192,0,0,0,301,-150,450\n";
        let csv = "t_s,mag_x_ut,mag_y_ut,mag_z_ut\n0,1,2,3\n";
        let report = import_files(&[("a.txt", serial.as_bytes()), ("b.csv", csv.as_bytes())])
            .expect("merged");
        assert_eq!(
            report.mag_frame.map(|frame| frame.unit),
            Some(MagUnit::MOTIONCAL_COUNT)
        );
        assert!(
            report
                .notes
                .iter()
                .any(|note| note.starts_with("b.csv has a magnetometer in other axes")),
            "{:?}",
            report.notes
        );
    }

    #[test]
    fn delimited_and_nmea_chunks_read_in_blocks_give_the_whole_files_import() {
        for (name, bytes) in [("tricky.csv", tricky_csv()), ("tricky.nmea", tricky_nmea())] {
            let whole = import(name, &bytes);
            assert!(whole
                .as_ref()
                .is_ok_and(|report| report.diagnostics.kept.len() > 5));
            let len = bytes.len();
            for chunk_len in [1usize, 2, 3, 7, 100, 4096, 16 * 1024, 16 * 1024 + 1, len] {
                let ends: Vec<usize> = (1..=len / chunk_len).map(|idx| idx * chunk_len).collect();
                assert_eq!(
                    read_in_chunks(name, &bytes, &ends),
                    whole,
                    "{name} in chunks of {chunk_len}"
                );
            }
        }
    }

    #[test]
    fn a_line_too_long_to_carry_goes_to_the_line_decoder_with_the_same_result() {
        let mut csv = b"t_s,mag_x_ut,mag_y_ut,mag_z_ut\n0,1,2,3\n0.2,1,2,3\n0.5,".to_vec();
        csv.extend(std::iter::repeat_n(b'7', 3 * MAX_CARRY_BYTES));
        csv.extend_from_slice(b",2,3\n1,1,2,3\n2,1,2,3\n");
        let mut nmea = format!(
            "{}\n{}\n{}\n",
            sentence("HEHDT,10.0,T"),
            sentence("HEHDT,10.5,T"),
            sentence("HEHDT,10.7,T")
        )
        .into_bytes();
        nmea.extend(std::iter::repeat_n(b'$', 3 * MAX_CARRY_BYTES));
        nmea.extend_from_slice(format!("\n{}\n", sentence("HEHDT,11.0,T")).as_bytes());
        for (name, bytes) in [("long.csv", csv), ("long.nmea", nmea)] {
            let whole = import(name, &bytes);
            let kept = whole.as_ref().map(|report| report.diagnostics.kept.clone());
            assert!(
                kept.as_ref().is_ok_and(|kept| {
                    kept.iter().any(|diagnostic| {
                        diagnostic.line == Some(4) && diagnostic.message.len() < 200
                    })
                }),
                "{name}: {kept:?}"
            );
            let ends: Vec<usize> = (1..bytes.len() / 65536).map(|idx| idx * 65536).collect();
            assert_eq!(read_in_chunks(name, &bytes, &ends), whole, "{name}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        #[test]
        fn any_chunks_give_the_whole_files_import(
            mut chunk_ends in proptest::collection::vec(0usize..80_000, 0..12),
            nmea in any::<bool>(),
        ) {
            let (name, bytes) = if nmea { ("p.nmea", tricky_nmea()) } else { ("p.csv", tricky_csv()) };
            chunk_ends.sort_unstable();
            prop_assert_eq!(read_in_chunks(name, &bytes, &chunk_ends), import(name, &bytes));
        }
    }
}
