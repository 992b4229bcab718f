//! Heading error models learned from a reference, and every heading method side by
//! side on one train/check split.
//!
//! Field-domain calibration ([`crate::analysis::calibration`]) cannot remove everything:
//! the misalignment between device and walking direction, tilt the accelerometer missed,
//! declination, soft iron that moves with the body and temperature all leave a heading
//! error that depends on the heading and on conditions. The models of
//! [`crate::deviation`] learn it from the reference heading ([`crate::reference`]):
//!
//! - [`crate::deviation::fourier`]: the PDR paper's unified model
//!   `δ = A + B sin ξ' + C cos ξ' + D sin 2ξ' + E cos 2ξ'` (Eq. 12), fitted by least
//!   squares on the train part;
//! - [`crate::deviation::rls`]: the same model adapted online while the reference is
//!   good;
//! - [`crate::deviation::neural`]: the 2007 paper's neural network (heading, |H|, gyro
//!   heading, dip, temperature in; the deviation out), on the raw heading and on the
//!   field-domain method that fits its train part best;
//!
//! the Fourier model on the raw heading and on top of each base ("ellipse + Fourier").
//! The models are fitted to the train part's 1 s bins, not to single samples: they see
//! circular means, which keeps the body's sway out of the regressor, and bins in a turn
//! are left out. The comparison (`compare.rs`) reports mean, std, RMS, 95th percentile
//! and the share within ±5° on train and on check, as the papers' tables do.

mod compare;

pub use compare::compare;

use serde::Serialize;

use crate::analysis::calibration::row_key::RowKey;
use crate::analysis::calibration::selection::Choice;
use crate::analysis::calibration::{CalibrationOptions, CalibrationReport};
use crate::base::stats::HeadingErrorStats;
use crate::deviation::fourier::{FourierDeviation, FourierFit};
use crate::deviation::rls::RlsSnapshot;
use crate::reference::ReferenceSource;

/// The bins (s) over which headings are averaged into the pairs a model is fitted to.
const PAIR_WINDOW_S: f64 = 1.0;
/// A bin whose headings spread further than this (rad, either side of their mean) is in
/// a turn and is left out.
const MAX_BIN_SPREAD_RAD: f64 = 0.17;
/// A bin is in a turn when the gyro heading spans more than this (degrees, peak to
/// peak) over it and [`TURN_MARGIN_S`] either side: a walker's yaw sway and a hand's
/// wander span a few degrees, a car's turn or a walker's corner 20° and more.
const MAX_BIN_TURN_DEG: f64 = 15.0;
const TURN_MARGIN_S: f64 = 0.5;
/// Online updates are spaced by at least this (s): a 50 Hz compass against a 1 Hz GPS
/// course adds nothing faster.
const ONLINE_UPDATE_SPACING_S: f64 = 0.2;
/// Coefficient snapshots for the convergence plot, every this many seconds.
const ONLINE_SNAPSHOT_SPACING_S: f64 = 5.0;

/// Choices that change the result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeadingOptions {
    /// The field-domain methods, the reference, the split and the declination.
    pub calibration: CalibrationOptions,
    /// Memory of the online adaptation (s): the forgetting factor per update is
    /// exp(−spacing / memory).
    pub online_memory_s: f64,
    /// Train the neural-network corrections (the slowest models by far; dead reckoning
    /// leaves them out unless asked for one).
    pub neural: bool,
}

impl Default for HeadingOptions {
    fn default() -> Self {
        HeadingOptions {
            calibration: CalibrationOptions::default(),
            online_memory_s: 300.0,
            neural: true,
        }
    }
}

/// One heading method's errors on train and check.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeadingRow {
    /// What the row is (written `raw`, `ellipse`, `ellipse+fourier`, ...).
    pub key: RowKey,
    pub label: String,
    pub train: Option<HeadingErrorStats>,
    pub check: Option<HeadingErrorStats>,
    /// Why it could not be fitted, and what to do.
    pub error: Option<String>,
}

/// A Fourier deviation model fitted on top of one base heading.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FourierReport {
    pub base_key: RowKey,
    pub base_label: String,
    /// The fit on the train part, with its own residual statistics and histogram.
    pub fit: FourierFit,
}

/// The online adaptation on one base heading.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OnlineReport {
    pub base_key: RowKey,
    pub base_label: String,
    pub memory_s: f64,
    pub forgetting_per_update: f64,
    pub n_updates: usize,
    pub model: FourierDeviation,
    pub snapshots: Vec<RlsSnapshot>,
}

/// What `compass-pdr heading --json` prints and the page shows.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeadingReport {
    pub file_name: String,
    pub reference: Option<ReferenceSource>,
    pub reference_description: Option<String>,
    pub train_until_s: Option<f64>,
    /// Samples with a reference heading on each part.
    pub n_train_referenced: usize,
    pub n_check_referenced: usize,
    pub rows: Vec<HeadingRow>,
    pub fourier: Vec<FourierReport>,
    /// The neural-network corrections (on the raw heading and on the best field-domain
    /// method), with their inputs and training.
    pub neural: Vec<crate::deviation::neural::NeuralReport>,
    pub online: Option<OnlineReport>,
    /// The row the analysis recommends, and why ([`crate::analysis::calibration::selection`]):
    /// the lowest check RMS (train RMS without a check part), never worse than the
    /// uncalibrated heading; without a reference, the field calibration the fits' own
    /// figures recommend. Its key is the JSON's `choice.key`.
    pub choice: Choice,
    pub notes: Vec<String>,
    /// The field-domain comparison it stands on.
    pub calibration: CalibrationReport,
}

impl HeadingReport {
    /// The row keyed `key`, if the comparison has one.
    pub fn row(&self, key: RowKey) -> Option<&HeadingRow> {
        self.rows.iter().find(|row| row.key == key)
    }

    /// The row whose key is written `text` (`raw`, `ellipse+fourier`, …): for callers
    /// that hold the text (a user's choice, a table of figures).
    pub fn row_written(&self, text: &str) -> Option<&HeadingRow> {
        self.row(RowKey::parse(text)?)
    }

    /// The Fourier model the plots feature: of those with all five terms, the one that
    /// fits its train part best; else the one on the raw heading.
    pub fn featured_fourier(&self) -> Option<&FourierReport> {
        featured(&self.fourier)
    }
}

/// The Fourier model to show and to adapt online: the best fitting (smallest residual
/// spread) of those with all five terms, else of those with fewer (when the train
/// headings cover too little of the circle for all five: a calibrated base with A, B
/// and C still shows more than the raw heading's constant).
fn featured(reports: &[FourierReport]) -> Option<&FourierReport> {
    let best = |full_only: bool| {
        reports
            .iter()
            .filter(|report| {
                !full_only || report.fit.terms == crate::deviation::fourier::FourierTerms::Full
            })
            .min_by(|a, b| a.fit.residual_std_deg.total_cmp(&b.fit.residual_std_deg))
    };
    best(true).or_else(|| best(false))
}

/// The report with the per-sample series the plots draw.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadingAnalysis {
    pub report: HeadingReport,
    pub t_s: Vec<f64>,
    pub reference_deg: Vec<Option<f64>>,
    /// Each row's heading per sample, by key.
    pub headings_deg: Vec<(RowKey, Vec<f64>)>,
}

/// The models see the train part in bins of PAIR_WINDOW_S: the circular mean of the
/// base heading and of the reference over each bin. Averaging takes out most of the
/// body's sway, whose noise in the raw heading would otherwise flatten the fitted
/// curve (noise in a regressor biases least squares); a bin in a turn is left out.
fn train_bins(
    t_s: &[f64],
    is_train: &[bool],
    reference_rad: &[Option<f64>],
    gyro_heading_deg: &[Option<f64>],
) -> Vec<Vec<usize>> {
    let mut bins: Vec<Vec<usize>> = Vec::new();
    let mut bin_start_s = f64::NEG_INFINITY;
    for (idx, (&sample_t_s, (&train, reference))) in t_s
        .iter()
        .zip(is_train.iter().zip(reference_rad))
        .enumerate()
    {
        if !train || reference.is_none() {
            continue;
        }
        match bins.last_mut() {
            Some(bin) if sample_t_s < bin_start_s + PAIR_WINDOW_S => bin.push(idx),
            _ => {
                bins.push(vec![idx]);
                bin_start_s = sample_t_s;
            }
        }
    }
    // A bin in a turn, or within a second of one, is left out when the gyro says so: a
    // GNSS course lags the heading in a turn (it is the direction of the last second's
    // motion), and a turn's bins would teach every model that lag.
    bins.retain(|bin| !turning(bin, t_s, gyro_heading_deg));
    bins
}

/// The circular mean of `values_rad` at `indices`, or `None` when they spread beyond
/// [`MAX_BIN_SPREAD_RAD`] or any is not finite.
fn steady_mean(values_rad: &[f64], indices: &[usize]) -> Option<f64> {
    let (mut sum_sin, mut sum_cos) = (0.0, 0.0);
    for &idx in indices {
        let value = *values_rad.get(idx)?;
        if !value.is_finite() {
            return None;
        }
        sum_sin += value.sin();
        sum_cos += value.cos();
    }
    let mean_rad = sum_sin.atan2(sum_cos);
    let spread_rad = indices
        .iter()
        .filter_map(|&idx| {
            Some(crate::base::angle::wrap_to_pi(values_rad.get(idx)? - mean_rad).abs())
        })
        .fold(0.0, f64::max);
    (spread_rad <= MAX_BIN_SPREAD_RAD && !indices.is_empty())
        .then_some(crate::base::angle::wrap_to_2pi(mean_rad))
}

/// Whether the gyro heading turns by more than [`MAX_BIN_TURN_DEG`] (peak to peak) over
/// the bin and [`TURN_MARGIN_S`] either side of it; `false` without a gyro there.
fn turning(bin: &[usize], t_s: &[f64], gyro_heading_deg: &[Option<f64>]) -> bool {
    let (Some(&first), Some(&last)) = (bin.first(), bin.last()) else {
        return false;
    };
    let (Some(&start_s), Some(&end_s)) = (t_s.get(first), t_s.get(last)) else {
        return false;
    };
    let lo = t_s.partition_point(|&t| t < start_s - TURN_MARGIN_S);
    let hi = t_s.partition_point(|&t| t <= end_s + TURN_MARGIN_S);
    let window = gyro_heading_deg.get(lo..hi).unwrap_or(&[]);
    let Some(origin_deg) = window.iter().flatten().next().copied() else {
        return false;
    };
    let (low, high) = window
        .iter()
        .flatten()
        .fold((0.0f64, 0.0f64), |(low, high), &deg| {
            let relative =
                crate::base::angle::wrap_to_pi((deg - origin_deg).to_radians()).to_degrees();
            (low.min(relative), high.max(relative))
        });
    high - low > MAX_BIN_TURN_DEG
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::canonical_csv;
    use crate::io::import::import;
    use crate::sim::walk::{simulate, WalkConfig};

    use crate::analysis::calibration::Method;
    use crate::reference::{ReferenceChoice, ReferenceOptions};
    use crate::sim::walk::GnssSim;

    /// The paper's Table II, data set 1.
    const TABLE_II_1: [f64; 5] = [9.0, 31.4, 0.9, 0.6, 1.8];

    fn simulated(config: &WalkConfig) -> crate::io::ImportReport {
        let text = canonical_csv::write(&simulate(config));
        import("walk.csv", text.as_bytes()).expect("imports")
    }

    /// The Fourier model fitted on the raw heading of the simulated `config`, every
    /// sample with a GPS course training (the reference must be the GPS course).
    fn raw_fourier_fit_on_gps(config: &WalkConfig) -> crate::deviation::fourier::FourierFit {
        let analysis = crate::pipeline::headings(&simulated(config), &all_train_on_gps())
            .map(|(_, headings)| headings)
            .expect("analyses");
        assert_eq!(
            analysis.report.reference.map(|source| source.label()),
            Some("GPS course")
        );
        analysis
            .report
            .fourier
            .into_iter()
            .find(|report| report.base_key == RowKey::RAW)
            .expect("fitted")
            .fit
    }

    /// A to E, in degrees.
    fn coefficients(model: &crate::deviation::fourier::FourierDeviation) -> [f64; 5] {
        [
            model.a_deg,
            model.b_deg,
            model.c_deg,
            model.d_deg,
            model.e_deg,
        ]
    }

    /// Every referenced sample trains, against the GPS course.
    fn all_train_on_gps() -> HeadingOptions {
        HeadingOptions {
            calibration: CalibrationOptions {
                methods: vec![Method::MinMax],
                train_until_s: Some(1e9),
                reference: ReferenceOptions {
                    choice: ReferenceChoice::Gps,
                    ..ReferenceOptions::default()
                },
                ..CalibrationOptions::default()
            },
            ..HeadingOptions::default()
        }
    }

    #[test]
    fn a_to_e_come_back_within_0_3_degrees_from_a_walk_with_2_degree_gps_course_noise() {
        // At the GNSS origin's place, dated: the Earth's field there has its declination,
        // which the analysis takes from the model, so A is the compass's own.
        let config = WalkConfig {
            deviation_deg: Some(TABLE_II_1),
            gnss: Some(GnssSim::default()),
            ..WalkConfig::from_seed(5, 1200.0)
        }
        .at_place(60.1699, 24.9384, 1_700_000_000.0)
        .expect("the model covers the place and date");
        let fit = raw_fourier_fit_on_gps(&config);
        let got = coefficients(&fit.model);
        for (got, want) in got.iter().zip(TABLE_II_1) {
            assert!(
                (got - want).abs() < 0.3,
                "{got:?} vs {TABLE_II_1:?} {fit:?}"
            );
        }
    }

    /// A car's compass swung against its GPS course: the vehicle loop (eight headings
    /// held in turn, 1° course noise), levelled in its mount. The declination the WMM
    /// gives for the log's place and date is applied first, so A is the car's own.
    #[test]
    fn a_to_e_of_a_cars_compass_come_back_from_its_gps_course_on_the_vehicle_loop() {
        let config = WalkConfig {
            mean_pitch_deg: 0.0,
            mean_roll_deg: 0.0,
            ..WalkConfig::vehicle_loop(1, 1200.0, 10.0)
        };
        let Some(truth) = config.deviation_deg else {
            panic!("the car's compass deviates")
        };
        let fit = raw_fourier_fit_on_gps(&config);
        assert_eq!(fit.terms, crate::deviation::fourier::FourierTerms::Full);
        let got = coefficients(&fit.model);
        for (got, want) in got.iter().zip(truth) {
            assert!((got - want).abs() < 0.3, "{got:?} vs {truth:?}");
        }
    }

    #[test]
    fn when_the_error_depends_on_temperature_the_mlp_beats_the_fourier_model_on_check() {
        // Hard iron that drifts 1 µT/°C with a ±10 °C swing every 5 minutes: the
        // deviation is no longer a function of heading alone.
        let config = WalkConfig {
            temp_swing_c: 10.0,
            temp_period_s: 300.0,
            hard_iron_temp_coeff_ut_per_c: [1.0, -0.8, 0.0],
            ..WalkConfig::from_seed(12, 1200.0)
        };
        let options = HeadingOptions {
            calibration: CalibrationOptions {
                methods: vec![Method::MinMax],
                ..CalibrationOptions::default()
            },
            ..HeadingOptions::default()
        };
        let analysis = crate::pipeline::headings(&simulated(&config), &options)
            .map(|(_, headings)| headings)
            .expect("analyses");
        let check_rms = |key: &str| {
            analysis
                .report
                .row(RowKey::parse(key).expect("a row key"))
                .and_then(|row| row.check)
                .map_or(f64::INFINITY, |stats| stats.rms_deg)
        };
        let (fourier, mlp) = (check_rms("min_max+fourier"), check_rms("min_max+mlp"));
        eprintln!("temperature-dependent error, check RMS: min/max + Fourier {fourier:.2}°, min/max + MLP {mlp:.2}°");
        assert!(mlp < 0.7 * fourier, "MLP {mlp}° against Fourier {fourier}°");
        let neural = analysis
            .report
            .neural
            .iter()
            .find(|report| report.base_key == "min_max")
            .expect("trained");
        assert_eq!(
            neural.inputs,
            vec![
                "heading",
                "|H|",
                "gyro heading (attitude filter)",
                "dip",
                "temperature"
            ]
        );
        assert_eq!(neural.correlation.len(), 25);
    }

    #[test]
    fn a_gap_in_the_reference_is_neither_bridged_nor_extrapolated() {
        let config = WalkConfig {
            gnss: Some(GnssSim::default()),
            ..WalkConfig::from_seed(6, 400.0)
        };
        let mut rows = simulate(&config);
        for row in &mut rows {
            row.ref_heading_deg = None;
            if (150.0..250.0).contains(&row.t_s) || row.t_s > 380.0 {
                row.gps_course_deg = None;
                row.gps_speed_mps = None;
            }
        }
        let text = canonical_csv::write(&rows);
        let report = import("walk.csv", text.as_bytes()).expect("imports");
        let analysis = crate::pipeline::headings(&report, &HeadingOptions::default())
            .map(|(_, headings)| headings)
            .expect("analyses");
        for (&t_s, reference) in analysis.t_s.iter().zip(&analysis.reference_deg) {
            if (151.5..248.5).contains(&t_s) || t_s > 381.5 {
                assert!(reference.is_none(), "a reference at {t_s} s");
            }
        }
        assert!(
            analysis
                .reference_deg
                .iter()
                .filter(|reference| reference.is_some())
                .count()
                > 5000
        );
    }

    #[test]
    fn every_base_gets_a_fourier_stack_and_a_row() {
        let text = canonical_csv::write(&simulate(&WalkConfig::from_seed(3, 180.0)));
        let report = import("walk.csv", text.as_bytes()).expect("imports");
        let analysis = crate::pipeline::headings(&report, &HeadingOptions::default())
            .map(|(_, headings)| headings)
            .expect("analyses");
        let keys: Vec<String> = analysis
            .report
            .rows
            .iter()
            .map(|row| row.key.text())
            .collect();
        assert!(
            keys.iter().any(|key| key == "raw") && keys.iter().any(|key| key == "fourier"),
            "{keys:?}"
        );
        assert!(analysis.report.online.is_some());
        assert!(analysis
            .headings_deg
            .iter()
            .all(|(_, headings)| headings.len() == analysis.t_s.len()));
    }
}
