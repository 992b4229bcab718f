//! Properties of the whole import path, over arbitrary input: no input panics, and the
//! same bytes cut into any chunks decode to the same lines. Bounded (case counts below)
//! so that it runs inside `./test`.
#![cfg(not(target_arch = "wasm32"))]

use compass_pdr::analysis::calibration::CalibrationOptions;
use compass_pdr::io::import::{import, import_files, merge, ChunkedImport, Inspection};
use compass_pdr::io::lines::LineDecoder;
use compass_pdr::pipeline::calibrate_file;
use proptest::prelude::*;

/// Lines of every format this tool reads, to be shuffled, cut and corrupted.
const SEED_LINES: &[&str] = &[
    "t_s,acc_x_mps2,acc_y_mps2,acc_z_mps2,mag_x_ut,mag_y_ut,mag_z_ut,ref_heading_deg",
    "0.02,0.1,0.2,-9.8,20.5,-3.25,40,12.5",
    "\"Time (s)\",\"X (µT)\",\"Y (µT)\",\"Z (µT)\"",
    "1.958608333E-2,1.839072609E1,3.549049377E0,-3.546667480E1",
    "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A",
    "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47",
    "$HCHDT,123.4,T",
    "$PTNTHPR,85.9,N,-0.9,N,0.8,N*2C",
    "Raw:120,-45,8190,3,-2,1,200,-150,400",
    "Uni:0.12,-0.05,9.81,0.001,0.002,0.0,20.1,-15.2,40.3",
    "mx:12.5,my:-3.25,mz:40.0",
    "(12.5, -3.25, 40.0)",
    "X: 1.0, Y: 2.0, Z: 3.0 uT",
    "1574562662058\tTYPE_MAGNETIC_FIELD_UNCALIBRATED\t-21.5\t-88.8\t-332.4\t-56.2\t-90.8\t-301.5\t3",
    "1574562662058\tTYPE_ACCELEROMETER\t-1.61\t-0.58\t10.27\t2",
    "ACCE;0.015;5236.123;0.1;0.2;9.8;3",
    "MAGN;0.020;5236.128;20.1;-15.2;40.3;3",
    "POSI;1.0;1;40.3133;-3.4834;0;0",
    "# comment",
    "",
    "NaN,NaN,NaN",
    "1e400,-1e400,1e-400",
];

/// A canonical CSV whose data rows are drawn from `picks`.
fn csv_of(picks: &[usize]) -> String {
    let mut text = String::from("t_s,mag_x_ut,mag_y_ut,mag_z_ut,ref_heading_deg\n");
    for (row_idx, &pick) in picks.iter().enumerate() {
        text.push_str(&format!(
            "{row_idx}.5,{},{}.25,-3{pick},x{}\n",
            pick * 3,
            pick,
            row_idx % 7
        ));
    }
    text
}

fn lines_of(bytes: &[u8], chunk_ends: &[usize]) -> Vec<(usize, String, bool)> {
    let mut lines = Vec::new();
    let mut decoder = LineDecoder::new(256);
    let mut start = 0;
    for &end in chunk_ends.iter().chain(std::iter::once(&bytes.len())) {
        let end = end.clamp(start, bytes.len());
        decoder.feed(&bytes[start..end], |line| {
            lines.push((line.number, line.text.into_owned(), line.truncated));
        });
        start = end;
    }
    decoder.finish(|line| lines.push((line.number, line.text.into_owned(), line.truncated)));
    lines
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        let _ = import("fuzz.bin", &bytes).map(|report| Inspection::of(&report));
        let _ = calibrate_file("fuzz.bin", &bytes, &CalibrationOptions::default());
    }

    #[test]
    fn mixed_and_corrupted_lines_never_panic(
        picks in proptest::collection::vec((0..SEED_LINES.len(), 0usize..80, any::<u8>(), any::<bool>()), 1..60),
        ending in prop_oneof![Just("\n"), Just("\r\n"), Just("\r")],
    ) {
        let mut text: Vec<u8> = Vec::new();
        for (line_idx, cut_at, replacement, corrupt) in picks {
            let mut line = SEED_LINES[line_idx].as_bytes().to_vec();
            if corrupt && !line.is_empty() {
                let position = cut_at % line.len();
                line[position] = replacement;
            }
            text.extend_from_slice(&line);
            text.extend_from_slice(ending.as_bytes());
        }
        let _ = import("mixed.txt", &text).map(|report| Inspection::of(&report));
        let _ = import_files(&[("a.txt", &text), ("b.txt", &text[..text.len() / 2])]);
        let _ = calibrate_file("mixed.txt", &text, &CalibrationOptions::default());
    }

    #[test]
    fn a_file_read_in_any_chunks_imports_as_when_read_whole(
        picks in proptest::collection::vec(0..SEED_LINES.len(), 1..80),
        mut chunk_ends in proptest::collection::vec(0usize..4000, 0..10),
    ) {
        // NMEA only, a canonical CSV, and a mixture: each must import the same in chunks.
        let nmea: Vec<&str> = picks.iter().map(|&idx| SEED_LINES[idx]).filter(|line| line.starts_with('$')).collect();
        let mixed: Vec<&str> = picks.iter().map(|&idx| SEED_LINES[idx]).collect();
        for candidate in [nmea.join("\n"), csv_of(&picks), mixed.join("\r\n")] {
            let bytes = candidate.as_bytes();
            chunk_ends.sort_unstable();
            let mut chunked = ChunkedImport::new("f.txt", Some(bytes.len()));
            let mut start = 0;
            let mut fed = Ok(());
            for &end in chunk_ends.iter().chain(std::iter::once(&bytes.len())) {
                let end = end.clamp(start, bytes.len());
                fed = fed.and_then(|()| chunked.feed(&bytes[start..end]));
                start = end;
            }
            let chunked_result = fed.and_then(|()| chunked.finish()).map(|file| merge(vec![("f.txt".to_string(), Ok(file))]));
            let whole = import("f.txt", bytes);
            match (chunked_result, whole) {
                (Ok(Ok(chunked)), Ok(whole)) => prop_assert_eq!(chunked, whole),
                (Ok(Err(chunked)) | Err(chunked), Err(whole)) => prop_assert_eq!(chunked, whole),
                (chunked, whole) => prop_assert!(false, "chunked {:?} but whole {:?}", chunked.is_ok(), whole.is_ok()),
            }
        }
    }

    #[test]
    fn any_chunking_gives_the_same_lines(
        bytes in proptest::collection::vec(prop_oneof![Just(b'\r'), Just(b'\n'), Just(b'a'), Just(0xffu8), any::<u8>()], 0..600),
        mut chunk_ends in proptest::collection::vec(0usize..600, 0..12),
    ) {
        chunk_ends.sort_unstable();
        prop_assert_eq!(lines_of(&bytes, &chunk_ends), lines_of(&bytes, &[]));
    }
}
