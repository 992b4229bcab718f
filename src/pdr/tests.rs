use super::fusion::Outage;
use super::references::{straight_segments, unconfirmed_speed};
use super::step_length::StepLengthModel;
use super::*;
use crate::analysis::calibration::row_key::{OnTop, RowKey};
use crate::analysis::calibration::Method;
use crate::io::canonical_csv;
use crate::io::import::import;
use crate::sim::walk::{simulate, GnssSim, WalkConfig};

fn sim_report(config: &WalkConfig) -> ImportReport {
    let text = canonical_csv::write(&simulate(config));
    import("sim.csv", text.as_bytes()).expect("readable")
}

fn with_gnss(seed: u64, duration_s: f64) -> WalkConfig {
    WalkConfig {
        gnss: Some(GnssSim {
            position_noise_m: 3.0,
            hacc_m: 3.0,
            ..GnssSim::default()
        }),
        ..WalkConfig::from_seed(seed, duration_s)
    }
}

fn weinberg_k(analysis: &PdrAnalysis) -> f64 {
    match analysis.report.step_model.model {
        StepLengthModel::Weinberg { k } => k,
        _ => f64::NAN,
    }
}

/// The simulator check: a 15-minute walk (varied gait, Weinberg-sized
/// bounces, the unified heading error of up to ~18°, 3 m GNSS) with GNSS ignored from
/// 4 to 14 minutes. The outage's RMS position error must stay under 1 % of the
/// distance walked in it, and the step count within 1 % of the truth's.
#[test]
fn a_ten_minute_outage_is_bridged_within_one_percent_of_the_distance() {
    for (seed, rate_hz, model) in [
        (1, 50.0, StepModelKind::Weinberg),
        (2, 100.0, StepModelKind::Linear),
        (3, 50.0, StepModelKind::Neural),
    ] {
        let config = WalkConfig::pdr_walk(seed, 900.0, rate_hz);
        let (rows, truth) = crate::sim::walk::simulate_with_truth(&config);
        let text = canonical_csv::write(&rows);
        let report = import("walk.csv", text.as_bytes()).expect("readable");
        let options = PdrOptions {
            step_model: model,
            gnss: GnssPolicy {
                outages: vec![Outage {
                    start_s: 240.0,
                    end_s: 840.0,
                }],
                ..GnssPolicy::default()
            },
            ..PdrOptions::default()
        };
        let analysis = crate::pipeline::dead_reckoning(&report, &options).expect("dead-reckons");
        let report = &analysis.report;
        let outage = report.outage_position_errors.first().expect("scored");
        let step_error_pct = 100.0 * (report.n_steps as f64 / truth.steps.len() as f64 - 1.0);
        eprintln!(
            "seed {seed}, {rate_hz} Hz, {model:?}: {} steps (truth {}), outage RMS {:.2} m = {:.3} % of {:.0} m, max {:.2} m, heading {}",
            report.n_steps,
            truth.steps.len(),
            outage.rms_m,
            outage.rms_pct,
            outage.distance_m,
            outage.max_m,
            report.heading_key
        );
        assert!(outage.rms_pct < 1.0, "{outage:?}");
        assert!(outage.distance_m > 500.0, "{outage:?}");
        assert!(step_error_pct.abs() < 1.0, "{step_error_pct} %");
        assert_eq!(report.step_model.trained_on, "gnss_speed");
        assert_eq!(report.step_model.model.kind(), model);
        assert_eq!(report.fixes.in_outage, 601, "{:?}", report.fixes);
    }
}

#[test]
fn gnss_positions_train_the_step_model_when_the_log_has_no_speed() {
    // 20 minutes: each 20-s stretch knows its length to about 2.3 m (3 m fixes), so
    // about 50 stretches give K to about 1.3 %.
    let config = with_gnss(21, 1200.0);
    let with_speed = crate::pipeline::dead_reckoning(&sim_report(&config), &PdrOptions::default())
        .expect("runs");
    assert_eq!(with_speed.report.step_model.trained_on, "gnss_speed");
    let mut report = sim_report(&config);
    for fix in &mut report.recording.gnss.values {
        fix.speed_mps = None;
    }
    let without_speed =
        crate::pipeline::dead_reckoning(&report, &PdrOptions::default()).expect("runs");
    let summary = &without_speed.report.step_model;
    assert_eq!(
        summary.trained_on, "gnss_positions",
        "{:?}",
        without_speed.report.notes
    );
    assert!(summary.n_references >= 10, "{summary:?}");
    let (k_speed, k_positions) = (weinberg_k(&with_speed), weinberg_k(&without_speed));
    assert!(
        (k_positions / k_speed - 1.0).abs() < 0.04,
        "{k_speed} from speed, {k_positions} from positions"
    );
}

/// Step `k` of a walk at two steps a second, its bounce from `a_min_mps2` to `a_max_mps2`.
fn step_at(k: usize, a_max_mps2: f64, a_min_mps2: f64) -> Step {
    Step {
        t_start_s: 0.5 * k as f64,
        t_end_s: 0.5 * (k + 1) as f64,
        t_peak_s: 0.5 * k as f64 + 0.1,
        frequency_hz: 2.0,
        variance_mps2_sq: 1.0,
        a_max_mps2,
        a_min_mps2,
        ends_bout: false,
    }
}

/// Whether a note of the analysis says `text`.
fn has_note(analysis: &PdrAnalysis, text: &str) -> bool {
    analysis.report.notes.iter().any(|note| note.contains(text))
}

#[test]
fn straight_segments_follow_straight_runs_of_steps_only() {
    let steps: Vec<Step> = (0..200).map(|k| step_at(k, 11.0, 8.5)).collect();
    // North for 50 s, then turning 9° a step.
    let headings: Vec<f64> = (0..200)
        .map(|k| {
            if k < 100 {
                0.0
            } else {
                (k - 100) as f64 * 9f64.to_radians()
            }
        })
        .collect();
    let positions: Vec<(f64, [f64; 2])> = (0..100)
        .map(|t| (t as f64, [0.0, 1.4 * t as f64]))
        .collect();
    let segments = straight_segments(&positions, &steps, &headings, 20.0, 15.0);
    assert!(!segments.is_empty());
    for segment in &segments {
        assert!(segment.steps.end <= 100, "{segment:?}");
        assert!(segment.distance_m >= 15.0);
    }
}

#[test]
fn a_gnss_speed_trains_only_where_the_fixes_confirm_it() {
    let steps: Vec<Step> = (0..40).map(|k| step_at(k, 12.0, 8.0)).collect();
    // Weinberg's K = 0.47 makes each of these steps 0.47 · 4^¼ = 0.665 m: 26.6 m.
    let model = StepLengthModel::Weinberg { k: 0.47 };
    let stretch = |distance_m: f64| {
        vec![step_length::SegmentReference {
            steps: 0..40,
            distance_m,
        }]
    };
    assert_eq!(unconfirmed_speed(&model, &steps, &stretch(26.6)), None);
    assert_eq!(unconfirmed_speed(&model, &steps, &stretch(30.0)), None);
    // A speed that makes the walk 60 % of what the fixes say is not believed ...
    let why = unconfirmed_speed(&model, &steps, &stretch(44.3)).expect("refused");
    assert!(why.contains("60 %"), "{why}");
    // ... and nor is one that nothing confirms.
    assert!(unconfirmed_speed(&model, &steps, &[]).is_some());
}

#[test]
fn a_heading_fitted_on_the_track_s_own_truth_does_not_steer_it() {
    // A simulated walk without GNSS: its reference-heading column is the truth that
    // scores the track, and the comparison is scored (and its models fitted) on it.
    let report = sim_report(&WalkConfig::from_seed(7, 240.0));
    let (calibration, mut headings) =
        crate::pipeline::headings(&report, &PdrOptions::default().heading_options)
            .expect("headings");
    let source = headings.report.reference.expect("a reference");
    assert!(source.scores_the_track(), "{source:?}");
    // Whatever the comparison chose, make it a model fitted on that reference: a
    // Fourier deviation on top of a calibration.
    let fitted = headings
        .headings_deg
        .iter()
        .map(|(key, _)| *key)
        .find(|key| {
            key.on_top == OnTop::Fourier
                && key
                    .field_method()
                    .is_some_and(|method| method != Method::RefLs)
        })
        .expect("a Fourier model on the reference");
    let base = RowKey::of(fitted.base);
    headings.report.choice.key = fitted;
    let options = PdrOptions::default();
    let analysis = dead_reckon(&report, (&calibration, &headings), &options).expect("runs");
    // The track takes the calibration under it, which needs no reference, and says why.
    assert_eq!(analysis.report.heading_key, base.text());
    assert!(
        has_note(&analysis, "also scores the track"),
        "{:?}",
        analysis.report.notes
    );
    // A choice with nothing fitted on the reference stands.
    headings.report.choice.key = base;
    let analysis = dead_reckon(&report, (&calibration, &headings), &options).expect("runs");
    assert_eq!(analysis.report.heading_key, base.text());
    // A reference that even the best model is 45° RMS from chooses nothing: the track
    // takes the attitude filter.
    let chosen_basis = headings.report.choice.basis.clone();
    headings.report.choice.basis =
        crate::analysis::calibration::selection::Basis::ReferenceTooFar {
            rms_deg: 45.0,
            closest: "reference LS (Eq. 8)".to_string(),
        };
    let analysis = dead_reckon(&report, (&calibration, &headings), &options).expect("runs");
    assert_eq!(analysis.report.heading_key, RowKey::ATTITUDE.text());
    assert!(
        has_note(&analysis, "too far to choose one"),
        "{:?}",
        analysis.report.notes
    );
    headings.report.choice.basis = chosen_basis;
    headings.report.choice.key = fitted;
    // Asked to train on the reference, it takes the comparison's choice.
    let trained = PdrOptions {
        train_on_reference_positions: true,
        ..PdrOptions::default()
    };
    let analysis = dead_reckon(&report, (&calibration, &headings), &trained).expect("runs");
    assert_eq!(analysis.report.heading_key, fitted.text());
}
