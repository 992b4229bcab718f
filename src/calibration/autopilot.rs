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

use crate::calib::attitude_aided::{agreement, fit_aided, Agreement, AidedModel, AidedSample};
use crate::io::autopilot::ardupilot::{
    compass_param, param_file, parse_param_file, ArduPilotCompass, MOTOR_BY_CURRENT,
};
use crate::io::autopilot::px4::{params_file, Px4Compass};
use crate::io::autopilot::{param_in, Autopilot, AutopilotLog, CompassLog};
use crate::recording::{Attitude, Stream};

/// ArduPilot's compass unit, mG, in µT.
const UT_PER_MG: f64 = 0.1;
/// The longest time (s) between a compass sample and the attitude it is paired with.
const MAX_ATTITUDE_GAP_S: f64 = 0.1;
/// The largest formal 1σ (mG) of a written offset: beyond it the flight did not
/// determine the offsets (a tenth of the Earth's field at its weakest).
const MAX_OFFSET_SIGMA_MG: f64 = 25.0;
/// The fewest compass samples with an attitude a fit is tried on (10 s at 10 Hz).
const MIN_SAMPLES: usize = 100;
/// The longest time (s) between a compass sample and the current it is paired with.
const MAX_CURRENT_GAP_S: f64 = 0.5;
/// The battery current must span this much (A) for the motor term to be fitted: a
/// hover draws several amperes more than the ground.
const MIN_CURRENT_RANGE_A: f64 = 3.0;

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

/// One model's fit on the first half, scored on the held-back second half.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    pub model: String,
    pub check_heading_rms_deg: Option<f64>,
}

/// One compass's new calibration beside the one in force.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompassResult {
    pub instance: usize,
    pub source: String,
    pub n_samples: usize,
    /// The model chosen on the held-back half.
    pub model: String,
    /// Every model's heading RMS on the held-back half, fitted on the first.
    pub candidates: Vec<Candidate>,
    /// The calibration in force on the held-back half.
    pub check_in_force_deg: Option<f64>,
    /// On the whole log: the calibration in force, and the new one as its `.param`
    /// lines read back give it.
    pub in_force: Option<Agreed>,
    pub fitted: Agreed,
    /// The new parameters, with the formal 1σ of the offsets (mG) and of the motor
    /// compensation (mG/A).
    pub params: Vec<(String, f64)>,
    pub offsets_sigma: [f64; 3],
    pub soft_iron_sigma: Option<f64>,
    pub motor_sigma: Option<[f64; 3]>,
}

/// A compass whose calibration in force is kept: the log could not improve on it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KeptCompass {
    pub instance: usize,
    pub source: String,
    pub n_samples: usize,
    /// The calibration in force on the whole log.
    pub in_force: Agreed,
}

impl KeptCompass {
    /// "Compass 1 (MAG)": the compass as the page and the CLI name it.
    pub fn label(&self) -> String {
        format!("Compass {} ({})", self.instance + 1, self.source)
    }

    /// What its parameters in force give on the log.
    pub fn judged(&self) -> String {
        format!(
            "{:.1}° from the autopilot's heading; |B| varies {:.2} % (parameters in force, kept)",
            self.in_force.heading_rms_deg, self.in_force.spread_pct
        )
    }
}

/// The calibration of every compass of an autopilot log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AutopilotCalibration {
    pub autopilot: &'static str,
    pub compasses: Vec<CompassResult>,
    /// The compasses not fitted whose parameters in force could be judged on the log
    /// (why each was not fitted is in `notes`).
    pub kept: Vec<KeptCompass>,
    /// The `.param` file to load in Mission Planner or MAVProxy.
    pub param_file: String,
    pub notes: Vec<String>,
}

/// The index of the sample of `times` nearest to `t_s`, within `max_gap_s`.
fn nearest(times: &[f64], t_s: f64, max_gap_s: f64) -> Option<usize> {
    let after = times.partition_point(|&t| t < t_s);
    [after.checked_sub(1), Some(after)]
        .into_iter()
        .flatten()
        .filter(|&idx| idx < times.len())
        .min_by(|&a, &b| (times[a] - t_s).abs().total_cmp(&(times[b] - t_s).abs()))
        .filter(|&idx| (times[idx] - t_s).abs() <= max_gap_s)
}

/// Pairs each raw sample with the attitude nearest in time (within 0.1 s) and the
/// battery current (within 0.5 s, else 0).
fn aided_samples(
    raw_ut: &Stream<Vector3<f64>>,
    attitude: &Stream<Attitude>,
    current_a: &Stream<f64>,
) -> Vec<AidedSample> {
    let mut samples = Vec::with_capacity(raw_ut.len());
    for (&t_s, raw) in raw_ut.t_s.iter().zip(&raw_ut.values) {
        let Some(idx) = nearest(&attitude.t_s, t_s, MAX_ATTITUDE_GAP_S) else {
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
        let current_a = nearest(&current_a.t_s, t_s, MAX_CURRENT_GAP_S)
            .map_or(0.0, |idx| current_a.values[idx]);
        samples.push(AidedSample {
            t_s,
            raw: raw / UT_PER_MG,
            body_to_ned: Rotation3::from_euler_angles(roll_rad, pitch_rad, yaw_rad),
            current_a,
        });
    }
    samples
}

fn model_label(model: &AidedModel) -> String {
    let mut label = match model.held_soft_iron {
        Some(_) => "offsets".to_string(),
        None => "offsets, soft iron".to_string(),
    };
    if model.motor {
        label.push_str(", motor (current)");
    }
    label
}

/// The calibration in force judged on the whole log, for a compass not fitted.
fn kept(
    compass: &CompassLog,
    samples: &[AidedSample],
    in_force: Option<ArduPilotCompass>,
) -> Option<KeptCompass> {
    let in_force = in_force?;
    let agreed = agreement(samples, |raw, current| in_force.apply(raw, current))?;
    Some(KeptCompass {
        instance: compass.instance,
        source: compass.source.clone(),
        n_samples: samples.len(),
        in_force: agreed.into(),
    })
}

/// One compass fitted, or `Err` with the calibration in force judged on the log (where
/// it can be) when nothing new is written; why goes to `notes`.
fn compass_result(
    compass: &CompassLog,
    log: &AutopilotLog,
    attitude: &Stream<Attitude>,
    notes: &mut Vec<String>,
) -> Result<CompassResult, Option<KeptCompass>> {
    let Some(raw_in_body_ut) = compass.raw_in_body_ut.as_ref() else {
        return Err(None);
    };
    let samples = aided_samples(raw_in_body_ut, attitude, &log.current_a);
    if samples.len() < MIN_SAMPLES {
        notes.push(format!(
            "{}: only {} samples with an attitude, fewer than {MIN_SAMPLES}: not fitted",
            compass.source,
            samples.len()
        ));
        return Err(None);
    }
    let lookup = |name: &str| log.param(name).filter(|value| value.is_finite());
    let in_force = in_body_form(compass, &lookup);
    let held = in_force.map_or_else(nalgebra::Matrix3::identity, |c| c.soft_iron);
    // The current must vary for its term to be seen: hover against ground.
    let current_range = samples.iter().map(|s| s.current_a).fold(0.0, f64::max)
        - samples
            .iter()
            .map(|s| s.current_a)
            .fold(f64::INFINITY, f64::min);
    let motor_options: &[bool] = if current_range >= MIN_CURRENT_RANGE_A {
        &[false, true]
    } else {
        &[false]
    };
    let half = samples.len() / 2;
    let (train, check) = samples.split_at(half);
    let mut candidates = Vec::new();
    let mut best: Option<(AidedModel, f64)> = None;
    for held_soft_iron in [Some(held), None] {
        for &motor in motor_options {
            let model = AidedModel {
                held_soft_iron,
                motor,
            };
            let check_deg = fit_aided(train, model)
                .and_then(|fit| agreement(check, |raw, current| fit.apply(raw, current)))
                .map(|agreed| agreed.heading_rms_deg);
            if let Some(deg) = check_deg {
                if best.is_none_or(|(_, best_deg)| deg < best_deg) {
                    best = Some((model, deg));
                }
            }
            candidates.push(Candidate {
                model: model_label(&model),
                check_heading_rms_deg: check_deg,
            });
        }
    }
    let check_in_force_deg = in_force
        .and_then(|c| agreement(check, |raw, current| c.apply(raw, current)))
        .map(|agreed| agreed.heading_rms_deg);
    let fit = best.and_then(|(model, _)| fit_aided(&samples, model));
    let (Some((model, _)), Some(fit)) = (best, fit) else {
        notes.push(format!(
            "{}: the attitude-aided fit failed ({} samples paired with an attitude): the \
             flight did not turn the vehicle enough to tell the offsets from the Earth's \
             field; fly a few full turns, or calibrate on the ground",
            compass.source,
            samples.len()
        ));
        return Err(kept(compass, &samples, in_force));
    };
    // Written only where the data can say more than the parameters in force.
    let refusal = match (best, check_in_force_deg) {
        (Some((_, best_deg)), Some(in_force_deg)) if best_deg > in_force_deg => Some(format!(
            "no model fitted on the first half agrees better with the second than the \
             parameters in force ({best_deg:.1}° against {in_force_deg:.1}° heading RMS)"
        )),
        _ if fit.offsets_sigma.amax() > MAX_OFFSET_SIGMA_MG => Some(format!(
            "the offsets are not determined by this flight (1σ up to {:.0} mG)",
            fit.offsets_sigma.amax()
        )),
        _ => None,
    };
    if let Some(reason) = refusal {
        notes.push(format!(
            "{}: not written, the parameters in force are kept: {reason}. Record a flight \
             (or a walk with the vehicle in hand) that turns through full circles with some \
             tilt, for a minute or more",
            compass.source
        ));
        return Err(kept(compass, &samples, in_force));
    }
    let new = ArduPilotCompass {
        instance: compass.instance,
        offsets_mg: fit.offsets,
        soft_iron: fit.soft_iron,
        scale: 1.0,
        motor_mg_per_a: fit.motor_per_a,
    };
    let (params, text) = match compass.px4_slot {
        Some((slot, rotation)) => {
            let params =
                Px4Compass::from_body_form(slot, rotation, fit.soft_iron, fit.offsets).params();
            let text = params_file(&[], &params);
            (params, text)
        }
        None => {
            let mut params = new.params();
            // COMPASS_SCALE is folded into M: write 1 where the log had another.
            if in_force.is_some_and(|c| c.scale != 1.0) {
                params.push((compass_param("SCALE", compass.instance, ""), 1.0));
            }
            let text = param_file(&[], &params);
            (params, text)
        }
    };
    // What the written lines give, read back and applied as the autopilot applies them
    // (COMPASS_MOTCT as the whole file sets it).
    let mut written = parse_param_file(&text);
    written.push(("COMPASS_MOTCT".to_string(), MOTOR_BY_CURRENT));
    let written_lookup = |name: &str| param_in(&written, name).or_else(|| lookup(name));
    let read_back = in_body_form(compass, &written_lookup).ok_or(None)?;
    let fitted = agreement(&samples, |raw, current| read_back.apply(raw, current)).ok_or(None)?;
    Ok(CompassResult {
        instance: compass.instance,
        source: compass.source.clone(),
        n_samples: samples.len(),
        model: model_label(&model),
        candidates,
        check_in_force_deg,
        in_force: in_force
            .and_then(|c| agreement(&samples, |raw, current| c.apply(raw, current)))
            .map(Agreed::from),
        fitted: fitted.into(),
        params,
        offsets_sigma: fit.offsets_sigma.into(),
        soft_iron_sigma: fit.soft_iron_sigma,
        motor_sigma: model.motor.then(|| fit.motor_sigma.into()),
    })
}

/// A compass's calibration in `params`, in body axes and ArduPilot's form (PX4's turned
/// into it, [`Px4Compass::body_form`]); `None` without the offsets (ArduPilot).
fn in_body_form(
    compass: &CompassLog,
    params: &dyn Fn(&str) -> Option<f64>,
) -> Option<ArduPilotCompass> {
    match compass.px4_slot {
        Some((slot, rotation)) => {
            let (soft_iron, offsets_mg) =
                Px4Compass::from_params(params, slot, rotation).body_form();
            Some(ArduPilotCompass {
                instance: compass.instance,
                offsets_mg,
                soft_iron,
                scale: 1.0,
                motor_mg_per_a: Vector3::zeros(),
            })
        }
        None => ArduPilotCompass::from_params(params, compass.instance),
    }
}

/// The calibration in force of the compass whose raw field is a recording's
/// magnetometer, applied as the autopilot applies it (the motor compensation at the
/// battery current of each sample): the field the vehicle's own heading is made from.
pub struct InForce<'a> {
    autopilot: Autopilot,
    correction: ArduPilotCompass,
    current_a: &'a Stream<f64>,
}

impl<'a> InForce<'a> {
    /// The main compass's calibration in force, where `mag_in_body_ut` is that
    /// compass's raw field (not, say, several logs' fields merged) and the log has its
    /// parameters.
    pub fn of(log: &'a AutopilotLog, mag_in_body_ut: &Stream<Vector3<f64>>) -> Option<InForce<'a>> {
        let compass = log.compasses.get(log.main_compass?)?;
        // The same samples bit for bit (a NaN equals itself here).
        let raw = compass.raw_in_body_ut.as_ref()?;
        fn bits(stream: &Stream<Vector3<f64>>) -> impl Iterator<Item = u64> + '_ {
            let values = stream.values.iter().flat_map(|value| value.iter());
            stream.t_s.iter().chain(values).map(|value| value.to_bits())
        }
        if raw.len() != mag_in_body_ut.len() || !bits(raw).eq(bits(mag_in_body_ut)) {
            return None;
        }
        let lookup = |name: &str| log.param(name).filter(|value| value.is_finite());
        Some(InForce {
            autopilot: log.autopilot,
            correction: in_body_form(compass, &lookup)?,
            current_a: &log.current_a,
        })
    }

    /// "ArduPilot" or "PX4".
    pub fn autopilot(&self) -> &'static str {
        self.autopilot.name()
    }

    /// The corrected field (body axes, µT) of a raw sample at `t_s`.
    pub fn corrected_ut(&self, t_s: f64, raw_ut: Vector3<f64>) -> Vector3<f64> {
        let current_a = nearest(&self.current_a.t_s, t_s, MAX_CURRENT_GAP_S)
            .map_or(0.0, |idx| self.current_a.values[idx]);
        self.correction.apply(raw_ut / UT_PER_MG, current_a) * UT_PER_MG
    }
}

/// The calibration of an autopilot log's compasses, where it has their raw fields and
/// an attitude with yaw; `None` otherwise. ArduPilot's are written as a `.param` file,
/// PX4's as a QGroundControl `.params` file (`CAL_MAGn_*`, without power compensation).
pub fn autopilot_calibration(
    log: &AutopilotLog,
    attitude: &Stream<Attitude>,
) -> Option<AutopilotCalibration> {
    if attitude.is_empty() {
        return None;
    }
    let is_px4 = log.autopilot == Autopilot::Px4;
    let mut notes = Vec::new();
    // PX4 logs a compass under several topics (sensor_mag, vehicle_magnetometer): one
    // calibration slot is fitted once, on the topic with the most raw samples.
    let n_raw = |compass: &CompassLog| compass.raw_in_body_ut.as_ref().map_or(0, |raw| raw.len());
    let fitted: Vec<&CompassLog> = log
        .compasses
        .iter()
        .filter(|compass| match compass.px4_slot {
            Some((slot, _)) => !log.compasses.iter().any(|other| {
                other
                    .px4_slot
                    .is_some_and(|(other_slot, _)| other_slot == slot)
                    && (n_raw(other), std::ptr::eq(other, *compass)) > (n_raw(compass), true)
            }),
            None => true,
        })
        .collect();
    let mut compasses: Vec<CompassResult> = Vec::new();
    let mut kept: Vec<KeptCompass> = Vec::new();
    for compass in fitted {
        match compass_result(compass, log, attitude, &mut notes) {
            Ok(result) => compasses.push(result),
            Err(judged) => kept.extend(judged),
        }
    }
    if compasses.is_empty() {
        // Nothing written; the reasons, and the parameters in force, still reach the
        // user.
        return (!notes.is_empty()).then(|| AutopilotCalibration {
            autopilot: log.autopilot.name(),
            compasses,
            kept,
            param_file: String::new(),
            notes,
        });
    }
    let mut header = vec![
        format!(
            "compass calibration by compass-pdr {}, attitude-aided fit on the log's {}",
            env!("CARGO_PKG_VERSION"),
            if is_px4 { "vehicle_attitude" } else { "ATT" }
        ),
        if is_px4 {
            "corrected = R · S · (raw − CAL_MAGn_OFF), S from CAL_MAGn_SCALE and CAL_MAGn_ODIAG (gauss)"
        } else {
            "corrected = M · (raw + COMPASS_OFS), M from COMPASS_DIA and COMPASS_ODI (mG)"
        }
        .to_string(),
    ];
    let mut params = Vec::new();
    if !is_px4 {
        params.push(("COMPASS_MOTCT".to_string(), MOTOR_BY_CURRENT));
    }
    for compass in &compasses {
        header.push(format!(
            "{} ({}): heading {:.1}° RMS against the Earth's field seen through the \
             autopilot's attitude, |B| spread {:.2} %{}",
            compass.source,
            compass.model,
            compass.fitted.heading_rms_deg,
            compass.fitted.spread_pct,
            compass
                .in_force
                .map_or_else(String::new, |in_force| format!(
                    "; parameters in force: {:.1}°, {:.2} %",
                    in_force.heading_rms_deg, in_force.spread_pct
                ))
        ));
        params.extend(compass.params.iter().cloned());
    }
    if log.current_a.is_empty() && !is_px4 {
        notes.push(
            "no battery current in the log (CURR, BAT): motor interference not fitted, \
             COMPASS_MOT written as 0"
                .to_string(),
        );
    }
    if is_px4 {
        notes.push(
            "PX4: offsets and soft iron in the sensor's axes (CAL_MAGn_ROT or the board's \
             rotation as in force); power compensation (CAL_MAGn_XCOMP) not fitted, the \
             values in force kept"
                .to_string(),
        );
    }
    Some(AutopilotCalibration {
        autopilot: log.autopilot.name(),
        param_file: if is_px4 {
            params_file(&header, &params)
        } else {
            param_file(&header, &params)
        },
        compasses,
        kept,
        notes,
    })
}
