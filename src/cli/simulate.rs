//! `compass-pdr simulate`: the simulator's scenarios written as logs, with their truth.

use std::path::Path;

use clap::ValueEnum;
use compass_pdr::io::canonical_csv;
use compass_pdr::sim::dance::{motioncal_raw_lines, DanceConfig};
use compass_pdr::sim::gait::StepTruth;
use compass_pdr::sim::walk::{simulate_with_truth, WalkConfig};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(super) enum Scenario {
    /// The demo log (`assets/demo-walk.csv`): a walk in Seattle with hard iron, scale
    /// factors and their temperature drift, varied steps, GNSS with an outage and
    /// multipath, and a passage near iron.
    Demo,
    /// A steady walk with hard iron and scale factors, no GNSS (the demo before 2026-11).
    Steady,
    /// The phone of the steady walk on a level turntable, one turn a minute.
    Turntable,
    /// A car's octagonal loop at 12 m/s, the phone in a fixed mount, its compass
    /// deviating by Eq. 12 (the car's iron), GNSS with its course.
    Vehicle,
    /// The 2007 paper's raw case on the turntable: a raw heading error of (12 ± 30)°
    /// (hard iron of 0.69 of the horizontal field, and a declination of −12° that the log
    /// does not reveal).
    Paper,
    /// The PDR walk: varied steps, unified-model compass error, 3 m GNSS noise.
    Pdr,
    /// A board's sphere "calibration dance", written as MotionCal `Raw:` lines (what a
    /// calibration sketch prints over the serial port), with an Eq. 5 distortion (hard
    /// iron, symmetric soft iron) as its truth. `--sample-rate-hz` is its line rate.
    Dance,
}

/// The truth file of the PDR scenario: the config and every step.
#[derive(serde::Serialize)]
pub(super) struct PdrTruth<'a> {
    pub(super) config: &'a WalkConfig,
    pub(super) path_length_m: f64,
    pub(super) steps: &'a [StepTruth],
}

pub(super) fn run_simulate(
    seed: u64,
    duration_s: f64,
    scenario: Scenario,
    sample_rate_hz: f64,
    out: &Path,
    truth: Option<&Path>,
) -> Result<(), String> {
    if !(duration_s.is_finite() && duration_s > 0.0 && duration_s <= 24.0 * 3600.0) {
        return Err(format!(
            "--duration-s {duration_s} is out of range: give a number of seconds from 0 to 86400"
        ));
    }
    if !(sample_rate_hz.is_finite() && (10.0..=1000.0).contains(&sample_rate_hz)) {
        return Err(format!(
            "--sample-rate-hz {sample_rate_hz} is out of range: give a rate from 10 to 1000 Hz"
        ));
    }
    if scenario == Scenario::Dance {
        let config = DanceConfig {
            rate_hz: sample_rate_hz,
            ..DanceConfig::from_seed(seed, duration_s)
        };
        let (text, dance_truth) = motioncal_raw_lines(&config);
        std::fs::write(out, text)
            .map_err(|error| format!("cannot write {}: {error}", out.display()))?;
        if let Some(truth) = truth {
            let json = serde_json::to_string_pretty(&dance_truth)
                .map_err(|error| format!("cannot encode the truth: {error}"))?;
            std::fs::write(truth, json + "\n")
                .map_err(|error| format!("cannot write {}: {error}", truth.display()))?;
        }
        return Ok(());
    }
    let config = match scenario {
        Scenario::Demo => WalkConfig::demo(seed, duration_s, sample_rate_hz),
        Scenario::Steady => WalkConfig {
            sample_rate_hz,
            ..WalkConfig::from_seed(seed, duration_s)
        },
        Scenario::Turntable => WalkConfig {
            sample_rate_hz,
            ..WalkConfig::turntable(seed, duration_s, 60.0)
        },
        Scenario::Vehicle => WalkConfig::vehicle_loop(seed, duration_s, sample_rate_hz),
        Scenario::Paper => WalkConfig {
            sample_rate_hz,
            ..WalkConfig::paper_raw_case(seed, duration_s)
        },
        Scenario::Pdr | Scenario::Dance => WalkConfig::pdr_walk(seed, duration_s, sample_rate_hz),
    };
    let (rows, walk_truth) = simulate_with_truth(&config);
    let is_nmea = out
        .extension()
        .is_some_and(|extension| extension.eq_ignore_ascii_case("nmea"));
    let text = if is_nmea {
        // Absolute rows (a config with a start) are written at their own times.
        let origin_unix_s = match config.start_unix_s {
            Some(_) => 0.0,
            None => compass_pdr::sim::nmea::DEFAULT_START_UNIX_S,
        };
        compass_pdr::sim::nmea::write(&rows, origin_unix_s, 10.0)
    } else {
        canonical_csv::write(&rows)
    };
    std::fs::write(out, text)
        .map_err(|error| format!("cannot write {}: {error}", out.display()))?;
    if let Some(truth) = truth {
        // The steady walk's truth is its config alone; a varied gait's has its steps.
        let encoded = match scenario {
            Scenario::Steady | Scenario::Turntable | Scenario::Paper | Scenario::Vehicle => {
                serde_json::to_string_pretty(&config)
            }
            Scenario::Demo | Scenario::Pdr | Scenario::Dance => {
                serde_json::to_string_pretty(&PdrTruth {
                    config: &config,
                    path_length_m: walk_truth.path_length_m,
                    steps: &walk_truth.steps,
                })
            }
        };
        let json = encoded.map_err(|error| format!("cannot encode the truth: {error}"))?;
        std::fs::write(truth, json + "\n")
            .map_err(|error| format!("cannot write {}: {error}", truth.display()))?;
    }
    Ok(())
}
