//! The one choice of "best": which heading method a log's analysis recommends, and which
//! field calibration goes to the device. Made here, by one rule, and used by every
//! consumer (the CLI, the page, the report, dead reckoning, the exports).
//!
//! ## The rule
//!
//! - **With a reference heading**, the method with the lowest RMS heading error on the
//!   check part (the train part when there is no check part), and **never one worse than
//!   the uncalibrated heading**: when nothing beats it, the uncalibrated heading is the
//!   choice, and the report says so. Methods within [`PARSIMONY_SHARE`] of the lowest
//!   count as tied, and of tied methods the simplest wins ([`complexity`]): a check part
//!   cannot tell them apart, and the one that learnt least from the reference carries
//!   best to headings the reference never covered (measured on walks with four
//!   directions of travel, where a reference least squares stacked under a Fourier model
//!   tied the 3D fit on check and then erred by 9° RMS across a GNSS outage).
//! - **Without a reference**, nothing can be scored, so the choice rests on what each
//!   fit says of itself: the 3D fit ([`crate::fit::ellipsoid`]) when its own heading
//!   uncertainty is within [`MAX_UNREFERENCED_HEADING_STD_DEG`], else the tilt-aware
//!   ellipse, else min/max, else the uncalibrated heading.
//!
//! The device calibration ([`device_calibration`]) is the chosen method's own 3D
//! correction where it has one ([`field_calibration_of`]: the ellipse's full model or
//! the ellipsoid's), else the one the same rule chooses among the methods that have one,
//! so that what is exported is never a calibration the analysis found worse than
//! another. [`device_write_back`] is the rule every device export (JSON, C snippet,
//! MotionCal packet) follows: that correction only where it beats the readings as logged
//! (the check part's heading error with a reference, the |B| spread without) and lies
//! inside [`crate::fit::quality`]'s bounds, and never for an autopilot log, whose
//! write-back is its parameter file.

use serde::Serialize;

use nalgebra::Vector3;

use super::row_key::RowKey;
use super::{CalibrationAnalysis, CalibrationReport, Method, MethodParameters, MethodReport};
use crate::fit::model::FieldCalibration;
use crate::reference::ReferenceSource;

/// Without a reference, the 3D fit is trusted when its own heading uncertainty (from
/// its parameters' covariance, at the log's attitudes) is within this many degrees.
pub const MAX_UNREFERENCED_HEADING_STD_DEG: f64 = 5.0;

/// Methods whose RMS is within this share of the lowest are tied (see the module
/// header): about the sampling noise of an RMS over the few hundred independent seconds
/// a check part holds.
pub const PARSIMONY_SHARE: f64 = 0.05;

/// What a choice was made on.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Basis {
    /// The lowest RMS error on the check part (or, `on_train`, on the train part).
    ReferenceRms {
        rms_deg: f64,
        raw_rms_deg: Option<f64>,
        on_train: bool,
    },
    /// No reference heading: the fits' own figures.
    WithoutReference { reason: String },
    /// A GPS course that even its closest model is more than [`MAX_CHOOSING_RMS_DEG`]
    /// from (RMS): it cannot judge the models, so the fits' own figures chose. `closest`
    /// is that model's label.
    ReferenceTooFar { rms_deg: f64, closest: String },
}

/// A GPS course from which even the best model is more than this far (RMS on the check
/// part, degrees) cannot choose among them: indoors a phone's course is that far from
/// every heading (40-139° on the IPIN walks that have one), where a compass that
/// calibrations can mend comes within 5-28° of a usable course (the shared phone and
/// car logs). A reference that is a truth by construction (a heading column, the legs
/// between surveyed positions, the autopilot's estimate) still judges: a compass can be
/// that far wrong (msft F4's raw field is 300-400 µT; its best model is 34° from the
/// legs and its track is best with that model).
pub const MAX_CHOOSING_RMS_DEG: f64 = 30.0;

/// The choice: by the reference where it scored the methods and can judge them, else
/// by the fits' own figures ([`choose_without_reference`]), saying when a GPS course was
/// too far to judge.
pub fn settle(by_reference: Option<Choice>, report: &CalibrationReport) -> Choice {
    let course = matches!(report.reference, Some(ReferenceSource::GpsCourse { .. }));
    match by_reference {
        Some(Choice {
            basis: Basis::ReferenceRms { rms_deg, .. },
            label,
            ..
        }) if course && rms_deg > MAX_CHOOSING_RMS_DEG => {
            let chosen = choose_without_reference(report);
            Choice {
                basis: Basis::ReferenceTooFar {
                    rms_deg,
                    closest: label,
                },
                ..chosen
            }
        }
        Some(choice) => choice,
        None => choose_without_reference(report),
    }
}

/// The method chosen, by its row's key (written `raw`, `ellipsoid`, `ellipsoid+fourier`,
/// ...): the analysis's one choice of "best", stored once on each report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Choice {
    pub key: RowKey,
    pub label: String,
    pub basis: Basis,
}

impl Choice {
    /// One sentence: what was chosen and why.
    pub fn sentence(&self) -> String {
        match &self.basis {
            Basis::ReferenceRms {
                rms_deg,
                raw_rms_deg,
                on_train,
            } => {
                let part = if *on_train { "train" } else { "check" };
                match (self.key == RowKey::RAW, raw_rms_deg) {
                    (true, _) => format!(
                        "{}: {rms_deg:.1}° RMS on the {part} part; no calibration beat it",
                        self.label
                    ),
                    (false, Some(raw_deg)) => format!(
                        "{}: {rms_deg:.1}° RMS on the {part} part (uncalibrated {raw_deg:.1}°)",
                        self.label
                    ),
                    (false, None) => {
                        format!("{}: {rms_deg:.1}° RMS on the {part} part", self.label)
                    }
                }
            }
            Basis::WithoutReference { reason } => format!("{}: {reason}", self.label),
            Basis::ReferenceTooFar { rms_deg, closest } => format!(
                "{}: the GPS course is {rms_deg:.0}° RMS from even the closest model ({closest}), too far to judge them (a phone's course indoors is that far), so the fits' own figures chose",
                self.label
            ),
        }
    }
}

/// One scored method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scored<'a> {
    pub key: RowKey,
    pub label: &'a str,
    pub train_rms_deg: Option<f64>,
    pub check_rms_deg: Option<f64>,
}

/// The method with the lowest check RMS (train RMS when no method has a check part),
/// never worse than the uncalibrated heading's row ([`RowKey::RAW`]); `None` when nothing was scored.
pub fn choose_by_reference(scored: &[Scored]) -> Option<Choice> {
    let on_train = scored.iter().all(|row| row.check_rms_deg.is_none());
    let metric = |row: &Scored| {
        if on_train {
            row.train_rms_deg
        } else {
            row.check_rms_deg
        }
    };
    let raw = scored.iter().find(|row| row.key == RowKey::RAW);
    let raw_rms_deg = raw.and_then(metric);
    let lowest = scored.iter().filter_map(metric).min_by(f64::total_cmp)?;
    let best = scored
        .iter()
        .filter_map(|row| Some((row, metric(row)?)))
        .filter(|(_, rms)| *rms <= lowest * (1.0 + PARSIMONY_SHARE))
        .min_by(|a, b| {
            a.0.key
                .complexity()
                .cmp(&b.0.key.complexity())
                .then_with(|| a.1.total_cmp(&b.1))
        })?;
    let (row, rms_deg) = match (raw, raw_rms_deg) {
        // Never worse than the uncalibrated heading: ties go to it too.
        (Some(raw), Some(raw_deg)) if best.1 >= raw_deg => (raw, raw_deg),
        _ => best,
    };
    Some(Choice {
        key: row.key,
        label: row.label.to_string(),
        basis: Basis::ReferenceRms {
            rms_deg,
            raw_rms_deg: raw_rms_deg.filter(|_| row.key != RowKey::RAW),
            on_train,
        },
    })
}

/// The field-domain method to use without a reference heading (see the module header).
pub fn choose_without_reference(report: &CalibrationReport) -> Choice {
    let fitted = |method: Method| {
        report
            .method(method)
            .filter(|method| method.error.is_none())
    };
    if let Some(ellipsoid) = fitted(Method::Ellipsoid) {
        if let Some(MethodParameters::Ellipsoid(fit)) = &ellipsoid.parameters {
            if fit.heading_std_deg <= MAX_UNREFERENCED_HEADING_STD_DEG {
                return Choice {
                    key: RowKey::method(Method::Ellipsoid),
                    label: Method::Ellipsoid.label().to_string(),
                    basis: Basis::WithoutReference {
                        reason: format!(
                            "no reference heading; its own uncertainty is ±{:.1}° of heading",
                            fit.heading_std_deg
                        ),
                    },
                };
            }
        }
    }
    let uncertain_3d = fitted(Method::Ellipsoid).and_then(|report| match &report.parameters {
        Some(MethodParameters::Ellipsoid(fit)) => Some(fit.heading_std_deg),
        _ => None,
    });
    let because = uncertain_3d.map_or(String::new(), |std_deg| {
        format!(" (the 3D fit's own heading uncertainty, ±{std_deg:.0}°, is too large)")
    });
    for method in [Method::Ellipse, Method::MinMax] {
        if fitted(method).is_some() {
            return Choice {
                key: RowKey::method(method),
                label: method.label().to_string(),
                basis: Basis::WithoutReference {
                    reason: format!("no reference heading{because}"),
                },
            };
        }
    }
    Choice {
        key: RowKey::RAW,
        label: "uncalibrated".to_string(),
        basis: Basis::WithoutReference {
            reason: format!("no reference heading and no calibration fitted{because}"),
        },
    }
}

/// The 3D correction a method's parameters hold, if any: the ellipsoid's, or the
/// ellipse's full model (`corrected = soft_iron · (raw − hard_iron)` before levelling).
pub fn field_calibration_of(report: &MethodReport) -> Option<FieldCalibration> {
    match &report.parameters {
        Some(MethodParameters::Ellipsoid(fit)) => Some(fit.calibration),
        Some(MethodParameters::Ellipse(fit)) => Some(FieldCalibration {
            hard_iron_ut: fit.hard_iron_ut,
            soft_iron: fit.soft_iron,
            field_ut: fit.horizontal_field_ut.hypot(fit.vertical_field_ut),
        }),
        _ => None,
    }
}

/// The calibration for the device: the best method's own when it has a 3D correction
/// (the ellipse's or the ellipsoid's, also under a deviation model; the ellipsoid's
/// rather than the ellipse's where the 3D fit found the tilt mostly not trusted
/// (`InertialFit::tilt_untrusted`): the check scores headings levelled with that
/// tilt, which the ellipse's correction, fitted on it, wins without being right; issue
/// 43's swinging phone, levelled with the true attitude, `tests/independent.rs`); else,
/// among the
/// methods with a 3D correction, the one the rule chooses (by check RMS with a
/// reference, by the fits' own figures without).
pub fn device_calibration(report: &CalibrationReport) -> Option<(Method, FieldCalibration)> {
    let three_d: Vec<&MethodReport> = report
        .methods
        .iter()
        .filter(|method| field_calibration_of(method).is_some())
        .collect();
    if let Some(best) = three_d
        .iter()
        .find(|method| Some(method.method) == report.best())
    {
        let fitted_in_3d = three_d
            .iter()
            .find(|method| {
                matches!(&method.parameters, Some(MethodParameters::Ellipsoid(fit)) if fit.tilt_untrusted)
            })
            .filter(|_| best.method == Method::Ellipse);
        let chosen = fitted_in_3d.unwrap_or(best);
        return Some((chosen.method, field_calibration_of(chosen)?));
    }
    let scored: Vec<Scored> = three_d
        .iter()
        .map(|method| Scored {
            key: RowKey::method(method.method),
            label: method.label,
            train_rms_deg: method.heading_error_train.map(|stats| stats.rms_deg),
            check_rms_deg: method.heading_error_check.map(|stats| stats.rms_deg),
        })
        .collect();
    let key = settle(choose_by_reference(&scored), report).key;
    let chosen = three_d
        .iter()
        .find(|method| RowKey::method(method.method) == key)
        // Without a reference and with no trusted 3D fit, min/max (2D) may be the
        // choice: the device still gets the best 3D correction there is.
        .or_else(|| {
            three_d
                .iter()
                .find(|method| method.method == Method::Ellipsoid)
        })
        .or_else(|| three_d.first())?;
    Some((chosen.method, field_calibration_of(chosen)?))
}

/// Why no device calibration is written back ([`device_write_back`]); each message says
/// what the user reads.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WriteBackRefused {
    #[error(
        "an autopilot log's calibration is its {autopilot} parameter file (each compass written only \
         where it beats the parameters in force); no sensor calibration is exported"
    )]
    AutopilotLog { autopilot: &'static str },
    #[error("the ellipse and ellipsoid methods both failed (see the table)")]
    NoThreeDFit,
    #[error(
        "on the check part the {label} gives {rms_deg:.1}° RMS against {raw_rms_deg:.1}° uncalibrated: \
         it is not better than the readings as they are, so nothing is written to the \
         device"
    )]
    NoBetterOnCheck {
        label: &'static str,
        rms_deg: f64,
        raw_rms_deg: f64,
    },
    #[error(
        "the {label} leaves |B| varying by {spread_pct:.1} % against {raw_spread_pct:.1} % for the \
         readings as they are: nothing better to write to the device"
    )]
    NoSteadierField {
        label: &'static str,
        spread_pct: f64,
        raw_spread_pct: f64,
    },
    #[error("the {label} is outside what a device accepts: {}", reasons.join("; "))]
    OutOfBounds {
        label: &'static str,
        reasons: Vec<String>,
    },
}

/// The device calibration to write back (JSON, C snippet, MotionCal packet), in body
/// axes, or why there is none. The rule every write-back follows: the calibration must be better than
/// the one in force (for a sensor, its readings as logged) on the part of the log held
/// back from the fits, and inside what a device accepts ([`crate::fit::quality`]).
/// With a reference heading "better" is the heading error on the check part; without
/// one, the |B| spread over the log (there is no held-back part then). An autopilot log's write-back is its parameter
/// file, judged compass by compass ([`crate::analysis::calibration::autopilot`]): it gets none here.
pub fn device_write_back(
    analysis: &CalibrationAnalysis,
) -> Result<(Method, FieldCalibration), WriteBackRefused> {
    let report = &analysis.report;
    if let Some(autopilot) = &report.autopilot {
        return Err(WriteBackRefused::AutopilotLog {
            autopilot: autopilot.autopilot,
        });
    }
    let (method, body_ut) = analysis
        .device_calibration()
        .ok_or(WriteBackRefused::NoThreeDFit)?;
    let label = method.label();
    let checked = report
        .method(method)
        .and_then(|row| row.heading_error_check)
        .zip(report.raw_heading_error_check);
    match checked {
        Some((new, raw)) if new.rms_deg >= raw.rms_deg => {
            return Err(WriteBackRefused::NoBetterOnCheck {
                label,
                rms_deg: new.rms_deg,
                raw_rms_deg: raw.rms_deg,
            });
        }
        Some(_) => {}
        None => {
            let spread = |correct: &dyn Fn(Vector3<f64>) -> Vector3<f64>| {
                crate::base::stats::spread_pct(analysis.mag_ut.iter().map(|&m| correct(m).norm()))
            };
            if let (Some(new), Some(raw)) = (spread(&|m| body_ut.apply(m)), spread(&|m| m)) {
                if new >= raw {
                    return Err(WriteBackRefused::NoSteadierField {
                        label,
                        spread_pct: new,
                        raw_spread_pct: raw,
                    });
                }
            }
        }
    }
    let frame = report
        .mag_frame
        .unwrap_or_else(crate::io::SensorFrame::body_ut);
    // The field strength is checked where it is in µT (counts of unknown sensitivity
    // are fitted as they are).
    let field_in_ut = frame.unit.ut_per_unit.is_some() || frame.is_body_ut();
    let reasons = if field_in_ut {
        crate::fit::quality::acceptance_reasons(
            &body_ut,
            report.expected_field.as_ref().map(|field| field.total_ut),
        )
    } else {
        crate::fit::quality::shape_reasons(&body_ut)
    };
    if !reasons.is_empty() {
        return Err(WriteBackRefused::OutOfBounds { label, reasons });
    }
    Ok((method, body_ut))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scored(key: &'static str, train: Option<f64>, check: Option<f64>) -> Scored<'static> {
        Scored {
            key: RowKey::parse(key).expect("a row key"),
            label: key,
            train_rms_deg: train,
            check_rms_deg: check,
        }
    }

    #[test]
    fn what_learns_from_the_reference_is_told_by_its_key() {
        for key in [
            "ref_ls",
            "ellipsoid+fourier",
            "fourier",
            "ref_ls+mlp",
            "mlp",
        ] {
            assert!(RowKey::parse(key).unwrap().learns_from_reference(), "{key}");
        }
        for key in ["raw", "min_max", "ellipse", "ellipsoid", "ahrs", "in_force"] {
            assert!(
                !RowKey::parse(key).unwrap().learns_from_reference(),
                "{key}"
            );
        }
    }

    #[test]
    fn the_lowest_check_rms_wins() {
        let choice = choose_by_reference(&[
            scored("raw", Some(30.0), Some(40.0)),
            scored("min_max", Some(3.0), Some(5.0)),
            scored("ellipsoid", Some(4.0), Some(2.0)),
        ])
        .expect("a choice");
        assert_eq!(choice.key.text(), "ellipsoid");
        assert_eq!(
            choice.basis,
            Basis::ReferenceRms {
                rms_deg: 2.0,
                raw_rms_deg: Some(40.0),
                on_train: false
            }
        );
    }

    #[test]
    fn of_methods_tied_on_check_the_simplest_wins() {
        let choice = choose_by_reference(&[
            scored("raw", Some(30.0), Some(60.0)),
            scored("ellipsoid", Some(4.0), Some(4.67)),
            scored("ellipsoid+fourier", Some(3.0), Some(4.49)),
            scored("ref_ls+fourier", Some(2.5), Some(4.48)),
            scored("min_max", Some(7.0), Some(7.5)),
        ])
        .expect("a choice");
        assert_eq!(choice.key.text(), "ellipsoid");
        assert_eq!(RowKey::parse("raw").unwrap().complexity(), 0);
        assert!(
            RowKey::parse("ellipsoid").unwrap().complexity()
                < RowKey::parse("ellipsoid+fourier").unwrap().complexity()
        );
        assert!(
            RowKey::parse("ellipsoid+fourier").unwrap().complexity()
                < RowKey::parse("ref_ls+fourier").unwrap().complexity()
        );
        assert!(
            RowKey::parse("min_max+fourier").unwrap().complexity()
                < RowKey::parse("min_max+mlp").unwrap().complexity()
        );
    }

    #[test]
    fn nothing_worse_than_uncalibrated_is_chosen() {
        let choice = choose_by_reference(&[
            scored("raw", Some(20.0), Some(24.7)),
            scored("min_max", Some(10.0), Some(38.0)),
            scored("ellipse", None, None),
        ])
        .expect("a choice");
        assert_eq!(choice.key.text(), "raw");
        assert!(
            choice.sentence().contains("no calibration beat it"),
            "{}",
            choice.sentence()
        );
    }

    #[test]
    fn without_a_check_part_the_train_part_decides() {
        let choice = choose_by_reference(&[
            scored("raw", Some(20.0), None),
            scored("min_max", Some(3.0), None),
        ])
        .expect("a choice");
        assert_eq!(choice.key.text(), "min_max");
        assert!(matches!(
            choice.basis,
            Basis::ReferenceRms { on_train: true, .. }
        ));
        assert_eq!(choose_by_reference(&[scored("raw", None, None)]), None);
    }
}
