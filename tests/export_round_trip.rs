//! Exported calibrations applied as they say, to the raw values of the log they came from.
//!
//! For each importer family a distorted magnetometer log is written in that family's own
//! raw format from a known truth (hard iron and a general 3×3 soft iron in the sensor's
//! own axes and units, over a sphere of directions), imported and calibrated by the
//! crate's analysis, and exported (C snippet, calibration JSON, MotionCal packet). The
//! numbers are then parsed back out of the exported text and bytes, here and not by the
//! crate, and applied exactly as the text says, `corrected = soft_iron · (raw − hard_iron)`,
//! to the raw values parsed here from the log's text: the corrected field must be
//! constant (its spread as small as the fit reports) and the hard iron the truth's, in
//! the sensor's axes and the log's unit.
#![cfg(not(target_arch = "wasm32"))]

use compass_pdr::analysis::calibration::{
    CalibrationAnalysis, CalibrationOptions, MethodParameters,
};
use compass_pdr::base::rng::SplitMix64;
use compass_pdr::fit::export::{c_snippet, motioncal_packet};
use compass_pdr::pipeline::calibrate_files;
use compass_pdr::present::report::{device_export, DeviceExport};
use compass_pdr::sim::dance::{motioncal_raw_lines, DanceConfig};
use nalgebra::{Matrix3, Vector3};

mod common;
use common::{parse_c_snippet, spread_pct, Parsed};

/// A distorted magnetometer in its own axes and raw unit: `raw = distortion · b + hard_iron
/// + noise`, `b` the field (`field` long) over a sphere of directions.
struct Truth {
    hard_iron: Vector3<f64>,
    distortion: Matrix3<f64>,
    field: f64,
    noise: f64,
}

impl Truth {
    /// A general (not symmetric) soft iron: scale, cross-coupling and a small rotation.
    fn general(hard_iron: [f64; 3], field: f64, noise: f64) -> Truth {
        Truth {
            hard_iron: Vector3::from(hard_iron),
            distortion: Matrix3::new(
                1.09, 0.04, -0.03, //
                -0.02, 0.93, 0.05, //
                0.035, -0.01, 1.04,
            ),
            field,
            noise,
        }
    }

    /// `n` raw readings over the sphere (a Fibonacci spiral of directions).
    fn readings(&self, n: usize, seed: u64) -> Vec<Vector3<f64>> {
        let mut rng = SplitMix64::new(seed);
        (0..n)
            .map(|idx| {
                let z = 1.0 - 2.0 * (idx as f64 + 0.5) / n as f64;
                let azimuth = idx as f64 * 2.399_963_229_728_653;
                let r = (1.0 - z * z).sqrt();
                let b = self.field * Vector3::new(r * azimuth.cos(), r * azimuth.sin(), z);
                let noise = Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian());
                self.distortion * b + self.hard_iron + noise * self.noise
            })
            .collect()
    }
}

/// The numbers of a calibration JSON, with its `axes` and `unit`.
fn parse_json(text: &str) -> (Parsed, String, String) {
    let value: serde_json::Value = serde_json::from_str(text).expect("JSON");
    let numbers = |key: &str| -> Vec<f64> {
        let mut flat = Vec::new();
        let mut stack = vec![&value[key]];
        while let Some(item) = stack.pop() {
            match item {
                serde_json::Value::Array(items) => stack.extend(items.iter().rev()),
                other => flat.push(other.as_f64().unwrap_or(f64::NAN)),
            }
        }
        flat
    };
    let parsed = Parsed {
        hard_iron: Vector3::from_column_slice(&numbers("hard_iron")),
        soft_iron: Matrix3::from_row_slice(&numbers("soft_iron")),
        field: numbers("field")[0],
        ut_per_unit: numbers("ut_per_unit")[0],
    };
    let text_of = |key: &str| value[key].as_str().unwrap_or_default().to_string();
    (parsed, text_of("axes"), text_of("unit"))
}

/// MotionCal's packet read here from its bytes (layout in `fit::export`): µT.
fn parse_packet(packet: &[u8]) -> Parsed {
    assert_eq!(packet.len(), 68);
    assert_eq!(&packet[..2], b"uT");
    let float = |idx: usize| {
        let at = 2 + 4 * idx;
        f64::from(f32::from_le_bytes([
            packet[at],
            packet[at + 1],
            packet[at + 2],
            packet[at + 3],
        ]))
    };
    let (xx, yy, zz, xy, xz, yz) = (
        float(10),
        float(11),
        float(12),
        float(13),
        float(14),
        float(15),
    );
    Parsed {
        hard_iron: Vector3::new(float(6), float(7), float(8)),
        soft_iron: Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz),
        field: float(9),
        ut_per_unit: 1.0,
    }
}

fn analyse(files: &[(&str, &str)]) -> CalibrationAnalysis {
    let slices: Vec<(&str, &[u8])> = files
        .iter()
        .map(|(name, text)| (*name, text.as_bytes()))
        .collect();
    calibrate_files(&slices, &CalibrationOptions::default()).expect("the log calibrates")
}

/// The spread the analysis reports for its device calibration: the ellipsoid fit's own
/// figure, else that of |B| after the analysis's 3D correction.
fn reported_spread_pct(analysis: &CalibrationAnalysis, export: &DeviceExport) -> f64 {
    let report = analysis.report.method(export.method);
    match report.and_then(|report| report.parameters.as_ref()) {
        Some(MethodParameters::Ellipsoid(fit)) => fit.field_spread_pct,
        _ => spread_pct(
            analysis
                .field_corrected_ut
                .iter()
                .map(|&norm| Vector3::new(norm, 0.0, 0.0)),
        ),
    }
}

/// What one family's round trip measured.
struct Measured {
    hard_iron_error_ut: f64,
    spread_raw_pct: f64,
    spread_fit_pct: f64,
    spread_snippet_pct: f64,
    spread_json_pct: f64,
    spread_packet_pct: f64,
}

/// Exports the analysis's device calibration three ways, parses each back, applies it to
/// `raw` (the log's values as written, parsed by the caller) and checks it against the
/// truth's hard iron (same axes and unit as `raw`).
fn round_trip(
    family: &str,
    analysis: &CalibrationAnalysis,
    raw: &[Vector3<f64>],
    truth_hard_iron: Vector3<f64>,
    expect_axes: &str,
    expect_unit: &str,
) -> Measured {
    let export = device_export(analysis).expect("a device calibration");
    let snippet = c_snippet(&export.calibration);
    assert!(snippet.contains(expect_axes), "{family}: {snippet}");
    assert!(
        snippet.contains(&format!("Unit: {expect_unit}")),
        "{family}: {snippet}"
    );
    let json = serde_json::to_string_pretty(&export.sensor).expect("JSON");
    let packet = motioncal_packet(&export.calibration.in_ut().expect("a unit with its µT"));

    let from_snippet = parse_c_snippet(&snippet);
    let (from_json, axes, unit) = parse_json(&json);
    let from_packet = parse_packet(&packet);
    assert_eq!(axes, "sensor", "{family}: {json}");
    assert!(
        expect_unit.contains(&unit.replace('µ', "u")),
        "{family}: {unit}"
    );
    assert_eq!(from_json.ut_per_unit, from_snippet.ut_per_unit, "{family}");
    let u = from_snippet.ut_per_unit;

    let spread_snippet_pct = spread_pct(raw.iter().map(|r| from_snippet.apply(r)));
    let spread_json_pct = spread_pct(raw.iter().map(|r| from_json.apply(r)));
    // The packet is in µT: the raw values in µT along the same axes.
    let spread_packet_pct = spread_pct(raw.iter().map(|r| from_packet.apply(&(r * u))));
    let spread_fit_pct = reported_spread_pct(analysis, &export);
    let measured = Measured {
        hard_iron_error_ut: ((from_snippet.hard_iron - truth_hard_iron) * u).norm(),
        spread_raw_pct: spread_pct(raw.iter().copied()),
        spread_fit_pct,
        spread_snippet_pct,
        spread_json_pct,
        spread_packet_pct,
    };
    eprintln!(
        "{family}: {} method, {} in {}; hard iron error {:.3} µT; |B| spread raw {:.2} %, \
         fit {:.3} %, after the C snippet {:.3} %, JSON {:.3} %, packet {:.3} %",
        export.method.label(),
        axes,
        unit,
        measured.hard_iron_error_ut,
        measured.spread_raw_pct,
        measured.spread_fit_pct,
        measured.spread_snippet_pct,
        measured.spread_json_pct,
        measured.spread_packet_pct
    );
    assert!(
        measured.hard_iron_error_ut < 0.2,
        "{family}: hard iron {} vs the truth's {truth_hard_iron} ({u} µT per unit)",
        from_snippet.hard_iron
    );
    assert!(
        (from_packet.hard_iron - truth_hard_iron * u).norm() < 0.2,
        "{family}: packet hard iron {} µT",
        from_packet.hard_iron
    );
    for (form, spread) in [
        ("C snippet", spread_snippet_pct),
        ("JSON", spread_json_pct),
        ("packet", spread_packet_pct),
    ] {
        assert!(
            (spread - spread_fit_pct).abs() < 0.5,
            "{family}, {form}: |B| spread {spread:.3} % after the export, {spread_fit_pct:.3} % in the fit"
        );
    }
    // The field strength is the corrected field's, in the same unit.
    let mean_norm = raw
        .iter()
        .map(|r| from_snippet.apply(r).norm())
        .sum::<f64>()
        / raw.len() as f64;
    assert!(
        (mean_norm / from_snippet.field - 1.0).abs() < 0.01,
        "{family}: field {} vs mean |corrected| {mean_norm}",
        from_snippet.field
    );
    assert!((from_json.field - from_snippet.field).abs() < 1e-4 * from_snippet.field.abs());
    measured
}

/// The body-axes calibration (what the exports used to write) applied to the raw values
/// as the old text said: the hard iron's error and the spread it leaves.
fn applied_in_body_axes(
    export: &DeviceExport,
    raw: &[Vector3<f64>],
    truth_hard_iron_ut: Vector3<f64>,
) -> (f64, f64) {
    let body = export.body_ut.to_calibration().expect("valid");
    let u = export.calibration.frame.unit.factor();
    let spread = spread_pct(raw.iter().map(|r| body.apply(r * u)));
    ((body.hard_iron_ut - truth_hard_iron_ut).norm(), spread)
}

#[test]
fn serial_motioncal_raw_dance_recovers_its_hard_iron_in_sensor_axes_through_the_c_snippet() {
    let (text, truth) = motioncal_raw_lines(&DanceConfig::from_seed(5, 60.0));
    // The raw counts, read here: the last three of the nine integers.
    let raw: Vec<Vector3<f64>> = text
        .lines()
        .filter_map(|line| line.strip_prefix("Raw:"))
        .map(|values| {
            let counts: Vec<f64> = values
                .split(',')
                .map(|count| count.trim().parse::<f64>().expect("an integer"))
                .collect();
            Vector3::new(counts[6], counts[7], counts[8])
        })
        .collect();
    assert_eq!(raw.len(), 3000);
    let analysis = analyse(&[("dance.txt", &text)]);
    let truth_ut = Vector3::from(truth.hard_iron_ut);
    let measured = round_trip(
        "serial, MotionCal Raw: counts",
        &analysis,
        &raw,
        truth_ut / 0.1,
        "Axes: the sensor's own x, y, z as printed",
        "MotionCal count (0.1 uT)",
    );
    assert!(
        measured.spread_raw_pct > 10.0,
        "{}",
        measured.spread_raw_pct
    );
    // The correction undoes the dance's (symmetric) distortion up to the field's scale.
    let export = device_export(&analysis).expect("a device calibration");
    let from_snippet = parse_c_snippet(&c_snippet(&export.calibration));
    let undone = from_snippet.soft_iron
        * truth.soft_iron_matrix()
        * (truth.field_total_ut / (from_snippet.field * from_snippet.ut_per_unit));
    assert!((undone - Matrix3::identity()).amax() < 0.01, "{undone}");
    // What the exports wrote before: body axes, two signs wrong.
    let raw_ut: Vec<Vector3<f64>> = raw.iter().map(|r| r * 0.1).collect();
    let (old_error_ut, old_spread_pct) = applied_in_body_axes(&export, &raw, truth_ut);
    eprintln!(
        "serial dance, the old body-axes export applied to the raw values: hard iron off by \
         {old_error_ut:.1} µT, |B| spread {old_spread_pct:.1} % (raw {:.1} %)",
        spread_pct(raw_ut.into_iter())
    );
    assert!(old_error_ut > 10.0 && old_spread_pct > 3.0 * measured.spread_snippet_pct);
}

#[test]
fn serial_circuitpython_gauss_tuples_round_trip_in_gauss() {
    let truth = Truth::general([0.12, -0.31, 0.08], 0.48, 0.002);
    let readings = truth.readings(2500, 11);
    let text: String = readings
        .iter()
        .map(|m| {
            format!(
                "Magnetometer (gauss): ({:.5}, {:.5}, {:.5})\n",
                m.x, m.y, m.z
            )
        })
        .collect();
    let raw: Vec<Vector3<f64>> = text
        .lines()
        .map(|line| {
            let inner = line
                .split_once('(')
                .and_then(|(_, rest)| rest.split_once("): ("))
                .map(|(_, values)| values.trim_end_matches(')'))
                .expect("a tuple");
            let values: Vec<f64> = inner
                .split(',')
                .map(|value| value.trim().parse().expect("a number"))
                .collect();
            Vector3::new(values[0], values[1], values[2])
        })
        .collect();
    let analysis = analyse(&[("lsm9ds1.txt", &text)]);
    round_trip(
        "serial, CircuitPython gauss",
        &analysis,
        &raw,
        truth.hard_iron,
        "Axes: the sensor's own x, y, z as printed",
        "gauss (100 uT)",
    );
}

/// Rows of a CSV's columns `columns` (by index), read here.
fn csv_vectors(text: &str, columns: [usize; 3]) -> Vec<Vector3<f64>> {
    text.lines()
        .skip(1)
        .map(|line| {
            let cells: Vec<f64> = line
                .split(',')
                .map(|cell| cell.trim().parse().unwrap_or(f64::NAN))
                .collect();
            Vector3::new(cells[columns[0]], cells[columns[1]], cells[columns[2]])
        })
        .collect()
}

#[test]
fn plain_xyz_csv_spread_after_the_export_is_the_fit_s() {
    let truth = Truth::general([14.0, -22.0, 37.5], 48.0, 0.25);
    let mut text = String::from("x,y,z\n");
    for m in truth.readings(3000, 12) {
        text.push_str(&format!("{:.3},{:.3},{:.3}\n", m.x, m.y, m.z));
    }
    let raw = csv_vectors(&text, [0, 1, 2]);
    let analysis = analyse(&[("plain.csv", &text)]);
    let measured = round_trip(
        "plain x,y,z CSV",
        &analysis,
        &raw,
        truth.hard_iron,
        "Axes: the log's x, y, z columns as written",
        "assumed uT (the log gives no unit)",
    );
    assert!(
        (measured.spread_snippet_pct - measured.spread_fit_pct).abs() < 0.5,
        "{} vs {}",
        measured.spread_snippet_pct,
        measured.spread_fit_pct
    );
}

/// A phone's readings in Android device axes (specific force `gravity` at rest).
fn phone_log(truth: &Truth, seed: u64) -> Vec<(f64, Vector3<f64>)> {
    truth
        .readings(3000, seed)
        .into_iter()
        .enumerate()
        .map(|(idx, m)| (idx as f64 * 0.01, m))
        .collect()
}

#[test]
fn phyphox_files_in_device_axes_round_trip_in_device_axes() {
    let truth = Truth::general([-31.0, 12.5, -48.0], 48.0, 0.25);
    let readings = phone_log(&truth, 13);
    // Held upright: gravity's reaction along device +y, a little off.
    let mut acc = String::from("\"Time (s)\",\"X (m/s^2)\",\"Y (m/s^2)\",\"Z (m/s^2)\"\n");
    let mut mag = String::from("\"Time (s)\",\"X (µT)\",\"Y (µT)\",\"Z (µT)\"\n");
    for (t_s, m) in &readings {
        acc.push_str(&format!("{t_s:.3E},4.0E-1,9.75E0,6.0E-1\n"));
        mag.push_str(&format!("{t_s:.3E},{:.4E},{:.4E},{:.4E}\n", m.x, m.y, m.z));
    }
    let raw = csv_vectors(&mag, [1, 2, 3]);
    let analysis = analyse(&[("Accelerometer.csv", &acc), ("Magnetometer.csv", &mag)]);
    let frame = analysis.report.mag_frame.expect("a frame");
    assert_ne!(
        frame.body_from_sensor,
        Matrix3::identity(),
        "upright: rotated"
    );
    round_trip(
        "phyphox (two files, upright)",
        &analysis,
        &raw,
        truth.hard_iron,
        "Axes: Android device axes: x right, y towards the top of the screen, z out of the screen",
        "uT",
    );
    let export = device_export(&analysis).expect("a device calibration");
    let (old_error_ut, old_spread_pct) = applied_in_body_axes(&export, &raw, truth.hard_iron);
    eprintln!(
        "phyphox, the old body-axes export applied to the raw values: hard iron off by \
         {old_error_ut:.1} µT, |B| spread {old_spread_pct:.1} %"
    );
    assert!(old_error_ut > 10.0);
}

#[test]
fn sensor_logger_columns_in_device_axes_round_trip_in_device_axes() {
    let truth = Truth::general([22.0, 40.0, -15.0], 50.0, 0.25);
    let readings = phone_log(&truth, 14);
    // Sensor Logger's bare names, z before y before x; flat, screen up.
    let mut text = String::from("seconds_elapsed,acc_z,acc_y,acc_x,mag_z,mag_y,mag_x\n");
    for (t_s, m) in &readings {
        text.push_str(&format!(
            "{t_s:.3},9.79,0.3,-0.2,{:.4},{:.4},{:.4}\n",
            m.z, m.y, m.x
        ));
    }
    let raw = csv_vectors(&text, [6, 5, 4]);
    let analysis = analyse(&[("Combined.csv", &text)]);
    round_trip(
        "Sensor Logger columns (flat)",
        &analysis,
        &raw,
        truth.hard_iron,
        "Axes: Android device axes",
        "assumed uT (the log gives no unit)",
    );
}

#[test]
fn android_sensor_dump_round_trips_in_device_axes() {
    let truth = Truth::general([-56.3, -90.9, -301.5], 48.0, 0.25);
    let readings = phone_log(&truth, 15);
    let mut text = String::from("#\tstartTime:1574562661929\n");
    for (idx, (_, m)) in readings.iter().enumerate() {
        let unix_ms = 1_574_562_662_000u64 + 20 * idx as u64;
        text.push_str(&format!(
            "{unix_ms}\tTYPE_ACCELEROMETER\t-0.3\t0.5\t9.7\t3\n\
             {unix_ms}\tTYPE_MAGNETIC_FIELD_UNCALIBRATED\t{:.5}\t{:.5}\t{:.5}\t-50.0\t-90.0\t-300.0\t3\n",
            m.x, m.y, m.z
        ));
    }
    let raw: Vec<Vector3<f64>> = text
        .lines()
        .filter(|line| line.contains("\tTYPE_MAGNETIC_FIELD_UNCALIBRATED\t"))
        .map(|line| {
            let cells: Vec<f64> = line
                .split('\t')
                .skip(2)
                .map(|cell| cell.parse().expect("a number"))
                .collect();
            Vector3::new(cells[0], cells[1], cells[2])
        })
        .collect();
    let analysis = analyse(&[("dump.txt", &text)]);
    round_trip(
        "Android sensor dump (flat)",
        &analysis,
        &raw,
        truth.hard_iron,
        "Axes: Android device axes",
        "uT",
    );
}

#[test]
fn get_sensor_data_round_trips_in_device_axes() {
    let truth = Truth::general([8.0, -27.0, 19.0], 45.0, 0.25);
    let readings = phone_log(&truth, 16);
    let mut text = String::from("% GetSensorData log\n");
    for (t_s, m) in &readings {
        text.push_str(&format!(
            "ACCE;{t_s:.3};{:.3};0.2;9.76;0.9;3\nMAGN;{:.3};{:.3};{:.5};{:.5};{:.5};3\n",
            1000.0 + t_s,
            t_s + 0.001,
            1000.0 + t_s,
            m.x,
            m.y,
            m.z
        ));
    }
    let raw: Vec<Vector3<f64>> = text
        .lines()
        .filter_map(|line| line.strip_prefix("MAGN;"))
        .map(|rest| {
            let cells: Vec<f64> = rest
                .split(';')
                .map(|cell| cell.parse().expect("a number"))
                .collect();
            Vector3::new(cells[2], cells[3], cells[4])
        })
        .collect();
    let analysis = analyse(&[("gsd.txt", &text)]);
    round_trip(
        "GetSensorData (upright)",
        &analysis,
        &raw,
        truth.hard_iron,
        "Axes: Android device axes",
        "uT",
    );
}
