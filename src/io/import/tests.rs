//! Tests of the import door: a magnetometer's frame through a merge, and chunked
//! imports (blocks of lines, over-long lines, any chunking) against reading whole.

use proptest::prelude::*;

use super::chunked::MAX_CARRY_BYTES;
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
fn a_second_recording_of_the_same_motion_is_left_out_not_interleaved() {
    // The raw and the filtered export of one calibration: the same times, two values.
    let raw = "t_s,mag_x_ut,mag_y_ut,mag_z_ut\n0,10,0,40\n0.1,11,0,40\n0.2,12,0,40\n";
    let filtered = "t_s,mag_x_ut,mag_y_ut,mag_z_ut\n0,10.5,0,40\n0.1,11.5,0,40\n0.2,12.5,0,40\n";
    let report = import_files(&[
        ("filtered.csv", filtered.as_bytes()),
        ("raw.csv", raw.as_bytes()),
    ])
    .expect("imports");
    assert_eq!(report.recording.mag_in_body_ut.len(), 3);
    assert_eq!(
        report.recording.mag_in_body_ut.values[0].x, 10.5,
        "the first file's"
    );
    assert!(
        report.notes.iter().any(|note| note.starts_with(
            "raw.csv: not used, filtered.csv already gives a magnetometer over the same time"
        )),
        "{:?}",
        report.notes
    );
    // One after the other in time, two files are one longer recording.
    let later = "t_s,mag_x_ut,mag_y_ut,mag_z_ut\n10,10,0,40\n10.1,11,0,40\n";
    let report =
        import_files(&[("a.csv", raw.as_bytes()), ("b.csv", later.as_bytes())]).expect("imports");
    assert_eq!(report.recording.mag_in_body_ut.len(), 5);
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
    let report =
        import_files(&[("a.txt", serial.as_bytes()), ("b.csv", csv.as_bytes())]).expect("merged");
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
                kept.iter()
                    .any(|diagnostic| diagnostic.line == Some(4) && diagnostic.message.len() < 200)
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

#[test]
fn a_json_file_is_named_json_whole_and_in_chunks() {
    // A floor plan as a phone logger keeps it beside its log: one line of GeoJSON.
    let mut map = String::from(
        r#"{"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": {"type": "MultiPolygon", "coordinates": [[["#,
    );
    for idx in 0..5_000 {
        map.push_str(&format!("[120.07{idx:04}, 30.29{idx:04}], "));
    }
    map.push_str("[120.0, 30.0]]]]}}]}\n");
    let error = import_file("geojson_map.json", map.as_bytes(), None).err();
    assert_eq!(
        error,
        Some(ImportError::Json {
            file_name: "geojson_map.json".to_string()
        })
    );
    let chunked = read_in_chunks("geojson_map.json", map.as_bytes(), &[1000, 20_000]).err();
    assert_eq!(chunked, error);
    // A byte-order mark and blank lines before it change nothing.
    let floor_info = "\u{feff}\n\n{\"map_info\": {\"height\": 188.4, \"width\": 257.9}}\n";
    assert!(matches!(
        import_file("floor_info.json", floor_info.as_bytes(), None),
        Err(ImportError::Json { .. })
    ));
}
