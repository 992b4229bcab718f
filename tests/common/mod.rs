//! What the replay tests on `../shared/data` share.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Vector3};

/// `../shared/data`, or `None` with a message saying why the test is skipped. Where
/// `COMPASS_PDR_REQUIRE_SHARED_DATA` is set (CI's `.ci/run` sets it: CI has the
/// recordings), a missing folder fails the test instead of skipping it.
pub fn shared_data() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else if std::env::var_os("COMPASS_PDR_REQUIRE_SHARED_DATA").is_some() {
        panic!(
            "{} not found, and COMPASS_PDR_REQUIRE_SHARED_DATA is set: the replay tests need \
             the real recordings",
            dir.display()
        );
    } else {
        eprintln!(
            "skipped: {} not found (the real recordings live beside the project; CI has them)",
            dir.display()
        );
        None
    }
}

/// Each file's name and bytes, read whole.
pub fn read_named(paths: &[PathBuf]) -> Vec<(String, Vec<u8>)> {
    paths
        .iter()
        .map(|path| {
            let name = path
                .file_name()
                .map(|name| name.to_string_lossy().into_owned())
                .unwrap_or_default();
            (name, std::fs::read(path).expect("readable file"))
        })
        .collect()
}

/// The files of one directory with the extension `ext`, sorted.
pub fn files_in(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("readable directory")
        .filter_map(|entry| entry.ok().map(|entry| entry.path()))
        .filter(|path| path.extension().is_some_and(|found| found == ext))
        .collect();
    paths.sort();
    paths
}

/// The TYREX trials under `data/tyrex-attitude`, sorted by name: each trial's name and
/// its files as a user drops the folder (the headerless per-sensor `.txt` files and
/// `record.properties`). None when the folder is absent.
pub fn tyrex_trials(data: &Path) -> Vec<(String, Vec<PathBuf>)> {
    tyrex_trials_in(data, "tyrex-attitude")
}

/// [`tyrex_trials`] under `data/SET` (`tyrex-attitude-more` holds four more).
pub fn tyrex_trials_in(data: &Path, set: &str) -> Vec<(String, Vec<PathBuf>)> {
    let mut trials: Vec<PathBuf> = std::fs::read_dir(data.join(set))
        .map(|entries| {
            entries
                .filter_map(|entry| entry.ok().map(|entry| entry.path()))
                .filter(|path| path.is_dir())
                .collect()
        })
        .unwrap_or_default();
    trials.sort();
    trials
        .into_iter()
        .map(|trial| {
            let name = trial
                .file_name()
                .map(|name| name.to_string_lossy().into_owned())
                .unwrap_or_default();
            let mut paths = files_in(&trial, "txt");
            paths.extend(files_in(&trial, "properties"));
            (name, paths)
        })
        .collect()
}

/// The files read and imported as one recording.
pub fn import_paths(paths: &[PathBuf]) -> compass_pdr::io::ImportReport {
    let contents = read_named(paths);
    let slices: Vec<(&str, &[u8])> = contents
        .iter()
        .map(|(name, bytes)| (name.as_str(), bytes.as_slice()))
        .collect();
    compass_pdr::io::import::import_files(&slices).expect("the recording imports")
}

/// One of the indoor walks of `msft-indoor-2020` dead-reckoned: the phone held flat, no
/// GNSS; the walk starts at the first waypoint, and no later waypoint trains anything.
pub fn indoor_walk(
    data: &Path,
    floor: &str,
    heading: &str,
    k: Option<f64>,
    declination: compass_pdr::analysis::calibration::DeclinationChoice,
) -> compass_pdr::pdr::PdrAnalysis {
    use compass_pdr::analysis::calibration::CalibrationOptions;
    use compass_pdr::analysis::headings::HeadingOptions;
    use compass_pdr::pdr::{HeadingChoice, PdrOptions};
    let paths = files_in(&data.join("msft-indoor-2020/site1").join(floor), "txt");
    compass_pdr::pipeline::dead_reckoning(
        &import_paths(&paths),
        &PdrOptions {
            heading: HeadingChoice::parse(heading),
            weinberg_k: k,
            heading_options: HeadingOptions {
                calibration: CalibrationOptions {
                    position_deg: Some((30.3, 120.1)),
                    declination,
                    ..CalibrationOptions::default()
                },
                ..HeadingOptions::default()
            },
            ..PdrOptions::default()
        },
    )
    .expect("dead-reckons")
}

/// Weinberg's K that makes an indoor walk's steps between its first and last waypoint
/// as long as the waypoint path (the PDR paper's protocol: fitted on one walk, used on
/// another).
pub fn fitted_k(data: &Path, floor: &str) -> f64 {
    let analysis = indoor_walk(
        data,
        floor,
        "device",
        None,
        compass_pdr::analysis::calibration::DeclinationChoice::Auto,
    );
    let errors = analysis
        .report
        .position_error
        .expect("waypoints score the walk");
    let sum: f64 = analysis
        .steps
        .iter()
        .filter(|step| (errors.start_s..=errors.end_s).contains(&step.mid_s()))
        .map(compass_pdr::pdr::step_length::weinberg_feature)
        .sum();
    errors.distance_m / sum
}

/// A calibration as parsed back from an export: `corrected = soft_iron · (raw − hard_iron)`.
#[derive(Debug, Clone, Copy)]
pub struct Parsed {
    pub hard_iron: Vector3<f64>,
    pub soft_iron: Matrix3<f64>,
    pub field: f64,
    /// µT per unit of `hard_iron`, `field` and the raw values.
    pub ut_per_unit: f64,
}

impl Parsed {
    pub fn apply(&self, raw: &Vector3<f64>) -> Vector3<f64> {
        self.soft_iron * (raw - self.hard_iron)
    }
}

/// The C floats between `start` and the next `end`.
fn c_floats(text: &str, start: &str, end: &str) -> Vec<f64> {
    let from = text.find(start).map(|at| at + start.len());
    let body = from
        .and_then(|from| {
            let rest = text.get(from..)?;
            rest.get(..rest.find(end)?)
        })
        .unwrap_or_else(|| panic!("no {start} … {end} in {text}"));
    body.split(|c: char| c == ',' || c == '{' || c == '}' || c.is_whitespace())
        .filter(|word| !word.is_empty())
        .map(|word| {
            word.trim_end_matches('f')
                .parse::<f64>()
                .unwrap_or_else(|_| panic!("{word:?} is not a C float"))
        })
        .collect()
}

/// The numbers of a C snippet, read as a C compiler would see them.
pub fn parse_c_snippet(snippet: &str) -> Parsed {
    let hard = c_floats(snippet, "float hard_iron[3] =", ";");
    let soft = c_floats(snippet, "float soft_iron[3][3] =", ";");
    let field = c_floats(snippet, "float mag_field =", ";");
    let ut_per_unit = c_floats(snippet, "float mag_ut_per_unit =", ";");
    assert_eq!(
        (hard.len(), soft.len(), field.len()),
        (3, 9, 1),
        "{snippet}"
    );
    Parsed {
        hard_iron: Vector3::from_column_slice(&hard),
        soft_iron: Matrix3::from_row_slice(&soft),
        field: field[0],
        ut_per_unit: ut_per_unit[0],
    }
}

/// Standard deviation of |v| over its mean, percent.
pub fn spread_pct(values: impl Iterator<Item = Vector3<f64>>) -> f64 {
    let norms: Vec<f64> = values.map(|v| v.norm()).collect();
    let n = norms.len() as f64;
    let mean = norms.iter().sum::<f64>() / n;
    let variance = norms.iter().map(|norm| (norm - mean).powi(2)).sum::<f64>() / n;
    100.0 * variance.sqrt() / mean
}

/// A recording's field corrected by the device's own hard-iron estimate (a TYREX trial's
/// uncalibrated and calibrated magnetometers), and the attitude gate's reference for it.
pub fn field_by_device_estimate(
    recording: &compass_pdr::io::recording::Recording,
) -> (
    compass_pdr::io::recording::Stream<Vector3<f64>>,
    Option<compass_pdr::attitude::gates::FieldReference>,
) {
    let bias = &recording.mag_bias_in_body_ut;
    let mut field = compass_pdr::io::recording::Stream::default();
    for (&t_s, &raw) in recording
        .mag_in_body_ut
        .t_s
        .iter()
        .zip(&recording.mag_in_body_ut.values)
    {
        let correction = bias
            .interpolate_at(t_s, f64::INFINITY)
            .unwrap_or_else(Vector3::zeros);
        field.push(t_s, raw - correction);
    }
    let mut down = compass_pdr::io::recording::Stream::default();
    for (&t_s, force) in recording
        .acc_in_body_mps2
        .t_s
        .iter()
        .zip(&recording.acc_in_body_mps2.values)
    {
        down.push(t_s, -force.normalize());
    }
    let reference =
        compass_pdr::attitude::gates::FieldReference::of_log(&field, &down, (None, None));
    (field, reference)
}
