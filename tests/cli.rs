//! The CLI as a user runs it: files in, text and files out, exit codes.
#![cfg(not(target_arch = "wasm32"))]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn compass_pdr(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_compass-pdr"))
        .args(args)
        .output()
        .expect("the CLI runs")
}

fn scratch_dir(test_name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(test_name);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// `compass-pdr simulate ARGS --out OUT`, which must succeed.
fn simulate_to(out: &Path, args: &[&str]) {
    let out_arg = ["--out", out.to_str().unwrap_or_default()];
    let all: Vec<&str> = ["simulate"]
        .iter()
        .chain(args)
        .chain(&out_arg)
        .copied()
        .collect();
    let output = compass_pdr(&all);
    assert!(output.status.success(), "{}", stderr(&output));
}

#[test]
fn the_committed_demo_is_what_the_simulator_writes() {
    let dir = scratch_dir("demo");
    let out = dir.join("demo-walk.csv");
    simulate_to(&out, &["--seed", "1", "--duration-s", "240"]);
    let regenerated = std::fs::read(&out).expect("written");
    let committed =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/demo-walk.csv"))
            .expect("committed demo");
    assert!(
        regenerated == committed,
        "assets/demo-walk.csv is stale: regenerate it with the command in docs/development.md"
    );
}

#[test]
fn simulate_writes_the_pdr_scenario_with_its_step_truth() {
    let dir = scratch_dir("pdr-scenario");
    let (out, truth) = (dir.join("pdr-walk.csv"), dir.join("pdr-walk.truth.json"));
    let output = compass_pdr(&[
        "simulate",
        "--scenario",
        "pdr",
        "--seed",
        "3",
        "--duration-s",
        "120",
        "--sample-rate-hz",
        "100",
        "--out",
        out.to_str().unwrap_or_default(),
        "--truth",
        truth.to_str().unwrap_or_default(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let text = std::fs::read_to_string(&out).expect("written");
    assert_eq!(text.lines().count(), 1 + 12_000);
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&truth).expect("truth written")).expect("JSON");
    assert_eq!(json["config"]["gait"]["kind"], "varied");
    assert_eq!(json["config"]["sample_rate_hz"], 100.0);
    assert_eq!(json["config"]["gnss"]["position_noise_m"], 3.0);
    let steps = json["steps"].as_array().cloned().unwrap_or_default();
    assert!(steps.len() > 100, "{} steps", steps.len());
    let sum_of_lengths_m: f64 = steps
        .iter()
        .map(|step| step["length_m"].as_f64().unwrap_or(f64::NAN))
        .sum();
    let path_length_m = json["path_length_m"].as_f64().unwrap_or(f64::NAN);
    assert!(
        (sum_of_lengths_m - path_length_m).abs() < 1e-6,
        "{sum_of_lengths_m} vs {path_length_m}"
    );
    for key in [
        "t_start_s",
        "t_end_s",
        "frequency_hz",
        "heading_rad",
        "vertical_peak_to_peak_mps2",
    ] {
        assert!(steps[0][key].is_f64(), "{key}");
    }

    // The steady walk's truth is the config alone, without a gait.
    let demo_truth = dir.join("demo.truth.json");
    let output = compass_pdr(&[
        "simulate",
        "--scenario",
        "steady",
        "--duration-s",
        "10",
        "--out",
        dir.join("demo.csv").to_str().unwrap_or_default(),
        "--truth",
        demo_truth.to_str().unwrap_or_default(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&demo_truth).expect("written")).expect("JSON");
    assert_eq!(json["seed"], 1);
    assert!(
        json.get("gait").is_none() && json.get("steps").is_none(),
        "{json}"
    );

    let bad = compass_pdr(&[
        "simulate",
        "--sample-rate-hz",
        "0",
        "--out",
        dir.join("never.csv").to_str().unwrap_or_default(),
    ]);
    assert_eq!(bad.status.code(), Some(1));
    assert!(
        stderr(&bad).contains("--sample-rate-hz 0 is out of range"),
        "{}",
        stderr(&bad)
    );
}

#[test]
fn simulate_writes_a_car_loop_as_nmea_that_reads_back() {
    let dir = scratch_dir("simulate-nmea");
    let out = dir.join("car.nmea");
    simulate_to(
        &out,
        &[
            "--scenario",
            "vehicle",
            "--duration-s",
            "60",
            "--sample-rate-hz",
            "10",
        ],
    );
    let text = std::fs::read_to_string(&out).expect("written");
    assert!(
        text.starts_with("$GPRMC,120000.00,A,4808."),
        "{}",
        &text[..80.min(text.len())]
    );
    let output = compass_pdr(&["inspect", out.to_str().unwrap_or_default(), "--json"]);
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
    assert_eq!(json["format"], "NMEA 0183");
    assert_eq!(
        json["diagnostics"]["kept"].as_array().map(Vec::len),
        Some(0)
    );
    let streams: Vec<String> = json["streams"]
        .as_array()
        .map(|streams| {
            streams
                .iter()
                .map(|stream| stream["stream"].to_string())
                .collect()
        })
        .unwrap_or_default();
    assert!(
        streams.iter().any(|name| name.contains("GNSS")),
        "{streams:?}"
    );
}

#[test]
fn calibrate_prints_json_with_the_heading_errors() {
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/demo-walk.csv");
    let output = compass_pdr(&[
        "calibrate",
        demo.to_str().unwrap_or_default(),
        "--method",
        "minmax",
        "--json",
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON on stdout");
    assert_eq!(json["n_samples_used"], 12000);
    assert_eq!(json["methods"].as_array().map(Vec::len), Some(1));
    let method = &json["methods"][0];
    assert_eq!(method["method"], "min_max");
    let rms_before = json["raw_heading_error_check"]["rms_deg"]
        .as_f64()
        .unwrap_or(f64::NAN);
    let rms_after = method["heading_error_check"]["rms_deg"]
        .as_f64()
        .unwrap_or(f64::NAN);
    // The demo's compass also drifts with temperature and passes near iron: a few
    // degrees are left after a field-domain calibration (the heading models take more).
    assert!(
        rms_before > 10.0 && rms_after < 5.0,
        "before {rms_before}, after {rms_after}"
    );
    for key in ["scale_x", "scale_y", "bias_x_ut", "bias_y_ut"] {
        assert!(method["parameters"][key].is_f64(), "{key}");
    }
    assert_eq!(json["reference"]["kind"], "column");
}

#[test]
fn calibrate_all_methods_and_export_the_device_calibration() {
    let dir = scratch_dir("exports");
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/demo-walk.csv");
    let (c_path, packet_path) = (dir.join("calibration.h"), dir.join("calibration.bin"));
    let output = compass_pdr(&[
        "calibrate",
        demo.to_str().unwrap_or_default(),
        "--export-c",
        c_path.to_str().unwrap_or_default(),
        "--export-packet",
        packet_path.to_str().unwrap_or_default(),
        "--declination",
        "-3.5",
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let text = String::from_utf8_lossy(&output.stdout);
    for label in [
        "uncalibrated",
        "min/max",
        "ellipse (tilt-aware 2D)",
        "ellipsoid (3D)",
        "reference LS (Eq. 8)",
        "best:",
    ] {
        assert!(text.contains(label), "{label} in {text}");
    }
    assert!(
        text.contains("declination: -3.50° (given by the user)"),
        "{text}"
    );
    let snippet = std::fs::read_to_string(&c_path).expect("C snippet written");
    assert!(
        snippet.contains("float hard_iron[3]") && snippet.contains("float soft_iron[3][3]"),
        "{snippet}"
    );
    let packet = std::fs::read(&packet_path).expect("packet written");
    assert_eq!(packet.len(), 68);
    assert_eq!(&packet[..2], b"uT");
    assert!(compass_pdr::fit::export::parse_motioncal_packet(&packet).is_ok());
    let bad = compass_pdr(&[
        "calibrate",
        demo.to_str().unwrap_or_default(),
        "--declination",
        "east",
    ]);
    assert_eq!(bad.status.code(), Some(1));
    assert!(
        stderr(&bad).contains("--declination east: give `auto` or degrees"),
        "{}",
        stderr(&bad)
    );
}

#[test]
fn calibrate_draws_the_plots_to_svg() {
    let dir = scratch_dir("plot");
    let svg = dir.join("plot.svg");
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/demo-walk.csv");
    let output = compass_pdr(&[
        "calibrate",
        demo.to_str().unwrap_or_default(),
        "--plot",
        svg.to_str().unwrap_or_default(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let text = std::fs::read_to_string(&svg).expect("SVG written");
    assert!(
        text.contains("Level-plane field")
            && text.contains("Heading error against the reference heading")
    );
    assert!(String::from_utf8_lossy(&output.stdout).contains("best:"));
}

#[test]
fn heading_compares_every_method_and_draws_the_deviation_figure() {
    let dir = scratch_dir("heading");
    let svg = dir.join("deviation.svg");
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/demo-walk.csv");
    let demo = demo.to_str().unwrap_or_default();
    let output = compass_pdr(&["heading", demo, "--plot", svg.to_str().unwrap_or_default()]);
    assert!(output.status.success(), "{}", stderr(&output));
    let text = std::fs::read_to_string(&svg).expect("SVG written");
    for caption in [
        "Deviation curve (Eq. 12)",
        "Residuals:",
        "Heading error against the reference heading",
        "Online A…E",
    ] {
        assert!(text.contains(caption), "{caption} missing from the figure");
    }
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("min/max + Fourier") && stdout.contains("MLP on "),
        "{stdout}"
    );
    let output = compass_pdr(&["heading", demo, "--json", "--reference", "legs"]);
    // The demo has positions on every row: legs between them are a reference too.
    assert!(output.status.success(), "{}", stderr(&output));
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
    assert_eq!(report["reference"]["kind"], "legs");
    assert!(report["rows"]
        .as_array()
        .is_some_and(|rows| rows.len() >= 9));
}

#[test]
fn pdr_dead_reckons_the_demo_and_writes_the_track_and_figure() {
    let dir = scratch_dir("pdr");
    let (svg, csv, gpx) = (
        dir.join("pdr.svg"),
        dir.join("track.csv"),
        dir.join("track.gpx"),
    );
    // A walk without GNSS: the step model is fitted to a known distance, if any.
    let steady = dir.join("steady.csv");
    simulate_to(&steady, &["--scenario", "steady"]);
    let demo = steady.to_str().unwrap_or_default();
    let output = compass_pdr(&[
        "pdr",
        demo,
        "--known-distance",
        "217",
        "--plot",
        svg.to_str().unwrap_or_default(),
        "--out",
        csv.to_str().unwrap_or_default(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(stdout.contains("fitted to the known distance"), "{stdout}");
    assert!(stdout.contains("GNSS: none in the log"), "{stdout}");
    let figure = std::fs::read_to_string(&svg).expect("SVG written");
    for caption in [
        "Trajectory: ",
        "Step length: Weinberg",
        "Position error against the reference",
    ] {
        assert!(
            figure.contains(caption),
            "{caption} missing from the figure"
        );
    }
    let track = std::fs::read_to_string(&csv).expect("track written");
    assert!(track.starts_with("t_s,east_m,north_m,lat_deg,lon_deg,"));
    assert!(track.lines().count() > 300, "a row per step");

    let output = compass_pdr(&["pdr", demo, "--json", "--step-model", "linear"]);
    assert!(output.status.success(), "{}", stderr(&output));
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
    assert!(report["n_steps"]
        .as_u64()
        .is_some_and(|n| (300..330).contains(&n)));
    assert!(report["position_error"]["rms_m"].is_number());
    // Nothing in the demo trains a linear model: the default Weinberg K is used, and said.
    assert_eq!(report["step_model"]["trained_on"], "default");

    // The demo has GNSS with a minute's gap: the step model learns from the GNSS speed,
    // the gap is bridged and scored, and the track has latitude and longitude for GPX.
    let gnss_demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/demo-walk.csv");
    let gnss_demo = gnss_demo.to_str().unwrap_or_default();
    let output = compass_pdr(&["pdr", gnss_demo, "--out", gpx.to_str().unwrap_or_default()]);
    assert!(output.status.success(), "{}", stderr(&output));
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(stdout.contains("trained on the GNSS speed"), "{stdout}");
    assert!(stdout.contains("no GNSS 143-204 s"), "{stdout}");
    let gpx_text = std::fs::read_to_string(&gpx).expect("GPX written");
    assert!(gpx_text.matches("<trkpt").count() > 400, "a point per step");
    let output = compass_pdr(&["pdr", gnss_demo, "--json"]);
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
    let gap_max_m = report["gnss_gaps"][0]["position_error"]["max_m"]
        .as_f64()
        .unwrap_or(f64::NAN);
    assert!(gap_max_m < 5.0, "{gap_max_m} m off at worst across the gap");

    // A track without GNSS has no latitude and longitude for GPX; a bad outage is refused.
    for (args, expected) in [
        (
            vec!["--out", gpx.to_str().unwrap_or_default()],
            "can only be written as CSV",
        ),
        (vec!["--outage", "5"], "give START:END in seconds"),
        (
            vec!["--step-model", "stride"],
            "choose linear, weinberg or mlp",
        ),
        (
            vec!["--out", "track.kml"],
            "end the file name with .csv, .geojson or .gpx",
        ),
    ] {
        let mut all = vec!["pdr", demo];
        all.extend(args);
        let output = compass_pdr(&all);
        assert_eq!(output.status.code(), Some(1));
        assert!(stderr(&output).contains(expected), "{}", stderr(&output));
    }
}

/// Bad input: exit code 1, a message naming the file and what to do, never a panic.
#[test]
fn simulate_writes_the_calibration_dance_as_motioncal_lines_with_its_truth() {
    let dir = scratch_dir("dance");
    let (out, truth) = (dir.join("dance.txt"), dir.join("dance.json"));
    let dance = [
        "--scenario",
        "dance",
        "--duration-s",
        "30",
        "--sample-rate-hz",
        "100",
    ];
    let with_truth: Vec<&str> = dance
        .iter()
        .copied()
        .chain(["--truth", truth.to_str().unwrap_or_default()])
        .collect();
    simulate_to(&out, &with_truth);
    let text = std::fs::read_to_string(&out).expect("written");
    assert_eq!(text.lines().count(), 3000);
    assert!(text.lines().all(|line| line.starts_with("Raw:")));
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&truth).expect("written")).expect("JSON");
    assert_eq!(truth["n_lines"], 3000);
    assert_eq!(truth["hard_iron_ut"].as_array().map(Vec::len), Some(3));
    // The same seed gives the same lines.
    let again = dir.join("again.txt");
    simulate_to(&again, &dance);
    assert_eq!(std::fs::read(&again).expect("written"), text.into_bytes());
}

#[test]
fn calibrate_exports_a_board_s_dance_in_the_board_s_axes_and_units() {
    let dir = scratch_dir("dance-exports");
    let (out, truth_path) = (dir.join("dance.txt"), dir.join("dance.json"));
    simulate_to(
        &out,
        &[
            "--scenario",
            "dance",
            "--truth",
            truth_path.to_str().unwrap_or_default(),
        ],
    );
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&truth_path).expect("written"))
            .expect("JSON");
    let truth_ut: Vec<f64> = (0..3)
        .map(|idx| truth["hard_iron_ut"][idx].as_f64().unwrap_or(f64::NAN))
        .collect();
    let (c_path, packet_path) = (dir.join("board.h"), dir.join("board.bin"));
    let args = [
        "calibrate",
        out.to_str().unwrap_or_default(),
        "--export-c",
        c_path.to_str().unwrap_or_default(),
        "--export-packet",
        packet_path.to_str().unwrap_or_default(),
    ];
    let output = compass_pdr(&args);
    assert!(output.status.success(), "{}", stderr(&output));
    let text = String::from_utf8_lossy(&output.stdout);
    for expected in [
        "in the magnetometer's own axes and unit: the sensor's own x, y, z as printed",
        "raw values in MotionCal count (0.1 µT)",
        "corrected = S · (raw − h)",
        "MotionCal packet written to",
        "in µT along the sensor's own x, y, z as printed",
    ] {
        assert!(text.contains(expected), "{expected} in {text}");
    }
    let snippet = std::fs::read_to_string(&c_path).expect("written");
    assert!(
        snippet.contains("// Unit: MotionCal count (0.1 uT)"),
        "{snippet}"
    );
    assert!(
        snippet.contains("float mag_ut_per_unit = 0.1f;"),
        "{snippet}"
    );
    // The packet's hard iron: µT, the board's axes.
    let packet = std::fs::read(&packet_path).expect("written");
    let float = |idx: usize| {
        let at = 2 + 4 * idx;
        f64::from(f32::from_le_bytes([
            packet[at],
            packet[at + 1],
            packet[at + 2],
            packet[at + 3],
        ]))
    };
    for (axis, truth_ut) in truth_ut.iter().enumerate() {
        let packet_ut = float(6 + axis);
        assert!(
            (packet_ut - truth_ut).abs() < 0.2,
            "axis {axis}: {packet_ut} vs {truth_ut}"
        );
    }
    // The JSON: the sensor's calibration in counts, and the body-axes one in µT.
    let output = compass_pdr(&[args[0], args[1], "--json"]);
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
    let device = &json["device_calibration"];
    assert_eq!(device["sensor"]["axes"], "sensor");
    assert_eq!(device["sensor"]["unit"], "MotionCal count");
    assert_eq!(device["body_ut"]["axes"], "body");
    let signs = [1.0, -1.0, -1.0];
    for (axis, (truth_ut, sign)) in truth_ut.iter().zip(signs).enumerate() {
        let counts = device["sensor"]["hard_iron"][axis]
            .as_f64()
            .unwrap_or(f64::NAN);
        let body_ut = device["body_ut"]["hard_iron"][axis]
            .as_f64()
            .unwrap_or(f64::NAN);
        assert!(
            (counts * 0.1 - truth_ut).abs() < 0.2,
            "axis {axis}: {counts}"
        );
        assert!(
            (body_ut - sign * truth_ut).abs() < 0.2,
            "axis {axis}: {body_ut}"
        );
    }
    assert_eq!(json["mag_frame"]["unit"]["name"], "MotionCal count");
    assert_eq!(
        json["mag_frame"]["body_from_sensor"],
        serde_json::json!([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    );
}

#[test]
fn report_writes_the_page_s_html_report_with_svg_figures() {
    let dir = scratch_dir("report");
    let out = dir.join("demo-report.html");
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/demo-walk.csv");
    let output = compass_pdr(&[
        "report",
        demo.to_str().unwrap_or_default(),
        "--out",
        out.to_str().unwrap_or_default(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let html = std::fs::read_to_string(&out).expect("written");
    assert!(html.starts_with("<!doctype html>"));
    assert!(
        html.contains("demo-walk.csv</title>"),
        "the log is named in the title"
    );
    assert_eq!(
        html.matches("<svg").count(),
        4,
        "the answer's picture, calibration, heading models, PDR"
    );
    assert!(html.contains("415 steps in 3 bouts"), "the PDR summary");
    assert!(
        html.contains("No GNSS fix from 143 to 204 s"),
        "the gap bridged"
    );
    assert!(!html.contains("<script"));
}

fn check_refused(test_name: &str, file_name: &str, content: &[u8], expect_in_message: &str) {
    let dir = scratch_dir(test_name);
    let path = dir.join(file_name);
    std::fs::write(&path, content).expect("written");
    let output = compass_pdr(&["calibrate", path.to_str().unwrap_or_default(), "--json"]);
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(1), "{message}");
    assert!(!message.contains("panicked"), "{message}");
    assert!(
        message.contains(file_name),
        "the message names the file: {message}"
    );
    assert!(message.contains(expect_in_message), "{message}");
    assert!(output.stdout.is_empty());
}

#[test]
fn bad_inputs_are_refused_with_clear_messages() {
    let garbage: Vec<u8> = (0..4096u32)
        .map(|idx| (idx.wrapping_mul(2_654_435_761) >> 24) as u8)
        .collect();
    check_refused("garbage", "garbage.bin", &garbage, "is not a text log");
    check_refused("empty", "empty.csv", b"", "is empty. Choose a log");
    check_refused(
        "nomag",
        "no-mag.csv",
        b"t_s,acc_x_mps2,acc_y_mps2,acc_z_mps2\n0,0,0,-9.81\n",
        "has no magnetometer columns",
    );
    check_refused(
        "nans",
        "nans.csv",
        b"t_s,mag_x_ut,mag_y_ut,mag_z_ut\n0,NaN,NaN,NaN\n1,NaN,NaN,NaN\n",
        "line 2: mag_x_ut is NaN",
    );
    check_refused("flat", "still.csv", b"t_s,mag_x_ut,mag_y_ut,mag_z_ut\n0,20,0,40\n1,20,0,40\n2,20,0,40\n3,20,0,40\n4,20,0,40\n5,20,0,40\n6,20,0,40\n7,20,0,40\n8,20,0,40\n9,20,0,40\n10,20,0,40\n11,20,0,40\n12,20,0,40\n13,20,0,40\n14,20,0,40\n15,20,0,40\n16,20,0,40\n17,20,0,40\n18,20,0,40\n19,20,0,40\n20,20,0,40\n", "Turn the device through a full circle");
}

#[test]
fn a_missing_file_is_reported() {
    let output = compass_pdr(&["calibrate", "/nonexistent/log.csv"]);
    assert_eq!(output.status.code(), Some(1));
    assert!(stderr(&output).contains("cannot read /nonexistent/log.csv"));
}

#[test]
fn bad_lines_are_listed_with_their_line_numbers_and_the_rest_is_used() {
    let dir = scratch_dir("badlines");
    let path = dir.join("partly-bad.csv");
    let mut text = String::from("t_s,mag_x_ut,mag_y_ut,mag_z_ut\n");
    for idx in 0..100 {
        let angle_rad = (idx as f64 * 3.6).to_radians();
        if idx == 10 {
            text.push_str("10,abc,1,2\n");
        } else {
            text.push_str(&format!(
                "{idx},{},{},40\n",
                20.0 * angle_rad.cos(),
                20.0 * angle_rad.sin()
            ));
        }
    }
    std::fs::write(&path, text).expect("written");
    let output = compass_pdr(&["calibrate", path.to_str().unwrap_or_default(), "--json"]);
    assert!(output.status.success(), "{}", stderr(&output));
    assert!(
        stderr(&output).contains("partly-bad.csv:12: mag_x_ut is not a number (abc)"),
        "{}",
        stderr(&output)
    );
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
    assert_eq!(json["n_samples_used"], 99);
}

#[test]
fn a_column_mapping_reads_an_unknown_header_and_is_remembered() {
    let dir = scratch_dir("mapping");
    let config_dir = dir.join("config");
    let _ = std::fs::remove_dir_all(&config_dir);
    let path = dir.join("logger.csv");
    let mut text = String::from("time,ch1,ch2,ch3,note\n");
    for idx in 0..200 {
        let angle_rad = (idx as f64 * 1.8).to_radians();
        text.push_str(&format!(
            "{},{},{},0.4,ok\n",
            idx * 10,
            0.2 * angle_rad.cos(),
            0.2 * angle_rad.sin()
        ));
    }
    std::fs::write(&path, text).expect("written");
    let path_text = path.to_str().unwrap_or_default();
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_compass-pdr"))
            .args(args)
            .env("XDG_CONFIG_HOME", &config_dir)
            .output()
            .expect("the CLI runs")
    };

    // Without a mapping, ch1..ch3 are not magnetometer columns.
    let refused = run(&["calibrate", path_text]);
    assert_eq!(refused.status.code(), Some(1), "{}", stderr(&refused));
    assert!(
        stderr(&refused).contains("no magnetometer columns"),
        "{}",
        stderr(&refused)
    );

    // A bad mapping says what to write.
    let bad = run(&["inspect", path_text, "--map", "ch1=magnet"]);
    assert_eq!(bad.status.code(), Some(1));
    assert!(
        stderr(&bad).contains("--map: 'magnet' (for column 'ch1') is not a name this tool reads"),
        "{}",
        stderr(&bad)
    );

    // With one, the gauss values become µT and time in ms becomes seconds.
    let mapped = run(&[
        "inspect",
        path_text,
        "--json",
        "--map",
        "ch1=mag_x_gauss,ch2=mag_y_gauss,ch3=mag_z_gauss,time=t_ms",
    ]);
    assert!(mapped.status.success(), "{}", stderr(&mapped));
    let json: serde_json::Value = serde_json::from_slice(&mapped.stdout).expect("JSON");
    let magnetometer = &json["streams"][0];
    assert_eq!(magnetometer["stream"], "magnetometer");
    assert_eq!(magnetometer["n_samples"], 200);
    assert!((magnetometer["duration_s"].as_f64().unwrap_or(0.0) - 1.99).abs() < 1e-9);
    assert!(
        (magnetometer["mean_magnitude"].as_f64().unwrap_or(0.0) - (20f64.hypot(40.0))).abs() < 1e-6
    );

    // The next run remembers it, and says so.
    let remembered = run(&["calibrate", path_text]);
    assert!(remembered.status.success(), "{}", stderr(&remembered));
    assert!(
        stderr(&remembered).contains("using the column mapping remembered for this header"),
        "{}",
        stderr(&remembered)
    );
}

#[test]
fn numbers_without_a_header_line_are_read_through_a_mapping_of_their_columns() {
    let dir = scratch_dir("headerless");
    let config_dir = dir.join("config");
    let _ = std::fs::remove_dir_all(&config_dir);
    let path = dir.join("mag.txt");
    let mut text = String::new();
    for idx in 0..200 {
        let angle_rad = (idx as f64 * 1.8).to_radians();
        text.push_str(&format!(
            "{:.2}  {:.4} {:.4}\t-40\n",
            idx as f64 * 0.02,
            20.0 * angle_rad.cos(),
            20.0 * angle_rad.sin()
        ));
    }
    std::fs::write(&path, text).expect("written");
    let path_text = path.to_str().unwrap_or_default();
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_compass-pdr"))
            .args(args)
            .env("XDG_CONFIG_HOME", &config_dir)
            .output()
            .expect("the CLI runs")
    };
    let refused = run(&["inspect", path_text]);
    assert_eq!(refused.status.code(), Some(1), "{}", stderr(&refused));
    assert!(
        stderr(&refused).contains("has no header line: line 1 is already 4 numbers"),
        "{}",
        stderr(&refused)
    );
    let mapped = run(&[
        "inspect",
        path_text,
        "--json",
        "--map",
        "column 1=t_s,column 2=mag_x_ut,column 3=mag_y_ut,column 4=mag_z_ut",
    ]);
    assert!(mapped.status.success(), "{}", stderr(&mapped));
    let json: serde_json::Value = serde_json::from_slice(&mapped.stdout).expect("JSON");
    assert_eq!(json["streams"][0]["stream"], "magnetometer");
    assert_eq!(json["streams"][0]["n_samples"], 200);
}

#[test]
fn the_qmc5883l_file_calibrates_at_50_hz_in_counts_without_warnings() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let path = data.join("qmc5883l-calibration/filtered_raw_data.csv");
    let output = compass_pdr(&["calibrate", path.to_str().unwrap_or_default()]);
    assert!(output.status.success(), "{}", stderr(&output));
    assert!(!stderr(&output).contains("warning"), "{}", stderr(&output));
    let text = String::from_utf8_lossy(&output.stdout);
    for expected in [
        "the samples are spaced at 50 Hz, the rate on line 1 (Fs,50.00)",
        "field: measured 7401.5 counts raw",
        "Hard iron (",
        ") counts",
    ] {
        assert!(text.contains(expected), "{expected}\n{text}");
    }
}

/// A drone log with nothing to write: `calibrate` reports it (the autopilot's compasses
/// are assessed on their own, whatever the generic fits say) with each compass's
/// parameters in force judged against the Earth's field and why they are kept, and
/// `--param-out` refuses with the same sentences.
#[test]
fn a_drone_log_with_nothing_to_write_is_told_to_keep_its_parameters_in_force() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let path = data.join("px4-ulog/sample_log_small.ulg");
    let output = compass_pdr(&["calibrate", path.to_str().unwrap_or_default()]);
    assert!(output.status.success(), "{}", stderr(&output));
    let text = String::from_utf8_lossy(&output.stdout).into_owned();
    let expected = "CAL_MAG1 (vehicle_magnetometer 0): parameters in force kept (";
    assert!(text.contains(expected), "{expected}\n{text}");
    assert!(text.contains("too few to judge a calibration on"), "{text}");
    let param = scratch_dir("drone-nothing").join("sample_log_small.params");
    let output = compass_pdr(&[
        "calibrate",
        path.to_str().unwrap_or_default(),
        "--param-out",
        param.to_str().unwrap_or_default(),
    ]);
    assert_eq!(output.status.code(), Some(1), "{}", stderr(&output));
    let message = stderr(&output);
    for expected in [
        "no autopilot parameters to write",
        expected,
        "Record a flight",
    ] {
        assert!(message.contains(expected), "{expected}\n{message}");
    }
    assert!(!param.exists());
}

/// `compass-pdr ARGS --json`, parsed; the command must succeed.
fn json_of(args: &[&str]) -> serde_json::Value {
    let all: Vec<&str> = args.iter().copied().chain(["--json"]).collect();
    let output = compass_pdr(&all);
    assert!(output.status.success(), "{args:?}: {}", stderr(&output));
    serde_json::from_slice(&output.stdout).expect("JSON")
}

/// Every command and the report name the same best method and the same device
/// calibration (one pipeline, one choice): on the demo (a reference column and GNSS),
/// on a walk with GNSS course only, and on a board turned in the hand (no reference).
#[test]
fn every_command_and_the_report_name_the_same_best_and_device_calibration() {
    let dir = scratch_dir("one-best");
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/demo-walk.csv");
    let dance = dir.join("dance.txt");
    let output = compass_pdr(&[
        "simulate",
        "--scenario",
        "dance",
        "--out",
        dance.to_str().unwrap_or_default(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let car = dir.join("car.csv");
    simulate_to(&car, &["--scenario", "vehicle", "--seed", "3"]);
    for (log, walks) in [(demo, true), (car, false), (dance, false)] {
        let log = log.to_str().unwrap_or_default();
        let calibrated = json_of(&["calibrate", log]);
        let headings = json_of(&["heading", log]);
        let best = headings["choice"]["key"]
            .as_str()
            .expect("a best")
            .to_string();
        assert_eq!(
            calibrated["choice"]["key"], headings["choice"]["key"],
            "{log}"
        );
        // The device calibration is the best's own when that has a 3D correction.
        let device = calibrated["device_calibration"]["method"]
            .as_str()
            .unwrap_or("");
        let base = best.split('+').next().unwrap_or("");
        if ["ellipse", "ellipsoid"].contains(&base) {
            assert_eq!(
                device, base,
                "{log}: the device calibration follows the best"
            );
        }
        if walks {
            let pdr = json_of(&["pdr", log]);
            assert_eq!(pdr["heading_key"].as_str(), Some(best.as_str()), "{log}");
        }
        let report = dir.join("report.html");
        let output = compass_pdr(&["report", log, "--out", report.to_str().unwrap_or_default()]);
        assert!(output.status.success(), "{}", stderr(&output));
        let html = std::fs::read_to_string(&report).expect("written");
        let label = headings["choice"]["label"].as_str().expect("a label");
        assert!(
            html.contains(&format!("Best: {}", label.replace('&', "&amp;"))),
            "{log}: the report names the best ({label})"
        );
        if !device.is_empty() {
            let text =
                String::from_utf8_lossy(&compass_pdr(&["calibrate", log]).stdout).into_owned();
            let hard_iron = text
                .lines()
                .find(|line| line.trim_start().starts_with("Hard iron ("))
                .expect("the device calibration's hard iron")
                .trim();
            assert!(
                html.contains(hard_iron),
                "{log}: the report's device calibration is {hard_iron}"
            );
        }
    }
}

#[test]
fn the_gyroscope_s_bias_can_be_stated_and_changes_the_attitude_filter_s_prior() {
    let dir = scratch_dir("gyro_bias");
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/demo-walk.csv");
    let demo = demo.to_str().unwrap_or_default();
    let inspect = compass_pdr(&["inspect", demo, "--gyro-bias", "removed"]);
    assert!(inspect.status.success(), "{}", stderr(&inspect));
    assert!(
        String::from_utf8_lossy(&inspect.stdout).contains(
            "--gyro-bias removed: the gyroscope's rates are taken as having the OS's bias estimate removed"
        ),
        "{}",
        String::from_utf8_lossy(&inspect.stdout)
    );
    let attitude_with = |stated: &[&str]| {
        let out = dir.join(format!("attitude{}.csv", stated.len()));
        let out_arg = out.to_str().unwrap_or_default();
        let mut args = vec!["heading", demo, "--attitude-out", out_arg];
        args.extend(stated);
        let output = compass_pdr(&args);
        assert!(output.status.success(), "{}", stderr(&output));
        std::fs::read_to_string(&out).expect("written")
    };
    // The demo's gyroscope has a raw bias (about 0.4°/s), which the CSV does not state.
    let as_logged = attitude_with(&[]);
    assert_eq!(as_logged, attitude_with(&["--gyro-bias", "raw"]));
    assert_ne!(as_logged, attitude_with(&["--gyro-bias", "removed"]));
    let refused = compass_pdr(&["inspect", demo, "--gyro-bias", "maybe"]);
    assert!(!refused.status.success());
    assert!(
        stderr(&refused).contains("possible values: removed, raw"),
        "{}",
        stderr(&refused)
    );
}
