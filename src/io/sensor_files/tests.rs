//! Tests of the per-sensor files ([`super`]): recognition by name and content, and
//! whole folders of Sensor Logger CSVs and headerless text read through the import,
//! with the merge's choices.

use nalgebra::Vector3;

use super::*;
use crate::io::import::import_files;
use crate::io::recording::GyroBias;
use crate::io::MagUnit;

fn lines(text: &str) -> Vec<&str> {
    text.lines()
        .map(str::trim)
        .filter(|line| !line.is_empty())
        .collect()
}

#[test]
fn files_are_recognised_by_name_and_content_together() {
    let logger = "time,seconds_elapsed,z,y,x\n1679068247375690000,0.17668994140625,9.6,0.1,0.2\n";
    let phyphox = "\"Time (s)\",\"X (m/s^2)\",\"Y (m/s^2)\",\"Z (m/s^2)\"\n0.01,0.1,0.2,9.8\n";
    assert_eq!(
        recognise("some/dir/TotalAcceleration.csv", &lines(logger)),
        Some(SensorFile::SensorLogger {
            kind: LoggerFile::TotalAcceleration,
            start_unix_s: Some(1_679_068_247.375_69 - 0.176_689_941_406_25),
        })
    );
    // The same name with phyphox's content, or the content under another name: no.
    assert_eq!(recognise("Accelerometer.csv", &lines(phyphox)), None);
    assert_eq!(recognise("walk.csv", &lines(logger)), None);
    assert_eq!(
        recognise(
            "C:\\trial\\magnetometer.txt",
            &["0.5 35.7 -71.3 375.9 59.9 -74.6 412.0"]
        ),
        Some(SensorFile::Headerless(HeaderlessFile::Magnetometer))
    );
    // A rotation vector has its own layout; a 4-number line is not a magnetometer.txt.
    assert_eq!(
        recognise("rotation-vector.txt", &["0.51 0.07 -0.02 -0.58 0.80 0.17"]),
        Some(SensorFile::Headerless(HeaderlessFile::RotationVector))
    );
    assert_eq!(
        recognise("magnetometer.txt", &["0.5 35.7 -71.3 375.9"]),
        None
    );
    assert_eq!(
        recognise("record.properties", &["[Device]", "Model = Nexus 5"]),
        Some(SensorFile::RecordProperties)
    );
}

const TOTAL: &str = "time,seconds_elapsed,z,y,x\n\
    1679068247375690000,0.17668994140625,9.7,0.1,0.2\n\
    1679068247395690000,0.19668994140625,9.7,0.1,0.2\n\
    1679068247415690000,0.21668994140625,9.7,0.1,0.3\n";
const GRAVITY: &str =
    "time,seconds_elapsed,z,y,x\n1679068247375690000,0.17668994140625,9.8,0.0,0.1\n";
const CALIBRATED: &str = "time,seconds_elapsed,z,y,x\n\
    1679068247375990000,0.17699,7.0,10.0,-7.0\n\
    1679068247395990000,0.19699,7.5,10.5,-7.0\n\
    1679068247415990000,0.21699,8.0,11.0,-7.0\n";
const UNCALIBRATED: &str = "time,seconds_elapsed,z,y,x\n\
    1679068247375690000,0.17669,29.0,70.0,8.0\n\
    1679068247395690000,0.19669,29.5,70.5,8.0\n\
    1679068247415690000,0.21669,30.0,bad,8.0\n";
const LOCATION: &str =
    "time,seconds_elapsed,horizontalAccuracy,speed,bearing,altitude,longitude,latitude\n\
    1679068248793000000,1.594,24.3,0,0,586.5,8.5104485,47.4072629\n";
const METADATA: &str =
    "version,device name,recording time,platform,appVersion,device id,sensors,sampleRateMs\n\
    3,SM-A520F,2023-03-17_15-50-47,android,1.12.0,8ea4,Accelerometer|Location,20|0\n";

#[test]
fn a_sensor_logger_folder_gives_each_file_its_meaning() {
    let files: Vec<(&str, &[u8])> = vec![
        ("Metadata.csv", METADATA.as_bytes()),
        ("Gravity.csv", GRAVITY.as_bytes()),
        ("Magnetometer.csv", CALIBRATED.as_bytes()),
        ("MagnetometerUncalibrated.csv", UNCALIBRATED.as_bytes()),
        ("TotalAcceleration.csv", TOTAL.as_bytes()),
        ("Location.csv", LOCATION.as_bytes()),
    ];
    let report = import_files(&files).expect("imports");
    let r = &report.recording;
    assert_eq!(
        r.acc_in_body_mps2.len(),
        3,
        "TotalAcceleration, not Gravity"
    );
    assert_eq!(r.mag_in_body_ut.len(), 2, "the raw field (one bad line)");
    assert_eq!(r.mag_bias_in_body_ut.len(), 2);
    assert_eq!(r.gnss.len(), 1);
    let start = r.start_unix_s.expect("dated");
    assert!((start - 1_679_068_247.199).abs() < 1e-3, "{start}");
    // Flat (gravity along device z): body = (y, x, −z); bias = raw − calibrated.
    let bias = r.mag_bias_in_body_ut.values[0];
    assert!(
        (bias - Vector3::new(60.0, 15.0, -22.0)).norm() < 1e-9,
        "{bias}"
    );
    assert!((r.mag_in_body_ut.values[0] - Vector3::new(70.0, 8.0, -29.0)).norm() < 1e-9);
    let frame = report.mag_frame.expect("a magnetometer frame");
    assert_eq!(frame.unit, MagUnit::MICROTESLA);
    let notes = report.notes.join("\n");
    for expected in [
        "Gravity.csv: Sensor Logger: the OS's gravity estimate",
        "MagnetometerUncalibrated.csv is the magnetometer",
        "Metadata.csv: Sensor Logger 1.12.0 (android) on SM-A520F",
        "Android device axes, phone held flat",
    ] {
        assert!(notes.contains(expected), "{expected}\n{notes}");
    }
    assert!(!notes.contains("guessed"), "{notes}");
    let bad = &report.diagnostics.kept;
    assert!(
        bad.iter()
            .any(|d| d.line == Some(4)
                && d.file_name.as_deref() == Some("MagnetometerUncalibrated.csv")),
        "{bad:?}"
    );
}

#[test]
fn sensor_loggers_gyroscope_is_bias_free_and_its_uncalibrated_twin_is_raw() {
    const RATES: &str = "time,seconds_elapsed,z,y,x\n\
        1679068247375690000,0.17668994140625,0.01,0.02,0.03\n\
        1679068247395690000,0.19668994140625,0.01,0.02,0.03\n";
    let gyro_bias = |names: &[&'static str]| {
        let mut files: Vec<(&str, &[u8])> = vec![("TotalAcceleration.csv", TOTAL.as_bytes())];
        files.extend(names.iter().map(|name| (*name, RATES.as_bytes())));
        let report = import_files(&files).expect("imports");
        assert_eq!(report.recording.gyro_in_body_radps.len(), 2, "{names:?}");
        report.recording.gyro_bias
    };
    assert_eq!(gyro_bias(&["Gyroscope.csv"]), GyroBias::RemovedByDevice);
    assert_eq!(gyro_bias(&["GyroscopeUncalibrated.csv"]), GyroBias::Unknown);
    for names in [
        ["Gyroscope.csv", "GyroscopeUncalibrated.csv"],
        ["GyroscopeUncalibrated.csv", "Gyroscope.csv"],
    ] {
        assert_eq!(gyro_bias(&names), GyroBias::RemovedByDevice, "{names:?}");
    }
}

#[test]
fn the_calibrated_magnetometer_alone_is_the_magnetometer() {
    let files: Vec<(&str, &[u8])> = vec![
        ("Magnetometer.csv", CALIBRATED.as_bytes()),
        ("TotalAcceleration.csv", TOTAL.as_bytes()),
    ];
    let report = import_files(&files).expect("imports");
    assert_eq!(report.recording.mag_in_body_ut.len(), 3);
    assert!(report.recording.mag_bias_in_body_ut.is_empty());
    assert!(report
        .notes
        .iter()
        .any(|note| note.contains("OS-calibrated field is the magnetometer")));
}

const TYREX_MAG: &str = "0.511100381 35.72998 -71.380615 375.9079 59.978516 -74.679565 412.08496\n\
    0.531241983 35.809326 -71.43402 375.88348 59.978516 -74.679565 412.08496\n\
    0.55 oops\n";
const TYREX_ACC: &str =
    "0.153586954 -0.74057007 1.3436584 9.141418\n0.158622354 -0.7410126 1.2962494 9.170898\n";
const TYREX_GYRO: &str =
    "0.566489786 -0.2216034 0.032287598 0.46340942 0.008499147 -0.003982544 0.068847656\n";
const TYREX_ROTATION: &str =
    "0.514793008 0.076385796 -0.022159554 -0.5843173 0.8076184 0.17453292\n";

#[test]
fn a_headerless_trial_folder_gives_acc_gyro_mag_and_the_os_bias() {
    let files: Vec<(&str, &[u8])> = vec![
        ("magnetometer.txt", TYREX_MAG.as_bytes()),
        ("accelerometer.txt", TYREX_ACC.as_bytes()),
        ("gyroscope.txt", TYREX_GYRO.as_bytes()),
        ("rotation-vector.txt", TYREX_ROTATION.as_bytes()),
        (
            "magnetometer-calibrated.txt",
            b"0.511100381 -24.249268 3.2989502 -36.177063\n",
        ),
        (
            "record.properties",
            b"[Device]\nManufacturer = LGE\nModel = Nexus 5\nOSVersion = 23\n\n[Time]\nStartTime = 1464686052",
        ),
    ];
    let report = import_files(&files).expect("imports");
    let r = &report.recording;
    assert_eq!(r.acc_in_body_mps2.len(), 2);
    assert_eq!(r.gyro_in_body_radps.len(), 1);
    assert_eq!(
        r.gyro_bias,
        GyroBias::RemovedByDevice,
        "the OS's drift removed"
    );
    assert_eq!(r.mag_in_body_ut.len(), 2, "not the rotation vector's");
    assert_eq!(r.mag_bias_in_body_ut.len(), 2);
    assert_eq!(r.start_unix_s, Some(1_464_686_052.0));
    // The raw rate minus the drift, flat: body = (y, x, −z).
    let gyro = r.gyro_in_body_radps.values[0];
    let expected = Vector3::new(
        0.032287598 + 0.003982544,
        -0.2216034 - 0.008499147,
        -(0.46340942 - 0.068847656),
    );
    assert!((gyro - expected).norm() < 1e-9, "{gyro}");
    assert!(report
        .diagnostics
        .kept
        .iter()
        .any(|d| d.line == Some(3) && d.file_name.as_deref() == Some("magnetometer.txt")));
    let notes = report.notes.join("\n");
    assert!(
        notes.contains("rotation-vector.txt: the phone's own attitude"),
        "{notes}"
    );
    assert!(
        notes.contains(
            "magnetometer-calibrated.txt: not used, magnetometer.txt is the magnetometer"
        ),
        "{notes}"
    );
    assert!(
        notes.contains("the phone: LGE Nexus 5, Android API 23"),
        "{notes}"
    );
}

#[test]
fn a_headerless_file_alone_is_read() {
    let report = import_files(&[("magnetometer.txt", TYREX_MAG.as_bytes())]).expect("imports");
    assert_eq!(report.recording.mag_in_body_ut.len(), 2);
    assert_eq!(report.format, HEADERLESS_TEXT);
    assert!(report.mag_frame.is_some());
}
