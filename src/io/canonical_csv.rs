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

use super::{delimited, ImportError, ImportReport};

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

/// Reads canonical CSV bytes: the delimited reader, whose names include the canonical
/// ones. Fails only when nothing can be read; every skipped or suspect line becomes a
/// diagnostic in the report.
pub fn read(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    let mut report = delimited::read(file_name, bytes)?;
    report.format = FORMAT_NAME;
    Ok(report)
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
        assert_eq!(lines, vec![Some(3), Some(4), Some(5), Some(6)]);
        assert!(report.diagnostics.kept[0]
            .message
            .contains("mag_x_ut is not a number (abc)"));
        assert!(report.diagnostics.kept[1]
            .message
            .contains("mag_x_ut is NaN"));
        // An ignored column is a fact about the file, said once in the notes.
        assert!(
            report.notes.iter().any(|note| note.contains("colour")),
            "{:?}",
            report.notes
        );
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
