//! Self-checks of the independent physics generator (`tests/physics/mod.rs`): its logs
//! must say what its truth says. Each check reads the written CSV back and compares it
//! with the truth the generator returns; the numbers are printed (`--nocapture`).
#![cfg(not(target_arch = "wasm32"))]

mod physics;

use std::sync::OnceLock;
use std::time::{Duration, Instant};

use compass_pdr::base::geodesy::LocalFrame;
use compass_pdr::io::canonical_csv::COLUMNS;
use nalgebra::{Rotation3, Vector2, Vector3};
use physics::{GeneratedLog, Rng, GRAVITY_MPS2, SCENARIOS};

const SEEDS: [u64; 2] = [1, 2];

// Column indices of the canonical CSV.
const T_S: usize = 0;
const ACC: usize = 1;
const GYRO: usize = 4;
const MAG: usize = 7;
const LAT: usize = 11;
const LON: usize = 12;
const SPEED: usize = 13;
const COURSE: usize = 14;
const HACC: usize = 15;
const REF_HEADING: usize = 16;
const REF_E: usize = 17;
const REF_N: usize = 18;

type Row = [Option<f64>; 19];

/// A generated log, its CSV parsed back, and how long it took to generate.
struct Case {
    scenario: &'static str,
    log: GeneratedLog,
    rows: Vec<Row>,
    generation: Duration,
}

fn parse(csv: &str) -> Vec<Row> {
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some(COLUMNS.join(",").as_str()), "header");
    lines
        .map(|line| {
            let mut row: Row = [None; 19];
            let fields: Vec<&str> = line.split(',').collect();
            assert_eq!(fields.len(), 19, "{line}");
            for (cell, field) in row.iter_mut().zip(fields) {
                *cell = (!field.is_empty()).then(|| field.parse().expect("a number"));
            }
            row
        })
        .collect()
}

/// Every scenario for every seed in [`SEEDS`], generated once for all the checks.
fn cases() -> &'static [Case] {
    static CASES: OnceLock<Vec<Case>> = OnceLock::new();
    CASES.get_or_init(|| {
        let mut cases = Vec::new();
        for (scenario, generate) in SCENARIOS {
            for seed in SEEDS {
                let started = Instant::now();
                let log = generate(seed);
                let generation = started.elapsed();
                let rows = parse(&log.csv);
                assert_eq!(rows.len(), log.true_t_s.len(), "{}", log.name);
                cases.push(Case {
                    scenario,
                    log,
                    rows,
                    generation,
                });
            }
        }
        cases
    })
}

fn vector(row: &Row, first: usize) -> Vector3<f64> {
    Vector3::new(
        row[first].expect("x written"),
        row[first + 1].expect("y written"),
        row[first + 2].expect("z written"),
    )
}

fn mean_and_std(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    (mean, variance.sqrt())
}

fn wrap_deg(angle_deg: f64) -> f64 {
    (angle_deg + 180.0).rem_euclid(360.0) - 180.0
}

fn is_walk(case: &Case) -> bool {
    case.scenario != "magnet_mount_drive"
}

#[test]
fn the_random_numbers_are_uniform_gaussian_and_seeded() {
    let mut rng = Rng::new(42);
    let uniform: Vec<f64> = (0..200_000).map(|_| rng.uniform()).collect();
    let (mean, std) = mean_and_std(&uniform);
    assert!((mean - 0.5).abs() < 0.003, "uniform mean {mean}");
    assert!(
        (std - (1.0_f64 / 12.0).sqrt()).abs() < 0.003,
        "uniform std {std}"
    );
    assert!(uniform.iter().all(|u| (0.0..1.0).contains(u)));
    let gaussian: Vec<f64> = (0..200_000).map(|_| rng.gaussian()).collect();
    let (mean, std) = mean_and_std(&gaussian);
    assert!(
        mean.abs() < 0.01 && (std - 1.0).abs() < 0.01,
        "gaussian {mean} {std}"
    );
    let beyond_3 = gaussian.iter().filter(|g| g.abs() > 3.0).count() as f64 / 200_000.0;
    assert!((beyond_3 - 0.0027).abs() < 0.001, "tails {beyond_3}");
    let first: Vec<u64> = (0..4).map(|_| Rng::stream(7, "a").next_u64()).collect();
    assert!(
        first.windows(2).all(|w| w[0] == w[1]),
        "a stream is a function of its seed"
    );
    assert_ne!(
        Rng::stream(7, "a").next_u64(),
        Rng::stream(7, "b").next_u64()
    );
    assert_ne!(
        Rng::stream(7, "a").next_u64(),
        Rng::stream(8, "a").next_u64()
    );
}

#[test]
fn the_true_correction_restores_the_true_field() {
    println!("log: |b| mean/F, |b| spread/F (allowed), vertical error mean±std (µT), disturbed, peak disturbance (µT)");
    for case in cases() {
        let log = &case.log;
        let (hard_iron, inverse) = log.true_correction();
        let field = log.field_ned_ut;
        let total = field.norm();
        let mut magnitudes = Vec::new();
        let mut vertical_errors = Vec::new();
        let mut peak_disturbance: f64 = 0.0;
        for (k, row) in case.rows.iter().enumerate() {
            let body = inverse * (vector(row, MAG) - hard_iron);
            let ned = log.true_attitude[k] * body;
            if log.disturbed[k] {
                peak_disturbance = peak_disturbance.max((ned - field).norm());
            } else {
                magnitudes.push(body.norm());
                vertical_errors.push(ned.z - field.z);
            }
        }
        let (magnitude, spread) = mean_and_std(&magnitudes);
        let (vertical_mean, vertical_std) = mean_and_std(&vertical_errors);
        // The noise, through S⁻¹, sets the spread; where the field is weak (23 µT in
        // Buenos Aires) 0.6 µT of noise alone exceeds 2 %.
        let noise_through_inverse = log.mag_noise_ut * inverse.norm() / 3_f64.sqrt();
        let allowed = 0.02_f64.max(1.3 * noise_through_inverse / total);
        let fraction =
            log.disturbed.iter().filter(|&&d| d).count() as f64 / log.disturbed.len() as f64;
        println!(
            "{}: {:.4}, {:.4} ({:.4}), {:+.3}±{:.3}, {:.3}, {:.1}",
            log.name,
            magnitude / total,
            spread / total,
            allowed,
            vertical_mean,
            vertical_std,
            fraction,
            peak_disturbance
        );
        assert!((magnitude / total - 1.0).abs() < 0.005, "{}", log.name);
        assert!(spread / total < allowed, "{}", log.name);
        assert!(vertical_mean.abs() < 0.05, "{}", log.name);
        assert!(vertical_std < 1.3 * noise_through_inverse, "{}", log.name);
        match case.scenario {
            "moving_iron_walk" => {
                assert!((fraction - 0.10).abs() < 0.015, "{}", log.name);
                assert!(peak_disturbance > 20.0, "{}", log.name);
            }
            "magnet_mount_drive" => {
                assert!((fraction - 0.05).abs() < 0.01, "{}", log.name);
                assert!(peak_disturbance > 20.0, "{}", log.name);
            }
            _ => assert_eq!(fraction, 0.0, "{}", log.name),
        }
    }
}

#[test]
fn the_hard_and_soft_iron_are_drawn_in_their_ranges() {
    for case in cases() {
        let log = &case.log;
        let soft = log.soft_iron;
        let (diag_max, hard_ok) = if case.scenario == "magnet_mount_drive" {
            let magnitude = log.hard_iron_ut.norm();
            (0.15, (150.0..=250.0).contains(&magnitude))
        } else {
            (0.1, log.hard_iron_ut.iter().all(|h| h.abs() <= 30.0))
        };
        assert!(hard_ok, "{}: {}", log.name, log.hard_iron_ut);
        for row in 0..3 {
            for column in 0..3 {
                let value = soft[(row, column)];
                let ok = if row == column {
                    (value - 1.0).abs() <= diag_max
                } else {
                    value.abs() <= 0.1
                };
                assert!(ok, "{}: {soft}", log.name);
            }
        }
        assert_ne!(soft, soft.transpose(), "{}: S is general", log.name);
    }
}

/// The kinematic acceleration (NED) at each sample from second differences of the true
/// horizontal position (walks are level; the car's grade is left out).
fn path_acceleration_ned(log: &GeneratedLog, k: usize) -> Vector3<f64> {
    let n = log.true_en_m.len();
    if k == 0 || k + 1 >= n {
        return Vector3::zeros();
    }
    let dt = 1.0 / log.sample_rate_hz;
    let a = (log.true_en_m[k + 1] - 2.0 * log.true_en_m[k] + log.true_en_m[k - 1]) / (dt * dt);
    Vector3::new(a.y, a.x, 0.0)
}

#[test]
fn the_accelerometer_reads_minus_gravity_along_true_down() {
    let gravity = Vector3::new(0.0, 0.0, GRAVITY_MPS2);
    println!(
        "log: standing second |f − Rᵀ(−g)| (m/s²), acc_z; worst 10 s window |f − Rᵀ(a − g)| (m/s²)"
    );
    for case in cases() {
        let log = &case.log;
        let rate = log.sample_rate_hz.round() as usize;
        // The first second: standing (walks) or stopped (the drive).
        let mut measured = Vector3::zeros();
        let mut expected = Vector3::zeros();
        for k in 0..rate {
            measured += vector(&case.rows[k], ACC) / rate as f64;
            expected += log.true_attitude[k].inverse() * (-gravity) / rate as f64;
        }
        let standing_error = (measured - expected).norm();
        assert!(
            standing_error < 0.1,
            "{}: {measured} vs {expected}",
            log.name
        );
        assert!(
            measured.z < -9.5,
            "{}: a level device reads −g on z",
            log.name
        );
        // The noise (σ ≤ 0.05 m/s², and idle vibration in the car) averaged over a second.
        let tolerance = 0.01 + 4.0 * 0.06 / (rate as f64).sqrt();
        assert!(
            (measured - expected - log.acc_bias_mps2).norm() < tolerance,
            "{}: the rest is the bias",
            log.name
        );
        // Walks: over 10 s windows (many whole strides) the step oscillations average
        // out and the mean specific force is Rᵀ(a_path − g), centripetal part included.
        let mut worst_window: f64 = 0.0;
        if is_walk(case) {
            let window = 10 * rate;
            for start in (0..case.rows.len() - window).step_by(window) {
                let mut error = Vector3::zeros();
                for k in start..start + window {
                    let body =
                        log.true_attitude[k].inverse() * (path_acceleration_ned(log, k) - gravity);
                    error += (vector(&case.rows[k], ACC) - body) / window as f64;
                }
                worst_window = worst_window.max(error.norm());
            }
            assert!(worst_window < 0.15, "{}: {worst_window}", log.name);
        }
        println!(
            "{}: {standing_error:.3}, {:.2}; {worst_window:.3}",
            log.name, measured.z
        );
    }
}

/// From one sample to the next: each gyro row is the mean body rate over the sample it
/// is centred on, so half a step of this row's rate, then half a step of the next's.
fn step(
    attitude: Rotation3<f64>,
    rate: Vector3<f64>,
    next_rate: Vector3<f64>,
    dt: f64,
) -> Rotation3<f64> {
    attitude * Rotation3::new(rate * dt / 2.0) * Rotation3::new(next_rate * dt / 2.0)
}

#[test]
fn the_gyro_integrates_to_the_true_heading() {
    println!("log: bias-corrected heading error: worst |e| (°), at end (°), worst |e|/minute; 2 s windows worst attitude error (°); uncorrected at 1 min (°)");
    for case in cases() {
        let log = &case.log;
        let dt = 1.0 / log.sample_rate_hz;
        let gyro: Vec<Vector3<f64>> = case.rows.iter().map(|row| vector(row, GYRO)).collect();
        let integrate = |from: usize, to: usize, bias: Vector3<f64>| {
            let mut attitude = log.true_attitude[from];
            let mut errors = Vec::with_capacity(to - from);
            for k in from..to {
                attitude = step(attitude, gyro[k] - bias, gyro[k + 1] - bias, dt);
                let heading = physics::heading_deg_of(&attitude);
                errors.push(wrap_deg(heading - log.true_heading_deg[k + 1]));
            }
            errors
        };
        let n = gyro.len();
        let errors = integrate(0, n - 1, log.gyro_bias_radps);
        let mut worst: f64 = 0.0;
        let mut worst_per_minute: f64 = 0.0;
        for (i, error) in errors.iter().enumerate() {
            let minutes = (i + 1) as f64 * dt / 60.0;
            worst = worst.max(error.abs());
            worst_per_minute = worst_per_minute.max(error.abs() / minutes.max(1.0));
        }
        let end = errors.last().copied().unwrap_or(0.0);
        // Short spans check the rate itself (frame, sign, centring): the whole attitude,
        // integrated over 2 s from the truth, against the truth (the bias wander adds at
        // most about 0.1° in 2 s).
        let window = (2.0 * log.sample_rate_hz) as usize;
        let mut worst_window: f64 = 0.0;
        for start in (0..n - window - 1).step_by(window) {
            let mut attitude = log.true_attitude[start];
            for k in start..start + window {
                let bias = log.gyro_bias_radps;
                attitude = step(attitude, gyro[k] - bias, gyro[k + 1] - bias, dt);
            }
            let error = (attitude.inverse() * log.true_attitude[start + window]).angle();
            worst_window = worst_window.max(error.to_degrees());
        }
        let minute = (60.0 * log.sample_rate_hz) as usize;
        let uncorrected = integrate(0, minute, Vector3::zeros())
            .last()
            .copied()
            .unwrap_or(0.0);
        println!(
            "{}: {worst:.2}, {end:+.2}, {worst_per_minute:.2}; {worst_window:.3}; {uncorrected:+.1}",
            log.name
        );
        assert!(worst_per_minute < 3.0, "{}", log.name);
        // In the car, road vibration (up to 5 mrad/s at 20 m/s, correlated over a few
        // samples) integrates to about 0.25° per axis in 2 s; the worst windows are on
        // fast straight stretches, not in turns.
        let window_tolerance = if is_walk(case) { 0.3 } else { 1.0 };
        assert!(worst_window < window_tolerance, "{}", log.name);
    }
}

#[test]
fn gnss_fixes_scatter_about_the_truth_as_stated() {
    println!("log: fixes, worst |error|/σ per axis, rms error/σ, mean hacc/σ, speed rms (m/s), course rms above 1 m/s (°)");
    for case in cases() {
        let log = &case.log;
        let frame = LocalFrame::at(log.origin);
        let dt = 1.0 / log.sample_rate_hz;
        let sigma = log.gnss_sigma_m;
        let mut fix_times = Vec::new();
        let (mut worst, mut sum_squares, mut hacc_sum) = (0.0_f64, 0.0, 0.0);
        let (mut speed_squares, mut course_squares, mut courses) = (0.0, 0.0, 0);
        for (k, row) in case.rows.iter().enumerate() {
            let (Some(lat), Some(lon)) = (row[LAT], row[LON]) else {
                assert!(row[SPEED].is_none() && row[HACC].is_none(), "{}", log.name);
                continue;
            };
            fix_times.push(log.true_t_s[k]);
            let error = frame.en_of(lat, lon) - log.true_en_m[k];
            worst = worst.max(error.x.abs().max(error.y.abs()) / sigma);
            sum_squares += error.norm_squared() / 2.0;
            hacc_sum += row[HACC].expect("hacc with every fix");
            let before = log.true_en_m[k.saturating_sub(1)];
            let after = log.true_en_m[(k + 1).min(log.true_en_m.len() - 1)];
            let velocity: Vector2<f64> = (after - before) / (2.0 * dt);
            let speed = row[SPEED].expect("speed with every fix");
            speed_squares += (speed - velocity.norm()).powi(2);
            if let Some(course) = row[COURSE] {
                if velocity.norm() > 1.0 {
                    let truth = velocity.x.atan2(velocity.y).to_degrees();
                    course_squares += wrap_deg(course - truth).powi(2);
                    courses += 1;
                }
            }
        }
        let fixes = fix_times.len() as f64;
        let rms = (sum_squares / fixes).sqrt() / sigma;
        let speed_rms = (speed_squares / fixes).sqrt();
        let course_rms = (course_squares / courses.max(1) as f64).sqrt();
        println!(
            "{}: {}, {worst:.2}, {rms:.2}, {:.2}, {speed_rms:.2}, {course_rms:.1}",
            log.name,
            fix_times.len(),
            hacc_sum / fixes / sigma,
        );
        assert!(worst < 4.0, "{}", log.name);
        assert!((0.5..1.6).contains(&rms), "{}: {rms}", log.name);
        assert!(
            (0.7..1.4).contains(&(hacc_sum / fixes / sigma)),
            "{}",
            log.name
        );
        assert!(speed_rms < 0.3, "{}", log.name);
        if is_walk(case) {
            // 2-5° at 1.4 m/s, more at the slower walkers' 1-1.4 m/s.
            assert!(
                (1.5..8.0).contains(&course_rms),
                "{}: {course_rms}",
                log.name
            );
        }
        // 1 Hz, on whole seconds, except in the outage.
        let outage = log.gnss_outage_s;
        for pair in fix_times.windows(2) {
            let gap = pair[1] - pair[0];
            let across_outage =
                outage.is_some_and(|(start, end)| pair[0] < start && pair[1] >= end);
            assert!(
                (gap - 1.0).abs() < 1e-6 || across_outage,
                "{}: gap {gap} at {}",
                log.name,
                pair[0]
            );
        }
        match outage {
            Some((start, end)) => {
                assert_eq!(case.scenario, "four_direction_walk");
                assert_eq!((start, end), (240.0, 840.0));
                assert!(fix_times.iter().all(|&t| !(start..end).contains(&t)));
                assert_eq!(fix_times.iter().filter(|&&t| t < start).count(), 240);
                assert_eq!(fix_times.iter().filter(|&&t| t >= end).count(), 60);
            }
            None => {
                let expected = (log.true_t_s.len() as f64 * dt).ceil();
                assert_eq!(fixes, expected, "{}", log.name);
            }
        }
    }
}

/// Directions of travel (degrees) over each second outside turns: the walker moved at
/// least 0.8 m and the direction changed by under 0.5° from the second before and after.
fn straight_directions(positions: &[Vector2<f64>]) -> Vec<f64> {
    let directions: Vec<Option<f64>> = positions
        .windows(2)
        .map(|pair| {
            let step = pair[1] - pair[0];
            (step.norm() > 0.8).then(|| step.x.atan2(step.y).to_degrees())
        })
        .collect();
    directions
        .windows(3)
        .filter_map(|three| match three {
            [Some(a), Some(b), Some(c)]
                if wrap_deg(b - a).abs() < 0.5 && wrap_deg(c - b).abs() < 0.5 =>
            {
                Some(*b)
            }
            _ => None,
        })
        .collect()
}

/// Clusters directions (degrees) that lie within `tolerance` of each other.
fn clusters(directions: &[f64], tolerance: f64) -> Vec<(f64, usize)> {
    let mut found: Vec<(f64, usize)> = Vec::new();
    for &direction in directions {
        match found
            .iter_mut()
            .find(|(centre, _)| wrap_deg(direction - *centre).abs() < tolerance)
        {
            Some(cluster) => cluster.1 += 1,
            None => found.push((direction, 1)),
        }
    }
    found
}

#[test]
fn the_routes_have_the_shapes_they_promise() {
    println!("log: minutes, distance (m), headings or directions");
    for case in cases() {
        let log = &case.log;
        let rate = log.sample_rate_hz.round() as usize;
        let minutes = log.true_t_s.len() as f64 / log.sample_rate_hz / 60.0;
        // Columns present as promised.
        let has = |column: usize| case.rows.iter().any(|row| row[column].is_some());
        assert_eq!(
            has(REF_HEADING),
            !matches!(case.scenario, "four_direction_walk" | "magnet_mount_drive")
        );
        assert_eq!(
            has(REF_E) && has(REF_N),
            case.scenario == "four_direction_walk"
        );
        // Dated, evenly sampled.
        let first = case.rows[0][T_S].expect("time");
        assert!(
            (1_609_459_200.0..1_830_297_600.0).contains(&first),
            "{}",
            log.name
        );
        let last = case.rows[case.rows.len() - 1][T_S].expect("time");
        let span = (case.rows.len() - 1) as f64 / log.sample_rate_hz;
        assert!((last - first - span).abs() < 2e-3, "{}", log.name);
        if has(REF_HEADING) {
            for (row, truth) in case.rows.iter().zip(&log.true_heading_deg) {
                let written = row[REF_HEADING].expect("a heading on every row");
                assert!(wrap_deg(written - truth).abs() < 1e-3, "{}", log.name);
            }
        }
        let bins = |range: std::ops::Range<usize>, width_deg: f64| {
            let count = (360.0 / width_deg) as usize;
            let mut seen = vec![false; count];
            for k in range {
                seen[(log.true_heading_deg[k] / width_deg) as usize % count] = true;
            }
            seen.iter().filter(|&&s| s).count()
        };
        let n = log.true_t_s.len();
        let summary = match case.scenario {
            "circle_walk" | "moving_iron_walk" => {
                assert!((6.0..=10.05).contains(&minutes), "{}", log.name);
                assert_eq!(bins(0..n / 2, 10.0), 36, "{}: first half", log.name);
                assert_eq!(bins(n / 2..n, 10.0), 36, "{}: second half", log.name);
                "all 36 10° bins in both halves".to_string()
            }
            "few_headings_walk" => {
                let per_second: Vec<Vector2<f64>> =
                    log.true_en_m.iter().step_by(rate).copied().collect();
                let found = clusters(&straight_directions(&per_second), 3.0);
                let legs: Vec<&(f64, usize)> =
                    found.iter().filter(|(_, count)| *count >= 5).collect();
                assert!((3..=5).contains(&legs.len()), "{}: {found:?}", log.name);
                format!("{} directions of travel", legs.len())
            }
            "four_direction_walk" => {
                assert_eq!(minutes, 15.0, "{}", log.name);
                let written: Vec<Vector2<f64>> = case
                    .rows
                    .iter()
                    .filter_map(|row| Some(Vector2::new(row[REF_E]?, row[REF_N]?)))
                    .collect();
                assert_eq!(written.len(), 900, "{}: once a second", log.name);
                let directions = straight_directions(&written);
                // The grid's orientation: the circular mean of the directions modulo 90°.
                let (sin, cos) = directions.iter().fold((0.0, 0.0), |(s, c), d| {
                    let angle = (4.0 * d).to_radians();
                    (s + angle.sin(), c + angle.cos())
                });
                let grid = f64::atan2(sin, cos).to_degrees() / 4.0;
                let mut seconds = [0_usize; 4];
                let mut worst: f64 = 0.0;
                for direction in &directions {
                    let quarter = ((direction - grid) / 90.0).round();
                    worst = worst.max(wrap_deg(direction - grid - 90.0 * quarter).abs());
                    seconds[(quarter as i64).rem_euclid(4) as usize] += 1;
                }
                assert!(worst < 2.0, "{}: {worst}", log.name);
                assert!(
                    seconds.iter().all(|&s| s >= 20),
                    "{}: {seconds:?}",
                    log.name
                );
                assert!(directions.len() > 600, "{}", log.name);
                format!("4 directions (seconds {seconds:?}, worst off-grid {worst:.3}°)")
            }
            _ => {
                assert!((20.0..=40.5).contains(&minutes), "{}", log.name);
                assert_eq!(bins(0..n, 30.0), 12, "{}", log.name);
                let top_speed = log
                    .true_en_m
                    .windows(2)
                    .map(|pair| (pair[1] - pair[0]).norm() * log.sample_rate_hz)
                    .fold(0.0, f64::max);
                assert!(top_speed <= 20.5, "{}: {top_speed}", log.name);
                format!("all 12 30° bins, top speed {top_speed:.1} m/s")
            }
        };
        println!(
            "{}: {minutes:.1}, {:.0}, {summary}",
            log.name, log.distance_m
        );
    }
}

#[test]
fn walks_show_their_steps_and_the_hand_tilt() {
    println!("log: steps/s while walking, m per step, vertical bounce std (m/s²), max |pitch|, |roll| (°)");
    for case in cases().iter().filter(|case| is_walk(case)) {
        let log = &case.log;
        let dt = 1.0 / log.sample_rate_hz;
        // The vertical specific force in NED, plus g: the bounce, seen through the truth.
        let vertical: Vec<f64> = case
            .rows
            .iter()
            .zip(&log.true_attitude)
            .map(|(row, attitude)| (attitude * vector(row, ACC)).z + GRAVITY_MPS2)
            .collect();
        // Smoothed over 0.1 s; a step is an upward crossing of +0.5 after one of −0.5.
        let smooth: Vec<f64> = vertical
            .windows(5)
            .map(|w| w.iter().sum::<f64>() / 5.0)
            .collect();
        let (mut steps, mut armed) = (0, false);
        for value in &smooth {
            if *value < -0.5 {
                armed = true;
            } else if *value > 0.5 && armed {
                steps += 1;
                armed = false;
            }
        }
        let walking_s = log
            .true_en_m
            .windows(2)
            .filter(|pair| (pair[1] - pair[0]).norm() / dt > 0.5)
            .count() as f64
            * dt;
        let walking_bounce: Vec<f64> = vertical
            .iter()
            .zip(log.true_en_m.windows(2))
            .filter(|(_, pair)| (pair[1] - pair[0]).norm() / dt > 1.0)
            .map(|(value, _)| *value)
            .collect();
        let (_, bounce) = mean_and_std(&walking_bounce);
        let (mut pitch, mut roll) = (0.0_f64, 0.0_f64);
        for attitude in &log.true_attitude {
            let (r, p, _) = attitude.euler_angles();
            pitch = pitch.max(p.abs().to_degrees());
            roll = roll.max(r.abs().to_degrees());
        }
        let cadence = steps as f64 / walking_s;
        let per_step = log.distance_m / steps as f64;
        println!(
            "{}: {cadence:.2}, {per_step:.3}, {bounce:.2}, {pitch:.1}, {roll:.1}",
            log.name
        );
        assert!((1.55..2.15).contains(&cadence), "{}", log.name);
        assert!((0.55..0.85).contains(&per_step), "{}", log.name);
        assert!((0.8..2.5).contains(&bounce), "{}", log.name);
        let most = if case.scenario == "four_direction_walk" {
            8.0
        } else {
            10.0
        };
        assert!(pitch < most + 2.0 && roll < most + 2.0, "{}", log.name);
        assert!(pitch > 2.0 && roll > 2.0, "{}: the hand tilts", log.name);
    }
}

#[test]
fn the_crates_importer_reads_the_logs_cleanly() {
    for case in cases() {
        let log = &case.log;
        let report = compass_pdr::io::canonical_csv::read("generated.csv", log.csv.as_bytes())
            .expect("readable");
        assert!(
            report.diagnostics.is_empty(),
            "{}: {:?}",
            log.name,
            report.diagnostics
        );
        let recording = report.recording;
        let n = log.true_t_s.len();
        assert_eq!(recording.mag_in_body_ut.len(), n, "{}", log.name);
        assert_eq!(recording.acc_in_body_mps2.len(), n, "{}", log.name);
        assert_eq!(recording.gyro_in_body_radps.len(), n, "{}", log.name);
        let fixes = case.rows.iter().filter(|row| row[LAT].is_some()).count();
        assert_eq!(recording.gnss.len(), fixes, "{}", log.name);
        println!(
            "{}: {n} samples, {fixes} fixes, start {:?} (generated {})",
            log.name, recording.start_unix_s, log.start_unix_s
        );
    }
}

#[test]
fn moving_iron_walk_is_circle_walk_plus_moving_iron() {
    let plain = physics::circle_walk(3);
    let disturbed = physics::moving_iron_walk(3);
    assert_eq!(plain.true_heading_deg, disturbed.true_heading_deg);
    assert_eq!(plain.hard_iron_ut, disturbed.hard_iron_ut);
    assert!(disturbed.disturbed.iter().any(|&d| d));
    assert_ne!(plain.csv, disturbed.csv);
}

#[test]
fn the_same_seed_gives_the_same_log_and_others_differ() {
    for (scenario, generate) in SCENARIOS {
        let first = generate(11);
        assert_eq!(first.csv, generate(11).csv, "{scenario}");
        assert_ne!(first.csv, generate(12).csv, "{scenario}");
    }
}

#[test]
fn generation_is_quick() {
    println!("log: generation time (debug build, opt-level 1), rows, CSV bytes");
    for case in cases() {
        println!(
            "{}: {:.0} ms, {}, {}",
            case.log.name,
            case.generation.as_secs_f64() * 1000.0,
            case.rows.len(),
            case.log.csv.len()
        );
        // Generous against a loaded machine; typically well under a second.
        assert!(
            case.generation < Duration::from_secs(3),
            "{}",
            case.log.name
        );
    }
}
