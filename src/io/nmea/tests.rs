//! Tests of the NMEA importer ([`super`]) on whole logs: times, untimed sentences,
//! midnight, invalid fixes, diagnostics, chunking, and bytes that must never panic; and
//! the helpers the sentence files' tests share.

use super::*;
use crate::io::lines::LineDecoder;
use crate::io::recording::{North, Recording};
use crate::io::Diagnostics;

/// Appends the checksum a sentence body needs, `$` included.
pub(super) fn sentence(body: &str) -> String {
    let checksum = body.bytes().fold(0u8, |acc, byte| acc ^ byte);
    format!("${body}*{checksum:02X}")
}

fn read_text(text: &str) -> ImportReport {
    read("test.nmea", text.as_bytes()).expect("readable")
}

pub(super) fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

pub(super) const GOLDEN_RMC: &str =
    "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A";
pub(super) const GOLDEN_GGA: &str =
    "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47";

#[test]
fn a_dated_log_knows_when_it_started() {
    let text = format!("{GOLDEN_RMC}\r\n{GOLDEN_GGA}\r\n");
    let report = read("dated.nmea", text.as_bytes()).expect("readable");
    // 1994-03-23 12:35:19 UTC.
    assert_eq!(report.recording.start_unix_s, Some(764_426_119.0));
    let undated = read("undated.nmea", format!("{GOLDEN_GGA}\n").as_bytes()).expect("readable");
    assert_eq!(undated.recording.start_unix_s, None);
}

#[test]
fn a_log_becomes_fixes_headings_and_attitude() {
    let text = [
        GOLDEN_RMC.to_string(),
        GOLDEN_GGA.to_string(),
        sentence("GPVTG,084.4,T,087.5,M,022.4,N,041.5,K,A"),
        sentence("HCHDG,90.0,1.0,E,3.1,W"),
        sentence("HCHDM,91.0,M"),
        sentence("HEHDT,88.0,T"),
        "$PTNTHPR,85.9,N,-0.9,N,0.8,N*2C".to_string(),
        sentence("GPGSV,3,1,11,03,03,111,00"),
        sentence("GPRMC,123520,A,4807.040,N,01131.002,E,022.0,084.0,230394,003.1,W"),
    ]
    .join("\r\n");
    let report = read_text(&text);
    assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);
    assert_eq!(report.format, FORMAT_NAME);
    assert_eq!(report.header, None);
    assert_eq!(report.n_data_lines, 9);
    let recording = &report.recording;
    // One merged RMC+GGA fix, one VTG fix, one more RMC fix.
    assert_eq!(recording.gnss.len(), 3, "{:?}", recording.gnss);
    let merged = recording.gnss.values[0];
    assert_eq!(recording.gnss.t_s[0], 0.0);
    assert_eq!(merged.alt_m, Some(545.4));
    assert!(merged.speed_mps.is_some() && merged.course_rad.is_some());
    assert_eq!(merged.hacc_m, None);
    assert_eq!(recording.gnss.t_s[2], 1.0);
    let norths: Vec<North> = recording
        .device_heading
        .values
        .iter()
        .map(|h| h.north)
        .collect();
    assert_eq!(
        norths,
        vec![
            North::Magnetic,
            North::Magnetic,
            North::True,
            North::Magnetic
        ]
    );
    assert!(close(
        recording.device_heading.values[0].heading_rad,
        91f64.to_radians()
    ));
    assert_eq!(recording.attitude.len(), 1);
    let attitude = recording.attitude.values[0];
    assert!(close(attitude.pitch_rad, -0.9f64.to_radians()));
    assert!(close(attitude.roll_rad, 0.8f64.to_radians()));
    assert!(close(
        attitude.yaw_rad.unwrap_or(f64::NAN),
        85.9f64.to_radians()
    ));
    let notes = report.notes.join("\n");
    assert!(
        notes.contains("read 2 RMC, 1 GGA, 1 VTG, 1 HDG, 1 HDM, 1 HDT, 1 PTNTHPR sentences"),
        "{notes}"
    );
    assert!(notes.contains("GPGSV 1"), "{notes}");
    assert!(notes.contains("merged into one fix (1 times)"), "{notes}");
    assert!(notes.contains("3.1° W"), "{notes}");
    assert!(notes.contains("12:35:19.00 UTC on 1994-03-23"), "{notes}");
}

#[test]
fn untimed_sentences_are_interpolated_between_timed_ones() {
    let mut lines = vec![sentence(
        "GPGGA,120000.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,,M,,",
    )];
    for heading in 0..4 {
        lines.push(sentence(&format!("HEHDT,{heading}.0,T")));
    }
    lines.push(sentence("PTNTHPR,10.0,N,1.0,N,2.0,N"));
    lines.push(sentence(
        "GPGGA,120001.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,,M,,",
    ));
    let report = read_text(&lines.join("\n"));
    let headings = &report.recording.device_heading;
    let expected: Vec<f64> = (1..=5).map(|k| f64::from(k) / 6.0).collect();
    assert_eq!(headings.len(), 5);
    for (got, want) in headings.t_s.iter().zip(&expected) {
        assert!(close(*got, *want), "{:?} vs {expected:?}", headings.t_s);
    }
    assert!(close(report.recording.attitude.t_s[0], 5.0 / 6.0));
    let notes = report.notes.join("\n");
    assert!(
        notes.contains("5 sentences (HDT, PTNTHPR) carry no time"),
        "{notes}"
    );
}

#[test]
fn untimed_sentences_outside_the_timed_ones_are_extrapolated() {
    let lines = [
        sentence("HEHDT,1.0,T"),
        sentence("GPGGA,120000.00,4807.038,N,01131.000,E,1,08,0.9,,,,,,"),
        sentence("HEHDT,2.0,T"),
        sentence("GPGGA,120001.00,4807.038,N,01131.000,E,1,08,0.9,,,,,,"),
        sentence("HEHDT,3.0,T"),
        sentence("HEHDT,4.0,T"),
    ];
    let report = read_text(&lines.join("\n"));
    // Two lines per second between the timed sentences: 0.5 s per line.
    assert_eq!(
        report.recording.device_heading.t_s,
        vec![-0.5, 0.5, 1.5, 2.0]
    );
    assert!(
        report.notes.join("\n").contains("0.5000 s per line"),
        "{:?}",
        report.notes
    );

    // A single timed epoch: a line stands for a second.
    let single = [
        sentence("HEHDT,1.0,T"),
        sentence("GPGGA,120000.00,,,,,1,,,,,,,,"),
        sentence("HEHDT,2.0,T"),
    ];
    let report = read_text(&single.join("\n"));
    assert_eq!(report.recording.device_heading.t_s, vec![-1.0, 1.0]);
    assert!(
        report.notes.join("\n").contains("single timed epoch"),
        "{:?}",
        report.notes
    );
}

#[test]
fn without_any_time_the_sample_number_stands_in() {
    let lines = [
        sentence("HEHDT,1.0,T"),
        sentence("PTNTHPR,10.0,N,1.0,N,2.0,N"),
        sentence("HEHDT,3.0,T"),
    ];
    let report = read_text(&lines.join("\n"));
    assert_eq!(report.recording.device_heading.t_s, vec![0.0, 1.0, 2.0]);
    assert_eq!(report.recording.attitude.t_s, vec![1.0]);
    assert!(
        report
            .notes
            .join("\n")
            .contains("sample number stands in for time"),
        "{:?}",
        report.notes
    );
}

#[test]
fn midnight_rollover_counts_on() {
    // Without a date: the time of day wraps.
    let lines = [
        sentence("GPGGA,235959.00,4807.038,N,01131.000,E,1,08,0.9,1.0,M,,M,,"),
        sentence("HEHDT,5.0,T"),
        sentence("GPGGA,000001.00,4807.038,N,01131.000,E,1,08,0.9,1.0,M,,M,,"),
    ];
    let report = read_text(&lines.join("\n"));
    assert_eq!(report.recording.gnss.t_s, vec![0.0, 2.0]);
    assert_eq!(report.recording.device_heading.t_s, vec![1.0]);
    assert!(
        report
            .notes
            .join("\n")
            .contains("passes midnight UTC 1 times"),
        "{:?}",
        report.notes
    );

    // With RMC dates, including a gap of more than a day that the time of day alone
    // could not show.
    let lines = [
        sentence("GPRMC,235959.00,A,4807.038,N,01131.000,E,0.0,0.0,311299,,"),
        sentence("GPRMC,000000.00,A,4807.038,N,01131.000,E,0.0,0.0,010100,,"),
        sentence("GPRMC,000000.00,A,4807.038,N,01131.000,E,0.0,0.0,030100,,"),
    ];
    let report = read_text(&lines.join("\n"));
    assert_eq!(
        report.recording.gnss.t_s,
        vec![0.0, 1.0, 1.0 + 2.0 * 86_400.0]
    );
    assert!(
        report.notes.join("\n").contains("1999-12-31"),
        "{:?}",
        report.notes
    );
}

#[test]
fn invalid_fixes_keep_their_time_but_not_their_position() {
    let lines = [
        sentence("GPRMC,120000,A,4807.038,N,01131.000,E,0.0,0.0,230394,,"),
        sentence("GPRMC,120001,V,4807.038,N,01131.000,E,0.0,0.0,230394,,"),
        sentence("HEHDT,5.0,T"),
        sentence("GPGGA,120002,4807.038,N,01131.000,E,0,08,0.9,1.0,M,,M,,"),
        sentence("GPRMC,,V,,,,,,,,,,N"),
    ];
    let report = read_text(&lines.join("\n"));
    assert_eq!(report.recording.gnss.t_s, vec![0.0]);
    // The HDT lies between the invalid RMC and GGA, whose times were kept.
    assert_eq!(report.recording.device_heading.t_s, vec![1.5]);
    let notes = report.notes.join("\n");
    assert!(notes.contains("2 RMC sentences had status V"), "{notes}");
    assert!(
        notes.contains("1 GGA sentences had fix quality 0"),
        "{notes}"
    );
    assert!(report.diagnostics.is_empty());
}

#[test]
fn bad_lines_become_diagnostics_and_the_rest_is_read() {
    let text = [
        GOLDEN_RMC.to_string(),
        "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6B".to_string(),
        "$HCHDT,128.0,T".to_string(),
        "$hchdt,128.0,t*22".to_string(),
        "# a comment from the logger".to_string(),
        String::new(),
        "$PTNTHPR,72.9,N,-1.6,N,-29.6,O*33".to_string(),
        "$PTNTHPR,,P,0.3,N,0.1,N*06".to_string(),
        "$PTNTHPR,85.9,N,-0.9,N,0.8,N*2c".to_string(),
    ]
    .join("\n");
    let report = read_text(&text);
    let lines: Vec<Option<usize>> = report.diagnostics.kept.iter().map(|d| d.line).collect();
    assert_eq!(lines, vec![Some(2), Some(4), Some(5), Some(7), Some(8)]);
    assert!(report.diagnostics.kept[0]
        .message
        .contains("calculated 6A, found 6B"));
    assert!(report.diagnostics.kept[3]
        .message
        .contains("roll high warning (O)"));
    assert!(report.diagnostics.kept[4]
        .message
        .contains("magnetic field high alarm (P)"));
    assert_eq!(report.n_data_lines, 8);
    assert_eq!(report.recording.gnss.len(), 1);
    assert_eq!(
        report.recording.device_heading.len(),
        2,
        "HDT without checksum and the normal HPR"
    );
    assert_eq!(report.recording.attitude.len(), 1);
    assert!(
        report.notes[0].ends_with("; 1 lines without checksum (accepted unchecked)"),
        "{:?}",
        report.notes
    );
}

#[test]
fn files_with_nothing_readable_are_errors() {
    assert!(matches!(
        read("x.nmea", b""),
        Err(ImportError::Empty { .. })
    ));
    assert!(matches!(
        read("x.nmea", b" \r\n\n"),
        Err(ImportError::Empty { .. })
    ));
    assert!(matches!(
        read("x.nmea", b"\x00\x01\x02$GPRMC"),
        Err(ImportError::NotText { .. })
    ));
    let garbage = read("x.nmea", b"hello world\nthis is, not NMEA\n");
    let Err(ImportError::NothingRecognised {
        n_lines,
        first_problem,
        format,
        ..
    }) = garbage
    else {
        panic!("{garbage:?}");
    };
    assert_eq!((n_lines, format), (2, FORMAT_NAME));
    assert!(
        first_problem.starts_with(" (line 1: not an NMEA sentence"),
        "{first_problem}"
    );
    let only_gsv = read("x.nmea", sentence("GPGSV,3,1,11").as_bytes());
    let Err(ImportError::NothingRecognised { first_problem, .. }) = only_gsv else {
        panic!("{only_gsv:?}");
    };
    assert!(
        first_problem.contains("GPGSV sentences are not read"),
        "{first_problem}"
    );
    let no_fix = read(
        "x.nmea",
        b"$GPRMC,,V,,,,,,,,,,N*53\n$GPGGA,,,,,,0,,,,,,,,*66\n",
    );
    let Err(ImportError::NothingRecognised { first_problem, .. }) = no_fix else {
        panic!("{no_fix:?}");
    };
    assert!(
        first_problem.contains("line 1: RMC status V"),
        "{first_problem}"
    );
    let message = read("walk.nmea", b"nonsense\n")
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        message.starts_with("walk.nmea: none of its 1 lines could be read as NMEA 0183"),
        "{message}"
    );
}

#[test]
fn overlong_lines_are_skipped_with_a_diagnostic() {
    let long = format!("$GPRMC,{}", "1".repeat(MAX_LINE_BYTES + 10));
    let text = format!("{long}\n$HCHDT,128.0,T*22\n");
    let report = read_text(&text);
    assert_eq!(report.n_data_lines, 2);
    assert_eq!(report.diagnostics.kept.len(), 1);
    assert_eq!(report.diagnostics.kept[0].line, Some(1));
    assert!(report.diagnostics.kept[0]
        .message
        .contains("longer than 4096 bytes"));
    assert_eq!(report.recording.device_heading.len(), 1);
}

#[test]
fn out_of_order_times_are_sorted_and_reported() {
    let lines = [
        sentence("GPGGA,120005,4807.038,N,01131.000,E,1,08,0.9,,,,,,"),
        sentence("GPGGA,120001,4807.038,N,01131.000,E,1,08,0.9,,,,,,"),
    ];
    let report = read_text(&lines.join("\n"));
    assert_eq!(report.recording.gnss.t_s, vec![-4.0, 0.0]);
    assert!(report.diagnostics.kept[0]
        .message
        .contains("time goes backwards once"));
}

#[test]
fn looks_like_nmea_and_not_like_csv() {
    assert!(looks_like(&[
        GOLDEN_RMC,
        GOLDEN_GGA,
        "",
        "$HCHDT,128.0,T",
        "!AIVDM,1,1,,A,13aG?P0P00PD;88MD5MTDww@2D7k,0*46"
    ]));
    assert!(looks_like(&[
        "\u{feff}$PTNTHPR,85.9,N,-0.9,N,0.8,N*2C",
        "garbled line",
        "$PTNTHPR,,P,0.3,N,0.1,N*06"
    ]));
    assert!(!looks_like(&["t_s,mag_x_ut,mag_y_ut,mag_z_ut", "0,1,2,3"]));
    assert!(!looks_like(&["$GPRMC,1*6A", "x", "y"]));
    assert!(!looks_like(&["$gprmc,1", "$GPRMC,1*6", "$TOOLONG,1"]));
    assert!(!looks_like(&[]));
    assert!(!looks_like(&["", "  "]));
}

fn recording_through_chunks(
    bytes: &[u8],
    splits: &[usize],
) -> (Recording, Diagnostics, Vec<String>) {
    let mut reader = NmeaReader::new();
    let mut decoder = LineDecoder::new(MAX_LINE_BYTES);
    let mut start = 0;
    for &split in splits.iter().chain([bytes.len()].iter()) {
        let end = split.clamp(start, bytes.len());
        decoder.feed(&bytes[start..end], |line| reader.read_decoded(&line));
        start = end;
    }
    decoder.finish(|line| reader.read_decoded(&line));
    let report = reader.finish("chunks.nmea").expect("readable");
    (report.recording, report.diagnostics, report.notes)
}

#[test]
fn every_chunking_gives_the_same_recording() {
    let text = [
        sentence("HEHDT,1.0,T"),
        GOLDEN_RMC.to_string(),
        GOLDEN_GGA.to_string(),
        sentence("HCHDG,90.0,1.0,E,3.1,W"),
        "$GPRMC,bad*00".to_string(),
        sentence("PTNTHPR,85.9,N,-0.9,N,0.8,N"),
        sentence("GPRMC,123520,A,4807.040,N,01131.002,E,022.0,084.0,230394,003.1,W"),
        sentence("HEHDT,2.0,T"),
    ];
    let mut bytes = Vec::new();
    for (idx, line) in text.iter().enumerate() {
        bytes.extend_from_slice(line.as_bytes());
        bytes.extend_from_slice([&b"\r\n"[..], b"\n", b"\r"][idx % 3]);
    }
    let whole = recording_through_chunks(&bytes, &[]);
    assert_eq!(whole, {
        let report = read("chunks.nmea", &bytes).expect("readable");
        (report.recording, report.diagnostics, report.notes)
    });
    for split in 0..=bytes.len() {
        assert_eq!(
            recording_through_chunks(&bytes, &[split]),
            whole,
            "split at {split}"
        );
    }
    let mut state = 7u64;
    for _ in 0..200 {
        let mut splits: Vec<usize> = (0..6)
            .map(|_| {
                state = lcg(state);
                (state >> 33) as usize % (bytes.len() + 1)
            })
            .collect();
        splits.sort_unstable();
        assert_eq!(
            recording_through_chunks(&bytes, &splits),
            whole,
            "splits {splits:?}"
        );
    }
}

pub(super) fn lcg(state: u64) -> u64 {
    state
        .wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407)
}

#[test]
fn arbitrary_bytes_never_panic() {
    const ALPHABET: &[u8] = b"$!*,.-0123456789ABCDEFGHMNOPRSTVWEgn \r\n";
    let mut state = 1u64;
    for round in 0..3000 {
        state = lcg(state);
        let len = (state >> 40) as usize % 160;
        let bytes: Vec<u8> = (0..len)
            .map(|_| {
                state = lcg(state);
                let byte = (state >> 33) as u8;
                if round % 2 == 0 {
                    ALPHABET[usize::from(byte) % ALPHABET.len()]
                } else {
                    byte
                }
            })
            .collect();
        let _ = read("fuzz.nmea", &bytes);
        let text = String::from_utf8_lossy(&bytes);
        let _ = parse_sentence(&text);
        let _ = looks_like(&[&text]);
    }
}

#[test]
fn mutated_sentences_with_valid_checksums_never_panic() {
    // Recomputing the checksum lets mutations reach the field parsers.
    let bodies = [
        "GPRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W,A",
        "GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
        "GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,A",
        "HCHDG,101.1,1.0,E,7.1,W",
        "HCHDM,45.5,M",
        "HEHDT,128.0,T",
        "PTNTHPR,85.9,N,-0.9,N,0.8,N",
    ];
    const REPLACEMENTS: &[u8] = b",.-+*$0123456789NSEWAVTMPeE \xff";
    let mut state = 3u64;
    for round in 0..20_000 {
        let body = bodies[round % bodies.len()];
        let mut bytes = body.as_bytes().to_vec();
        for _ in 0..3 {
            state = lcg(state);
            let at = (state >> 33) as usize % bytes.len();
            state = lcg(state);
            let replacement = REPLACEMENTS[(state >> 33) as usize % REPLACEMENTS.len()];
            match (state >> 20) % 3 {
                0 => bytes[at] = replacement,
                1 => bytes.insert(at, replacement),
                _ => {
                    bytes.remove(at);
                }
            }
            if bytes.is_empty() {
                bytes.push(b'G');
            }
        }
        let text = sentence(&String::from_utf8_lossy(&bytes));
        let _ = parse_sentence(&text);
        let mut reader = NmeaReader::new();
        reader.read_line(1, &text);
        reader.read_line(2, GOLDEN_RMC);
        let _ = reader.finish("mutated.nmea");
    }
}
