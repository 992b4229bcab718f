//! The calibration of an autopilot's compasses, written back as its parameters.
//!
//! For each compass whose raw field the log gives ([`crate::io::autopilot`]), the
//! attitude-aided fit ([`crate::calib::attitude_aided`]) is run with two models, offsets
//! only (the soft iron in force held) and offsets with soft iron, on the first half of
//! the log; the model whose heading agrees best with the Earth's field on the second
//! half is refitted on the whole log. It is compared with the calibration in force, as
//! ArduPilot applies each ([`ArduPilotCompass`]), on the whole log: heading agreement and
//! the spread of the corrected field's magnitude. The parameters are written as a
//! `.param` file, which is read back and applied to the raw field to check that it
//! does what its figures say.

use nalgebra::{Rotation3, Vector3};
use serde::Serialize;

use crate::calib::attitude_aided::{agreement, fit_aided, AidedFit, AidedModel, AidedSample, Agreement};
use crate::io::autopilot::ardupilot::{param_file, parse_param_file, ArduPilotCompass};
use crate::io::autopilot::{Autopilot, AutopilotLog, CompassLog};
use crate::recording::{Attitude, Stream};

/// ArduPilot's compass unit, mG, in µT.
const UT_PER_MG: f64 = 0.1;
/// The longest time (s) between a compass sample and the attitude it is paired with.
const MAX_ATTITUDE_GAP_S: f64 = 0.1;

/// How a calibration agrees with the Earth's field, for people and the page.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Agreed {
    pub heading_rms_deg: f64,
    pub spread_pct: f64,
    /// The corrected field's mean magnitude, in the compass's unit.
    pub mean_field: f64,
}

impl From<Agreement> for Agreed {
    fn from(agreement: Agreement) -> Agreed {
        Agreed {
            heading_rms_deg: agreement.heading_rms_deg,
            spread_pct: agreement.spread_pct,
            mean_field: agreement.mean_magnitude,
        }
    }
}

/// One compass's new calibration beside the one in force.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompassResult {
    pub instance: usize,
    pub source: String,
    pub n_samples: usize,
    /// The model chosen on the held-back half: "offsets" or "offsets and soft iron".
    pub model: &'static str,
    /// The held-back half's heading RMS of each model fitted on the first half, and of
    /// the calibration in force.
    pub check_offsets_deg: Option<f64>,
    pub check_soft_iron_deg: Option<f64>,
    pub check_in_force_deg: Option<f64>,
    /// On the whole log: the calibration in force, and the new one as its `.param`
    /// lines read back give it.
    pub in_force: Option<Agreed>,
    pub fitted: Agreed,
    /// The new parameters, and their formal 1σ for the offsets (mG).
    pub params: Vec<(String, f64)>,
    pub offsets_sigma: [f64; 3],
    pub soft_iron_sigma: Option<f64>,
}

/// The calibration of every compass of an autopilot log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AutopilotCalibration {
    pub autopilot: &'static str,
    pub compasses: Vec<CompassResult>,
    /// The `.param` file to load in Mission Planner or MAVProxy.
    pub param_file: String,
    pub notes: Vec<String>,
}

/// Pairs each raw sample with the attitude nearest in time (within 0.1 s).
fn aided_samples(raw_ut: &Stream<Vector3<f64>>, attitude: &Stream<Attitude>) -> Vec<AidedSample> {
    let mut samples = Vec::with_capacity(raw_ut.len());
    for (&t_s, raw) in raw_ut.t_s.iter().zip(&raw_ut.values) {
        let after = attitude.t_s.partition_point(|&a| a < t_s);
        let nearest = [after.checked_sub(1), Some(after)]
            .into_iter()
            .flatten()
            .filter(|&idx| idx < attitude.len())
            .min_by(|&a, &b| {
                (attitude.t_s[a] - t_s)
                    .abs()
                    .total_cmp(&(attitude.t_s[b] - t_s).abs())
            });
        let Some(idx) = nearest.filter(|&idx| (attitude.t_s[idx] - t_s).abs() <= MAX_ATTITUDE_GAP_S)
        else {
            continue;
        };
        let Attitude {
            roll_rad,
            pitch_rad,
            yaw_rad: Some(yaw_rad),
        } = attitude.values[idx]
        else {
            continue;
        };
        samples.push(AidedSample {
            t_s,
            raw: raw / UT_PER_MG,
            body_to_ned: Rotation3::from_euler_angles(roll_rad, pitch_rad, yaw_rad),
        });
    }
    samples
}

fn compass_result(
    compass: &CompassLog,
    log: &AutopilotLog,
    attitude: &Stream<Attitude>,
    notes: &mut Vec<String>,
) -> Option<CompassResult> {
    let samples = aided_samples(compass.raw_in_body_ut.as_ref()?, attitude);
    let lookup = |name: &str| log.param(name).filter(|value| value.is_finite());
    let in_force = ArduPilotCompass::from_params(&lookup, compass.instance);
    let held_soft_iron = in_force.map_or_else(nalgebra::Matrix3::identity, |c| c.soft_iron);
    let half = samples.len() / 2;
    let (train, check) = samples.split_at(half);
    let check_of = |fit: Option<AidedFit>| {
        fit.and_then(|fit| agreement(check, |raw| fit.apply(raw)))
            .map(|agreed| agreed.heading_rms_deg)
    };
    let offsets_model = AidedModel::Offsets {
        soft_iron: held_soft_iron,
    };
    let check_offsets_deg = check_of(fit_aided(train, offsets_model));
    let check_soft_iron_deg = check_of(fit_aided(train, AidedModel::OffsetsAndSoftIron));
    let check_in_force_deg = in_force
        .and_then(|c| agreement(check, |raw| c.apply(raw)))
        .map(|agreed| agreed.heading_rms_deg);
    let soft_iron_wins = match (check_soft_iron_deg, check_offsets_deg) {
        (Some(soft), Some(offsets)) => soft < offsets,
        (Some(_), None) => true,
        _ => false,
    };
    let (model, label) = if soft_iron_wins {
        (AidedModel::OffsetsAndSoftIron, "offsets and soft iron")
    } else {
        (offsets_model, "offsets")
    };
    let Some(fit) = fit_aided(&samples, model) else {
        notes.push(format!(
            "{}: the attitude-aided fit failed ({} samples paired with an attitude): the \
             flight did not turn the vehicle enough to tell the offsets from the Earth's \
             field; fly a few full turns, or calibrate on the ground",
            compass.source,
            samples.len()
        ));
        return None;
    };
    let new = ArduPilotCompass {
        instance: compass.instance,
        offsets_mg: fit.offsets,
        soft_iron: fit.soft_iron,
        scale: 1.0,
    };
    let mut params = new.params();
    // COMPASS_SCALE is folded into M: write 1 where the log had another.
    if in_force.is_some_and(|c| c.scale != 1.0) {
        params.push((
            crate::io::autopilot::ardupilot::compass_param("SCALE", compass.instance, ""),
            1.0,
        ));
    }
    // What the written lines give, read back and applied as ArduPilot applies them.
    let written = parse_param_file(&param_file(&[], &params));
    let written_lookup = |name: &str| {
        written
            .iter()
            .find(|(known, _)| known == name)
            .map(|&(_, value)| value)
            .or_else(|| lookup(name))
    };
    let read_back = ArduPilotCompass::from_params(&written_lookup, compass.instance)?;
    let fitted = agreement(&samples, |raw| read_back.apply(raw))?;
    Some(CompassResult {
        instance: compass.instance,
        source: compass.source.clone(),
        n_samples: samples.len(),
        model: label,
        check_offsets_deg,
        check_soft_iron_deg,
        check_in_force_deg,
        in_force: in_force
            .and_then(|c| agreement(&samples, |raw| c.apply(raw)))
            .map(Agreed::from),
        fitted: fitted.into(),
        params,
        offsets_sigma: fit.offsets_sigma.into(),
        soft_iron_sigma: fit.soft_iron_sigma,
    })
}

/// The calibration of an ArduPilot log's compasses, where it has their raw fields and
/// an attitude with yaw; `None` otherwise (PX4 parameters are not written yet).
pub fn autopilot_calibration(
    log: &AutopilotLog,
    attitude: &Stream<Attitude>,
) -> Option<AutopilotCalibration> {
    if log.autopilot != Autopilot::ArduPilot || attitude.is_empty() {
        return None;
    }
    let mut notes = Vec::new();
    let compasses: Vec<CompassResult> = log
        .compasses
        .iter()
        .filter_map(|compass| compass_result(compass, log, attitude, &mut notes))
        .collect();
    if compasses.is_empty() {
        return None;
    }
    let mut header = vec![
        format!(
            "compass calibration by compass-pdr {}, attitude-aided fit on the log's ATT",
            env!("CARGO_PKG_VERSION")
        ),
        "corrected = M · (raw + COMPASS_OFS), M from COMPASS_DIA and COMPASS_ODI (mG)".to_string(),
    ];
    let mut params = Vec::new();
    for compass in &compasses {
        header.push(format!(
            "{} ({}): heading {:.1}° RMS against the Earth's field seen through ATT, |B| \
             spread {:.2} %{}",
            compass.source,
            compass.model,
            compass.fitted.heading_rms_deg,
            compass.fitted.spread_pct,
            compass.in_force.map_or_else(String::new, |in_force| format!(
                "; parameters in force: {:.1}°, {:.2} %",
                in_force.heading_rms_deg, in_force.spread_pct
            ))
        ));
        params.extend(compass.params.iter().cloned());
    }
    notes.push(
        "COMPASS_MOT (motor interference) not fitted: the parameters in force are kept".to_string(),
    );
    Some(AutopilotCalibration {
        autopilot: log.autopilot.name(),
        param_file: param_file(&header, &params),
        compasses,
        notes,
    })
}
