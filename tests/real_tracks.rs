//! A GPX track dropped with a sensor log: the Sensor Logger walk in `../shared/data`
//! with its `Location.csv` replaced by the same fixes written as GPX (times in UTC,
//! positions and heights, no course or speed), which must place the fixes on the log's
//! clock and serve as the reference heading and positions. Skipped, with a message,
//! where the folder is absent.

mod common;

use compass_pdr::analysis::calibration::{calibrate, CalibrationOptions};
use compass_pdr::reference::ReferenceSource;

/// `Location.csv` (time ns, seconds_elapsed, accuracy, speed, bearing, altitude, lon,
/// lat) as a GPX track.
fn gpx_of(location_csv: &str) -> (String, usize) {
    let mut gpx = String::from(
        "<?xml version=\"1.0\"?>\n<gpx version=\"1.1\" creator=\"test\"><trk><trkseg>\n",
    );
    let mut n = 0;
    for line in location_csv.lines().skip(1) {
        let fields: Vec<&str> = line.split(',').collect();
        let (Some(time_ns), Some(alt), Some(lon), Some(lat)) = (
            fields.first().and_then(|v| v.parse::<f64>().ok()),
            fields.get(5),
            fields.get(6),
            fields.get(7),
        ) else {
            continue;
        };
        let unix_s = time_ns / 1e9;
        let days = (unix_s / 86_400.0).floor();
        let (year, month, day) = compass_pdr::base::calendar::civil_from_days(days as i64);
        let seconds = unix_s - days * 86_400.0;
        let (h, m, s) = (
            (seconds / 3600.0).floor(),
            ((seconds % 3600.0) / 60.0).floor(),
            seconds % 60.0,
        );
        gpx.push_str(&format!(
            "<trkpt lat=\"{lat}\" lon=\"{lon}\"><ele>{alt}</ele><time>{year:04}-{month:02}-{day:02}T{h:02}:{m:02}:{s:06.3}Z</time></trkpt>\n"
        ));
        n += 1;
    }
    gpx.push_str("</trkseg></trk></gpx>\n");
    (gpx, n)
}

#[test]
fn a_gpx_track_dropped_with_a_phone_log_is_its_reference() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let dir = data.join("sensorlogger-walk-ethz");
    let mut files = common::read_named(&common::files_in(&dir, "csv"));
    let location = files
        .iter()
        .position(|(name, _)| name == "Location.csv")
        .unwrap();
    let (_, location_csv) = files.remove(location);
    let (gpx, n_points) = gpx_of(&String::from_utf8_lossy(&location_csv));
    files.push(("walk.gpx".to_string(), gpx.into_bytes()));
    let slices: Vec<(&str, &[u8])> = files
        .iter()
        .map(|(n, b)| (n.as_str(), b.as_slice()))
        .collect();
    let report = compass_pdr::io::import::import_files(&slices).unwrap();
    let gnss = &report.recording.gnss;
    assert_eq!(gnss.len(), n_points);
    // The first fix is 1.594 s (its seconds_elapsed) after the log's start.
    assert!((gnss.t_s[0] - 1.594).abs() < 0.01, "{}", gnss.t_s[0]);
    assert!(report
        .notes
        .iter()
        .any(|note| note.contains("walk.gpx: placed on the sensor log's clock")));
    let analysis = calibrate(report, &CalibrationOptions::default()).unwrap();
    let calibration = &analysis.report;
    let Some(ReferenceSource::GpsCourse { used, .. }) = calibration.reference else {
        panic!("the track is the reference: {:?}", calibration.reference)
    };
    assert!(used.n_from_fixes > 200, "{used:?}");
    // The WMM at the track's first position and the log's date.
    assert!(calibration.expected_field.is_some());
    // Every field-domain method that was fitted beats the uncalibrated heading on the
    // held-back part, as with the phone's own Location.csv.
    let raw = calibration
        .raw_heading_error_check
        .as_ref()
        .unwrap()
        .rms_deg;
    for method in &calibration.methods {
        if let Some(check) = &method.heading_error_check {
            eprintln!(
                "{}: check RMS {:.1}° (uncalibrated {raw:.1}°)",
                method.label, check.rms_deg
            );
            assert!(check.rms_deg < raw, "{}", method.label);
        }
    }
}
