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
use super::frame::RAW_COUNT_MAGNITUDES;
use super::lines::{decode_all, Line, LineDecoder};
use super::number::{parse_f64, parse_prefix, parse_prefix_at};
use super::{
    ensure_text, shorten, Diagnostics, HeaderInfo, ImportError, ImportReport, MagUnit, SensorFrame,
};
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
    /// The unit the magnetometer columns were written in (already converted to µT in the
    /// report); `None` without magnetometer samples.
    pub mag_unit: Option<MagUnit>,
}

/// A user's mapping of a file's column names to names this reader knows, for files whose
/// header it cannot read by itself: `Bx=mag_x_gauss,By=mag_y_gauss,Bz=mag_z_gauss,
/// time=t_ms`. The target `ignore` leaves a column out. Column names match without
/// regard to case or surrounding quotes.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ColumnMapping {
    /// (the file's column name, the name to read it as)
    pub renames: Vec<(String, String)>,
}

/// A mapping that cannot be used, with what to write instead.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MappingError {
    #[error("the mapping entry '{entry}' is not COLUMN=NAME; write for example Bx=mag_x_gauss")]
    NotAnAssignment { entry: String },
    #[error(
        "'{target}' (for column '{column}') is not a name this tool reads; use a name such as \
         mag_x_ut, mag_x_gauss, acc_x_mps2, acc_x_g, gyro_x_radps, gyro_x_dps, t_s, t_ms, temp_c, \
         lat_deg, lon_deg, ref_heading_deg, or ignore"
    )]
    UnknownTarget { column: String, target: String },
}

impl ColumnMapping {
    /// Parses `COLUMN=NAME,COLUMN=NAME,…`, checking every name.
    pub fn parse(spec: &str) -> Result<ColumnMapping, MappingError> {
        let mut renames = Vec::new();
        for entry in spec
            .split(',')
            .map(str::trim)
            .filter(|entry| !entry.is_empty())
        {
            let Some((column, target)) = entry.split_once('=') else {
                return Err(MappingError::NotAnAssignment {
                    entry: entry.to_string(),
                });
            };
            let (column, target) = (
                column.trim().trim_matches('"').to_string(),
                target.trim().to_string(),
            );
            if !target.eq_ignore_ascii_case(IGNORE) && resolve(&target).is_none() {
                return Err(MappingError::UnknownTarget { column, target });
            }
            renames.push((column, target));
        }
        Ok(ColumnMapping { renames })
    }

    /// The name a column is to be read as, if the mapping names it.
    fn target_of(&self, column: &str) -> Option<&str> {
        self.renames
            .iter()
            .find(|(from, _)| from.eq_ignore_ascii_case(column))
            .map(|(_, to)| to.as_str())
    }
}

/// The mapping target that leaves a column out.
const IGNORE: &str = "ignore";

/// What a column can be mapped to, with a label for people: the choices of the page's
/// mapping dialog, and valid `--map` names.
pub const MAPPING_TARGETS: &[(&str, &str)] = &[
    ("ignore", "ignore"),
    ("t_s", "time (s)"),
    ("t_ms", "time (ms)"),
    ("mag_x_ut", "magnetometer x (µT)"),
    ("mag_y_ut", "magnetometer y (µT)"),
    ("mag_z_ut", "magnetometer z (µT)"),
    ("mag_x_gauss", "magnetometer x (gauss)"),
    ("mag_y_gauss", "magnetometer y (gauss)"),
    ("mag_z_gauss", "magnetometer z (gauss)"),
    ("mag_x_mg", "magnetometer x (mG)"),
    ("mag_y_mg", "magnetometer y (mG)"),
    ("mag_z_mg", "magnetometer z (mG)"),
    ("mag_x_nt", "magnetometer x (nT)"),
    ("mag_y_nt", "magnetometer y (nT)"),
    ("mag_z_nt", "magnetometer z (nT)"),
    ("acc_x_mps2", "accelerometer x (m/s²)"),
    ("acc_y_mps2", "accelerometer y (m/s²)"),
    ("acc_z_mps2", "accelerometer z (m/s²)"),
    ("acc_x_g", "accelerometer x (g)"),
    ("acc_y_g", "accelerometer y (g)"),
    ("acc_z_g", "accelerometer z (g)"),
    ("gyro_x_radps", "gyroscope x (rad/s)"),
    ("gyro_y_radps", "gyroscope y (rad/s)"),
    ("gyro_z_radps", "gyroscope z (rad/s)"),
    ("gyro_x_dps", "gyroscope x (deg/s)"),
    ("gyro_y_dps", "gyroscope y (deg/s)"),
    ("gyro_z_dps", "gyroscope z (deg/s)"),
    ("temp_c", "temperature (°C)"),
    ("ref_heading_deg", "reference heading (°)"),
    ("lat_deg", "latitude (°)"),
    ("lon_deg", "longitude (°)"),
];

/// The mapping target suggested for a column: the one it already reads as, where it is
/// among [`MAPPING_TARGETS`], else `ignore`.
pub fn suggested_target(column: &str) -> &'static str {
    let Some((resolved, _)) = resolve(column) else {
        return IGNORE;
    };
    MAPPING_TARGETS
        .iter()
        .find(|(target, _)| resolve(target).is_some_and(|(candidate, _)| candidate == resolved))
        .map_or(IGNORE, |(target, _)| target)
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

/// Large files on native builds and the browser's threaded build ([`crate::par`]): the
/// data lines are cut into one part per thread at line boundaries, parsed side by side,
/// and joined in order, with line numbers counted on across the parts. The result is the
/// same as reading line by line (a test checks it); only the time differs. The browser's
/// default build reads on one thread.
///
/// The dense streams' vectors are made once for the whole file, with room for at most
/// one sample per line of each part, and each part writes into its own share of that
/// room (so that each thread touches, and the system maps, its own memory, and no part
/// is copied after the others); the shares are then closed up. GNSS fixes and attitudes
/// (few, or absent) are gathered per part and appended.
#[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
mod parallel {
    use std::mem::MaybeUninit;

    use super::*;

    /// Below this size one thread is as fast.
    const MIN_PARALLEL_BYTES: usize = 4 << 20;

    /// A block (see [`read_lines_block`]) below this size is read on one thread.
    const MIN_PARALLEL_BLOCK_BYTES: usize = 1 << 20;

    /// `None` when the file is better read on one thread: small, on one core, or without
    /// a time column (the sample number is then counted across the whole file).
    pub(super) fn read_raw(
        file_name: &str,
        bytes: &[u8],
        mapping: Option<&ColumnMapping>,
    ) -> Option<Result<RawImport, ImportError>> {
        let n_threads = crate::par::n_threads();
        if bytes.len() < MIN_PARALLEL_BYTES || n_threads < 2 {
            return None;
        }
        // Read up to the header on this thread.
        let (mut reader, data_offset, n_header_lines) = read_up_to_header(bytes, mapping, None)?;
        // (Data lines read with the header, after lone CRs, would have to come first.)
        if reader.plan.time.is_none() || reader.n_data_lines > 0 {
            return None;
        }
        let header = reader.header.clone()?;
        let parts = cut_into_parts(bytes.get(data_offset..)?, n_threads);
        let max_rows = crate::par::on_each_part(parts.iter(), |part| count_lines(part))?;
        let filled = reader.plan.filled_streams();
        // Two rows of spare room, given back by `finish`. (Measured with glibc's malloc
        // in the import benchmark's loop: with exact capacities the columns' memory went
        // back to the system after every import, and the next import faulted it in
        // again, 34,000 page faults per import instead of 14,000. The shrink's small
        // remainders keep the heap in place. An allocator's detail, not a guarantee.)
        let mut columns = Columns::new(filled, max_rows.iter().sum::<usize>() + 2);
        let results = crate::par::on_each_part(
            columns.shares(&max_rows).into_iter().zip(&parts),
            |(share, part)| {
                let mut part_reader = part_reader(&header, share);
                // Numbered from 2, so that no part's first line is taken for the file's
                // first (where a byte-order mark is dropped).
                let n_lines = part_reader.read_data_bytes(part, 1);
                PartResult::of(part_reader, n_lines)
            },
        )?;
        if results.iter().any(|result| result.overflowed) {
            return None;
        }
        let share_lens: Vec<[usize; N_COLUMNS]> =
            results.iter().map(|result| result.lens).collect();
        columns.close_up(&max_rows, &share_lens, &mut reader.recording);
        // Join in order; each part's line numbers count on from the lines before it.
        let mut lines_before = n_header_lines;
        for result in results {
            let part = Joined {
                diagnostics: result.diagnostics,
                n_data_lines: result.n_data_lines,
                row_times: result.row_times,
                recording: result.sparse,
            };
            part.join_into(&mut reader, lines_before);
            lines_before += result.n_lines;
        }
        Some(reader.finish(file_name))
    }

    /// A block of whole data lines (a chunk of a file read in chunks, as the page reads
    /// a dropped file) on every thread: each part into a reader of its own, joined in
    /// order into `reader` (samples appended, line numbers counted on), as
    /// [`read_raw`] joins a whole file's parts. `None` (nothing read) when the block is
    /// better read on one thread: small, on one thread, or without a time column.
    pub(super) fn read_lines_block(
        reader: &mut DelimitedReader,
        bytes: &[u8],
        n_lines_before: usize,
    ) -> Option<usize> {
        let n_threads = crate::par::n_threads();
        if bytes.len() < MIN_PARALLEL_BLOCK_BYTES || n_threads < 2 || reader.plan.time.is_none() {
            return None;
        }
        let header = reader.header.clone()?;
        let parts = cut_into_parts(bytes, n_threads);
        let results = crate::par::on_each_part(parts.iter(), |part| {
            let mut part_reader = part_reader(&header, Recording::default());
            // Numbered from 2, as in `read_raw`.
            let n_lines = part_reader.read_data_bytes(part, 1);
            (part_reader, n_lines)
        })?;
        let mut lines_before = n_lines_before;
        for (part_reader, n_lines) in results {
            let part = Joined {
                diagnostics: part_reader.diagnostics,
                n_data_lines: part_reader.n_data_lines,
                row_times: part_reader.row_times,
                recording: part_reader.recording,
            };
            part.join_into(reader, lines_before);
            lines_before += n_lines;
        }
        Some(lines_before - n_lines_before)
    }

    /// A reader of one part's data lines, under the file's header, writing into
    /// `recording`.
    fn part_reader<S>(header: &Header, recording: S) -> DelimitedReader<S> {
        DelimitedReader {
            header: Some(header.clone()),
            plan: Plan::of(header),
            row: vec![f64::NAN; header.columns.len()],
            recording,
            diagnostics: Diagnostics::default(),
            n_data_lines: 0,
            size_hint_bytes: None,
            mapping: None,
            problems: Vec::new(),
            row_times: RowTimes::default(),
            settings: Vec::new(),
            xyz_columns: None,
        }
    }

    /// What a part adds to the whole file's reader once it is read.
    struct Joined {
        diagnostics: Diagnostics,
        n_data_lines: usize,
        row_times: RowTimes,
        /// Samples to append (a whole file's parts: only their GNSS fixes and
        /// attitudes; the dense streams are in the shared columns already).
        recording: Recording,
    }

    impl Joined {
        /// Joins the part after the ones before it, its line numbers (counted from 2 in
        /// the part) counted on from the `lines_before` lines before it.
        fn join_into(self, reader: &mut DelimitedReader, lines_before: usize) {
            for diagnostic in self.diagnostics.kept {
                reader.diagnostics.push(
                    diagnostic.line.map(|line| line - 1 + lines_before),
                    diagnostic.message,
                );
            }
            reader.diagnostics.n_not_kept += self.diagnostics.n_not_kept;
            reader.n_data_lines += self.n_data_lines;
            reader.row_times = reader.row_times.then(self.row_times);
            reader.recording.append(self.recording);
        }
    }

    /// The data bytes cut into about `n_parts` parts that end just after a newline. A
    /// lone CR never ends a part, so every part starts a line, as when the file is read
    /// line by line.
    fn cut_into_parts(rest: &[u8], n_parts: usize) -> Vec<&[u8]> {
        let part_len = rest.len() / n_parts + 1;
        let mut parts: Vec<&[u8]> = Vec::with_capacity(n_parts);
        let mut start = 0usize;
        while start < rest.len() {
            let tentative = (start + part_len).min(rest.len());
            let end = match rest
                .get(tentative..)
                .and_then(|tail| memchr::memchr(b'\n', tail))
            {
                Some(newline) if tentative < rest.len() => tentative + newline + 1,
                _ => rest.len(),
            };
            parts.push(rest.get(start..end).unwrap_or_default());
            start = end;
        }
        parts
    }

    /// The lines of a part: a line ends at an LF, a CRLF or a lone CR, or at the end of
    /// the part. No stream gets more samples than this from the part.
    fn count_lines(part: &[u8]) -> usize {
        let n_endings = if memchr::memchr(b'\r', part).is_none() {
            memchr::memchr_iter(b'\n', part).count()
        } else {
            memchr::memchr2_iter(b'\n', b'\r', part)
                .filter(|&idx| part.get(idx) == Some(&b'\n') || part.get(idx + 1) != Some(&b'\n'))
                .count()
        };
        let ends_a_line = matches!(part.last(), Some(b'\n' | b'\r') | None);
        n_endings + usize::from(!ends_a_line)
    }

    /// What a part's reader leaves once its share is written.
    struct PartResult {
        /// Samples written in each column's share, in [`Columns`] order.
        lens: [usize; N_COLUMNS],
        overflowed: bool,
        /// The part's GNSS fixes and attitudes.
        sparse: Recording,
        diagnostics: Diagnostics,
        n_data_lines: usize,
        n_lines: usize,
        row_times: RowTimes,
    }

    impl PartResult {
        fn of(reader: DelimitedReader<Share<'_>>, n_lines: usize) -> PartResult {
            let share = reader.recording;
            let streams = [
                (share.acc.len, share.acc.overflowed),
                (share.gyro.len, share.gyro.overflowed),
                (share.mag.len, share.mag.overflowed),
                (share.temp.len, share.temp.overflowed),
                (share.pressure.len, share.pressure.overflowed),
                (share.ref_heading.len, share.ref_heading.overflowed),
                (share.ref_position.len, share.ref_position.overflowed),
            ];
            PartResult {
                lens: streams.map(|(len, _)| len),
                overflowed: streams.iter().any(|(_, overflowed)| *overflowed),
                sparse: Recording {
                    gnss: share.gnss,
                    attitude: share.attitude,
                    ..Recording::default()
                },
                diagnostics: reader.diagnostics,
                n_data_lines: reader.n_data_lines,
                n_lines,
                row_times: reader.row_times,
            }
        }
    }

    /// The dense streams, in the order of [`PartResult::lens`].
    const N_COLUMNS: usize = 7;

    /// The dense streams' vectors for the whole file, empty, with room for every part.
    struct Columns {
        acc: Stream<Vector3<f64>>,
        gyro: Stream<Vector3<f64>>,
        mag: Stream<Vector3<f64>>,
        temp: Stream<f64>,
        pressure: Stream<f64>,
        ref_heading: Stream<f64>,
        ref_position: Stream<Vector2<f64>>,
    }

    impl Columns {
        fn new(filled: FilledStreams, n_rows: usize) -> Columns {
            fn stream<T>(filled: bool, n_rows: usize) -> Stream<T> {
                let n_rows = if filled { n_rows } else { 0 };
                Stream {
                    t_s: Vec::with_capacity(n_rows),
                    values: Vec::with_capacity(n_rows),
                }
            }
            Columns {
                acc: stream(filled.acc, n_rows),
                gyro: stream(filled.gyro, n_rows),
                mag: stream(filled.mag, n_rows),
                temp: stream(filled.temp, n_rows),
                pressure: stream(filled.pressure, n_rows),
                ref_heading: stream(filled.ref_heading, n_rows),
                ref_position: stream(filled.ref_position, n_rows),
            }
        }

        /// One share of every column per part, of `max_rows[part_idx]` samples (fewer
        /// where a column has less room: a stream the plan does not fill has none).
        fn shares(&mut self, max_rows: &[usize]) -> Vec<Share<'_>> {
            let mut acc = ShareRoom::of(&mut self.acc);
            let mut gyro = ShareRoom::of(&mut self.gyro);
            let mut mag = ShareRoom::of(&mut self.mag);
            let mut temp = ShareRoom::of(&mut self.temp);
            let mut pressure = ShareRoom::of(&mut self.pressure);
            let mut ref_heading = ShareRoom::of(&mut self.ref_heading);
            let mut ref_position = ShareRoom::of(&mut self.ref_position);
            max_rows
                .iter()
                .map(|&size| Share {
                    acc: acc.next_share(size),
                    gyro: gyro.next_share(size),
                    mag: mag.next_share(size),
                    temp: temp.next_share(size),
                    pressure: pressure.next_share(size),
                    ref_heading: ref_heading.next_share(size),
                    ref_position: ref_position.next_share(size),
                    gnss: Stream::default(),
                    attitude: Stream::default(),
                })
                .collect()
        }

        /// Closes up the shares (part after part, each with `share_lens[part_idx]`
        /// samples written at its start) and moves the columns into `recording`.
        fn close_up(
            self,
            max_rows: &[usize],
            share_lens: &[[usize; N_COLUMNS]],
            recording: &mut Recording,
        ) {
            let lens_of = |column_idx: usize| -> Vec<usize> {
                share_lens
                    .iter()
                    .map(|lens| lens.get(column_idx).copied().unwrap_or(0))
                    .collect()
            };
            let Columns {
                mut acc,
                mut gyro,
                mut mag,
                mut temp,
                mut pressure,
                mut ref_heading,
                mut ref_position,
            } = self;
            close_up_stream(&mut acc, max_rows, &lens_of(0));
            close_up_stream(&mut gyro, max_rows, &lens_of(1));
            close_up_stream(&mut mag, max_rows, &lens_of(2));
            close_up_stream(&mut temp, max_rows, &lens_of(3));
            close_up_stream(&mut pressure, max_rows, &lens_of(4));
            close_up_stream(&mut ref_heading, max_rows, &lens_of(5));
            close_up_stream(&mut ref_position, max_rows, &lens_of(6));
            recording.acc_in_body_mps2 = acc;
            recording.gyro_in_body_radps = gyro;
            recording.mag_in_body_ut = mag;
            recording.temp_c = temp;
            recording.pressure_hpa = pressure;
            recording.ref_heading_rad = ref_heading;
            recording.ref_position_en_m = ref_position;
        }
    }

    fn close_up_stream<T: Copy>(stream: &mut Stream<T>, max_rows: &[usize], lens: &[usize]) {
        close_up(&mut stream.t_s, max_rows, lens);
        close_up(&mut stream.values, max_rows, lens);
    }

    /// The unused room of a vector, handed out in consecutive shares.
    struct ShareRoom<'a, T> {
        t_s: &'a mut [MaybeUninit<f64>],
        values: &'a mut [MaybeUninit<T>],
    }

    impl<'a, T> ShareRoom<'a, T> {
        fn of(stream: &'a mut Stream<T>) -> Self {
            ShareRoom {
                t_s: stream.t_s.spare_capacity_mut(),
                values: stream.values.spare_capacity_mut(),
            }
        }

        /// The next `size` samples of room (fewer where the room runs out).
        fn next_share(&mut self, size: usize) -> ShareStream<'a, T> {
            let t_s = std::mem::take(&mut self.t_s);
            let (share_t_s, rest_t_s) = t_s.split_at_mut(size.min(t_s.len()));
            self.t_s = rest_t_s;
            let values = std::mem::take(&mut self.values);
            let (share_values, rest_values) = values.split_at_mut(size.min(values.len()));
            self.values = rest_values;
            ShareStream {
                t_s: share_t_s,
                values: share_values,
                len: 0,
                overflowed: false,
            }
        }
    }

    /// One part's share of a dense stream: samples are written from its start.
    struct ShareStream<'a, T> {
        t_s: &'a mut [MaybeUninit<f64>],
        values: &'a mut [MaybeUninit<T>],
        len: usize,
        /// A sample found no room (it cannot happen: a share has room for one sample per
        /// line; the file is then read on one thread rather than lose it).
        overflowed: bool,
    }

    impl<T> SampleSink<T> for ShareStream<'_, T> {
        #[inline(always)]
        fn push(&mut self, t_s: f64, value: T) {
            match (self.t_s.get_mut(self.len), self.values.get_mut(self.len)) {
                (Some(t_slot), Some(value_slot)) => {
                    t_slot.write(t_s);
                    value_slot.write(value);
                    self.len += 1;
                }
                _ => self.overflowed = true,
            }
        }
    }

    /// One part's shares of every dense stream, and its own sparse streams.
    struct Share<'a> {
        acc: ShareStream<'a, Vector3<f64>>,
        gyro: ShareStream<'a, Vector3<f64>>,
        mag: ShareStream<'a, Vector3<f64>>,
        temp: ShareStream<'a, f64>,
        pressure: ShareStream<'a, f64>,
        ref_heading: ShareStream<'a, f64>,
        ref_position: ShareStream<'a, Vector2<f64>>,
        gnss: Stream<GnssFix>,
        attitude: Stream<Attitude>,
    }

    impl<'a> SampleSinks for Share<'a> {
        type Vector = ShareStream<'a, Vector3<f64>>;
        type Scalar = ShareStream<'a, f64>;
        type Position = ShareStream<'a, Vector2<f64>>;

        #[inline(always)]
        fn targets(&mut self) -> Targets<'_, Self::Vector, Self::Scalar, Self::Position> {
            Targets {
                acc: &mut self.acc,
                gyro: &mut self.gyro,
                mag: &mut self.mag,
                temp: &mut self.temp,
                pressure: &mut self.pressure,
                ref_heading: &mut self.ref_heading,
                ref_position: &mut self.ref_position,
                gnss: &mut self.gnss,
                attitude: &mut self.attitude,
            }
        }

        /// The room was made for the whole file beforehand.
        fn reserve_rows(&mut self, _plan: &Plan, _n_rows: usize) {}
    }

    /// Closes up an empty vector whose unused room was handed out in consecutive shares
    /// of `max_rows[part_idx]` elements (fewer where the room ran out), each written at
    /// its start with `lens[part_idx]` elements: moves every share's elements down to
    /// follow the previous share's and sets the length to their total.
    fn close_up<T: Copy>(vec: &mut Vec<T>, max_rows: &[usize], lens: &[usize]) {
        if !vec.is_empty() {
            return;
        }
        let room = vec.spare_capacity_mut();
        let mut share_start = 0usize;
        let mut n_closed = 0usize;
        for (&max_rows, &len) in max_rows.iter().zip(lens) {
            let share_size = max_rows.min(room.len() - share_start);
            let len = len.min(share_size);
            if share_start != n_closed {
                room.copy_within(share_start..share_start + len, n_closed);
            }
            n_closed += len;
            share_start += share_size;
        }
        // SAFETY: `n_closed` ≤ capacity, and elements 0..n_closed are initialised: the
        // shares were consecutive slices of this room, of the sizes computed the same
        // way here as in `ShareRoom::next_share`, and each share's writer wrote its
        // first `len` slots (`ShareStream::push` counts only slots it wrote); each share's
        // written elements were just moved to follow the previous share's.
        unsafe { vec.set_len(n_closed) };
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        #[test]
        fn lines_are_counted_as_the_line_decoder_counts_them() {
            for text in [
                &b""[..],
                b"a",
                b"a\n",
                b"a\r\nb",
                b"a\rb\r",
                b"a\r\r\nb\n\n",
                b"\r\n\r\n",
            ] {
                let mut n_lines = 0;
                crate::io::lines::decode_all(text, MAX_LINE_BYTES, |_| n_lines += 1);
                assert_eq!(count_lines(text), n_lines, "{text:?}");
            }
        }

        #[test]
        fn shares_written_in_part_are_closed_up_in_order() {
            let max_rows = [4usize, 3, 5];
            let mut stream: Stream<f64> = Stream {
                t_s: Vec::with_capacity(12),
                values: Vec::with_capacity(12),
            };
            let mut room = ShareRoom::of(&mut stream);
            let mut shares: Vec<ShareStream<'_, f64>> =
                max_rows.iter().map(|&size| room.next_share(size)).collect();
            for (share_idx, (share, n_written)) in shares.iter_mut().zip([2, 3, 0]).enumerate() {
                for sample_idx in 0..n_written {
                    let t_s = (share_idx * 10 + sample_idx) as f64;
                    share.push(t_s, -t_s);
                }
            }
            // A share that is full refuses (and flags) a sample instead of spilling over.
            shares[1].push(99.0, -99.0);
            assert!(shares[1].overflowed && !shares[0].overflowed);
            let lens: Vec<usize> = shares.iter().map(|share| share.len).collect();
            close_up_stream(&mut stream, &max_rows, &lens);
            assert_eq!(stream.t_s, vec![0.0, 1.0, 10.0, 11.0, 12.0]);
            assert_eq!(stream.values, vec![-0.0, -1.0, -10.0, -11.0, -12.0]);
            // A column without room (a stream the plan does not fill) closes up empty.
            let mut empty: Stream<f64> = Stream::default();
            let mut room = ShareRoom::of(&mut empty);
            let mut share = room.next_share(4);
            share.push(1.0, 1.0);
            assert!(share.overflowed);
            close_up_stream(&mut empty, &max_rows, &[0, 0, 0]);
            assert!(empty.is_empty());
        }
    }
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

/// The delimited reader, line by line, for files read in chunks (see
/// [`super::lines::LineDecoder`]). Values go straight into the recording in the file's
/// units and are converted in place by [`DelimitedReader::finish`], so that memory holds
/// one copy of the samples. (The parallel reader's parts write into their share of
/// columns prepared for the whole file instead: `S`, see `SampleSinks`.)
pub struct DelimitedReader<S = Recording> {
    header: Option<Header>,
    plan: Plan,
    /// One value per field of the current line; NaN where the field is empty, unused or
    /// unreadable.
    row: Vec<f64>,
    recording: S,
    diagnostics: Diagnostics,
    n_data_lines: usize,
    size_hint_bytes: Option<usize>,
    mapping: Option<ColumnMapping>,
    /// The current line's problems (kept between lines for its room).
    problems: Vec<String>,
    row_times: RowTimes,
    /// `key,value` lines before the header (`Fs,50.00`), with their line numbers.
    settings: Vec<(usize, Setting)>,
    /// What bare x, y, z columns are, where the file's name told it.
    xyz_columns: Option<XyzColumns>,
}

/// A `key,value` line before the header, such as `Fs,50.00` or `Initialization time,60`:
/// a data logger's settings.
#[derive(Debug, Clone, PartialEq)]
struct Setting {
    key: String,
    value: f64,
    /// The line as written, for the notes.
    text: String,
}

impl Setting {
    /// The sample rate in Hz, where the key names one (`Fs`, `sample rate`, `ODR`, …)
    /// and the value is a plausible rate.
    fn sample_rate_hz(&self) -> Option<f64> {
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

/// How many settings lines the notes list.
const MAX_SETTINGS_NOTED: usize = 8;

/// The highest sample rate a settings line is believed to give.
const MAX_SAMPLE_RATE_HZ: f64 = 100_000.0;

/// A settings line (`key,value` before the header): two fields, a key with a letter that
/// names no column, and a number. `None` for any other line.
fn setting_of(text: &str, mapping: Option<&ColumnMapping>) -> Option<Setting> {
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
    (key.chars().any(|c| c.is_alphabetic()) && !names_a_column).then(|| Setting {
        key: key.to_string(),
        value,
        text: text.to_string(),
    })
}

/// Whether a line is only numbers (and so no header).
fn is_number_line(text: &str) -> bool {
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

/// What the x, y, z columns of a phone app's per-sensor file hold, told from its file
/// name (see `io::sensor_files`): that sensor, in Android device axes and the app's own
/// unit (m/s², rad/s, µT).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum XyzColumns {
    Accelerometer,
    Gyroscope,
    Magnetometer,
}

/// Whether the times of the rows read so far ever went back.
#[derive(Debug, Clone, Copy)]
struct RowTimes {
    first: Option<f64>,
    last: f64,
    went_back: bool,
}

impl Default for RowTimes {
    fn default() -> Self {
        RowTimes {
            first: None,
            last: f64::NEG_INFINITY,
            went_back: false,
        }
    }
}

impl RowTimes {
    #[inline(always)]
    fn record(&mut self, t_raw: f64) {
        self.went_back |= t_raw < self.last;
        self.last = t_raw;
        self.first.get_or_insert(t_raw);
    }

    /// Joins the rows that follow (another part of the file).
    #[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
    fn then(self, next: RowTimes) -> RowTimes {
        match next.first {
            None => self,
            Some(next_first) => RowTimes {
                first: self.first.or(next.first),
                last: next.last,
                went_back: self.went_back || next.went_back || next_first < self.last,
            },
        }
    }
}

/// Where each quantity sits in a data line, resolved once from the header.
#[derive(Debug, Default)]
struct Plan {
    time: Option<usize>,
    acc: Option<[usize; 3]>,
    gyro: Option<[usize; 3]>,
    mag: Option<[usize; 3]>,
    /// Indexed by `Quantity as usize` for the scalar quantities.
    /// (Boxed: readers are kept in an enum beside other formats' readers, and this is
    /// most of their size.)
    scalar: Box<[Option<usize>; N_QUANTITIES]>,
    /// Whether a field is used at all (unused fields are not parsed).
    used: Vec<bool>,
    /// Vector quantities whose header lacks an axis.
    incomplete: Vec<&'static str>,
}

impl Plan {
    fn filled_streams(&self) -> FilledStreams {
        let scalar = |quantity: Quantity| self.scalar[quantity as usize].is_some();
        FilledStreams {
            acc: self.acc.is_some(),
            gyro: self.gyro.is_some(),
            mag: self.mag.is_some(),
            temp: scalar(Quantity::Temp),
            pressure: scalar(Quantity::Pressure),
            ref_heading: scalar(Quantity::RefHeading),
            ref_position: scalar(Quantity::RefEast) && scalar(Quantity::RefNorth),
        }
    }

    fn of(header: &Header) -> Plan {
        let mut plan = Plan {
            time: header.time_field,
            used: vec![false; header.columns.len()],
            ..Plan::default()
        };
        let mut axes: [[Option<usize>; 3]; 3] = [[None; 3]; 3];
        for (field_idx, column) in header.columns.iter().enumerate() {
            let Some(column) = column else { continue };
            let vector_idx = match column.quantity {
                Quantity::Acc => Some(0),
                Quantity::Gyro => Some(1),
                Quantity::Mag => Some(2),
                _ => None,
            };
            match vector_idx {
                Some(vector_idx) => {
                    if let Some(slot) = axes
                        .get_mut(vector_idx)
                        .and_then(|axes| axes.get_mut(column.axis))
                    {
                        slot.get_or_insert(field_idx);
                    }
                }
                None if column.quantity != Quantity::Time => {
                    if let Some(slot) = plan.scalar.get_mut(column.quantity as usize) {
                        slot.get_or_insert(field_idx);
                    }
                }
                None => {}
            }
        }
        for (vector_idx, (name, found)) in ["accelerometer", "gyroscope", "magnetometer"]
            .iter()
            .zip(axes)
            .enumerate()
        {
            let complete = match found {
                [Some(x), Some(y), Some(z)] => Some([x, y, z]),
                [None, None, None] => None,
                _ => {
                    plan.incomplete.push(name);
                    None
                }
            };
            match vector_idx {
                0 => plan.acc = complete,
                1 => plan.gyro = complete,
                _ => plan.mag = complete,
            }
        }
        let vector_fields = [plan.acc, plan.gyro, plan.mag]
            .into_iter()
            .flatten()
            .flatten();
        let scalar_fields = plan.scalar.iter().flatten().copied();
        for field_idx in vector_fields.chain(scalar_fields).chain(plan.time) {
            if let Some(used) = plan.used.get_mut(field_idx) {
                *used = true;
            }
        }
        plan
    }
}

impl DelimitedReader {
    /// A reader; `size_hint_bytes` (the file's size, where known) lets it reserve room
    /// for the samples once instead of growing.
    pub fn new(size_hint_bytes: Option<usize>) -> Self {
        DelimitedReader {
            header: None,
            plan: Plan::default(),
            row: Vec::new(),
            recording: Recording::default(),
            diagnostics: Diagnostics::default(),
            n_data_lines: 0,
            size_hint_bytes,
            mapping: None,
            problems: Vec::new(),
            row_times: RowTimes::default(),
            settings: Vec::new(),
            xyz_columns: None,
        }
    }

    /// Reads the header through the user's mapping.
    pub fn with_mapping(mut self, mapping: Option<ColumnMapping>) -> Self {
        self.mapping = mapping;
        self
    }

    /// Reads bare `x`, `y`, `z` columns as this sensor, in Android device axes and the
    /// app's unit (a phone app's per-sensor file, told by its name).
    pub fn with_xyz_columns(mut self, xyz_columns: Option<XyzColumns>) -> Self {
        self.xyz_columns = xyz_columns;
        self
    }

    pub fn read_line(&mut self, line: &Line<'_>) {
        self.read_any_line(line);
    }

    /// Reads a block of whole data lines (after the header; the last may lack its
    /// ending) where they lie, numbered on from `n_lines_before`, as reading the file
    /// whole does; returns how many lines there were. For a file read in chunks
    /// ([`super::import::ChunkedImport`]), which keeps an unfinished line for the next.
    pub(crate) fn read_lines_block(&mut self, bytes: &[u8], n_lines_before: usize) -> usize {
        #[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
        if let Some(n_lines) = parallel::read_lines_block(self, bytes, n_lines_before) {
            return n_lines;
        }
        self.read_data_bytes(bytes, n_lines_before)
    }
}

// Every method here is private: the (private) bound is no part of the public interface.
#[allow(private_bounds)]
impl<S: SampleSinks> DelimitedReader<S> {
    fn read_any_line(&mut self, line: &Line<'_>) {
        if line.truncated {
            self.diagnostics.push(
                Some(line.number),
                format!("line longer than {MAX_LINE_BYTES} bytes; its end was ignored"),
            );
        }
        let text: &str = &line.text;
        // A byte-order mark can only start the file.
        let text = if line.number == 1 {
            text.trim_start_matches('\u{feff}')
        } else {
            text
        };
        let trimmed = text.trim_ascii();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            return;
        }
        match &self.header {
            None => {
                if let Some(setting) = setting_of(trimmed, self.mapping.as_ref()) {
                    self.settings.push((line.number, setting));
                    return;
                }
                let header = Header::of_first_line(
                    line.number,
                    trimmed,
                    self.mapping.as_ref(),
                    self.xyz_columns,
                );
                let headerless = header.headerless;
                self.plan = Plan::of(&header);
                self.row = vec![f64::NAN; header.columns.len()];
                self.header = Some(header);
                // Without a header line, the first line is data.
                if headerless {
                    self.n_data_lines += 1;
                    self.read_data_line(line.number, trimmed);
                }
            }
            Some(_) => {
                if self.n_data_lines == 0 {
                    self.reserve(trimmed.len() + 1);
                }
                self.n_data_lines += 1;
                self.read_data_line(line.number, trimmed);
            }
        }
    }

    /// Reserves room for the rows the file probably holds, judged from its size and the
    /// length of its first data line.
    fn reserve(&mut self, first_line_bytes: usize) {
        let Some(size_hint_bytes) = self.size_hint_bytes else {
            return;
        };
        let n_rows = size_hint_bytes / first_line_bytes.max(1)
            + size_hint_bytes / first_line_bytes.max(1) / 50
            + 16;
        self.recording.reserve_rows(&self.plan, n_rows);
    }

    /// Reads data lines (whole lines after the header; the last may lack its ending),
    /// numbered on from `n_lines_before`, and returns how many lines there were. Lines of
    /// plain numbers take [`DelimitedReader::read_line_fast`]; any other line (comments,
    /// blanks, quotes, padding, lone CRs, bad fields, too long) goes through the line
    /// decoder and [`DelimitedReader::read_line`], with the same line numbers and
    /// diagnostics as when the whole file is read that way.
    fn read_data_bytes(&mut self, bytes: &[u8], n_lines_before: usize) -> usize {
        let Some(delimiter) = self.header.as_ref().map(|header| header.delimiter as u8) else {
            return 0;
        };
        let mut line_start = 0usize;
        let mut n_lines = n_lines_before;
        while line_start < bytes.len() {
            if let Some(next_start) = self.read_line_fast(bytes, line_start, delimiter, n_lines + 1)
            {
                n_lines += 1;
                line_start = next_start;
                continue;
            }
            let line_end = bytes
                .get(line_start..)
                .and_then(|rest| memchr::memchr(b'\n', rest))
                .map_or(bytes.len(), |newline| line_start + newline + 1);
            let mut decoder = LineDecoder::continuing(MAX_LINE_BYTES, n_lines);
            decoder.feed(
                bytes.get(line_start..line_end).unwrap_or_default(),
                |line| self.read_any_line(&line),
            );
            if line_end == bytes.len() {
                decoder.finish(|line| self.read_any_line(&line));
            }
            n_lines = decoder.n_lines();
            line_start = line_end;
        }
        n_lines - n_lines_before
    }

    /// The data line at `bytes[line_start..]` when it is made of plain numbers and empty
    /// fields (unused fields may hold anything but a line ending), has no more fields
    /// than the header, no surrounding white space and an LF or CRLF ending: its values
    /// are recorded and the index after its ending returned. `None`, with nothing
    /// recorded, for every other line: [`DelimitedReader::read_line`] then reads it.
    /// For the lines it takes, the result is the same as `read_line`'s.
    #[inline(always)]
    fn read_line_fast(
        &mut self,
        bytes: &[u8],
        line_start: usize,
        delimiter: u8,
        line_number: usize,
    ) -> Option<usize> {
        let first = *bytes.get(line_start)?;
        if first.is_ascii_whitespace() || first == b'#' || delimiter == WHITESPACE as u8 {
            return None;
        }
        let mut pos = line_start;
        let mut n_fields = 0usize;
        let mut line_end = None;
        for (slot, &used) in self.row.iter_mut().zip(&self.plan.used) {
            n_fields += 1;
            *slot = f64::NAN;
            // An empty field (the next byte is the delimiter) needs no parse.
            if used && bytes.get(pos) != Some(&delimiter) {
                if let Some((value, end)) = parse_prefix_at(bytes, pos) {
                    *slot = value;
                    pos = end;
                }
            } else if !used {
                while let Some(&byte) = bytes.get(pos) {
                    if byte == delimiter || byte == b'\n' || byte == b'\r' {
                        break;
                    }
                    pos += 1;
                }
            }
            match bytes.get(pos) {
                Some(&byte) if byte == delimiter => pos += 1,
                Some(b'\n' | b'\r') => {
                    line_end = Some(pos);
                    break;
                }
                // Not a number, or the end of the input without a line ending.
                _ => return None,
            }
        }
        // `None` here: a delimiter after the last column (more fields than the header).
        let line_end = line_end?;
        let next_start = match bytes.get(line_end..)? {
            [b'\n', ..] => line_end + 1,
            [b'\r', b'\n', ..] => line_end + 2,
            _ => return None,
        };
        let last = *bytes.get(line_end.checked_sub(1)?)?;
        if last.is_ascii_whitespace() || line_end - line_start > MAX_LINE_BYTES {
            return None;
        }
        for slot in self.row.iter_mut().skip(n_fields) {
            *slot = f64::NAN;
        }
        if self.n_data_lines == 0 {
            self.reserve(line_end - line_start + 1);
        }
        self.n_data_lines += 1;
        self.record_row(line_number);
        Some(next_start)
    }

    fn read_data_line(&mut self, line_number: usize, text: &str) {
        let Some(header) = &self.header else { return };
        let delimiter = header.delimiter as u8;
        let mut problems = std::mem::take(&mut self.problems);
        self.row.fill(f64::NAN);
        if header.delimiter == WHITESPACE {
            let mut n_fields = 0usize;
            for (field_idx, field) in text.split_ascii_whitespace().enumerate() {
                n_fields += 1;
                if self.plan.used.get(field_idx).copied().unwrap_or(false) {
                    let is_time = self.plan.time == Some(field_idx);
                    read_field_slowly(
                        header,
                        is_time,
                        field_idx,
                        field,
                        &mut self.row,
                        &mut problems,
                    );
                }
            }
            if n_fields > header.columns.len() {
                problems.push(format!(
                    "{n_fields} fields where the first line (line {}) has {}; the extra fields \
                     were ignored",
                    header.line,
                    header.columns.len()
                ));
            }
            self.problems = problems;
            self.record_row(line_number);
            return;
        }
        let bytes = text.as_bytes();
        let mut field_start = 0usize;
        let mut n_fields = 0usize;
        loop {
            let field_idx = n_fields;
            n_fields += 1;
            let rest = bytes.get(field_start..).unwrap_or_default();
            let used = self.plan.used.get(field_idx).copied().unwrap_or(false);
            // The usual case in one pass: a plain number, then the delimiter or the end.
            let fast = if used {
                parse_prefix(rest).filter(|&(_, consumed)| {
                    rest.get(consumed).is_none_or(|&byte| byte == delimiter)
                })
            } else {
                None
            };
            let field_len = match fast {
                Some((value, consumed)) => {
                    if let Some(slot) = self.row.get_mut(field_idx) {
                        *slot = value;
                    }
                    consumed
                }
                None => {
                    let field_len = rest
                        .iter()
                        .position(|&byte| byte == delimiter)
                        .unwrap_or(rest.len());
                    if used && field_len > 0 {
                        let field = text.get(field_start..field_start + field_len).unwrap_or("");
                        let is_time = self.plan.time == Some(field_idx);
                        read_field_slowly(
                            header,
                            is_time,
                            field_idx,
                            field,
                            &mut self.row,
                            &mut problems,
                        );
                    }
                    field_len
                }
            };
            let field_end = field_start + field_len;
            if field_end >= bytes.len() {
                break;
            }
            field_start = field_end + 1;
        }
        if n_fields > header.columns.len() {
            problems.push(format!(
                "{n_fields} fields where the header (line {}) has {}; the extra fields were ignored",
                header.line,
                header.columns.len()
            ));
        }
        self.problems = problems;
        self.record_row(line_number);
    }

    /// Records the values of the line in `self.row` (NaN where a field is empty or
    /// unreadable) in their streams, with the line's problems (`self.problems`, then
    /// emptied) as one diagnostic.
    #[inline(always)]
    fn record_row(&mut self, line_number: usize) {
        let problems = &mut self.problems;
        let row = &self.row;
        let value_at = |field: Option<usize>| {
            field
                .and_then(|idx| row.get(idx).copied())
                .filter(|value| !value.is_nan())
        };
        let t_raw = match self.plan.time {
            Some(time_field) => match value_at(Some(time_field)) {
                Some(t_raw) => t_raw,
                None => {
                    problems.push("no time, so the line was skipped".to_string());
                    self.diagnostics
                        .push(Some(line_number), problems.join("; "));
                    problems.clear();
                    return;
                }
            },
            // Without a time column the sample number stands in for time.
            None => self.n_data_lines as f64 - 1.0,
        };
        self.row_times.record(t_raw);
        let plan = &self.plan;
        let targets = self.recording.targets();
        // One call per sensor rather than a loop, so that each is compiled for its stream.
        record_vector(row, plan.acc, targets.acc, t_raw, "accelerometer", problems);
        record_vector(row, plan.gyro, targets.gyro, t_raw, "gyroscope", problems);
        record_vector(row, plan.mag, targets.mag, t_raw, "magnetometer", problems);
        let scalar = |quantity: Quantity| value_at(plan.scalar[quantity as usize]);
        if let Some(temp) = scalar(Quantity::Temp) {
            targets.temp.push(t_raw, temp);
        }
        if let Some(pressure) = scalar(Quantity::Pressure) {
            targets.pressure.push(t_raw, pressure);
        }
        // A negative speed, course or accuracy is an "invalid" marker (phyphox: −1).
        let non_negative = |quantity: Quantity| scalar(quantity).filter(|value| *value >= 0.0);
        let fix = GnssFix {
            lat_deg: scalar(Quantity::Lat),
            lon_deg: scalar(Quantity::Lon),
            alt_m: scalar(Quantity::Alt),
            speed_mps: non_negative(Quantity::Speed),
            course_rad: non_negative(Quantity::Course),
            hacc_m: non_negative(Quantity::HorizontalAccuracy),
        };
        let GnssFix {
            lat_deg,
            lon_deg,
            alt_m,
            speed_mps,
            course_rad,
            hacc_m,
        } = fix;
        if [lat_deg, lon_deg, alt_m, speed_mps, course_rad, hacc_m]
            .iter()
            .any(Option::is_some)
        {
            targets.gnss.push(t_raw, fix);
        }
        if let (Some(roll), Some(pitch)) = (scalar(Quantity::Roll), scalar(Quantity::Pitch)) {
            targets.attitude.push(
                t_raw,
                Attitude {
                    roll_rad: roll,
                    pitch_rad: pitch,
                    yaw_rad: scalar(Quantity::Yaw),
                },
            );
        }
        if let Some(heading) = scalar(Quantity::RefHeading) {
            targets.ref_heading.push(t_raw, heading);
        }
        match (scalar(Quantity::RefEast), scalar(Quantity::RefNorth)) {
            (Some(east_m), Some(north_m)) => targets
                .ref_position
                .push(t_raw, Vector2::new(east_m, north_m)),
            (None, None) => {}
            _ => problems.push("reference position has only one of east and north".to_string()),
        }
        if !problems.is_empty() {
            self.diagnostics
                .push(Some(line_number), problems.join("; "));
            problems.clear();
        }
    }
}

impl DelimitedReader {
    /// Converts times and units in place and hands over the import, still in the file's
    /// axes.
    pub fn finish(mut self, file_name: &str) -> Result<RawImport, ImportError> {
        let file_name = file_name.to_string();
        let Some(header) = self.header.take() else {
            return Err(ImportError::NoHeader { file_name });
        };
        if header.columns.iter().all(Option::is_none) {
            if header.headerless {
                return Err(ImportError::NoHeaderLine {
                    file_name,
                    line: header.line,
                    n_columns: header.names.len(),
                });
            }
            return Err(ImportError::UnknownHeader {
                file_name,
                line: header.line,
                found: shorten(&header.names.join(", ")),
            });
        }
        let mut notes = Vec::new();
        if header.headerless {
            notes.push(format!(
                "no header line: the {} columns{} are named column 1 to column {} and read \
                 as the mapping says",
                header.names.len(),
                if header.delimiter == WHITESPACE {
                    ", split on white space,"
                } else {
                    ""
                },
                header.names.len()
            ));
        }
        // The first settings line that gives a sample rate times the samples when there is
        // no time column.
        let rate = self
            .settings
            .iter()
            .find_map(|(line, setting)| Some((*line, setting, setting.sample_rate_hz()?)));
        if !self.settings.is_empty() {
            let described: Vec<String> = self
                .settings
                .iter()
                .map(|(line, setting)| {
                    let role = match rate {
                        Some((rate_line, _, _)) if rate_line == *line => {
                            if header.time_field.is_none() {
                                "the sample rate in Hz, used for the times"
                            } else {
                                "a sample rate; the time column is used instead"
                            }
                        }
                        _ => "not used",
                    };
                    format!(
                        "{} = {} (line {line}: {role})",
                        shorten(&setting.key),
                        setting.value
                    )
                })
                .take(MAX_SETTINGS_NOTED)
                .collect();
            let more = self.settings.len().saturating_sub(MAX_SETTINGS_NOTED);
            notes.push(format!(
                "settings lines before the header: {}{}",
                described.join("; "),
                if more > 0 {
                    format!("; and {more} more")
                } else {
                    String::new()
                }
            ));
        }
        // Ignored columns and a missing time are facts about the file, not problems of a
        // line: they are notes.
        let unknown: Vec<&str> = header
            .names
            .iter()
            .zip(&header.columns)
            .filter(|(_, column)| column.is_none())
            .map(|(name, _)| name.as_str())
            .collect();
        if !unknown.is_empty() {
            notes.push(format!(
                "columns ignored (not recognised): {}",
                shorten(&unknown.join(", "))
            ));
        }
        for name in &self.plan.incomplete {
            notes.push(format!(
                "{name} columns ignored: the header lacks one of x, y, z"
            ));
        }
        if header.time_field.is_none() {
            notes.push(match rate {
                Some((line, setting, rate_hz)) => format!(
                    "no time column: the samples are spaced at {rate_hz} Hz, the rate on line \
                     {line} ({})",
                    shorten(&setting.text)
                ),
                None => "no time column: the sample number is used as time".to_string(),
            });
        }

        let scale_of = |quantity: Quantity| {
            // The time column used, where a file has several (`time` and
            // `seconds_elapsed`); the first of its quantity for the others.
            let time_column = header
                .time_field
                .and_then(|idx| header.columns.get(idx).copied().flatten())
                .filter(|_| quantity == Quantity::Time);
            time_column
                .or_else(|| {
                    header
                        .columns
                        .iter()
                        .flatten()
                        .find(|column| column.quantity == quantity)
                        .copied()
                })
                .and_then(|column| column.scale)
        };
        let recording = &mut self.recording;
        let time_scale = match (header.time_field, scale_of(Quantity::Time)) {
            // Sample numbers, at the rate the settings give.
            (None, _) => rate.map_or(1.0, |(_, _, rate_hz)| 1.0 / rate_hz),
            (Some(_), Some(scale)) => scale,
            (Some(_), None) => {
                let (scale, guess) = guess_time_scale(recording);
                if header.time_field.is_some() {
                    notes.push(format!("time unit guessed from the values: {guess}"));
                }
                scale
            }
        };
        // Absolute times (epoch seconds, from date-times or epoch counters) are made
        // relative to the first sample; times that already count from a start are kept,
        // so that times the user quotes from the file still mean the same.
        let first_raw = if self.row_times.went_back {
            first_time(recording)
        } else {
            first_time_of_sorted(recording)
        };
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
        // (t − 0) · 1 is t: the pass is skipped when it would change nothing.
        if t0_raw != 0.0 || time_scale != 1.0 {
            for_each_time(recording, |t| *t = (*t - t0_raw) * time_scale);
        }
        if t0_raw != 0.0 {
            recording.start_unix_s = Some(t0_raw * time_scale);
        }

        let (acc_scale, acc_note) = unit_or_guess(
            scale_of(Quantity::Acc),
            &recording.acc_in_body_mps2.values,
            guess_acc_scale,
        );
        let (gyro_scale, gyro_note) = unit_or_guess(
            scale_of(Quantity::Gyro),
            &recording.gyro_in_body_radps.values,
            guess_gyro_scale,
        );
        // The unit the field was written in, for calibrations exported in it.
        let mag_values = &recording.mag_in_body_ut.values;
        let (mag_unit, mag_note) = match scale_of(Quantity::Mag) {
            Some(scale) => (Some(mag_unit_of_scale(scale)), None),
            None if mag_values.is_empty() => (None, None),
            None => {
                let median = median_norm(mag_values);
                let (unit, description) = guess_mag_unit(median);
                (
                    Some(unit),
                    Some(format!(
                        "{description} (median magnitude {median:.3}); override the unit if \
                         this is wrong"
                    )),
                )
            }
        };
        let mag_scale = mag_unit.map_or(1.0, |unit| unit.factor());
        notes.extend([acc_note, gyro_note, mag_note].into_iter().flatten());
        for (stream, scale) in [
            (&mut recording.acc_in_body_mps2, acc_scale),
            (&mut recording.gyro_in_body_radps, gyro_scale),
            (&mut recording.mag_in_body_ut, mag_scale),
        ] {
            if scale != 1.0 {
                stream.values.iter_mut().for_each(|value| *value *= scale);
            }
        }
        for (stream, scale) in [
            (
                &mut recording.temp_c,
                scale_of(Quantity::Temp).unwrap_or(1.0),
            ),
            (
                &mut recording.pressure_hpa,
                scale_of(Quantity::Pressure).unwrap_or(1.0),
            ),
            (&mut recording.ref_heading_rad, DEG_TO_RAD),
        ] {
            if scale != 1.0 {
                stream.values.iter_mut().for_each(|value| *value *= scale);
            }
        }
        let course_scale = scale_of(Quantity::Course).unwrap_or(DEG_TO_RAD);
        for fix in &mut recording.gnss.values {
            fix.course_rad = fix.course_rad.map(|course| course * course_scale);
        }
        let angle_scale = scale_of(Quantity::Roll).unwrap_or(1.0);
        for attitude in &mut recording.attitude.values {
            attitude.roll_rad *= angle_scale;
            attitude.pitch_rad *= angle_scale;
            attitude.yaw_rad = attitude.yaw_rad.map(|yaw| yaw * angle_scale);
        }
        if !recording.attitude.is_empty() && header.axes == SensorAxes::AndroidDevice {
            // The app's orientation angles are in its own conventions, which are not
            // converted yet; they are kept out rather than passed on wrong.
            recording.attitude = Stream::default();
            notes.push("the app's roll/pitch/yaw columns were not used (their axis convention is the app's)".to_string());
        }
        // Every stream's times are some of the rows' times, in the rows' order: when
        // those never go back, no stream needs sorting (or the pass that looks).
        let n_out_of_order = if self.row_times.went_back {
            recording.sort_all_by_time()
        } else {
            0
        };
        if n_out_of_order > 0 {
            self.diagnostics.push(
                Some(header.line),
                format!(
                    "time goes backwards {n_out_of_order} times; the samples were sorted by time"
                ),
            );
        }
        shrink_all(recording);
        Ok(RawImport {
            report: ImportReport {
                file_name,
                format: FORMAT_NAME,
                recording: std::mem::take(recording),
                diagnostics: self.diagnostics,
                header: Some(HeaderInfo {
                    line: header.line,
                    columns: header.names,
                }),
                n_data_lines: self.n_data_lines,
                notes,
                // Set with the axes, by `RawImport::into_report`.
                mag_frame: None,
            },
            axes: header.axes,
            mag_unit,
        })
    }
}

/// A field that is not a plain number: quoted, padded, a date-time, non-finite or not a
/// number at all.
fn read_field_slowly(
    header: &Header,
    is_time: bool,
    field_idx: usize,
    field: &str,
    row: &mut [f64],
    problems: &mut Vec<String>,
) {
    match parse_f64(field).or_else(|| parse_field_slowly(field, is_time)) {
        Some(value) if value.is_finite() => {
            if let Some(slot) = row.get_mut(field_idx) {
                *slot = value;
            }
        }
        Some(_) => problems.push(format!(
            "{} is {}",
            field_name(header, field_idx),
            shorten(field.trim())
        )),
        None if field.trim().trim_matches('"').trim().is_empty() => {}
        None => problems.push(format!(
            "{} is not a number ({})",
            field_name(header, field_idx),
            shorten(field.trim())
        )),
    }
}

fn field_name(header: &Header, field_idx: usize) -> &str {
    header
        .names
        .get(field_idx)
        .map(String::as_str)
        .unwrap_or("?")
}

/// A field the fast parser did not take: quoted or padded numbers, and date-times in
/// the time column.
fn parse_field_slowly(field: &str, is_time: bool) -> Option<f64> {
    let field = field.trim().trim_matches('"').trim();
    if field.is_empty() {
        return None;
    }
    parse_f64(field).or_else(|| {
        if is_time {
            parse_datetime_s(field)
        } else {
            None
        }
    })
}

/// Records the vector in the row's `fields` (x, y, z), if the plan has them: a sample
/// when all three are there, a problem when only some are.
#[inline(always)]
fn record_vector(
    row: &[f64],
    fields: Option<[usize; 3]>,
    stream: &mut impl SampleSink<Vector3<f64>>,
    t_raw: f64,
    label: &str,
    problems: &mut Vec<String>,
) {
    let Some(fields) = fields else { return };
    let [x, y, z] = fields.map(|idx| row.get(idx).copied().filter(|value| !value.is_nan()));
    match (x, y, z) {
        (Some(x), Some(y), Some(z)) => stream.push(t_raw, Vector3::new(x, y, z)),
        (None, None, None) => {}
        _ => problems.push(format!(
            "{label} has only some of x, y, z; that sample was skipped"
        )),
    }
}

/// Where one stream's samples go.
trait SampleSink<T> {
    fn push(&mut self, t_s: f64, value: T);
}

impl<T> SampleSink<T> for Stream<T> {
    /// [`Stream::push`], always inlined into the hot loop.
    #[inline(always)]
    fn push(&mut self, t_s: f64, value: T) {
        self.t_s.push(t_s);
        self.values.push(value);
    }
}

/// The streams one row's samples go to.
struct Targets<'a, V, S, P> {
    acc: &'a mut V,
    gyro: &'a mut V,
    mag: &'a mut V,
    temp: &'a mut S,
    pressure: &'a mut S,
    ref_heading: &'a mut S,
    ref_position: &'a mut P,
    gnss: &'a mut Stream<GnssFix>,
    attitude: &'a mut Stream<Attitude>,
}

/// Where a reader's samples go: a recording, or (native, large files) one part's share
/// of columns prepared for the whole file.
trait SampleSinks {
    type Vector: SampleSink<Vector3<f64>>;
    type Scalar: SampleSink<f64>;
    type Position: SampleSink<Vector2<f64>>;

    fn targets(&mut self) -> Targets<'_, Self::Vector, Self::Scalar, Self::Position>;

    /// Makes room for `n_rows` samples in each stream the plan fills.
    fn reserve_rows(&mut self, plan: &Plan, n_rows: usize);
}

impl SampleSinks for Recording {
    type Vector = Stream<Vector3<f64>>;
    type Scalar = Stream<f64>;
    type Position = Stream<Vector2<f64>>;

    #[inline(always)]
    fn targets(&mut self) -> Targets<'_, Self::Vector, Self::Scalar, Self::Position> {
        Targets {
            acc: &mut self.acc_in_body_mps2,
            gyro: &mut self.gyro_in_body_radps,
            mag: &mut self.mag_in_body_ut,
            temp: &mut self.temp_c,
            pressure: &mut self.pressure_hpa,
            ref_heading: &mut self.ref_heading_rad,
            ref_position: &mut self.ref_position_en_m,
            gnss: &mut self.gnss,
            attitude: &mut self.attitude,
        }
    }

    fn reserve_rows(&mut self, plan: &Plan, n_rows: usize) {
        fn reserve<T>(stream: &mut Stream<T>, planned: bool, n_rows: usize) {
            if planned {
                stream.t_s.reserve_exact(n_rows);
                stream.values.reserve_exact(n_rows);
            }
        }
        let filled = plan.filled_streams();
        reserve(&mut self.acc_in_body_mps2, filled.acc, n_rows);
        reserve(&mut self.gyro_in_body_radps, filled.gyro, n_rows);
        reserve(&mut self.mag_in_body_ut, filled.mag, n_rows);
        reserve(&mut self.temp_c, filled.temp, n_rows);
        reserve(&mut self.pressure_hpa, filled.pressure, n_rows);
        reserve(&mut self.ref_heading_rad, filled.ref_heading, n_rows);
        reserve(&mut self.ref_position_en_m, filled.ref_position, n_rows);
    }
}

/// Which of the dense streams a plan fills (the ones room is made for).
#[derive(Debug, Clone, Copy)]
struct FilledStreams {
    acc: bool,
    gyro: bool,
    mag: bool,
    temp: bool,
    pressure: bool,
    ref_heading: bool,
    ref_position: bool,
}

/// Calls `f` on every sample time of every stream.
fn for_each_time(recording: &mut Recording, mut f: impl FnMut(&mut f64)) {
    for t_s in [
        &mut recording.acc_in_body_mps2.t_s,
        &mut recording.gyro_in_body_radps.t_s,
        &mut recording.mag_in_body_ut.t_s,
        &mut recording.temp_c.t_s,
        &mut recording.pressure_hpa.t_s,
        &mut recording.gnss.t_s,
        &mut recording.attitude.t_s,
        &mut recording.ref_heading_rad.t_s,
        &mut recording.ref_position_en_m.t_s,
    ] {
        t_s.iter_mut().for_each(&mut f);
    }
}

/// The earliest sample time of any stream, in the file's units.
fn first_time(recording: &mut Recording) -> f64 {
    let mut first = f64::INFINITY;
    for_each_time(recording, |t| first = first.min(*t));
    first
}

/// [`first_time`] of a recording whose streams are sorted by time: the earliest of their
/// first samples' times.
fn first_time_of_sorted(recording: &Recording) -> f64 {
    [
        recording.acc_in_body_mps2.t_s.first(),
        recording.gyro_in_body_radps.t_s.first(),
        recording.mag_in_body_ut.t_s.first(),
        recording.temp_c.t_s.first(),
        recording.pressure_hpa.t_s.first(),
        recording.gnss.t_s.first(),
        recording.attitude.t_s.first(),
        recording.ref_heading_rad.t_s.first(),
        recording.ref_position_en_m.t_s.first(),
    ]
    .into_iter()
    .flatten()
    .fold(f64::INFINITY, |first, &t| first.min(t))
}

/// Gives back the room reserved for rows the file did not have.
fn shrink_all(recording: &mut Recording) {
    fn shrink<T>(stream: &mut Stream<T>) {
        stream.t_s.shrink_to_fit();
        stream.values.shrink_to_fit();
    }
    shrink(&mut recording.acc_in_body_mps2);
    shrink(&mut recording.gyro_in_body_radps);
    shrink(&mut recording.mag_in_body_ut);
    shrink(&mut recording.temp_c);
    shrink(&mut recording.pressure_hpa);
    shrink(&mut recording.ref_heading_rad);
    shrink(&mut recording.ref_position_en_m);
}

/// Times beyond this many seconds (about three years) are taken as absolute (epoch).
const ABSOLUTE_TIME_S: f64 = 1e8;
const N_QUANTITIES: usize = Quantity::Pressure as usize + 1;
const DEG_TO_RAD: f64 = std::f64::consts::PI / 180.0;
/// Standard gravity (CGPM 1901), for accelerometers that report in g.
const STANDARD_GRAVITY_MPS2: f64 = 9.806_65;

/// The delimiter that stands for "runs of spaces and tabs" (a line with no comma, tab
/// or semicolon, split on white space).
const WHITESPACE: char = ' ';

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
fn split_fields(text: &str, delimiter: char) -> Vec<&str> {
    if delimiter == WHITESPACE {
        text.split_ascii_whitespace().collect()
    } else {
        text.split(delimiter).collect()
    }
}

/// The header line, resolved.
#[derive(Debug, Clone)]
struct Header {
    line: usize,
    delimiter: char,
    names: Vec<String>,
    columns: Vec<Option<Column>>,
    axes: SensorAxes,
    /// The time column, if any: a preferred one (seconds elapsed) wins over others.
    time_field: Option<usize>,
    /// The file has no header line: `line` is its first data line, and the columns are
    /// named "column 1", "column 2", ….
    headerless: bool,
}

impl Header {
    /// The header from the first line that is not a comment or a setting: the line
    /// itself, or, when it is only numbers, columns named "column 1", "column 2", …
    /// (the file has no header line, and that line is data).
    fn of_first_line(
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
                && compact.get(..1).and_then(sensor_of).is_some()
                && compact.get(1..).and_then(axis_of).is_some() =>
        {
            // "mx", "ax", "gz". `get` and not indexing: a two-byte name may be one
            // character ("À"), and slicing inside it would panic.
            let quantity = compact.get(..1).and_then(sensor_of)?;
            return Some((
                column(quantity, compact.get(1..).and_then(axis_of)?, scale),
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
    let median = median_norm(values);
    let (scale, description) = guess(median);
    (
        scale,
        Some(format!(
            "{description} (median magnitude {median:.3}); override the unit if this is wrong"
        )),
    )
}

/// The median magnitude of finite vectors (0 without any).
fn median_norm(values: &[Vector3<f64>]) -> f64 {
    let mut norms: Vec<f64> = values
        .iter()
        .map(|value| value.norm())
        .filter(|norm| norm.is_finite())
        .collect();
    norms.sort_by(f64::total_cmp);
    norms.get(norms.len() / 2).copied().unwrap_or(0.0)
}

/// Magnetometer unit from the median field magnitude. Earth's field is 25-65 µT; hard
/// iron can multiply a raw reading several times, so the bands are wide; between µT and
/// nT lie raw counts ([`RAW_COUNT_MAGNITUDES`]).
fn guess_mag_unit(median: f64) -> (MagUnit, &'static str) {
    if median < 1e-3 {
        (
            MagUnit::TESLA.guessed(),
            "magnetometer unit guessed as tesla",
        )
    } else if median < 5.0 {
        (
            MagUnit::GAUSS.guessed(),
            "magnetometer unit guessed as gauss",
        )
    } else if median < RAW_COUNT_MAGNITUDES.start {
        (
            MagUnit::MICROTESLA.guessed(),
            "magnetometer unit guessed as µT",
        )
    } else if RAW_COUNT_MAGNITUDES.contains(&median) {
        (
            MagUnit::COUNTS,
            "magnetometer values without a unit, far from the Earth's field in µT, gauss or \
             nT: read as raw counts, kept as they are (the µT per count is unknown, so field \
             strengths are in counts)",
        )
    } else {
        (
            MagUnit::NANOTESLA.guessed(),
            "magnetometer unit guessed as nT",
        )
    }
}

/// The magnetometer unit whose factor to µT is `scale` (one of [`unit_scale`]'s).
fn mag_unit_of_scale(scale: f64) -> MagUnit {
    [
        MagUnit::MICROTESLA,
        MagUnit::GAUSS,
        MagUnit::MILLIGAUSS,
        MagUnit::NANOTESLA,
        MagUnit::TESLA,
    ]
    .into_iter()
    .find(|unit| unit.ut_per_unit == Some(scale))
    .unwrap_or(MagUnit {
        name: "the log's unit",
        ut_per_unit: Some(scale),
        origin: crate::io::UnitOrigin::Stated,
    })
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
fn guess_time_scale(recording: &mut Recording) -> (f64, &'static str) {
    let mut largest = 0.0f64;
    for_each_time(recording, |t| {
        if t.is_finite() {
            largest = largest.max(t.abs());
        }
    });
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
    // The range checks above make the casts exact.
    let days = crate::civil::days_from_civil(year, month as u32, day as u32);
    Some(days as f64 * 86_400.0 + hours * 3600.0 + minutes * 60.0 + seconds - offset_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_text(text: &str) -> ImportReport {
        read("test.csv", text.as_bytes()).expect("readable")
    }

    #[test]
    fn a_two_byte_column_name_that_is_one_character_does_not_panic() {
        // Found by the arbitrary-bytes property test: "À" is two bytes, one character.
        for text in ["À,mx,my,mz\n1,2,3,4\n", "t_s,À\n0,1\n", "À\n1\n"] {
            let _ = read("accents.csv", text.as_bytes());
        }
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
        // The frame turns the file's own values into the body ones.
        let frame = report.mag_frame.expect("a magnetometer frame");
        assert_eq!(
            frame,
            SensorFrame::android_device(PhoneMount::Flat, MagUnit::MICROTESLA)
        );
        assert_eq!(
            frame.body_from_sensor * Vector3::new(18.0, 3.5, -35.0),
            mag.values[0]
        );
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
        assert_eq!(
            report.mag_frame,
            Some(SensorFrame::columns_as_body(MagUnit::GAUSS))
        );
    }

    #[test]
    fn missing_units_are_guessed_and_said() {
        let report = read_text("x,y,z\n0.2,0.1,-0.4\n0.25,0.1,-0.4\n");
        assert!((report.recording.mag_in_body_ut.values[0].x - 20.0).abs() < 1e-9);
        assert_eq!(
            report.mag_frame,
            Some(SensorFrame::columns_as_body(MagUnit::GAUSS.guessed()))
        );
        let microtesla = read_text("x,y,z\n20,10,-40\n");
        let frame = microtesla.mag_frame.expect("a frame");
        assert_eq!(frame.unit.label(), "assumed µT (the log gives no unit)");
        // No magnetometer, no frame.
        assert_eq!(
            read_text("t_s,acc_x_mps2,acc_y_mps2,acc_z_mps2\n0,0,0,-9.8\n").mag_frame,
            None
        );
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
    fn a_large_file_read_in_parts_equals_reading_it_line_by_line() {
        let rows = crate::sim::walk::simulate(&crate::sim::walk::WalkConfig::from_seed(4, 900.0));
        let mut text = crate::io::canonical_csv::write(&rows);
        // Bad lines scattered through the file keep their line numbers.
        text = text
            .lines()
            .enumerate()
            .map(|(idx, line)| {
                if idx % 9973 == 5 {
                    "1.0,oops,2,3".to_string()
                } else {
                    line.to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("\r\n");
        assert!(
            text.len() > 4 << 20,
            "large enough to be read in parts: {}",
            text.len()
        );
        let in_parts = read_raw("big.csv", text.as_bytes()).expect("readable");
        let mut reader = DelimitedReader::new(None);
        decode_all(text.as_bytes(), MAX_LINE_BYTES, |line| {
            reader.read_line(&line)
        });
        let line_by_line = reader.finish("big.csv").expect("readable");
        assert_eq!(in_parts, line_by_line);
        assert!(in_parts
            .report
            .diagnostics
            .kept
            .iter()
            .any(|diagnostic| diagnostic.line == Some(9979)));
    }

    /// Reads `bytes` line by line through [`DelimitedReader::read_line`] only, the
    /// reference the fast and parallel paths must equal.
    fn read_line_by_line(bytes: &[u8]) -> Result<RawImport, ImportError> {
        let mut reader = DelimitedReader::new(None);
        decode_all(bytes, MAX_LINE_BYTES, |line| reader.read_line(&line));
        reader.finish("f.csv")
    }

    /// Data lines the fast path takes and lines it must hand to the general path, with
    /// the same result.
    const TRICKY_LINES: &[&[u8]] = &[
        b"0.5,1.25,-2.5,40.125,unused,12.5",
        b"1,2,3,4,,5",
        b"1.5,-9.6864,0.00058,33.259,x,359.999",
        b"2,1e1,2E-1,3.5e+2,,1",
        b"2.5,,,,,",
        b"3,1,2,,,",
        b",1,2,3,,4",
        b" 4,1,2,3,,4",
        b"4.5,1,2,3,,4 ",
        b"5,1,2,3,,4,extra",
        b"5.5,1,2,3,,4,",
        b"6,\"7\",8,9,,10",
        b"6.5,abc,8,9,,10",
        b"7,NaN,8,9,,10",
        b"7.5,1e400,8,9,,10",
        b"8,1,2,3,\xff\xfe,4",
        b"8.5,1\xff,2,3,,4",
        b"\xef\xbb\xbf9,1,2,3,,4",
        b"# a comment",
        b"",
        b"   ",
        b"1.0,2,3,4,,5\t",
        b"0.25,12345678.5,1.123456789,99999999,,7",
        b"10,123456789012345678901,2,3,,4",
        b"10.5,-,.,-.,,+",
        b"11,+1.5,-0,0.000,,.5",
    ];

    #[test]
    fn the_fast_path_reads_every_line_as_the_general_path_does() {
        let header: &[u8] = b"t_s,mag_x_ut,mag_y_ut,mag_z_ut,colour,ref_heading_deg";
        let endings: [&[u8]; 4] = [b"\n", b"\r\n", b"\r", b"\r\r\n"];
        let mut state: u64 = 0x853C_49E6_748F_EA9B;
        let mut next = |bound: usize| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) as usize % bound
        };
        let mut long_line = b"12,1,2,3,".to_vec();
        long_line.resize(MAX_LINE_BYTES + 10, b'z');
        for case_idx in 0..400 {
            let mut text = header.to_vec();
            text.extend_from_slice(endings[next(2)]);
            for _ in 0..next(30) {
                let line: &[u8] = if next(50) == 0 {
                    &long_line
                } else {
                    TRICKY_LINES[next(TRICKY_LINES.len())]
                };
                text.extend_from_slice(line);
                // Mostly LF or CRLF, sometimes a lone CR or CR CR LF.
                text.extend_from_slice(endings[if next(5) == 0 { 2 + next(2) } else { next(2) }]);
            }
            if next(3) == 0 {
                // No line ending after the last line.
                text.extend_from_slice(TRICKY_LINES[next(TRICKY_LINES.len())]);
            }
            let fast = read_raw("f.csv", &text);
            let reference = read_line_by_line(&text);
            assert_eq!(
                fast,
                reference,
                "case {case_idx}: {:?}",
                String::from_utf8_lossy(&text)
            );
        }
    }

    /// About 5 MiB of data lines with a tricky line after a lone CR every 10,007 rows.
    fn large_text_with_every_kind_of_line() -> Vec<u8> {
        let header: &[u8] = b"t_s,mag_x_ut,mag_y_ut,mag_z_ut,colour,ref_heading_deg\n";
        let mut text = header.to_vec();
        let mut row_idx = 0usize;
        while text.len() < 5 << 20 {
            row_idx += 1;
            let line = format!(
                "{}.{:03},{}.5,-{},0.{},red,{}",
                row_idx / 50,
                row_idx % 1000,
                row_idx % 97,
                row_idx % 13,
                row_idx % 7,
                row_idx % 360
            );
            text.extend_from_slice(line.as_bytes());
            if row_idx.is_multiple_of(10_007) {
                let tricky = TRICKY_LINES[(row_idx / 10_007) % TRICKY_LINES.len()];
                text.extend_from_slice(b"\r");
                text.extend_from_slice(tricky);
            }
            text.extend_from_slice(if row_idx.is_multiple_of(3) {
                b"\r\n"
            } else {
                b"\n"
            });
        }
        text
    }

    #[test]
    fn a_large_file_with_every_kind_of_line_read_in_parts_equals_line_by_line() {
        let text = large_text_with_every_kind_of_line();
        let in_parts = read_raw("f.csv", &text).expect("readable");
        let line_by_line = read_line_by_line(&text).expect("readable");
        assert!(!line_by_line.report.diagnostics.is_empty());
        assert_eq!(in_parts, line_by_line);
    }

    #[test]
    fn large_blocks_read_in_parts_equal_line_by_line() {
        let text = large_text_with_every_kind_of_line();
        let (mut reader, data_offset, n_header_lines) =
            read_up_to_header(&text, None, None).expect("a header");
        // Blocks of whole lines, as a file read in chunks gives them: the first two
        // large enough to be read in parts, the rest whole.
        let data = text.get(data_offset..).expect("data");
        let mut n_lines = n_header_lines;
        let mut start = 0usize;
        for block_bytes in [3 << 20, 1_200_000, 1 << 30] {
            let tentative = (start + block_bytes).min(data.len());
            let end = data
                .get(tentative..)
                .and_then(|tail| memchr::memchr(b'\n', tail))
                .map_or(data.len(), |newline| tentative + newline + 1);
            n_lines += reader.read_lines_block(data.get(start..end).expect("a block"), n_lines);
            start = end;
        }
        let in_blocks = reader.finish("f.csv").expect("readable");
        let line_by_line = read_line_by_line(&text).expect("readable");
        assert!(!line_by_line.report.diagnostics.is_empty());
        assert_eq!(in_blocks, line_by_line);
    }

    #[test]
    fn the_first_time_of_sorted_streams_is_the_earliest_first_sample() {
        let mut recording = Recording::default();
        recording.mag_in_body_ut.push(5.0, Vector3::zeros());
        recording.mag_in_body_ut.push(9.0, Vector3::zeros());
        recording.ref_heading_rad.push(3.5, 0.0);
        recording.gnss.push(4.0, GnssFix::default());
        assert_eq!(first_time_of_sorted(&recording), 3.5);
        assert_eq!(first_time(&mut recording), 3.5);
        assert_eq!(first_time_of_sorted(&Recording::default()), f64::INFINITY);
    }

    #[test]
    fn a_mapping_renames_columns_and_every_offered_target_is_valid() {
        for (target, _) in MAPPING_TARGETS {
            assert!(
                ColumnMapping::parse(&format!("c={target}")).is_ok(),
                "{target}"
            );
        }
        let mapping = ColumnMapping::parse(
            "ch1=mag_x_gauss, ch2=mag_y_gauss ,ch3=mag_z_gauss,when=t_ms,junk=ignore",
        )
        .expect("valid");
        let mut reader = DelimitedReader::new(None).with_mapping(Some(mapping));
        decode_all(
            b"when;ch1;ch2;ch3;junk\n1000;0.2;0.1;-0.4;7\n",
            MAX_LINE_BYTES,
            |line| reader.read_line(&line),
        );
        let report = reader.finish("m.csv").expect("readable").into_report();
        let mag = &report.recording.mag_in_body_ut;
        assert_eq!(mag.t_s, vec![1.0]);
        assert!((mag.values[0] - Vector3::new(20.0, 10.0, -40.0)).norm() < 1e-9);
        assert!(matches!(
            ColumnMapping::parse("x"),
            Err(MappingError::NotAnAssignment { .. })
        ));
        assert!(matches!(
            ColumnMapping::parse("x=mag"),
            Err(MappingError::UnknownTarget { .. })
        ));
    }

    #[test]
    fn suggestions_and_previews_for_the_mapping_dialog() {
        assert_eq!(suggested_target("mag_x_gauss"), "mag_x_gauss");
        assert_eq!(suggested_target("Time (s)"), "t_s");
        assert_eq!(suggested_target("ch1"), "ignore");
        let preview = preview(&["# a comment", "t;ch1;ch2", "0.5;1.25"]).expect("a header");
        assert_eq!(preview.columns, vec!["t", "ch1", "ch2"]);
        assert_eq!(preview.first_values, vec!["0.5", "1.25", ""]);
    }

    #[test]
    fn settings_lines_before_the_header_give_the_rate_and_raw_counts_are_counts() {
        let text = "Fs,50.00\nInitialization time,60\nmx,my,mz\n6202,682,4812\n6177,682,4827\n6190,690,4800\n";
        let report = read_text(text);
        assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);
        let mag = &report.recording.mag_in_body_ut;
        assert_eq!(mag.t_s, vec![0.0, 0.02, 0.04]);
        // Kept as they are, in counts.
        assert_eq!(mag.values[0], Vector3::new(6202.0, 682.0, 4812.0));
        assert_eq!(
            report.mag_frame,
            Some(SensorFrame::columns_as_body(MagUnit::COUNTS))
        );
        let notes = report.notes.join("\n");
        for expected in [
            "Fs = 50 (line 1: the sample rate in Hz, used for the times)",
            "Initialization time = 60 (line 2: not used)",
            "no time column: the samples are spaced at 50 Hz, the rate on line 1 (Fs,50.00)",
            "read as raw counts",
        ] {
            assert!(notes.contains(expected), "{expected}\n{notes}");
        }
        assert!(looks_like(&[
            "Fs,50.00",
            "Initialization time,60",
            "mx,my,mz",
            "1,2,3"
        ]));
        assert_eq!(
            header_columns(&["Fs,50.00", "mx,my,mz"]),
            Some(vec!["mx".to_string(), "my".to_string(), "mz".to_string()])
        );
        // With a time column, the rate is only noted.
        let timed = read_text("rate,100\nt_s,mx,my,mz\n0,20,0,-40\n0.5,21,0,-40\n");
        assert_eq!(timed.recording.mag_in_body_ut.t_s, vec![0.0, 0.5]);
        assert!(timed
            .notes
            .iter()
            .any(|note| note.contains("the time column is used instead")));
        // The guess's bands: µT below 1000, counts to 20,000, nT above.
        assert_eq!(guess_mag_unit(600.0).0, MagUnit::MICROTESLA.guessed());
        assert_eq!(guess_mag_unit(7000.0).0, MagUnit::COUNTS);
        assert_eq!(guess_mag_unit(48_000.0).0, MagUnit::NANOTESLA.guessed());
    }

    #[test]
    fn numbers_without_a_header_line_are_split_on_white_space_and_read_through_a_mapping() {
        let text = "0.50 35.7 -71.3 375.9\n0.52   35.8\t-71.4 375.8\n0.54 oops -71.4 375.8\n";
        let sample: Vec<&str> = text.lines().collect();
        assert!(!looks_like(&sample));
        assert!(looks_headerless(&sample));
        assert_eq!(header_columns(&sample), None);
        let shown = preview(&sample).expect("a preview");
        assert_eq!(
            shown.columns,
            vec!["column 1", "column 2", "column 3", "column 4"]
        );
        assert_eq!(shown.first_values, vec!["0.50", "35.7", "-71.3", "375.9"]);
        // Without a mapping: the error says there is no header line.
        assert!(matches!(
            read("m.txt", text.as_bytes()),
            Err(ImportError::NoHeaderLine {
                n_columns: 4,
                line: 1,
                ..
            })
        ));
        let mapping = ColumnMapping::parse(
            "column 1=t_s,column 2=mag_x_ut,column 3=mag_y_ut,column 4=mag_z_ut",
        )
        .expect("valid");
        let report = read_raw_mapped("m.txt", text.as_bytes(), Some(&mapping))
            .expect("readable")
            .into_report();
        let mag = &report.recording.mag_in_body_ut;
        assert_eq!(mag.t_s, vec![0.5, 0.52]);
        assert_eq!(mag.values[1], Vector3::new(35.8, -71.4, 375.8));
        assert!(report
            .diagnostics
            .kept
            .iter()
            .any(|diagnostic| diagnostic.line == Some(3)));
        assert!(report
            .notes
            .iter()
            .any(|note| note.contains("no header line")));
        // A header split on white space.
        let spaced = read_text("t_s mag_x_ut mag_y_ut mag_z_ut\n0 1 2 3\n1 1 2 4\n");
        assert_eq!(spaced.recording.mag_in_body_ut.len(), 2);
        assert!(!looks_like(&["x 1.5"]));
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
