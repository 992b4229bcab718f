//! [`ChunkedImport`]: a file fed in chunks (the CLI's reads, the page's `File` slices)
//! with the same result as reading it whole. The format is told from the first bytes;
//! delimited text and NMEA then go in blocks of whole lines, every other format line by
//! line through the line decoder.

use super::{format_for, refuse_json, sample_lines, FileImport, Format, SAMPLE_BYTES};
use crate::io::delimited::{self, ColumnMapping, DelimitedReader};
use crate::io::lines::{Line, LineDecoder};
use crate::io::sensor_files::{self, SensorFile, SensorFileReader};
use crate::io::tagged_lines::LineReader as _;
use crate::io::{
    dataflash, first_binary_offset, gpx, nmea, serial_lines, tagged_lines, ulog, ImportError,
    MAX_LINE_BYTES,
};

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
    /// A binary autopilot log, read message by message.
    Binary(Box<dataflash::BinaryReader>),
    Ulog(Box<ulog::UlogReader>),
    /// A GPX or KML track, read whole at the end (tracks are small).
    Track(Vec<u8>),
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
pub(super) const MAX_CARRY_BYTES: usize = 1 << 20;

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
            Reading::Binary(reader) => reader.feed(chunk),
            Reading::Ulog(reader) => reader.feed(chunk),
            Reading::Track(bytes) => bytes.extend_from_slice(chunk),
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
            other @ (Reading::Lines(..)
            | Reading::Binary(_)
            | Reading::Ulog(_)
            | Reading::Track(_)) => other,
        }
    }

    fn finish(self, file_name: &str) -> Result<FileImport, ImportError> {
        match self {
            Reading::Binary(reader) => Ok(FileImport::Final(dataflash::finish_binary(
                *reader, file_name,
            )?)),
            Reading::Ulog(reader) => Ok(FileImport::Final(reader.finish(file_name)?)),
            Reading::Track(bytes) => Ok(FileImport::Final(gpx::read(file_name, &bytes)?)),
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
    DataflashText(dataflash::TextReader),
}

impl FormatReader {
    fn read_line(&mut self, line: &Line<'_>) {
        match self {
            FormatReader::Delimited(reader) => reader.read_line(line),
            FormatReader::SensorFile(reader) => reader.read_line(line),
            FormatReader::Nmea(reader) => reader.read_decoded(line),
            FormatReader::Serial(reader) => reader.read_line(line.number, &line.text, None),
            FormatReader::Android(reader) => {
                reader.read_line(line.number, &line.text, line.truncated);
            }
            FormatReader::GetSensorData(reader) => {
                reader.read_line(line.number, &line.text, line.truncated);
            }
            FormatReader::DataflashText(reader) => reader.read_line(line.number, &line.text),
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
            FormatReader::DataflashText(reader) => {
                FileImport::Final(dataflash::finish_text(reader, file_name)?)
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
        if dataflash::looks_like_binary(&self.prefix) {
            let mut reader = Box::<dataflash::BinaryReader>::default();
            reader.feed(&std::mem::take(&mut self.prefix));
            self.reader = Some(Reading::Binary(reader));
            return Ok(());
        }
        if ulog::looks_like(&self.prefix) {
            let mut reader = Box::<ulog::UlogReader>::default();
            reader.feed(&std::mem::take(&mut self.prefix));
            self.reader = Some(Reading::Ulog(reader));
            return Ok(());
        }
        if let Some(byte_offset) = first_binary_offset(&self.prefix) {
            return Err(ImportError::NotText {
                file_name: self.file_name.clone(),
                byte_offset,
            });
        }
        let sample_lines = sample_lines(&self.prefix);
        let sample: Vec<&str> = sample_lines.iter().map(String::as_str).collect();
        refuse_json(&self.file_name, &sample)?;
        if let Some(sensor_file) = sensor_files::recognise(&self.file_name, &sample) {
            self.start_reading_sensor_file(sensor_file);
            return Ok(());
        }
        let format = format_for(&sample, self.mapping.as_ref());
        if format == Some(Format::Track) {
            self.reader = Some(Reading::Track(std::mem::take(&mut self.prefix)));
            return Ok(());
        }
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
            Some(Format::DataflashText) => {
                FormatReader::DataflashText(dataflash::TextReader::default())
            }
            // Taken whole above.
            Some(Format::Track) => return Ok(()),
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
            Format::AndroidDump
            | Format::GetSensorData
            | Format::SerialLines
            | Format::DataflashText
            | Format::Track => return None,
        };
        let reading = Reading::Blocks {
            reader,
            carry: Vec::new(),
            n_lines,
        };
        Some((reading, data_start))
    }

    /// Ends the file and hands over what was read, for [`merge`](super::merge).
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
