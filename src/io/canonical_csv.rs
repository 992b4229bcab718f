//! The canonical CSV: this tool's own format, read and written.
//!
//! ```text
//! t_s,acc_x_mps2,acc_y_mps2,acc_z_mps2,gyro_x_radps,gyro_y_radps,gyro_z_radps,
//! mag_x_ut,mag_y_ut,mag_z_ut,temp_c,lat_deg,lon_deg,gps_speed_mps,gps_course_deg,
//! gps_hacc_m,ref_heading_deg,ref_e_m,ref_n_m
//! ```
//!
//! Header names carry their units. Any column may be absent or empty; unknown columns
//! are ignored (and listed once). Body axes are x forward, y right, z down; headings and
//! courses are degrees clockwise from true north; the accelerometer gives specific force
//! (a level device at rest reads `acc_z_mps2 ≈ −9.81`). Comma, tab or semicolon
//! separate the fields; lines starting with `#` are comments. Degrees become radians
//! here, once.

use std::fmt::Write as _;

use nalgebra::{Vector2, Vector3};

use super::lines::decode_all;
use super::{first_binary_offset, Diagnostics, HeaderInfo, ImportError, ImportReport};
use crate::recording::{GnssFix, Recording};

pub const FORMAT_NAME: &str = "canonical CSV";

/// The canonical columns, in the order the writer uses.
pub const COLUMNS: [&str; 19] = [
    "t_s",
    "acc_x_mps2",
    "acc_y_mps2",
    "acc_z_mps2",
    "gyro_x_radps",
    "gyro_y_radps",
    "gyro_z_radps",
    "mag_x_ut",
    "mag_y_ut",
    "mag_z_ut",
    "temp_c",
    "lat_deg",
    "lon_deg",
    "gps_speed_mps",
    "gps_course_deg",
    "gps_hacc_m",
    "ref_heading_deg",
    "ref_e_m",
    "ref_n_m",
];

/// Lines longer than this are cut (a canonical row is under 300 bytes).
const MAX_LINE_BYTES: usize = 64 * 1024;

/// The position of each canonical column in [`COLUMNS`].
mod col {
    pub const T: usize = 0;
    pub const ACC: usize = 1;
    pub const GYRO: usize = 4;
    pub const MAG: usize = 7;
    pub const TEMP: usize = 10;
    pub const LAT: usize = 11;
    pub const LON: usize = 12;
    pub const SPEED: usize = 13;
    pub const COURSE: usize = 14;
    pub const HACC: usize = 15;
    pub const REF_HEADING: usize = 16;
    pub const REF_E: usize = 17;
    pub const REF_N: usize = 18;
}

/// One row of the canonical CSV, in its own units (degrees at this edge).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CanonicalRow {
    pub t_s: f64,
    pub acc_mps2: Option<Vector3<f64>>,
    pub gyro_radps: Option<Vector3<f64>>,
    pub mag_ut: Option<Vector3<f64>>,
    pub temp_c: Option<f64>,
    pub lat_deg: Option<f64>,
    pub lon_deg: Option<f64>,
    pub gps_speed_mps: Option<f64>,
    pub gps_course_deg: Option<f64>,
    pub gps_hacc_m: Option<f64>,
    pub ref_heading_deg: Option<f64>,
    pub ref_en_m: Option<Vector2<f64>>,
}

/// Writes rows as canonical CSV text, header first.
pub fn write(rows: &[CanonicalRow]) -> String {
    let mut text = String::with_capacity(rows.len() * 160 + 256);
    text.push_str(&COLUMNS.join(","));
    text.push('\n');
    for row in rows {
        // Writing into a String cannot fail.
        let _ = write!(text, "{:.3}", row.t_s);
        push_vector(&mut text, row.acc_mps2, 4);
        push_vector(&mut text, row.gyro_radps, 5);
        push_vector(&mut text, row.mag_ut, 3);
        for (value, decimals) in [
            (row.temp_c, 2),
            (row.lat_deg, 7),
            (row.lon_deg, 7),
            (row.gps_speed_mps, 2),
            (row.gps_course_deg, 2),
            (row.gps_hacc_m, 1),
            (row.ref_heading_deg, 3),
            (row.ref_en_m.map(|en| en.x), 3),
            (row.ref_en_m.map(|en| en.y), 3),
        ] {
            push_value(&mut text, value, decimals);
        }
        text.push('\n');
    }
    text
}

fn push_value(text: &mut String, value: Option<f64>, decimals: usize) {
    text.push(',');
    if let Some(value) = value {
        let _ = write!(text, "{value:.decimals$}");
    }
}

fn push_vector(text: &mut String, vector: Option<Vector3<f64>>, decimals: usize) {
    for axis in 0..3 {
        push_value(text, vector.map(|v| v[axis]), decimals);
    }
}

/// Reads canonical CSV bytes. Fails only when nothing can be read; every skipped or
/// suspect line becomes a diagnostic in the report.
pub fn read(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    let file_name = file_name.to_string();
    if bytes.iter().all(|byte| byte.is_ascii_whitespace()) {
        return Err(ImportError::Empty { file_name });
    }
    if let Some(byte_offset) = first_binary_offset(bytes) {
        return Err(ImportError::NotText {
            file_name,
            byte_offset,
        });
    }

    let mut reader = Reader::default();
    decode_all(bytes, MAX_LINE_BYTES, |line| {
        if line.truncated {
            reader.diagnostics.push(
                Some(line.number),
                format!("line longer than {MAX_LINE_BYTES} bytes; its end was ignored"),
            );
        }
        reader.read_line(line.number, &line.text);
    });
    reader.finish(file_name)
}

#[derive(Default)]
struct Reader {
    header: Option<Header>,
    recording: Recording,
    diagnostics: Diagnostics,
    n_data_lines: usize,
}

struct Header {
    line: usize,
    delimiter: char,
    names: Vec<String>,
    /// For each field of a data line, the canonical column it fills, if any.
    column_of_field: Vec<Option<usize>>,
    has_time: bool,
}

impl Reader {
    fn read_line(&mut self, line_number: usize, text: &str) {
        let trimmed = text.trim_start_matches('\u{feff}').trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            return;
        }
        match &self.header {
            None => self.header = Some(Header::parse(line_number, trimmed)),
            Some(_) => {
                self.n_data_lines += 1;
                self.read_data_line(line_number, trimmed);
            }
        }
    }

    fn read_data_line(&mut self, line_number: usize, text: &str) {
        let Some(header) = &self.header else { return };
        let mut values: [Option<f64>; COLUMNS.len()] = [None; COLUMNS.len()];
        let mut problems: Vec<String> = Vec::new();
        let mut n_fields = 0usize;
        for (field_idx, field) in text.split(header.delimiter).enumerate() {
            n_fields += 1;
            let Some(Some(column)) = header.column_of_field.get(field_idx) else {
                continue;
            };
            let field = field.trim().trim_matches('"').trim();
            if field.is_empty() {
                continue;
            }
            match field.parse::<f64>() {
                Ok(value) if value.is_finite() => values[*column] = Some(value),
                Ok(_) => problems.push(format!("{} is {field}", COLUMNS[*column])),
                Err(_) => problems.push(format!(
                    "{} is not a number ({})",
                    COLUMNS[*column],
                    shorten(field)
                )),
            }
        }
        // Fewer fields than the header are empty trailing columns; more may mean the
        // columns are shifted, which the user should know.
        if n_fields > header.column_of_field.len() {
            problems.push(format!(
                "{n_fields} fields where the header (line {}) has {}; the extra fields were ignored",
                header.line,
                header.column_of_field.len()
            ));
        }

        let t_s = if header.has_time {
            match values[col::T] {
                Some(t_s) => t_s,
                None => {
                    problems.push("no time (t_s), so the line was skipped".to_string());
                    self.diagnostics
                        .push(Some(line_number), problems.join("; "));
                    return;
                }
            }
        } else {
            // Without a time column the sample number stands in for time.
            self.n_data_lines as f64 - 1.0
        };

        let recording = &mut self.recording;
        let vector =
            |first: usize, name: &str, problems: &mut Vec<String>| -> Option<Vector3<f64>> {
                match (values[first], values[first + 1], values[first + 2]) {
                    (Some(x), Some(y), Some(z)) => Some(Vector3::new(x, y, z)),
                    (None, None, None) => None,
                    _ => {
                        problems.push(format!(
                            "{name} has only some of x, y, z; that sample was skipped"
                        ));
                        None
                    }
                }
            };
        if let Some(acc) = vector(col::ACC, "accelerometer", &mut problems) {
            recording.acc_in_body_mps2.push(t_s, acc);
        }
        if let Some(gyro) = vector(col::GYRO, "gyroscope", &mut problems) {
            recording.gyro_in_body_radps.push(t_s, gyro);
        }
        if let Some(mag) = vector(col::MAG, "magnetometer", &mut problems) {
            recording.mag_in_body_ut.push(t_s, mag);
        }
        if let Some(temp_c) = values[col::TEMP] {
            recording.temp_c.push(t_s, temp_c);
        }
        let fix = GnssFix {
            lat_deg: values[col::LAT],
            lon_deg: values[col::LON],
            alt_m: None,
            speed_mps: values[col::SPEED],
            course_rad: values[col::COURSE].map(f64::to_radians),
            hacc_m: values[col::HACC],
        };
        if fix != GnssFix::default() {
            recording.gnss.push(t_s, fix);
        }
        if let Some(ref_heading_deg) = values[col::REF_HEADING] {
            recording
                .ref_heading_rad
                .push(t_s, ref_heading_deg.to_radians());
        }
        match (values[col::REF_E], values[col::REF_N]) {
            (Some(e_m), Some(n_m)) => recording
                .ref_position_en_m
                .push(t_s, Vector2::new(e_m, n_m)),
            (None, None) => {}
            _ => problems.push("reference position has only one of ref_e_m, ref_n_m".to_string()),
        }
        if !problems.is_empty() {
            self.diagnostics
                .push(Some(line_number), problems.join("; "));
        }
    }

    fn finish(mut self, file_name: String) -> Result<ImportReport, ImportError> {
        let Some(header) = self.header.take() else {
            return Err(ImportError::NoHeader { file_name });
        };
        if header.column_of_field.iter().all(Option::is_none) {
            return Err(ImportError::UnknownHeader {
                file_name,
                line: header.line,
                found: shorten(&header.names.join(", ")),
            });
        }
        let unknown: Vec<&str> = header
            .names
            .iter()
            .zip(&header.column_of_field)
            .filter(|(_, column)| column.is_none())
            .map(|(name, _)| name.as_str())
            .collect();
        if !unknown.is_empty() {
            self.diagnostics.push(
                Some(header.line),
                format!(
                    "columns ignored (not canonical names): {}",
                    shorten(&unknown.join(", "))
                ),
            );
        }
        if !header.has_time {
            self.diagnostics.push(
                Some(header.line),
                "no t_s column: the sample number is used as time",
            );
        }
        self.sort_streams(header.line);
        Ok(ImportReport {
            file_name,
            format: FORMAT_NAME,
            recording: self.recording,
            diagnostics: self.diagnostics,
            header: Some(HeaderInfo {
                line: header.line,
                columns: header.names,
            }),
            n_data_lines: self.n_data_lines,
            notes: Vec::new(),
        })
    }

    fn sort_streams(&mut self, header_line: usize) {
        let recording = &mut self.recording;
        let n_out_of_order = recording.acc_in_body_mps2.sort_by_time()
            + recording.gyro_in_body_radps.sort_by_time()
            + recording.mag_in_body_ut.sort_by_time()
            + recording.temp_c.sort_by_time()
            + recording.gnss.sort_by_time()
            + recording.ref_heading_rad.sort_by_time()
            + recording.ref_position_en_m.sort_by_time();
        if n_out_of_order > 0 {
            self.diagnostics.push(
                Some(header_line),
                format!(
                    "time goes backwards {n_out_of_order} times; the samples were sorted by time"
                ),
            );
        }
    }
}

impl Header {
    fn parse(line: usize, text: &str) -> Header {
        let delimiter = if text.contains(',') {
            ','
        } else if text.contains('\t') {
            '\t'
        } else if text.contains(';') {
            ';'
        } else {
            ','
        };
        let names: Vec<String> = text
            .split(delimiter)
            .map(|name| name.trim().trim_matches('"').trim().to_string())
            .collect();
        let column_of_field: Vec<Option<usize>> = names
            .iter()
            .map(|name| {
                COLUMNS
                    .iter()
                    .position(|column| column.eq_ignore_ascii_case(name))
            })
            .collect();
        let has_time = column_of_field.contains(&Some(col::T));
        Header {
            line,
            delimiter,
            names,
            column_of_field,
            has_time,
        }
    }
}

/// Cuts text quoted in a message to a readable length.
fn shorten(text: &str) -> String {
    const MAX_CHARS: usize = 80;
    if text.chars().count() <= MAX_CHARS {
        text.to_string()
    } else {
        let head: String = text.chars().take(MAX_CHARS).collect();
        format!("{head}…")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_text(text: &str) -> Result<ImportReport, ImportError> {
        read("test.csv", text.as_bytes())
    }

    #[test]
    fn round_trip_through_the_writer() {
        let row = CanonicalRow {
            t_s: 1.25,
            acc_mps2: Some(Vector3::new(0.1, -0.2, -9.81)),
            mag_ut: Some(Vector3::new(20.0, -5.5, 40.125)),
            ref_heading_deg: Some(359.5),
            ref_en_m: Some(Vector2::new(3.0, 4.0)),
            ..CanonicalRow::default()
        };
        let report = read_text(&write(&[row, CanonicalRow { t_s: 2.0, ..row }])).expect("readable");
        assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);
        let recording = report.recording;
        assert_eq!(recording.mag_in_body_ut.t_s, vec![1.25, 2.0]);
        assert_eq!(
            recording.mag_in_body_ut.values[0],
            Vector3::new(20.0, -5.5, 40.125)
        );
        assert_eq!(recording.acc_in_body_mps2.len(), 2);
        assert!(recording.gyro_in_body_radps.is_empty());
        assert!(recording.gnss.is_empty());
        assert!((recording.ref_heading_rad.values[0].to_degrees() - 359.5).abs() < 1e-9);
        assert_eq!(
            recording.ref_position_en_m.values[1],
            Vector2::new(3.0, 4.0)
        );
    }

    #[test]
    fn bad_lines_become_diagnostics_and_the_rest_is_read() {
        let text = "t_s,mag_x_ut,mag_y_ut,mag_z_ut,colour\n\
                    0,1,2,3,red\n\
                    1,abc,2,3\n\
                    2,NaN,2,3\n\
                    ,1,2,3\n\
                    3,1,2\n\
                    4,4,5,6\n";
        let report = read_text(text).expect("readable");
        assert_eq!(report.recording.mag_in_body_ut.t_s, vec![0.0, 4.0]);
        let lines: Vec<Option<usize>> = report.diagnostics.kept.iter().map(|d| d.line).collect();
        assert_eq!(lines, vec![Some(3), Some(4), Some(5), Some(6), Some(1)]);
        assert!(report.diagnostics.kept[0]
            .message
            .contains("mag_x_ut is not a number (abc)"));
        assert!(report.diagnostics.kept[1]
            .message
            .contains("mag_x_ut is NaN"));
        assert!(report.diagnostics.kept[4].message.contains("colour"));
    }

    #[test]
    fn delimiters_quotes_comments_and_case_are_accepted() {
        let text = "# exported by hand\n\"T_S\";\"MAG_X_UT\";\"mag_y_ut\";\"mag_z_ut\"\r\n0;1;2;3\r\n\r\n1;4;5;6\r\n";
        let report = read_text(text).expect("readable");
        assert_eq!(report.header.map(|header| header.line), Some(2));
        assert_eq!(report.recording.mag_in_body_ut.len(), 2);
        assert!(report.diagnostics.is_empty());
    }

    #[test]
    fn out_of_order_time_is_sorted_and_reported() {
        let report =
            read_text("t_s,mag_x_ut,mag_y_ut,mag_z_ut\n1,1,1,1\n0,0,0,0\n").expect("readable");
        assert_eq!(report.recording.mag_in_body_ut.t_s, vec![0.0, 1.0]);
        assert!(report.diagnostics.kept[0]
            .message
            .contains("time goes backwards"));
    }

    #[test]
    fn files_with_nothing_readable_are_errors() {
        assert!(matches!(read_text(""), Err(ImportError::Empty { .. })));
        assert!(matches!(
            read_text("\n \r\n"),
            Err(ImportError::Empty { .. })
        ));
        assert!(matches!(
            read_text("# only a comment\n"),
            Err(ImportError::NoHeader { .. })
        ));
        assert!(matches!(
            read_text("a,b,c\n1,2,3\n"),
            Err(ImportError::UnknownHeader { line: 1, .. })
        ));
        assert!(matches!(
            read("x.bin", b"\x00\x01\x02garbage"),
            Err(ImportError::NotText { .. })
        ));
    }

    #[test]
    fn error_messages_name_the_file_and_what_to_do() {
        let message = read_text("a,b\n").map(|_| ()).unwrap_err().to_string();
        assert!(message.starts_with("test.csv, line 1:"), "{message}");
        assert!(message.contains("mag_x_ut"), "{message}");
    }
}
