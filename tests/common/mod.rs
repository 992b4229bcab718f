//! What the replay tests on `../shared/data` share.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// `../shared/data`, or `None` with a message saying why the test is skipped.
pub fn shared_data() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if dir.is_dir() {
        Some(dir)
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
    declination: compass_pdr::calibration::DeclinationChoice,
) -> compass_pdr::pdr::PdrAnalysis {
    use compass_pdr::calibration::CalibrationOptions;
    use compass_pdr::deviation::HeadingOptions;
    use compass_pdr::pdr::{HeadingChoice, PdrOptions};
    let paths = files_in(&data.join("msft-indoor-2020/site1").join(floor), "txt");
    compass_pdr::pdr::run(
        import_paths(&paths),
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
        compass_pdr::calibration::DeclinationChoice::Auto,
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
