//! Tests of the tagged line importers ([`super`]) on whole logs: the formats told
//! apart, files with nothing readable, every chunking, bytes that must never panic, and
//! the real recordings of the Microsoft Indoor Location Competition in
//! `../shared/data`; and the samples and helpers the files' tests share.

use nalgebra::{Rotation3, Vector3};

use super::*;
use crate::io::lines::LineDecoder;
use crate::io::recording::{Attitude, Recording};

pub(super) const ANDROID_SAMPLE: &str = "#\tstartTime:1574562661929\n\
#\tSiteID:5dd3d7732a57a34356595932\tFloorName:F1\n\
#\tBrand:OPPO\tModel:PBCM10\tAndroidName:8.1.0\tAPILevel:27\t\n\
1574562661934\tTYPE_DIST1\t6.5834045\t-20.037842\t-10.961151\n\
1574562661937\tTYPE_WAYPOINT\t197.70462\t82.66885\n\
1574562662058\tTYPE_ACCELEROMETER\t-1.6145935\t-0.5860138\t10.276016\t2\n\
1574562662058\tTYPE_MAGNETIC_FIELD\t34.79004\t2.0629883\t-30.970764\t3\n\
1574562662058\tTYPE_GYROSCOPE\t0.759079\t0.22821045\t-0.5694275\t3\n\
1574562662058\tTYPE_ROTATION_VECTOR\t-0.059935603\t-0.032342788\t0.7208543\t3\n\
1574562662058\tTYPE_MAGNETIC_FIELD_UNCALIBRATED\t-21.505737\t-88.80005\t-332.47528\t-56.295776\t-90.86304\t-301.50452\t3\n\
1574562662058\tTYPE_GYROSCOPE_UNCALIBRATED\t0.7575226\t0.22758484\t-0.5695648\t-0.0015563965\t-6.2561035E-4\t-1.373291E-4\t3\n\
1574562662058\tTYPE_ACCELEROMETER_UNCALIBRATED\t-1.1854248\t-0.9481354\t10.3598175\t0.0\t0.0\t0.0\t3\n\
1574562662078\tTYPE_ACCELEROMETER\t-1.1279755\t-0.15145874\t10.395737\t2\n\
1574562662451\tTYPE_WIFI\tintime_free\t0e:74:9c:2e:98:9f\t-41\t5825\t1574562661435\n\
1574562662451\tTYPE_WIFI\tintime_lease\t12:74:9c:2e:98:9f\t-41\t5825\t1574562661435\n\
1574562662564\tTYPE_BLUE\tSMG\t03:2F:22:41:3E:13\t-100\n\
#\tendTime:1574562776515\n";

/// A GetSensorData log written from the app's own format strings: a phone lying
/// flat, top edge pointing east, every tag once or twice.
pub(super) const GET_SENSOR_DATA_SAMPLE: &str = "% LogFile created by the 'GetSensorData' App for Android.\n\
% Date of creation: Fri Sep 20 10:12:03 GMT+02:00 2019\n\
% Version 2.1 January 2018\n\
% LogFile Data format:\n\
% Accelerometer data: \t'ACCE;AppTimestamp(s);SensorTimestamp(s);Acc_X(m/s^2);Acc_Y(m/s^2);Acc_Z(m/s^2);Accuracy(integer)'\n\
% POSI Reference:    \t\t'POSI;Timestamp(s);Counter;Latitude(degrees); Longitude(degrees);floor ID(0,1,2..4);Building ID(0,1,2..3);'\n\
% \n\
\n\
ACCE;0.012;9635.412;0.07184;0.11971;9.81532;3\n\
GYRO;0.013;9635.413;-0.00122;0.00244;0.00061;3\n\
MAGN;0.015;9635.409;-2.04000;22.62000;-40.38000;3\n\
PRES;0.020;9635.398;947.3125;0\n\
TEMP;0.021;9635.400;24.5;0\n\
AHRS;0.024;9635.416;0.000000;0.000000;-90.000000;0.00000000;0.00000000;-0.70710678;3\n\
ACCE;0.032;9635.432;0.06945;0.12210;9.80814;3\n\
WIFI;0.405;9634.100;eduroam;00:0b:86:27:36:c1;2412;-67\n\
BLE4;0.410;iBeacon;D9:1B:36:39:C3:7F;-83;-74;18479;42247;b9407f30-f5f8-466e-aff9-25556b57fe6d\n\
LIGH;0.420;9635.818;112.0;0\n\
PROX;0.430;9635.829;5.0;0\n\
HUMI;0.440;9635.838;40.5;0\n\
SOUN;0.450;0.0123;0.0008;32.1\n\
RFID;0.460;1;3457;-61;-63\n\
BLUE;0.470;JBL Flip;00:1A:7D:DA:71:13;-79\n\
GNSS;0.512;1568967124.000;40.313541;-3.483176;651.200;45.000;8.0;1.2;12;9\n\
POSI;0.600;1;40.31355012;-3.48318510;0;0\n";

pub(super) fn android(text: &str) -> Result<ImportReport, ImportError> {
    read_android_dump("walk.txt", text.as_bytes())
}

pub(super) fn gsd(text: &str) -> Result<ImportReport, ImportError> {
    read_get_sensor_data("logfile.txt", text.as_bytes())
}

pub(super) fn assert_close(got: f64, expect: f64, tolerance: f64, what: &str) {
    assert!(
        (got - expect).abs() <= tolerance,
        "{what}: got {got}, expected {expect} ± {tolerance}"
    );
}

pub(super) fn assert_vector_close(got: Vector3<f64>, expect: Vector3<f64>, what: &str) {
    assert!(
        (got - expect).norm() < 1e-9,
        "{what}: got {got:?}, expected {expect:?}"
    );
}

pub(super) fn yaw_deg(attitude: &Attitude) -> f64 {
    attitude.yaw_rad.unwrap_or(f64::NAN).to_degrees()
}

#[test]
fn the_formats_are_told_apart() {
    let android_lines: Vec<&str> = ANDROID_SAMPLE.lines().collect();
    let gsd_lines: Vec<&str> = GET_SENSOR_DATA_SAMPLE.lines().collect();
    assert!(looks_like_android_dump(&android_lines));
    assert!(!looks_like_get_sensor_data(&android_lines));
    assert!(looks_like_get_sensor_data(&gsd_lines));
    assert!(!looks_like_android_dump(&gsd_lines));
    // Without its header, a GetSensorData log is still recognised by its tags.
    assert!(looks_like_get_sensor_data(&gsd_lines[8..]));
    let csv = ["t_s,mag_x_ut,mag_y_ut,mag_z_ut", "0,1,2,3"];
    assert!(!looks_like_android_dump(&csv));
    assert!(!looks_like_get_sensor_data(&csv));
    let nmea = ["$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A"];
    assert!(!looks_like_android_dump(&nmea));
    assert!(!looks_like_get_sensor_data(&nmea));
    assert!(!looks_like_android_dump(&[]));
    assert!(!looks_like_get_sensor_data(&[]));
}

#[test]
fn files_with_nothing_readable_are_errors() {
    for read in [read_android_dump, read_get_sensor_data] {
        assert!(matches!(read("x.txt", b""), Err(ImportError::Empty { .. })));
        assert!(matches!(
            read("x.txt", b" \r\n\n"),
            Err(ImportError::Empty { .. })
        ));
        assert!(matches!(
            read("x.bin", b"\x00\x01\x02garbage"),
            Err(ImportError::NotText { byte_offset: 0, .. })
        ));
    }
    let error = android("hello world\nthis is not a log\n")
        .map(|_| ())
        .unwrap_err();
    let ImportError::NothingRecognised {
        format,
        n_lines,
        first_problem,
        ..
    } = &error
    else {
        panic!("unexpected {error:?}");
    };
    assert_eq!((*format, *n_lines), (ANDROID_DUMP, 2));
    assert!(first_problem.starts_with(" (line 1: "), "{first_problem}");
    let message = error.to_string();
    assert!(
        message.starts_with("walk.txt: none of its 2 lines"),
        "{message}"
    );

    let error = gsd("% GetSensorData\nhello;world\n")
        .map(|_| ())
        .unwrap_err();
    assert!(
        matches!(&error, ImportError::NothingRecognised { first_problem, .. }
            if first_problem.starts_with(" (line 2: ")),
        "{error:?}"
    );
    // Only tags this tool ignores: still nothing, and the message says why.
    let error = gsd("WIFI;0.4;9634.1;eduroam;00:0b:86:27:36:c1;2412;-67\n")
        .map(|_| ())
        .unwrap_err();
    assert!(
        matches!(&error, ImportError::NothingRecognised { first_problem, .. }
            if first_problem.contains("line 1: only WIFI ×1")),
        "{error:?}"
    );
    let error = android("# only a comment\n").map(|_| ()).unwrap_err();
    assert!(
        matches!(&error, ImportError::NothingRecognised { first_problem, .. } if first_problem.is_empty()),
        "{error:?}"
    );
}

fn read_chunks(reader: impl LineReader, chunks: &[&[u8]]) -> Result<ImportReport, ImportError> {
    let mut reader = reader;
    let mut decoder = LineDecoder::new(MAX_LINE_BYTES);
    for chunk in chunks {
        decoder.feed(chunk, |line| {
            reader.read_line(line.number, &line.text, line.truncated);
        });
    }
    decoder.finish(|line| reader.read_line(line.number, &line.text, line.truncated));
    reader.finish("walk.txt".to_string())
}

#[test]
fn every_chunking_gives_the_same_report() {
    let android_text = "#\tstartTime:1000\r\n1000\tTYPE_ACCELEROMETER\t0\t0\t9.8\t3\r\n\
                        1020\tTYPE_WAYPOINT\t1\t2\r1040\tTYPE_ROTATION_VECTOR\t0\t0\t0.5\n\
                        1060\tTYPE_ACCELEROMETER\t0\tx\t9.8";
    let whole = read_android_dump("walk.txt", android_text.as_bytes()).expect("readable");
    let bytes = android_text.as_bytes();
    for split in 0..=bytes.len() {
        let chunks = [&bytes[..split], &bytes[split..]];
        let got = read_chunks(AndroidReader::default(), &chunks).expect("readable");
        assert_eq!(got, whole, "split at {split}");
    }

    let gsd_text = "% GetSensorData\r\nACCE;0.01;5.0;0;0;9.8;3\r\nPOSI;0.5;1;40.3;-3.4;0;0\r\
                    AHRS;0.02;5.01;0;0;0;0;0;0.5;3\nACCE;0.03;5.02;0;y;9.8;3";
    let whole = read_get_sensor_data("walk.txt", gsd_text.as_bytes()).expect("readable");
    let bytes = gsd_text.as_bytes();
    for split in 0..=bytes.len() {
        let chunks = [&bytes[..split], &bytes[split..]];
        let got = read_chunks(GetSensorDataReader::default(), &chunks).expect("readable");
        assert_eq!(got, whole, "split at {split}");
    }
}

#[test]
fn pseudo_random_bytes_never_panic() {
    // Bytes drawn mostly from the formats' own alphabet, so that the parsers get far.
    let alphabet: &[u8] = b"0123456789.-eE;\t\n\r #%TYPE_ACCELROMTGYSNWIFHUDKVQ";
    let words: [&[u8]; 10] = [
        b"TYPE_ACCELEROMETER\t",
        b"TYPE_MAGNETIC_FIELD_UNCALIBRATED\t",
        b"TYPE_ROTATION_VECTOR\t",
        b"TYPE_WAYPOINT\t",
        b"ACCE;",
        b"AHRS;",
        b"GNSS;",
        b"POSI;",
        b"NaN",
        b"#\tstartTime:",
    ];
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    let mut next = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 33) as usize
    };
    for _ in 0..400 {
        let len = next() % 600;
        let mut bytes = Vec::with_capacity(len + 64);
        while bytes.len() < len {
            match next() % 10 {
                0 => bytes.extend_from_slice(words[next() % words.len()]),
                1 => bytes.push((next() % 256) as u8),
                _ => bytes.push(alphabet[next() % alphabet.len()]),
            }
        }
        let _ = read_android_dump("random.txt", &bytes);
        let _ = read_get_sensor_data("random.txt", &bytes);
        let text = String::from_utf8_lossy(&bytes);
        let lines: Vec<&str> = text.lines().collect();
        let _ = looks_like_android_dump(&lines);
        let _ = looks_like_get_sensor_data(&lines);
    }
}

// ---- the real recordings in ../shared/data -------------------------------------

/// The bytes of a file under `../shared/data`, or `None` (with a message) where the
/// folder is absent, as in a user's clone.
fn shared_data(path: &str) -> Option<Vec<u8>> {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data");
    let full = format!("{root}/{path}");
    match std::fs::read(&full) {
        Ok(bytes) => Some(bytes),
        Err(error) => {
            eprintln!("skipped: ../shared/data not found ({full}: {error})");
            None
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Expected {
    n_samples: usize,
    n_waypoints: usize,
}

fn check_msft_walk(path: &str, expected: Expected) {
    let Some(bytes) = shared_data(path) else {
        return;
    };
    let report = read_android_dump(path, &bytes).expect("readable");
    let r = &report.recording;
    for (name, n) in [
        ("accelerometer", r.acc_in_body_mps2.len()),
        ("gyroscope", r.gyro_in_body_radps.len()),
        ("magnetometer", r.mag_in_body_ut.len()),
        ("OS bias", r.mag_bias_in_body_ut.len()),
        ("rotation vector", r.attitude.len()),
    ] {
        assert_eq!(n, expected.n_samples, "{path}: {name}");
    }
    assert_eq!(
        r.ref_position_en_m.len(),
        expected.n_waypoints,
        "{path}: waypoints"
    );
    // The last waypoint comes after later sensor lines, but each stream is in order.
    assert!(
        report.diagnostics.is_empty(),
        "{path}: {:?}",
        report.diagnostics
    );

    let duration_s = r.acc_in_body_mps2.duration_s();
    let rate_hz = (r.acc_in_body_mps2.len() - 1) as f64 / duration_s;
    assert!(
        (113.0..=120.0).contains(&duration_s),
        "{path}: {duration_s} s"
    );
    assert!((48.0..=52.0).contains(&rate_hz), "{path}: {rate_hz} Hz");

    let notes = report.notes.join("\n");
    assert!(
        notes.contains("phone mount: Flat, detected"),
        "{path}: {notes}"
    );
    assert!(
        notes.contains("from the startTime header"),
        "{path}: {notes}"
    );
    let n = r.acc_in_body_mps2.len() as f64;
    let mean_acc = r.acc_in_body_mps2.values.iter().sum::<Vector3<f64>>() / n;
    assert!(
        mean_acc.z < -9.0,
        "{path}: mean specific force {mean_acc:?}"
    );

    // The OS bias is on every magnetometer sample, and raw − bias is the Earth's field
    // there (about 48 µT).
    assert_eq!(r.mag_bias_in_body_ut.t_s, r.mag_in_body_ut.t_s);
    let n_mag = r.mag_in_body_ut.len() as f64;
    let calibrated: Vec<Vector3<f64>> = r
        .mag_in_body_ut
        .values
        .iter()
        .zip(&r.mag_bias_in_body_ut.values)
        .map(|(raw, bias)| raw - bias)
        .collect();
    let mean_calibrated_ut = calibrated.iter().map(Vector3::norm).sum::<f64>() / n_mag;
    let mean_raw_ut = r
        .mag_in_body_ut
        .values
        .iter()
        .map(Vector3::norm)
        .sum::<f64>()
        / n_mag;
    assert!(
        (33.0..=63.0).contains(&mean_calibrated_ut),
        "{path}: {mean_calibrated_ut} µT"
    );

    assert!(r.attitude.values.iter().all(|a| a.roll_rad.is_finite()
        && a.pitch_rad.is_finite()
        && a.yaw_rad.is_some_and(f64::is_finite)));

    // The attitude agrees with the other sensors: it turns specific force to about
    // 9.8 m/s² up, and the calibrated field to magnetic north, dipping down.
    let mut gravity_ned = Vector3::zeros();
    let mut field_ned = Vector3::zeros();
    let mut n_pairs = 0usize;
    for (idx, attitude) in r.attitude.values.iter().enumerate() {
        let (Some(&t_att), Some(&t_acc), Some(&t_mag)) = (
            r.attitude.t_s.get(idx),
            r.acc_in_body_mps2.t_s.get(idx),
            r.mag_in_body_ut.t_s.get(idx),
        ) else {
            continue;
        };
        if t_att != t_acc || t_att != t_mag {
            continue;
        }
        let ned_from_body = Rotation3::from_euler_angles(
            attitude.roll_rad,
            attitude.pitch_rad,
            attitude.yaw_rad.unwrap_or(0.0),
        );
        gravity_ned += ned_from_body * r.acc_in_body_mps2.values[idx];
        field_ned += (ned_from_body * calibrated[idx]).normalize();
        n_pairs += 1;
    }
    assert!(
        n_pairs as f64 > 0.9 * n,
        "{path}: only {n_pairs} samples share a time"
    );
    let gravity_ned = gravity_ned / n_pairs as f64;
    let field_ned = field_ned / n_pairs as f64;
    let field_azimuth_deg = field_ned.y.atan2(field_ned.x).to_degrees();
    let field_dip_deg = field_ned.z.atan2(field_ned.xy().norm()).to_degrees();
    assert_close(gravity_ned.z, -9.8, 0.5, "vertical specific force in NED");
    assert!(gravity_ned.xy().norm() < 0.5, "{path}: {gravity_ned:?}");
    assert!(
        field_azimuth_deg.abs() < 15.0,
        "{path}: field azimuth {field_azimuth_deg}°"
    );
    assert!(
        (30.0..=60.0).contains(&field_dip_deg),
        "{path}: field dip {field_dip_deg}°"
    );

    // Its roll and pitch follow the accelerometer's tilt: one-second means of both
    // rise and fall together (a sign error would make them move oppositely).
    let (pitch_correlation, roll_correlation) = tilt_correlations(r);
    assert!(
        pitch_correlation > 0.3,
        "{path}: pitch correlation {pitch_correlation}"
    );
    assert!(
        roll_correlation > 0.3,
        "{path}: roll correlation {roll_correlation}"
    );

    eprintln!(
        "{path}: {} samples per sensor, {} waypoints, {duration_s:.2} s, {rate_hz:.2} Hz, \
         mean |raw − bias| {mean_calibrated_ut:.1} µT, mean |raw| {mean_raw_ut:.1} µT, \
         mean specific force (body) {mean_acc:?}, field azimuth {field_azimuth_deg:.1}°, \
         dip {field_dip_deg:.1}°, gravity in NED {gravity_ned:?}, tilt correlations \
         {pitch_correlation:.2} (pitch), {roll_correlation:.2} (roll), diagnostics {:?}",
        expected.n_samples, expected.n_waypoints, report.diagnostics.kept
    );
}

/// Correlations of one-second means of the attitude's pitch and roll with those
/// seen in the specific force, sample by sample (the streams share their times).
fn tilt_correlations(r: &Recording) -> (f64, f64) {
    const WINDOW: usize = 50;
    let n_windows = r.attitude.len().min(r.acc_in_body_mps2.len()) / WINDOW;
    let mut series: [Vec<f64>; 4] = Default::default();
    for window in 0..n_windows {
        let range = window * WINDOW..(window + 1) * WINDOW;
        let attitude = &r.attitude.values[range.clone()];
        let force = r.acc_in_body_mps2.values[range]
            .iter()
            .sum::<Vector3<f64>>();
        series[0].push(attitude.iter().map(|a| a.pitch_rad).sum::<f64>());
        series[1].push(force.x.atan2(force.yz().norm()));
        series[2].push(attitude.iter().map(|a| a.roll_rad).sum::<f64>());
        series[3].push((-force.y).atan2(-force.z));
    }
    let correlation = |a: &[f64], b: &[f64]| {
        let n = a.len() as f64;
        let (mean_a, mean_b) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
        let covariance: f64 = a
            .iter()
            .zip(b)
            .map(|(x, y)| (x - mean_a) * (y - mean_b))
            .sum();
        let var_a: f64 = a.iter().map(|x| (x - mean_a).powi(2)).sum();
        let var_b: f64 = b.iter().map(|y| (y - mean_b).powi(2)).sum();
        covariance / (var_a * var_b).sqrt()
    };
    (
        correlation(&series[0], &series[1]),
        correlation(&series[2], &series[3]),
    )
}

#[test]
fn the_msft_f1_walk_is_read() {
    check_msft_walk(
        "msft-indoor-2020/site1/F1/5dd9ef979191710006b57086.txt",
        Expected {
            n_samples: 5755,
            n_waypoints: 17,
        },
    );
}

#[test]
fn the_msft_f4_walk_is_read() {
    check_msft_walk(
        "msft-indoor-2020/site1/F4/5ddb6573c5b77e0006b17932.txt",
        Expected {
            n_samples: 5971,
            n_waypoints: 25,
        },
    );
}
