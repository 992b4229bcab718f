//! Tests of the serial line importer ([`super`]) on whole logs: mixed formats, lines
//! joined into samples, the unit checks and notes, chunking, the live reader, errors,
//! detection, and bytes that must never panic; and the helpers the files' tests share.

use nalgebra::{Matrix3, Vector3};

use super::*;
use crate::io::lines::LineDecoder;
use crate::io::SensorFrame;

pub(super) fn sample(text: &str) -> SensorSample {
    match parse_line(text) {
        Ok(SerialLine::Sample(sample)) => sample,
        other => panic!("{text:?} gave {other:?}"),
    }
}

pub(super) fn assert_close(got: Option<Vector3<f64>>, want: [f64; 3], what: &str) {
    let got = got.unwrap_or_else(|| panic!("{what}: no vector"));
    let want = Vector3::from(want);
    assert!(
        (got - want).norm() < 1e-9,
        "{what}: got {got:?}, want {want:?}"
    );
}

pub(super) fn read_text(text: &str) -> Result<ImportReport, ImportError> {
    read("serial.txt", text.as_bytes())
}

#[test]
fn the_magnetometer_frame_is_the_board_s_axes_in_the_unit_the_lines_use() {
    let frame_of = |text: &str| {
        read_text(text)
            .ok()
            .and_then(|report| report.mag_frame)
            .map(|frame| (frame.body_from_sensor, frame.unit))
    };
    let board = SensorFrame::serial_board(MagUnit::MICROTESLA).body_from_sensor;
    assert_eq!(
        frame_of("Raw:0,0,8192,0,0,0,300,-150,450\nRaw:0,0,8192,0,0,0,301,-150,450\n"),
        Some((board, MagUnit::MOTIONCAL_COUNT))
    );
    // A Raw: line followed by its Uni: line is read in µT.
    assert_eq!(
        frame_of("Raw:0,0,8192,0,0,0,300,-150,450\nUni:0,0,9.8,0,0,0,30.01,-15.0,45.0\n"),
        Some((board, MagUnit::MICROTESLA))
    );
    assert_eq!(
        frame_of("Magnetometer (gauss): (0.25, -0.1, 0.4)\n"),
        Some((board, MagUnit::GAUSS))
    );
    assert_eq!(
        frame_of("12.5,-3.25,40.0\n12.6,-3.25,40.0\n"),
        Some((board, MagUnit::assumed_microtesla()))
    );
    // Mixed units: the most common one, and a note.
    let report =
        read_text("X:1.0 Y:2.0 Z:3.0 uT\nRaw:0,0,8192,0,0,0,1,2,3\nRaw:0,0,8192,0,0,0,1,2,3\n")
            .expect("readable");
    assert_eq!(
        report.mag_frame.map(|frame| frame.unit),
        Some(MagUnit::MOTIONCAL_COUNT)
    );
    assert!(
        report
            .notes
            .iter()
            .any(|note| note.contains("several units") && note.contains("1 in µT")),
        "{:?}",
        report.notes
    );
    // Accelerometer only: no magnetometer frame.
    assert_eq!(frame_of("Accel X: 0.1 Y: 0.2 Z: 9.8 m/s^2\n"), None);
}

#[test]
fn mixed_formats_in_one_file() {
    let text = "Adafruit AHRS - IMU Calibration!\n\
                Raw:0,0,8192,0,0,0,200,-100,-400\n\
                Uni:0.00,0.00,9.81,0.0000,0.0000,0.0000,20.03,-10.01,-40.02\n\
                Cal1:0.000,0.000,0.000,0.000,0.000,0.000,0.000,0.000,0.000,50.000\n\
                mx:21 my:-11 mz:-41\n\
                (22.0, -12.0, -42.0)\n\
                X: 23.00, Y: -13.00, Z: -43.00 uT\n\
                24,-14,-44\n\
                Orientation: 1.0, 2.0, 3.0\n";
    let report = read_text(text).expect("readable");
    let mag = &report.recording.mag_in_body_ut;
    let mag_x: Vec<f64> = mag.values.iter().map(|v| v.x).collect();
    assert_eq!(mag_x, vec![20.03, 21.0, 22.0, 23.0, 24.0]);
    assert_close(
        mag.values.first().copied(),
        [20.03, 10.01, 40.02],
        "Uni in body axes",
    );
    assert_eq!(mag.t_s, vec![0.0, 0.01, 0.02, 0.03, 0.04]);
    assert_eq!(report.n_data_lines, 9);
    let lines: Vec<Option<usize>> = report.diagnostics.kept.iter().map(|d| d.line).collect();
    assert_eq!(lines, vec![Some(1), Some(9)]);
    assert!(report.diagnostics.kept[1].message.contains("Orientation"));
    assert_eq!(report.format, FORMAT_NAME);
    assert_eq!(report.header, None);
    let notes = report.notes.join("\n");
    assert!(
        notes.contains("no timestamps: samples are spaced at an assumed 100 Hz"),
        "{notes}"
    );
    assert!(notes.contains("MotionCal Raw: counts (1)"), "{notes}");
    assert!(notes.contains("Uni: SI values (1)"), "{notes}");
    assert!(notes.contains("X: Y: Z: with a unit (1)"), "{notes}");
    assert!(
        notes.contains("Cal1:/Cal2: calibration echoes (1)"),
        "{notes}"
    );
    assert!(notes.contains("(x, −y, −z)"), "{notes}");
    assert!(
        notes.contains("the Uni: values (more digits) were used"),
        "{notes}"
    );
}

#[test]
fn a_level_sensor_at_rest_reads_minus_g_on_body_z() {
    let report =
        read_text("Uni:0.00,0.00,9.81,0.0000,0.0000,0.0500,20.00,0.00,-40.00\n").expect("readable");
    let acc = report.recording.acc_in_body_mps2.values.first().copied();
    assert_close(acc, [0.0, 0.0, -9.81], "acc body");
    assert_close(
        report.recording.gyro_in_body_radps.values.first().copied(),
        [0.0, 0.0, -0.05],
        "gyro body",
    );
    let columns = [Vector3::x(), Vector3::y(), Vector3::z()].map(sensor_to_body);
    assert!((Matrix3::from_columns(&columns).determinant() - 1.0).abs() < 1e-12);
}

#[test]
fn lines_of_different_sensors_are_joined_into_one_sample() {
    let text = "Acceleration: X:   0.00, Y:   0.00, Z:   9.80 m/s^2\n\
                Gyro          X:   0.00, Y:   0.00, Z:   0.00 rad/s\n\
                Magnetic      X:  20.00, Y:   0.00, Z: -40.00 uT\n\
                \n\
                Acceleration: X:   0.00, Y:   0.00, Z:   9.80 m/s^2\n\
                Gyro          X:   0.00, Y:   0.00, Z:   0.00 rad/s\n\
                Magnetic      X:  21.00, Y:   0.00, Z: -40.00 uT\n";
    let report = read_text(text).expect("readable");
    assert_eq!(report.recording.mag_in_body_ut.t_s, vec![0.0, 0.01]);
    assert_eq!(report.recording.acc_in_body_mps2.t_s, vec![0.0, 0.01]);
    assert!(
        report
            .notes
            .iter()
            .any(|note| note.contains("2 samples were joined")),
        "{:?}",
        report.notes
    );
}

#[test]
fn unitless_accelerometer_in_g_is_rescaled() {
    let text: String = (0..10)
        .map(|i| format!("ax:0.0{i} ay:0.0 az:1.0 mx:20 my:0 mz:40\n"))
        .collect();
    let report = read_text(&text).expect("readable");
    let acc = report.recording.acc_in_body_mps2.values.first().copied();
    assert_close(acc, [0.0, 0.0, -9.80665], "acc in g");
    assert!(
        report.notes.iter().any(|note| note.contains("read as g")),
        "{:?}",
        report.notes
    );
}

#[test]
fn unknown_labels_are_listed_once() {
    let text = "mx:1 my:2 mz:3 loop:1\nmx:1 my:2 mz:3 loop:2 LOOP2:5\n";
    let report = read_text(text).expect("readable");
    let note = report
        .notes
        .iter()
        .find(|note| note.starts_with("labels ignored"))
        .expect("note");
    assert_eq!(
        note,
        "labels ignored (no sensor axis this tool knows): loop, LOOP2"
    );
}

fn read_in_chunks(bytes: &[u8], splits: &[usize]) -> Result<ImportReport, ImportError> {
    let mut reader = SerialReader::new(ASSUMED_FILE_RATE_HZ);
    let mut decoder = LineDecoder::new(MAX_LINE_BYTES);
    let mut start = 0;
    for &split in splits.iter().chain(std::iter::once(&bytes.len())) {
        decoder.feed(&bytes[start..split], |line| {
            reader.read_line(line.number, &line.text, None);
        });
        start = split;
    }
    decoder.finish(|line| reader.read_line(line.number, &line.text, None));
    reader.finish("serial.txt")
}

#[test]
fn line_endings_and_chunking_do_not_matter() {
    let lf = "Raw:0,0,8192,0,0,0,200,0,-400\nmx:1 my:2 mz:3\n(4, 5, 6)\n7 8 9\n";
    let crlf = lf.replace('\n', "\r\n");
    let cr = lf.replace('\n', "\r");
    let whole = read_text(lf).expect("readable");
    assert_eq!(whole.recording.mag_in_body_ut.len(), 4);
    for text in [&crlf, &cr] {
        assert_eq!(read_text(text).expect("readable"), whole);
    }
    let bytes = crlf.as_bytes();
    for split in 0..=bytes.len() {
        assert_eq!(
            read_in_chunks(bytes, &[split]).expect("readable"),
            whole,
            "split at {split}"
        );
    }
}

#[test]
fn the_live_reader_uses_arrival_times() {
    let mut reader = SerialReader::new(50.0);
    reader.read_line(1, "mx:1 my:2 mz:3", Some(10.0));
    reader.read_line(2, "mx:1 my:2 mz:4", Some(10.25));
    reader.read_line(3, "Cal1:0,0,0,0,0,0,1,2,3,45", Some(10.3));
    assert_eq!(reader.echoes().len(), 1);
    let (report, echoes) = reader.finish_with_echoes("port").expect("readable");
    assert_eq!(report.recording.mag_in_body_ut.t_s, vec![10.0, 10.25]);
    assert_eq!(echoes.first().and_then(|echo| echo.arrival_t_s), Some(10.3));
    assert!(!report
        .notes
        .iter()
        .any(|note| note.contains("no timestamps")));
}

#[test]
fn garbage_is_nothing_recognised_with_a_line_number() {
    let error = read_text("\nhello world\nmore text\n").unwrap_err();
    let ImportError::NothingRecognised {
        n_lines,
        first_problem,
        format,
        ..
    } = &error
    else {
        panic!("{error:?}");
    };
    assert_eq!(*format, FORMAT_NAME);
    assert_eq!(*n_lines, 3);
    assert!(
        first_problem.starts_with(" (line 2: not a sensor line"),
        "{first_problem}"
    );
    assert!(
        error
            .to_string()
            .starts_with("serial.txt: none of its 3 lines"),
        "{error}"
    );
}

#[test]
fn binary_and_empty_files_are_refused() {
    assert!(matches!(
        read("x.bin", b"\x00\x01\x02Raw:1,2,3"),
        Err(ImportError::NotText { .. })
    ));
    assert!(matches!(read("x.txt", b""), Err(ImportError::Empty { .. })));
    assert!(matches!(
        read("x.txt", b" \r\n\n"),
        Err(ImportError::Empty { .. })
    ));
}

#[test]
fn long_lines_are_skipped_with_a_diagnostic() {
    let text = format!("mx:1 my:2 mz:3\n{}\n", "1,".repeat(MAX_LINE_BYTES));
    let report = read_text(&text).expect("readable");
    assert_eq!(report.recording.mag_in_body_ut.len(), 1);
    assert_eq!(
        report.diagnostics.kept.first().and_then(|d| d.line),
        Some(2)
    );
}

#[test]
fn detection_takes_serial_lines_but_not_delimited_files() {
    assert!(looks_like(&[
        "Raw:0,0,8192,0,0,0,200,0,-400",
        "Uni:0,0,9.8,0,0,0,20,0,-40"
    ]));
    assert!(looks_like(&["mx:1 my:2 mz:3", "mx:1 my:2 mz:3"]));
    assert!(looks_like(&["(1.0, 2.0, 3.0)", "junk", "(1.0, 2.0, 3.0)"]));
    assert!(looks_like(&[
        "Sensor: LSM6DS",
        "Type: Acceleration",
        "Max Value: 156",
        "Raw:0,0,8192,0,0,0,1,2,3",
        "Uni:0,0,9.8,0,0,0,0.1,0.2,0.3"
    ]));
    assert!(!looks_like(&[
        "t_s,mag_x_ut,mag_y_ut,mag_z_ut",
        "0,1,2,3",
        "1,1,2,3"
    ]));
    assert!(!looks_like(&["mag_x,mag_y,mag_z", "1,2,3", "1,2,3"]));
    assert!(!looks_like(&[
        "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47"
    ]));
    assert!(!looks_like(&[]));
}

#[test]
fn pseudo_random_bytes_never_panic() {
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    let mut next = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 33) as u8
    };
    let alphabet = b"0123456789-+.,;: \t\r\n()eERawUniCal12xyzXYZmagutG/s^";
    for round in 0..400 {
        let len = usize::from(next()) % 120;
        let bytes: Vec<u8> = (0..len)
            .map(|_| {
                let byte = next();
                if round % 2 == 0 {
                    alphabet[usize::from(byte) % alphabet.len()]
                } else {
                    byte
                }
            })
            .collect();
        let _ = read("fuzz.txt", &bytes);
        let _ = read_with_echoes("fuzz.txt", &bytes);
        let text = String::from_utf8_lossy(&bytes);
        for line in text.lines() {
            let _ = parse_line(line);
        }
        let _ = looks_like(&text.lines().collect::<Vec<_>>());
    }
}
