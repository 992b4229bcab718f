//! Property tests on the independent generator (`tests/physics`): random distortions
//! and motions drawn from the physics, every method's check heading error against the
//! true calibration's floor on the same samples. Distributions, not one seed.

mod physics;

use compass_pdr::analysis::calibration::CalibrationOptions;
use physics::scoring::{quantile, score, Scores};

fn run(
    name: &str,
    scenario: fn(u64) -> physics::GeneratedLog,
    seeds: std::ops::Range<u64>,
) -> Vec<Scores> {
    let options = CalibrationOptions::default();
    seeds
        .map(|seed| {
            let scores = score(&scenario(seed), &options);
            eprintln!(
                "{name} seed {seed}: export {:.2?}° over {:.2?}° ({:.2}×); floor {:.2}° (true tilt {:.2?}°), raw {:?}, heading {:?} ({:.2}× floor), field {:?} ({:.2}×); {}",
                scores.export_true_tilt_deg,
                scores.true_calibration_floor_deg,
                scores.export_over_true_tilt_floor(),
                scores.floor_deg,
                scores.true_tilt_floor_deg,
                scores.raw_deg.map(|rms| (rms * 100.0).round() / 100.0),
                scores.heading.as_ref().map(|(key, rms)| format!("{key} {rms:.2}°")),
                scores.heading_over_floor(),
                scores.best.as_ref().map(|(key, rms)| format!("{key} {rms:.2}°")),
                scores.best_over_floor(),
                scores
                    .methods
                    .iter()
                    .map(|(key, rms, error)| match (rms, error) {
                        (Some(rms), _) => format!("{key} {rms:.2}°"),
                        (None, Some(error)) => format!(
                            "{key} refused ({})",
                            error.chars().take(60).collect::<String>()
                        ),
                        _ => format!("{key} —"),
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            scores
        })
        .collect()
}

#[test]
fn circle_only_walks_with_walking_tilt_come_within_1_3_of_the_true_calibration_in_90_percent_of_seeds(
) {
    let scores = run("circle_walk", physics::circle_walk, 1..21);
    let ratios: Vec<f64> = scores.iter().map(Scores::heading_over_floor).collect();
    let within = ratios.iter().filter(|&&ratio| ratio <= 1.3).count();
    eprintln!(
        "circle_walk: best/floor median {:.2}, 90th percentile {:.2}, worst {:.2}; {within} of {} within 1.3×",
        quantile(&ratios, 0.5),
        quantile(&ratios, 0.9),
        quantile(&ratios, 1.0),
        ratios.len()
    );
    assert!(within * 10 >= ratios.len() * 9, "{ratios:?}");
}

/// A car with a magnet mount (hard iron 150-250 µT, three to five times the Earth's
/// field), referenced by its GNSS course: every seed gets a heading, never worse than
/// uncalibrated, and near the true calibration's floor.
#[test]
fn a_magnet_mount_drive_gets_a_heading_near_the_floor_and_never_worse_than_uncalibrated() {
    let scores = run("magnet_mount_drive", physics::magnet_mount_drive, 1..7);
    for scores in &scores {
        let (key, rms) = scores.heading.clone().expect("a heading was chosen");
        let raw = scores.raw_deg.expect("the raw heading is scored");
        assert!(
            rms <= raw,
            "{}: {key} {rms}° against uncalibrated {raw}°",
            scores.name
        );
        assert!(
            key != "raw",
            "{}: no calibration beat uncalibrated",
            scores.name
        );
    }
    let ratios: Vec<f64> = scores.iter().map(Scores::heading_over_floor).collect();
    eprintln!(
        "magnet_mount_drive: chosen/floor median {:.2}, worst {:.2}",
        quantile(&ratios, 0.5),
        quantile(&ratios, 1.0)
    );
    assert!(quantile(&ratios, 1.0) <= 1.3, "{ratios:?}");
}

/// A 15-minute walk on a grid (four directions of travel) with GNSS for the first four
/// minutes and the last one: the dead reckoning across the 10-minute outage drifts by
/// about 1 % of the distance (the PDR paper's own figure), over a dozen seeds.
#[test]
fn a_four_direction_walk_drifts_about_one_percent_across_a_ten_minute_outage() {
    use compass_pdr::pdr::PdrOptions;
    use compass_pdr::pipeline::dead_reckoning;
    let mut rms_pct = Vec::new();
    for seed in 1..=12 {
        let log = physics::four_direction_walk(seed);
        let report =
            compass_pdr::io::import::import("walk.csv", log.csv.as_bytes()).expect("imports");
        let analysis = dead_reckoning(&report, &PdrOptions::default()).expect("dead-reckons");
        let gap = analysis
            .report
            .gnss_gaps
            .first()
            .and_then(|gap| gap.position_error)
            .expect("the outage is scored against the true path");
        eprintln!(
            "four_direction_walk seed {seed}: heading {}, outage RMS {:.2} % (max {:.2} %) of {:.0} m",
            analysis.report.heading_key, gap.rms_pct, gap.max_pct, gap.distance_m
        );
        rms_pct.push(gap.rms_pct);
    }
    let within = rms_pct.iter().filter(|&&pct| pct <= 1.0).count();
    // Every walk's error over its outage, as one RMS (the walks are of about one length).
    let pooled_pct =
        (rms_pct.iter().map(|pct| pct * pct).sum::<f64>() / rms_pct.len() as f64).sqrt();
    eprintln!(
        "four_direction_walk: outage RMS over all walks {pooled_pct:.2} %; median {:.2} %, 90th percentile {:.2} %, worst {:.2} %; {within} of {} within 1 %",
        quantile(&rms_pct, 0.5),
        quantile(&rms_pct, 0.9),
        quantile(&rms_pct, 1.0),
        rms_pct.len()
    );
    assert!(pooled_pct <= 1.0, "{rms_pct:?}");
    assert!(quantile(&rms_pct, 0.5) <= 1.0, "{rms_pct:?}");
    assert!(within * 4 >= rms_pct.len() * 3, "{rms_pct:?}");
    assert!(quantile(&rms_pct, 1.0) <= 1.5, "{rms_pct:?}");
}

/// Issue 43's check: for each motion, 20 seeds of the generator with its magnetometer
/// (symmetric soft iron, 10-60 µT of hard iron) and the GNSS course as the only
/// reference. Two ratios per seed: the exported device calibration, applied as its JSON
/// says and levelled with the true attitude, over the true calibration levelled the same
/// way (both against the true heading: the calibration alone is judged); and the tool's
/// own chosen heading over the true calibration on the log's own tilt and reference.
/// Asserts the issue's bar on both: every seed within 2 × and 18 of the 20 within 1.3 ×.
fn issue_43_motion(name: &str, scenario: physics::Scenario) {
    let scores = run(name, scenario, 1..21);
    let export: Vec<f64> = scores
        .iter()
        .map(Scores::export_over_true_tilt_floor)
        .collect();
    let heading: Vec<f64> = scores.iter().map(Scores::heading_over_floor).collect();
    let within = |ratios: &[f64]| ratios.iter().filter(|&&ratio| ratio <= 1.3).count();
    eprintln!(
        "{name}: exported calibration / true calibration (true attitude) median {:.2}, 90th percentile {:.2}, worst {:.2}, {} of 20 within 1.3 ×; chosen heading / floor median {:.2}, worst {:.2}, {} of 20 within 1.3 ×",
        quantile(&export, 0.5),
        quantile(&export, 0.9),
        quantile(&export, 1.0),
        within(&export),
        quantile(&heading, 0.5),
        quantile(&heading, 1.0),
        within(&heading),
    );
    assert!(quantile(&export, 1.0) <= 2.0, "{name}: {export:?}");
    assert!(within(&export) >= 18, "{name}: {export:?}");
    assert!(quantile(&heading, 1.0) <= 2.0, "{name}: {heading:?}");
    assert!(within(&heading) >= 18, "{name}: {heading:?}");
}

/// A car on open roads, turns of 10-200 m at up to 6 m/s², GNSS speed and course.
#[test]
fn issue_43_car_s_exported_calibration_is_near_the_true_one() {
    issue_43_motion("car", physics::car);
}

/// The same drives whose fixes carry no speed: the speed between the fixes' positions
/// takes the turns' centripetal acceleration out of the tilt (`attitude::down`); without
/// it the exported calibration was 1.36 × at the median and 4.3 × at worst.
#[test]
fn issue_43_car_without_a_speed_is_as_near_as_with_one() {
    issue_43_motion("car_without_speed", physics::car_without_speed);
}

#[test]
fn issue_43_walk_s_exported_calibration_is_near_the_true_one() {
    issue_43_motion("walk", physics::steady_walk);
}

#[test]
fn issue_43_hand_s_exported_calibration_is_near_the_true_one() {
    issue_43_motion("hand", physics::hand_walk);
}

/// The phone swinging at the arm's end by ±30-60°: down follows the gyroscope over 10 s
/// once its bias is removed (`attitude::down`), which averages the arm's acceleration
/// away; its tilt is still trusted little, so each sample's dip weighs its trust
/// (`fit::ellipsoid`). Before the bias was removed: 1.6 × the true calibration at the
/// median, 2.6 × at worst, 5 of 20 within 1.3 ×; with the bias seen over 3 s windows
/// 1.15 ×, 1.9 × and 14 of 20; over 15 s windows 1.11 ×, 1.9 × and 18.
#[test]
fn issue_43_swinging_phone_s_exported_calibration_is_near_the_true_one() {
    issue_43_motion("swing", physics::swing_walk);
}
