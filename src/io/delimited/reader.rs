//! The delimited reader's pass over the data lines ([`super`]): each line split into
//! fields once, plain numbers parsed in place ([`crate::io::number`]), quoted or padded
//! fields and ISO 8601 date-times in the time column the slow way, and each row's
//! samples recorded in the file's units (converted at the end, in `finish.rs`).

use nalgebra::{Vector2, Vector3};

use super::header::{setting_of, Header, Quantity, Setting, N_QUANTITIES, WHITESPACE};
#[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
use super::parallel;
use super::sinks::{FilledStreams, SampleSink, SampleSinks};
use super::{ColumnMapping, XyzColumns, MAX_LINE_BYTES};
use crate::io::lines::{Line, LineDecoder};
use crate::io::number::{parse_f64, parse_prefix, parse_prefix_at};
use crate::io::recording::{Attitude, GnssFix, Recording};
use crate::io::{shorten, Diagnostics};

/// The delimited reader, line by line, for files read in chunks (see
/// [`crate::io::lines::LineDecoder`]). Values go straight into the recording in the file's
/// units and are converted in place by [`DelimitedReader::finish`], so that memory holds
/// one copy of the samples. (The parallel reader's parts write into their share of
/// columns prepared for the whole file instead: `S`, see `SampleSinks`.)
pub struct DelimitedReader<S = Recording> {
    pub(super) header: Option<Header>,
    pub(super) plan: Plan,
    /// One value per field of the current line; NaN where the field is empty, unused or
    /// unreadable.
    pub(super) row: Vec<f64>,
    pub(super) recording: S,
    pub(super) diagnostics: Diagnostics,
    pub(super) n_data_lines: usize,
    pub(super) size_hint_bytes: Option<usize>,
    pub(super) mapping: Option<ColumnMapping>,
    /// The current line's problems (kept between lines for its room).
    pub(super) problems: Vec<String>,
    pub(super) row_times: RowTimes,
    /// `key,value` lines before the header (`Fs,50.00`), with their line numbers.
    pub(super) settings: Vec<(usize, Setting)>,
    /// What bare x, y, z columns are, where the file's name told it.
    pub(super) xyz_columns: Option<XyzColumns>,
}

/// Whether the times of the rows read so far ever went back.
#[derive(Debug, Clone, Copy)]
pub(super) struct RowTimes {
    first: Option<f64>,
    last: f64,
    pub(super) went_back: bool,
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
    pub(super) fn then(self, next: RowTimes) -> RowTimes {
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
pub(super) struct Plan {
    pub(super) time: Option<usize>,
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
    pub(super) incomplete: Vec<&'static str>,
}

impl Plan {
    pub(super) fn filled_streams(&self) -> FilledStreams {
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

    pub(super) fn of(header: &Header) -> Plan {
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
    /// ([`crate::io::import::ChunkedImport`]), which keeps an unfinished line for the next.
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
    pub(super) fn read_data_bytes(&mut self, bytes: &[u8], n_lines_before: usize) -> usize {
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
        read_fields(header, &self.plan, &mut self.row, &mut self.problems, text);
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

/// The fields of a data line read the slow way (any line [`DelimitedReader::read_line_fast`]
/// does not take) into `row` (NaN where a field is empty or unreadable), with what is
/// wrong with them added to `problems`. Not generic over the reader's sinks, so that
/// the readers of whole files and of a part's share (`parallel`) share one copy.
fn read_fields(
    header: &Header,
    plan: &Plan,
    row: &mut [f64],
    problems: &mut Vec<String>,
    text: &str,
) {
    let delimiter = header.delimiter as u8;
    row.fill(f64::NAN);
    if header.delimiter == WHITESPACE {
        let mut n_fields = 0usize;
        for (field_idx, field) in text.split_ascii_whitespace().enumerate() {
            n_fields += 1;
            if plan.used.get(field_idx).copied().unwrap_or(false) {
                let is_time = plan.time == Some(field_idx);
                read_field_slowly(header, is_time, field_idx, field, row, problems);
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
        return;
    }
    let bytes = text.as_bytes();
    let mut field_start = 0usize;
    let mut n_fields = 0usize;
    loop {
        let field_idx = n_fields;
        n_fields += 1;
        let rest = bytes.get(field_start..).unwrap_or_default();
        let used = plan.used.get(field_idx).copied().unwrap_or(false);
        // The usual case in one pass: a plain number, then the delimiter or the end.
        let fast = if used {
            parse_prefix(rest)
                .filter(|&(_, consumed)| rest.get(consumed).is_none_or(|&byte| byte == delimiter))
        } else {
            None
        };
        let field_len = match fast {
            Some((value, consumed)) => {
                if let Some(slot) = row.get_mut(field_idx) {
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
                    let is_time = plan.time == Some(field_idx);
                    read_field_slowly(header, is_time, field_idx, field, row, problems);
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
    header.names.get(field_idx).map_or("?", String::as_str)
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
    let Some([x_field, y_field, z_field]) = fields else {
        return;
    };
    // Field by field rather than `fields.map(…)`, which stayed a call per row (4 % of
    // reading a 100 MB CSV, `perf record`).
    let value = |idx: usize| row.get(idx).copied().filter(|value| !value.is_nan());
    match (value(x_field), value(y_field), value(z_field)) {
        (Some(x), Some(y), Some(z)) => stream.push(t_raw, Vector3::new(x, y, z)),
        (None, None, None) => {}
        _ => problems.push(format!(
            "{label} has only some of x, y, z; that sample was skipped"
        )),
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
    let days = crate::base::calendar::days_from_civil(year, month as u32, day as u32);
    Some(days as f64 * 86_400.0 + hours * 3600.0 + minutes * 60.0 + seconds - offset_s)
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
