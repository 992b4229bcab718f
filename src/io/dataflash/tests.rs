//! DataFlash logs built byte by byte, cut and corrupted; the real logs are read in
//! `tests/real_autopilot.rs`.

use super::*;

/// A binary message: head, type, payload.
fn message(type_id: u8, payload: &[u8]) -> Vec<u8> {
    let mut bytes = vec![0xA3, 0x95, type_id];
    bytes.extend_from_slice(payload);
    bytes
}

fn padded(text: &str, size: usize) -> Vec<u8> {
    let mut bytes = text.as_bytes().to_vec();
    bytes.resize(size, 0);
    bytes
}

fn fmt(type_id: u8, length: u8, name: &str, format: &str, columns: &str) -> Vec<u8> {
    let mut payload = vec![type_id, length];
    payload.extend(padded(name, 4));
    payload.extend(padded(format, 16));
    payload.extend(padded(columns, 64));
    message(128, &payload)
}

fn mag(t_ms: u32, field: [i16; 3], offsets: [i16; 3]) -> Vec<u8> {
    let mut payload = t_ms.to_le_bytes().to_vec();
    for value in field.iter().chain(&offsets).chain(&[0i16; 3]) {
        payload.extend_from_slice(&value.to_le_bytes());
    }
    message(15, &payload)
}

fn parm(name: &str, value: f32) -> Vec<u8> {
    let mut payload = padded(name, 16);
    payload.extend_from_slice(&value.to_le_bytes());
    message(129, &payload)
}

/// A small log: FMT of FMT, PARM and MAG (as ArduCopter 3.3 wrote them), the
/// parameters, then 50 MAG samples.
fn small_log() -> Vec<u8> {
    let mut bytes = fmt(128, 89, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns");
    bytes.extend(fmt(129, 23, "PARM", "Nf", "Name,Value"));
    bytes.extend(fmt(
        15,
        25,
        "MAG",
        "Ihhhhhhhhh",
        "TimeMS,MagX,MagY,MagZ,OfsX,OfsY,OfsZ,MOfsX,MOfsY,MOfsZ",
    ));
    for (name, value) in [
        ("COMPASS_OFS_X", -97.8),
        ("COMPASS_OFS_Y", 118.1),
        ("COMPASS_OFS_Z", 213.2),
        ("COMPASS_DIA_X", 1.1),
        ("COMPASS_DIA_Y", 0.9),
        ("COMPASS_DIA_Z", 1.0),
        ("COMPASS_ODI_X", 0.05),
    ] {
        bytes.extend(parm(name, value));
    }
    for i in 0..50u32 {
        let i16_of = |v: u32| (v as i16) * 3 - 70;
        bytes.extend(mag(1000 + 100 * i, [i16_of(i), 200, -400], [-98, 118, 213]));
    }
    bytes
}

#[test]
fn a_built_log_gives_its_compass_raw_with_the_calibration_undone() {
    let report = read_binary("small.bin", &small_log()).unwrap();
    assert_eq!(report.format, BINARY);
    let mag = &report.recording.mag_in_body_ut;
    assert_eq!(mag.len(), 50);
    assert!((mag.t_s[0] - 1.0).abs() < 1e-12);
    let autopilot = report.autopilot.as_ref().unwrap();
    assert_eq!(
        autopilot.param("COMPASS_DIA_X").map(|v| v as f32),
        Some(1.1)
    );
    // Applying ArduPilot's correction to the raw field gives the logged one back.
    let lookup = |name: &str| autopilot.param(name);
    let m = ArduPilotCompass::from_params(&lookup, 0).unwrap().soft_iron;
    let offsets = Vector3::new(-97.8f32 as f64, 118.1f32 as f64, 213.2f32 as f64);
    let compass = &autopilot.compasses[0];
    for (raw_ut, logged_ut) in mag.values.iter().zip(&compass.logged_in_body_ut.values) {
        let corrected_mg = m * (raw_ut / UT_PER_MG + offsets);
        assert!((corrected_mg * UT_PER_MG - logged_ut).amax() < 1e-9);
    }
}

#[test]
fn any_chunking_gives_the_same_report() {
    let bytes = small_log();
    let whole = read_binary("small.bin", &bytes).unwrap();
    for chunk in [1, 2, 3, 7, 89, 4096] {
        let mut reader = BinaryReader::default();
        for piece in bytes.chunks(chunk) {
            reader.feed(piece);
        }
        assert_eq!(
            finish_binary(reader, "small.bin").unwrap(),
            whole,
            "chunks of {chunk}"
        );
    }
}

#[test]
fn a_log_cut_anywhere_keeps_every_whole_message_before_the_cut() {
    let bytes = small_log();
    let whole = read_binary("small.bin", &bytes).unwrap();
    let first_mag = bytes.len() - 50 * 25;
    for cut in 0..bytes.len() {
        match read_binary("cut.bin", &bytes[..cut]) {
            Ok(report) => {
                let n_whole = cut.saturating_sub(first_mag) / 25;
                assert_eq!(
                    report.recording.mag_in_body_ut.len(),
                    n_whole,
                    "cut at {cut}"
                );
                assert_eq!(
                    report.recording.mag_in_body_ut.values[..],
                    whole.recording.mag_in_body_ut.values[..n_whole]
                );
                if (cut - first_mag.min(cut)) % 25 != 0 {
                    assert!(report
                        .diagnostics
                        .kept
                        .iter()
                        .any(|d| d.message.contains("byte")));
                }
            }
            Err(error) => assert!(cut < 89 * 3, "cut at {cut}: {error}"),
        }
    }
}

#[test]
fn flipped_bytes_lose_only_the_messages_they_hit() {
    let bytes = small_log();
    let first_mag = bytes.len() - 50 * 25;
    for (n, position) in (first_mag..bytes.len()).step_by(7).enumerate() {
        let mut damaged = bytes.clone();
        damaged[position] ^= 0x5A ^ (n as u8);
        let report = read_binary("flipped.bin", &damaged).unwrap();
        let n_read = report.recording.mag_in_body_ut.len();
        // A flip in a head or type loses that message (and the reader says where); a
        // flip in a value changes only the value.
        assert!(n_read >= 48, "flip at {position}: {n_read} samples");
        if n_read < 50 {
            assert!(!report.diagnostics.is_empty());
        }
    }
    // Random noise between messages is skipped and reported by byte.
    let mut noisy = bytes[..first_mag + 250].to_vec();
    noisy.extend((0..300u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 11) as u8));
    noisy.extend_from_slice(&bytes[first_mag + 250..]);
    let report = read_binary("noisy.bin", &noisy).unwrap();
    assert_eq!(report.recording.mag_in_body_ut.len(), 50);
    assert!(report.diagnostics.kept[0]
        .message
        .starts_with(&format!("bytes {}", first_mag + 250)));
}

#[test]
fn a_text_log_reads_like_the_binary_one() {
    let text = "ArduCopter V3.1\n\
        FMT, 128, 89, FMT, BBnNZ, Type,Length,Name,Format\n\
        FMT, 129, 23, PARM, Nf, Name,Value\n\
        FMT, 15, 25, MAG, Ihhhhhhhhh, TimeMS,MagX,MagY,MagZ,OfsX,OfsY,OfsZ,MOfsX,MOfsY,MOfsZ\n\
        FMT, 1, 19, ATT, IccccCC, TimeMS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw\n\
        PARM, COMPASS_OFS_X, -86.91773\n\
        PARM, COMPASS_MOT_X, NaN\n\
        MAG, 95980, -424, 68, 62, -86, 10, 139, 0, 0, 0\n\
        MAG, 96080, 0, 0, 0, -86, 10, 139, 0, 0, 0\n\
        ATT, 95891, 0.00, -0.25, 0.00, 0.26, 189.54, 189.54\n\
        XYZ, 1, 2\n";
    assert!(looks_like_text(&text.lines().collect::<Vec<_>>()));
    let report = read_text("nan.log", text.as_bytes()).unwrap();
    assert_eq!(report.format, TEXT);
    let autopilot = report.autopilot.unwrap();
    assert_eq!(autopilot.firmware.as_deref(), Some("ArduCopter V3.1"));
    assert!(autopilot.param("COMPASS_MOT_X").unwrap().is_nan());
    // Only OFS_X is a PARM here, so the logged offsets are used.
    let raw = report.recording.mag_in_body_ut.values[0] / UT_PER_MG;
    assert!((raw - Vector3::new(-424.0 + 86.0, 68.0 - 10.0, 62.0 - 139.0)).amax() < 1e-3);
    // A reading of exactly (0, 0, 0) is the compass reading nothing: left out, noted.
    assert_eq!(report.recording.mag_in_body_ut.len(), 1);
    assert!(report
        .notes
        .iter()
        .any(|note| note.starts_with("MAG: 1 reading of exactly (0, 0, 0) left out")));
    let yaw = report.recording.attitude.values[0].yaw_rad.unwrap();
    assert!((yaw.to_degrees() - 189.54).abs() < 1e-9);
    assert_eq!(report.diagnostics.kept[0].line, Some(11));
}

#[test]
fn a_mag_stream_out_of_time_order_stays_its_main_compass_s_raw_field() {
    // Swap two MAG messages: the recording's magnetometer is sorted by time, and so is
    // the compass it came from, sample for sample (the heading comparison's in-force
    // row applies the compass's parameters to exactly these samples).
    let mut bytes = small_log();
    let one = mag(1000, [0, 0, 0], [0; 3]).len();
    let end = bytes.len();
    let (third_last, second_last) = (end - 2 * one, end - one);
    let last = bytes[second_last..].to_vec();
    let before = bytes[third_last..second_last].to_vec();
    bytes.truncate(third_last);
    bytes.extend(last);
    bytes.extend(before);
    let report = read_binary("swapped.bin", &bytes).unwrap();
    let autopilot = report.autopilot.as_ref().unwrap();
    assert_eq!(autopilot.main_compass, Some(0));
    let raw = autopilot.compasses[0].raw_in_body_ut.as_ref().unwrap();
    assert_eq!(*raw, report.recording.mag_in_body_ut);
    assert!(raw.t_s.windows(2).all(|pair| pair[0] <= pair[1]));
    assert!(
        report
            .diagnostics
            .kept
            .iter()
            .any(|diagnostic| diagnostic.message.contains("time goes backwards once")),
        "{:?}",
        report.diagnostics
    );
}
