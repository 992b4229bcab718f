//! The verdict ([`compass_pdr::present::verdict`]) on every real recording in `../shared/data`,
//! each folder's files imported together as a person drops them: the answer has the kind
//! the log allows (a heading error where there is a reference, the field's spread and
//! coverage for a board turned in the hand, the compasses of an autopilot log), its
//! figure, and a grade that agrees with the figure. Skipped with a message when
//! `../shared/data` is absent.
#![cfg(not(target_arch = "wasm32"))]

use std::path::{Path, PathBuf};

mod common;

use common::shared_data;
use compass_pdr::pdr::PdrOptions;
use compass_pdr::pipeline;
use compass_pdr::present::verdict::{
    verdict, Grade, Picture, Verdict, VerdictKind, FAIR_HEADING_RMS_DEG, GOOD_HEADING_RMS_DEG,
};

/// A folder's files as a person drops them: everything but the licence and readme.
fn dropped(dir: &Path) -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("readable directory")
        .filter_map(|entry| entry.ok().map(|entry| entry.path()))
        .filter(|path| path.is_file())
        .filter(|path| {
            let name = path
                .file_name()
                .map_or(String::new(), |name| name.to_string_lossy().to_lowercase());
            let markdown = path
                .extension()
                .is_some_and(|ext| ext.eq_ignore_ascii_case("md"));
            !name.starts_with("licen") && !markdown
        })
        .collect();
    paths.sort();
    paths
}

/// The files dropped together, analysed as the page analyses them.
fn analysis_of(paths: &[PathBuf]) -> pipeline::Analysis {
    let import = common::import_paths(paths);
    let mut options = PdrOptions::default();
    // The network is the slowest model and is not what the verdict is about.
    options.heading_options.neural = false;
    pipeline::analyse(&import, &options).expect("analyses")
}

fn verdict_of(paths: &[PathBuf]) -> Verdict {
    let analysis = analysis_of(paths);
    let pdr = analysis
        .pdr
        .as_ref()
        .and_then(|pdr| pdr.as_ref().ok())
        .map(|pdr| &pdr.report);
    let verdict = verdict(&analysis.calibration, &analysis.headings.report, pdr);
    eprintln!(
        "{:?} {:?}: {}\n  {}\n  {:?}\n  {:?}",
        verdict.kind,
        verdict.grade,
        verdict.headline,
        verdict.method,
        verdict.figures,
        verdict.to_do
    );
    verdict
}

fn figure<'a>(verdict: &'a Verdict, label: &str) -> &'a str {
    verdict
        .figures
        .iter()
        .find(|figure| figure.label == label)
        .map_or_else(
            || panic!("no figure {label:?} in {:?}", verdict.figures),
            |figure| figure.value.as_str(),
        )
}

/// The first number in `text`.
fn number(text: &str) -> f64 {
    let start = text
        .find(|c: char| c.is_ascii_digit() || c == '-')
        .expect("a number");
    let digits: String = text[start..]
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == '-')
        .collect();
    digits.parse().expect("a number")
}

#[test]
fn a_board_turned_in_the_hand_gets_its_spread_and_coverage_not_a_heading_error() {
    let Some(data) = shared_data() else { return };
    let dir = data.join("qmc5883l-calibration");
    for file in ["filtered_raw_data.csv", "noisy_raw_data.csv"] {
        let verdict = verdict_of(&[dir.join(file)]);
        assert_eq!(verdict.kind, VerdictKind::FieldOnly, "{file}");
        let spread = figure(&verdict, "|B| varies (std / mean)");
        let (before, after) = spread.split_once('→').expect("before → after");
        assert!(number(after) < number(before), "{file}: {spread}");
        assert!(figure(&verdict, "Directions covered").contains("of 100 regions"));
        // The coverage map the summary draws is the one its figure counts.
        let coverage = verdict.coverage.as_ref().expect("a coverage map");
        assert!(
            figure(&verdict, "Directions covered")
                .starts_with(&format!("{} of 100", coverage.n_covered)),
            "{file}: {} against {}",
            coverage.n_covered,
            figure(&verdict, "Directions covered")
        );
        assert!(
            verdict.headline.contains("directions covered"),
            "{}",
            verdict.headline
        );
        // Counts of unknown scale: no field in µT is claimed.
        assert!(verdict
            .figures
            .iter()
            .all(|figure| figure.label != "Fitted field"));
        assert!(verdict
            .to_do
            .iter()
            .any(|line| line.contains("reference heading")));
    }
}

#[test]
fn the_hmc5883l_sphere_is_judged_by_its_spread_against_the_live_panel_s_bar() {
    let Some(data) = shared_data() else { return };
    let verdict = verdict_of(&dropped(&data.join("hmc5883l-sphere/full-sphere")));
    assert_eq!(verdict.kind, VerdictKind::FieldOnly);
    let spread = figure(&verdict, "|B| varies (std / mean)");
    let after = number(spread.split_once('→').expect("before → after").1);
    // The grade follows the live panel's conditions: a spread of 3 % or more is poor.
    if after >= compass_pdr::fit::quality::GOOD_MAX_SPREAD_PCT {
        assert_eq!(verdict.grade, Grade::Poor, "{spread}");
    }
}

#[test]
fn logs_with_a_reference_get_the_heading_error_before_and_after() {
    let Some(data) = shared_data() else { return };
    let verdict = verdict_of(&dropped(&data.join("sensorlogger-walk-ethz")));
    assert_eq!(verdict.kind, VerdictKind::Heading);
    let after = number(figure(&verdict, "Heading error after"));
    assert!(
        verdict.headline.contains(&format!("{after:.1}°")),
        "{}",
        verdict.headline
    );
    let expected = if after <= GOOD_HEADING_RMS_DEG {
        Grade::Good
    } else if after <= FAIR_HEADING_RMS_DEG {
        Grade::Fair
    } else {
        Grade::Poor
    };
    assert_eq!(verdict.grade, expected, "{after}°");
    let verdict = verdict_of(&[data.join("vehicle-pixel6a/2023-08-09_12-47-42.csv")]);
    assert_eq!(verdict.kind, VerdictKind::Heading);
    // A car's "steps" are hundreds of metres apart: no step statistics for it.
    assert!(
        figure(&verdict, "Dead reckoning").starts_with("not a walk"),
        "{:?}",
        verdict.figures
    );
    // ... and the page's status line, which takes its steps from the verdict, none.
    assert_eq!(verdict.steps, None);
}

/// An indoor GPS course (14 samples at a walk, 40-139° from every heading on the IPIN
/// walks) cannot judge the headings: the answer is the field's figures and says why,
/// never "Poor: 75.6° → 43.7° with reference LS" fitted to that course. Surveyed legs
/// (msft F4) judge however far the compass is from them.
#[test]
fn a_gps_course_far_from_every_heading_judges_nothing_but_surveyed_legs_do() {
    let Some(data) = shared_data() else { return };
    let walk = data.join("ipin2023-track3-walks/IPIN2023_T3_TrainingTrial24_repetition01.txt");
    let verdict = verdict_of(&[walk]);
    assert_eq!(verdict.kind, VerdictKind::FieldOnly, "{}", verdict.headline);
    assert!(
        verdict.method.contains("the GPS course is") && verdict.method.contains("too far to judge"),
        "{}",
        verdict.method
    );
    assert!(
        !verdict.headline.contains("Heading error"),
        "{}",
        verdict.headline
    );
    // ... and what to record instead says why this log's GPS could not judge.
    assert!(
        verdict
            .to_do
            .iter()
            .any(|item| item.contains("course is too far from every heading")),
        "{:?}",
        verdict.to_do
    );
    let f4 = data.join("msft-indoor-2020/site1/F4");
    let verdict = verdict_of(&dropped(&f4));
    assert_eq!(verdict.kind, VerdictKind::Heading, "{}", verdict.headline);
    assert!(
        verdict.method.starts_with("Method: min/max"),
        "{}",
        verdict.method
    );
}

#[test]
fn an_indoor_walk_without_a_north_reference_gets_the_field_figures_and_its_steps() {
    let Some(data) = shared_data() else { return };
    // The hallway loop's GPS is too poor indoors for a course, and a closed gyro loop
    // does not know north: no heading error can be given, so the field's figures are.
    let verdict = verdict_of(&dropped(&data.join("phyphox-hallway-loop")));
    assert_eq!(verdict.kind, VerdictKind::FieldOnly);
    assert!(figure(&verdict, "Dead reckoning").contains("steps over"));
    let steps = verdict
        .steps
        .as_deref()
        .expect("a walk's steps for the status line");
    assert!(steps.ends_with(" m."), "{steps}");
    assert!(steps.contains(" steps dead-reckoned over "), "{steps}");
}

#[test]
fn an_autopilot_log_gets_each_compass_in_force_and_as_written() {
    let Some(data) = shared_data() else { return };
    let verdict = verdict_of(&[data.join("ardupilot-copter-log171/log171.bin")]);
    assert_eq!(verdict.kind, VerdictKind::Autopilot);
    assert_eq!(verdict.steps, None, "a drone does not walk");
    assert_eq!(verdict.figures.len(), 3, "{:?}", verdict.figures);
    assert!(
        verdict.headline.starts_with("Compass 1"),
        "{}",
        verdict.headline
    );
    // The written parameters are no worse than those in force against the Earth's field
    // (they are not written otherwise).
    let (before, after) = verdict.headline.split_once('→').expect("before → after");
    let before = number(&before[before.rfind("vector error").expect("vector error")..]);
    assert!(number(after) <= before, "{}", verdict.headline);
}

#[test]
fn every_other_recording_gets_an_answer() {
    let Some(data) = shared_data() else { return };
    let mut logs: Vec<Vec<PathBuf>> = vec![
        vec![data.join("ardupilot-text-log/nan.log")],
        vec![data.join("px4-ulog/sample.ulg")],
        vec![data.join("px4-ulog/sample_log_small.ulg")],
        dropped(&data.join("hmc5883l-sphere/rotate-ccw-around-z-pointing-up")),
        // Never turned: no calibration, and the answer says why.
        dropped(&data.join("hmc5883l-sphere/unmoved-with-x-pointing-forward")),
        dropped(&data.join("msft-indoor-2020/site1/F1")),
    ];
    logs.extend(
        common::tyrex_trials(&data)
            .into_iter()
            .take(1)
            .map(|(_, files)| files),
    );
    for paths in logs {
        let verdict = verdict_of(&paths);
        assert!(!verdict.headline.is_empty());
        assert!(!verdict.figures.is_empty(), "{paths:?}: {verdict:?}");
        assert!(!verdict.headline.contains("NaN"), "{}", verdict.headline);
    }
}

/// A drone log whose compass could not be judged on it leads with its primary compass's
/// parameters in force against the Earth's field, not the raw field (its calibration
/// undone), and says what to record.
#[test]
fn an_autopilot_log_with_nothing_to_write_is_judged_by_its_parameters_in_force() {
    let Some(data) = shared_data() else { return };
    let verdict = verdict_of(&[data.join("px4-ulog/sample_log_small.ulg")]);
    assert_eq!(verdict.kind, VerdictKind::Autopilot, "{verdict:?}");
    assert!(
        verdict
            .headline
            .starts_with("CAL_MAG1 (vehicle_magnetometer 0): parameters in force kept: "),
        "{}",
        verdict.headline
    );
    assert!(
        verdict.headline.contains("mG from the Earth's field"),
        "{}",
        verdict.headline
    );
    assert!(
        verdict.to_do[0].starts_with("To calibrate CAL_MAG0 (sensor_mag 0) and CAL_MAG1"),
        "{:?}",
        verdict.to_do
    );
}

/// A board that never turned, and a drone that yawed a few degrees: no method can be
/// fitted (min/max included: the extremes of a still board are its noise), and the
/// analysis still answers, uncalibrated, saying why and what to record.
#[test]
fn nothing_to_fit_is_answered_uncalibrated_with_what_to_record() {
    let Some(data) = shared_data() else { return };
    for paths in [
        dropped(&data.join("hmc5883l-sphere/unmoved-with-x-pointing-forward")),
        vec![data.join("px4-ulog/sample_log_small.ulg")],
    ] {
        let analysis = analysis_of(&paths);
        let report = &analysis.calibration.report;
        let why = report.why_no_method_fitted().expect("nothing fitted");
        assert!(why.contains("hardly turned"), "{paths:?}: {why}");
        assert_eq!(report.best(), None, "{paths:?}");
        assert!(
            report
                .notes
                .iter()
                .any(|note| note.starts_with("No calibration could be fitted")),
            "{:?}",
            report.notes
        );
        let verdict = verdict_of(&paths);
        assert!(!verdict.to_do.is_empty(), "{paths:?}: says what to do");
    }
}

/// Issue 45: the answer's picture is chosen by what the log is: a walk on a map's track,
/// a reference's heading error, a board's (or an unmapped walk's) coverage, an
/// autopilot's compasses, and the field's magnitude where there is neither a reference
/// nor a calibration.
#[test]
fn each_kind_of_log_gets_its_picture() {
    let Some(data) = shared_data() else { return };
    let cases = [
        (
            dropped(&data.join("msft-indoor-2020/site1/F1")),
            Picture::Track,
        ),
        (
            dropped(&data.join("vehicle-pixel6a")),
            Picture::HeadingError,
        ),
        (
            dropped(&data.join("hmc5883l-sphere/full-sphere")),
            Picture::Coverage,
        ),
        (
            dropped(&data.join("hmc5883l-sphere/unmoved-with-x-pointing-forward")),
            Picture::FieldMagnitude,
        ),
        (
            vec![data.join("px4-ulog/sample.ulg")],
            Picture::CompassErrors,
        ),
    ];
    for (paths, picture) in cases {
        assert_eq!(verdict_of(&paths).picture, picture, "{paths:?}");
    }
}
