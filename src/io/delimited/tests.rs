//! Tests of the delimited reader ([`super`]) through its entry points: headers, units,
//! phone apps' files, and large files read in parts equal to reading them line by line.

use super::*;
use crate::io::STANDARD_GRAVITY_MPS2;

pub(super) fn read_text(text: &str) -> ImportReport {
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
fn phyphox_gyroscopes_are_bias_removed_and_other_rate_columns_are_not_said_to_be() {
    use crate::io::recording::GyroBias;
    for (text, expected) in [
        // phyphox, one sensor's experiment and several sensors'.
        (
            "\"Time (s)\",\"X (rad/s)\",\"Y (rad/s)\",\"Z (rad/s)\"\n0.01,0.1,0.2,0.3\n",
            GyroBias::RemovedByDevice,
        ),
        (
            "\"Time (s)\",\"Gyroscope x (rad/s)\",\"Gyroscope y (rad/s)\",\"Gyroscope z (rad/s)\",\"Absolute (rad/s)\"\n0.01,0.1,0.2,0.3,0.37\n",
            GyroBias::RemovedByDevice,
        ),
        // Any other naming of the same rates says nothing of the bias.
        ("t_s,gyro_x,gyro_y,gyro_z\n0,0.1,0.2,0.3\n", GyroBias::Unknown),
        ("t_s,gyro_x_dps,gyro_y_dps,gyro_z_dps\n0,1,2,3\n", GyroBias::Unknown),
    ] {
        let report = read_text(text);
        assert_eq!(report.recording.gyro_in_body_radps.len(), 1, "{text}");
        assert_eq!(report.recording.gyro_bias, expected, "{text}");
        assert_eq!(
            report.notes.iter().any(|note| note.contains("phyphox's rotation rate")),
            expected == GyroBias::RemovedByDevice,
            "{text}: {:?}",
            report.notes
        );
    }
}

#[test]
fn units_in_suffixes_are_converted() {
    let report = read_text("t_s,mag_x_gauss,mag_y_gauss,mag_z_gauss,acc_x_g,acc_y_g,acc_z_g,gyro_x_dps,gyro_y_dps,gyro_z_dps\n0,0.25,-0.3,-0.4,0,0,-1,90,0,0\n");
    let recording = &report.recording;
    assert!((recording.mag_in_body_ut.values[0] - Vector3::new(25.0, -30.0, -40.0)).norm() < 1e-9);
    assert!((recording.acc_in_body_mps2.values[0].z + STANDARD_GRAVITY_MPS2).abs() < 1e-9);
    assert!((recording.gyro_in_body_radps.values[0].x - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
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
        reader.read_line(&line);
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
    let mapping =
        ColumnMapping::parse("column 1=t_s,column 2=mag_x_ut,column 3=mag_y_ut,column 4=mag_z_ut")
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
