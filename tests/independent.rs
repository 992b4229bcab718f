//! Property tests on the independent generator (`tests/physics`): random distortions
//! and motions drawn from the physics, every method's check heading error against the
//! true calibration's floor on the same samples. Distributions, not one seed.

mod physics;

use compass_pdr::calibration::CalibrationOptions;
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
                "{name} seed {seed}: floor {:.2}° (true tilt {:.2?}°), raw {:?}, heading {:?} ({:.2}× floor), field {:?} ({:.2}×); {}",
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

#[test]
#[ignore]
fn debug_one() {
    use compass_pdr::calibration::MethodParameters;
    let seed: u64 = std::env::var("SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(14);
    let name = std::env::var("SCENARIO").unwrap_or_else(|_| "circle_walk".to_string());
    let scenario = physics::SCENARIOS
        .iter()
        .find(|(key, _)| *key == name)
        .map(|(_, scenario)| *scenario)
        .expect("a scenario");
    let log = scenario(seed);
    let analysis = physics::scoring::analyse(&log, &CalibrationOptions::default());
    let (h, d) = log.true_correction();
    eprintln!("truth h {:?}\nD {d}", h.as_slice());
    eprintln!(
        "field {:?} |F| {:.2} dip {:.2}",
        log.field_ned_ut.as_slice(),
        log.field_ned_ut.norm(),
        (log.field_ned_ut.z / log.field_ned_ut.norm())
            .asin()
            .to_degrees()
    );
    for method in &analysis.report.methods {
        match &method.parameters {
            Some(MethodParameters::Ellipsoid(fit)) => {
                let c = fit.calibration;
                let scale = log.field_ned_ut.norm() / c.field_ut;
                eprintln!("ellipsoid h {:?} ±{:?} D*{scale:.3} {} dip {:?} heading± {:.2} unobserved {:?} model {:?} {:?} outliers {:.1}% vrms {:?} rms {:.2}", c.hard_iron_ut.as_slice(), fit.hard_iron_std_ut.as_slice(), c.soft_iron * scale, fit.inclination_deg, fit.heading_std_deg, fit.unobserved, fit.model, fit.model_reason, fit.outlier_pct, fit.vertical_rms_ut, fit.residual_rms_ut);
            }
            Some(MethodParameters::Ellipse(fit)) => {
                eprintln!(
                    "ellipse h {:?} D {} dip {:.2}",
                    fit.hard_iron_ut.as_slice(),
                    fit.soft_iron,
                    fit.inclination_deg
                );
            }
            _ => {}
        }
        eprintln!(
            "{} check {:?}",
            method.label,
            method
                .heading_error_check
                .map(|s| (s.mean_deg, s.std_deg, s.rms_deg))
        );
    }
    let truth = compass_pdr::calib::model::FieldCalibration {
        hard_iron_ut: h,
        soft_iron: d,
        field_ut: log.field_ned_ut.norm(),
    };
    eprintln!(
        "floor {:?}, with the true tilt {:?}",
        physics::scoring::check_rms_of(&analysis, &truth),
        physics::scoring::true_tilt_floor(&log, &analysis)
    );
}

#[test]
#[ignore]
fn debug_tilt() {
    use compass_pdr::calib::gravity::estimate_gravity;
    use compass_pdr::calib::tilt::Tilt;
    use compass_pdr::recording::Stream;
    let seed: u64 = std::env::var("SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(9);
    let name = std::env::var("SCENARIO").unwrap_or_else(|_| "circle_walk".to_string());
    let scenario = physics::SCENARIOS
        .iter()
        .find(|(key, _)| *key == name)
        .map(|(_, scenario)| *scenario)
        .expect("a scenario");
    let log = scenario(seed);
    let report = compass_pdr::io::import::import("x.csv", log.csv.as_bytes()).expect("imports");
    let recording = &report.recording;
    let t0 = log.start_unix_s - recording.start_unix_s.unwrap_or(0.0);
    for (label, speed) in [
        ("plain", Stream::default()),
        ("speed", recording.gnss.clone()),
    ] {
        let estimate = estimate_gravity(
            &recording.acc_in_body_mps2,
            &recording.gyro_in_body_radps,
            &speed,
            1.0,
        );
        let mut sum = 0.0;
        let mut n = 0;
        let mut worst = 0.0f64;
        for (&t_s, f) in estimate
            .specific_force_mps2
            .t_s
            .iter()
            .zip(&estimate.specific_force_mps2.values)
        {
            let idx = log.true_t_s.partition_point(|&tt| tt + t0 < t_s - 1e-6);
            let Some(attitude) = log.true_attitude.get(idx) else {
                continue;
            };
            let (roll, pitch, _) = attitude.euler_angles();
            let Some(tilt) = Tilt::from_specific_force(*f) else {
                continue;
            };
            let e = ((tilt.roll_rad - roll).powi(2) + (tilt.pitch_rad - pitch).powi(2))
                .sqrt()
                .to_degrees();
            sum += e * e;
            n += 1;
            worst = worst.max(e);
        }
        eprintln!(
            "{label}: {:?} tilt RMS error {:.2}° worst {:.2}° over {n}",
            estimate.source,
            (sum / n as f64).sqrt(),
            worst
        );
    }
}

#[test]
#[ignore]
fn survey() {
    let name = std::env::var("SCENARIO").unwrap_or_else(|_| "magnet_mount_drive".to_string());
    let scenario = physics::SCENARIOS
        .iter()
        .find(|(key, _)| *key == name)
        .map(|(_, scenario)| *scenario)
        .expect("a scenario");
    let n: u64 = std::env::var("SEEDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5);
    let scores = run(&name, scenario, 1..n + 1);
    let ratios: Vec<f64> = scores.iter().map(Scores::heading_over_floor).collect();
    eprintln!(
        "{name}: best/floor median {:.2}, 90th percentile {:.2}, worst {:.2}",
        quantile(&ratios, 0.5),
        quantile(&ratios, 0.9),
        quantile(&ratios, 1.0)
    );
}

#[test]
#[ignore]
fn survey_pdr() {
    use compass_pdr::pdr::{run as dead_reckon, PdrOptions};
    let n: u64 = std::env::var("SEEDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5);
    for seed in 1..=n {
        let log = physics::four_direction_walk(seed);
        let report =
            compass_pdr::io::import::import("walk.csv", log.csv.as_bytes()).expect("imports");
        let analysis = dead_reckon(report, &PdrOptions::default()).expect("dead-reckons");
        let r = &analysis.report;
        eprintln!(
            "four_direction_walk seed {seed}: {} steps, {:.0} m, heading {}, step model {:?}, gaps {:?}",
            r.n_steps,
            r.pdr_distance_m,
            r.heading_key,
            r.step_model.model,
            r.gnss_gaps.iter().map(|gap| (gap.start_s, gap.end_s, gap.pdr_distance_m, gap.position_error.as_ref().map(|e| (e.rms_m, e.rms_pct, e.max_pct)))).collect::<Vec<_>>()
        );
        if let Some(gap) = r.gnss_gaps.first() {
            let t0 = log.true_t_s.first().copied().unwrap_or(0.0);
            let path: f64 = log
                .true_t_s
                .windows(2)
                .zip(log.true_en_m.windows(2))
                .filter(|(t, _)| t[0] - t0 >= gap.start_s && t[1] - t0 <= gap.end_s)
                .map(|(_, en)| (en[1] - en[0]).norm())
                .sum();
            eprintln!(
                "  gap: PDR {:.1} m against the true {path:.1} m ({:+.2} %)",
                gap.pdr_distance_m,
                100.0 * (gap.pdr_distance_m / path - 1.0)
            );
        }
    }
}

#[test]
#[ignore]
fn debug_pdr_headings() {
    use compass_pdr::deviation::{analyse_headings, HeadingOptions};
    use compass_pdr::reference::{ReferenceChoice, ReferenceOptions};
    let seed: u64 = std::env::var("SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5);
    let log = physics::four_direction_walk(seed);
    let report = compass_pdr::io::import::import("walk.csv", log.csv.as_bytes()).expect("imports");
    let options = HeadingOptions {
        calibration: CalibrationOptions {
            reference: ReferenceOptions {
                choice: ReferenceChoice::Gps,
                ..ReferenceOptions::default()
            },
            ..CalibrationOptions::default()
        },
        neural: false,
        ..HeadingOptions::default()
    };
    let analysis = analyse_headings(report, &options).expect("analyses");
    // Truth: the walking direction's heading error of each row over the outage.
    let t0 = log.true_t_s.first().copied().unwrap_or(0.0);
    let start_offset = analysis.t_s.first().copied().unwrap_or(0.0);
    let _ = start_offset;
    for row in &analysis.report.rows {
        let Some((_, series)) = analysis
            .headings_deg
            .iter()
            .find(|(key, _)| *key == row.key)
        else {
            continue;
        };
        let mut errors = Vec::new();
        for (&t_s, &heading_deg) in analysis.t_s.iter().zip(series) {
            let rel = t_s - t0;
            if !(240.0..840.0).contains(&rel) {
                continue;
            }
            let idx = log.true_t_s.partition_point(|&tt| tt - t0 < rel);
            if let Some(&truth) = log.true_heading_deg.get(idx) {
                errors.push(
                    compass_pdr::angle::wrap_to_pi((heading_deg - truth).to_radians()).to_degrees(),
                );
            }
        }
        let n = errors.len().max(1) as f64;
        let mean = errors.iter().sum::<f64>() / n;
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        eprintln!(
            "{:<36} check {:>7} outage vs true heading: mean {mean:+.2}° rms {rms:.2}°",
            row.key,
            row.check
                .map_or("—".to_string(), |s| format!("{:.2}", s.rms_deg))
        );
    }
    eprintln!("best {:?}", analysis.report.best);
}
