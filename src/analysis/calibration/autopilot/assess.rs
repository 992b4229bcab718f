//! One compass assessed: the models the flight supports fitted on its first half and
//! scored on the held-back second half, the best refitted on the whole log, written as
//! the autopilot's parameters and read back, and the rule of the module header applied.

use nalgebra::{Matrix3, Vector3};

use super::acceptance::{self, FieldSeen, Limits, ModelDifference};
use super::samples::{aided_samples, identity, in_body_form};
use super::score::{self, EarthField, Score};
use super::{Candidate, CompassResult, Figures, Truth};
use crate::fit::autopilot_aided::{fit_aided, AidedFit, AidedModel, AidedSample, Step};
use crate::fit::coverage::sphere_coverage;
use crate::io::autopilot::ardupilot::{
    compass_param, param_file, parse_param_file, ArduPilotCompass, MOTOR_BY_CURRENT,
};
use crate::io::autopilot::px4::Px4Compass;
use crate::io::autopilot::{param_in, Autopilot, AutopilotLog, CompassLog};
use crate::io::recording::{Attitude, Stream};

/// The fewest compass samples with an attitude a fit is tried on (10 s at 10 Hz).
const MIN_SAMPLES: usize = 100;
/// The shortest log (s) a calibration is judged on: a held-back half of 10 s, a hundred
/// samples at ArduPilot's 10 Hz (PX4's `sample_log_small.ulg`, 6.5 s on one heading, is
/// not enough to judge its compass on).
const MIN_DURATION_S: f64 = 20.0;
/// The battery current must span this much (A) for the motor term to be fitted: a
/// hover draws several amperes more than the ground.
const MIN_CURRENT_RANGE_A: f64 = 3.0;
/// How far the Earth's field must turn in the body (the standard deviation of its
/// direction, along the direction it turns most and along the next) for a step to be
/// tried. One heading with a few degrees of tilt turns it by 2-4°: the offsets only. A
/// scale needs the field's size seen along a changing direction; a symmetric iron its
/// six entries told apart, which needs the direction to turn two ways, as a full turn
/// does (17° each way at an inclination of 66°, 40° at the equator).
const MIN_SPREAD_SCALE_DEG: f64 = 8.0;
const MIN_SPREAD_IRON_DEG: f64 = 8.0;
/// Without the model's field, the offsets are told from the field only by turning: as
/// for the iron.
const MIN_SPREAD_FITTED_FIELD_DEG: f64 = 8.0;
/// The largest formal 1σ (mG) of an offset, and of the iron's entries or the scale, a
/// written model may have: beyond them the flight did not determine them.
const MAX_OFFSET_SIGMA_MG: f64 = 25.0;
const MAX_IRON_SIGMA: f64 = 0.02;
/// A richer model is chosen only where its held-back vector error is lower than the
/// simpler one's by more than this share.
const PARSIMONY_SHARE: f64 = 0.03;
/// New parameters must lower the held-back vector error of the parameters in force by
/// at least this share: less is within what a half of a flight can tell.
const MIN_IMPROVEMENT_SHARE: f64 = 0.02;
/// The reference's own error (RMS, a share of the Earth's field's strength): the World
/// Magnetic Model against the local field (about 1° and 1-2 % away from iron) and the
/// autopilot's attitude against the truth (1-2° of yaw, under 1° of tilt). A new
/// calibration is written only where its gain is larger than that error could make it
/// look ([`score::gain_is_real`]).
const REFERENCE_ERROR_SHARE: f64 = 0.05;
/// The same without a position, where each calibration is judged against its own mean
/// field in the Earth's frame: a steady error of the reference is then fitted away with
/// it, and only the attitude's wandering (about 1°) is left.
const FITTED_REFERENCE_ERROR_SHARE: f64 = 0.02;

/// A correction as the autopilot's acceptance checks it: the scale folded into the iron,
/// as it is written.
fn candidate_of(
    offsets_mg: Vector3<f64>,
    soft_iron: Matrix3<f64>,
    motor_mg_per_a: Vector3<f64>,
) -> acceptance::Candidate {
    acceptance::Candidate {
        offsets_mg,
        soft_iron,
        scale: 1.0,
        motor_mg_per_a,
    }
}

/// What one compass's assessment works on.
struct Assessment<'a> {
    log: &'a AutopilotLog,
    truth: &'a Truth,
    limits: Limits,
    samples: Vec<AidedSample>,
    in_force: ArduPilotCompass,
}

impl Assessment<'_> {
    fn halves(&self) -> (&[AidedSample], &[AidedSample]) {
        self.samples.split_at(self.samples.len() / 2)
    }

    /// The Earth's field a correction is judged against on `samples`, fitted on `fit_on`
    /// where the model's is unknown.
    fn earth_for(
        &self,
        fit_on: &[AidedSample],
        correct: &dyn Fn(Vector3<f64>, f64) -> Vector3<f64>,
    ) -> Option<Vector3<f64>> {
        self.truth
            .earth
            .model_ned_mg()
            .or_else(|| score::field_seen_ned(fit_on, correct))
    }

    /// The score of a correction on `samples`, its field fitted on `fit_on`.
    fn score(
        &self,
        samples: &[AidedSample],
        fit_on: &[AidedSample],
        correct: &dyn Fn(Vector3<f64>, f64) -> Vector3<f64>,
    ) -> Option<Score> {
        let earth = self.earth_for(fit_on, correct)?;
        score::score(samples, &earth, self.truth.declination_rad, correct)
    }

    /// How the corrected field looks over the whole log, for the pre-arm checks.
    fn field_seen(&self, correct: &dyn Fn(Vector3<f64>, f64) -> Vector3<f64>) -> FieldSeen {
        let mut strengths: Vec<f64> = self
            .samples
            .iter()
            .map(|s| correct(s.raw, s.current_a).norm())
            .collect();
        let median_strength_mg = crate::base::stats::median(&mut strengths).unwrap_or(f64::NAN);
        let model = self.truth.earth.model_ned_mg().and_then(|earth| {
            let (horizontal_mg, vertical_mg) =
                score::median_ned_difference_mg(&self.samples, &earth, correct)?;
            Some(ModelDifference {
                horizontal_mg,
                vertical_mg,
                model_strength_mg: earth.norm(),
            })
        });
        FieldSeen {
            median_strength_mg,
            model,
        }
    }

    /// The Earth's field's directions in the body over the log: how many of the
    /// sphere's 100 regions they cross, and how far they turn (degrees, along the
    /// direction they turn most and along the next).
    fn coverage(&self) -> (usize, [f64; 2]) {
        let in_force = |raw, current| self.in_force.apply(raw, current);
        let Some(earth) = self.earth_for(&self.samples, &in_force) else {
            return (0, [0.0; 2]);
        };
        let directions: Vec<Vector3<f64>> = self
            .samples
            .iter()
            .filter_map(|s| (s.body_to_ned.inverse() * earth).try_normalize(1e-9))
            .collect();
        let n_regions = sphere_coverage(directions.iter().copied()).n_covered;
        if directions.is_empty() {
            return (n_regions, [0.0; 2]);
        }
        let n = directions.len() as f64;
        let mean = directions.iter().sum::<Vector3<f64>>() / n;
        let scatter = directions
            .iter()
            .map(|d| (d - mean) * (d - mean).transpose())
            .sum::<Matrix3<f64>>()
            / n;
        let variances = scatter.symmetric_eigenvalues();
        // The largest and the middle one (the three add up to the trace).
        let (largest, smallest) = (variances.max(), variances.min());
        let middle = variances.sum() - largest - smallest;
        // Unit vectors: a standard deviation of x along a direction is x radians.
        let turned = |variance: f64| variance.max(0.0).sqrt().to_degrees();
        (n_regions, [turned(largest), turned(middle)])
    }

    /// The models the flight supports, from the least to the most.
    fn models(&self, [most_deg, next_deg]: [f64; 2]) -> Vec<AidedModel> {
        let has_model_field = self.truth.earth.model_ned_mg().is_some();
        let steps: Vec<Step> = Step::ALL
            .into_iter()
            .filter(|step| match step {
                Step::Offsets if has_model_field => true,
                Step::Offsets => next_deg >= MIN_SPREAD_FITTED_FIELD_DEG,
                Step::Scale => has_model_field && most_deg >= MIN_SPREAD_SCALE_DEG,
                Step::Iron => next_deg >= MIN_SPREAD_IRON_DEG,
            })
            .collect();
        // The current must vary for its term to be seen (hover against ground), the
        // vehicle turn (on one heading a slow drift of the reference looks like it), and
        // only ArduPilot's COMPASS_MOT by current (COMPASS_MOTCT 2, or none in force)
        // is written.
        let currents = self.samples.iter().map(|s| s.current_a);
        let range = currents.clone().fold(f64::NEG_INFINITY, f64::max)
            - currents.fold(f64::INFINITY, f64::min);
        let motct = self.log.param("COMPASS_MOTCT").filter(|v| v.is_finite());
        let motor_options: &[bool] = if self.log.autopilot == Autopilot::ArduPilot
            && range >= MIN_CURRENT_RANGE_A
            && most_deg >= MIN_SPREAD_SCALE_DEG
            && motct.is_none_or(|motct| motct == 0.0 || motct == MOTOR_BY_CURRENT)
        {
            &[false, true]
        } else {
            &[false]
        };
        // The iron in force is held where it is one the autopilot accepts.
        let held = self.in_force.soft_iron * self.in_force.scale;
        let held_accepted = self
            .limits
            .refusals(
                &candidate_of(Vector3::zeros(), held, Vector3::zeros()),
                None,
            )
            .is_empty();
        let held_soft_iron = if held_accepted {
            held
        } else {
            Matrix3::identity()
        };
        steps
            .into_iter()
            .flat_map(|step| {
                motor_options.iter().map(move |&motor| AidedModel {
                    step,
                    motor,
                    held_soft_iron,
                })
            })
            .collect()
    }

    /// `model` fitted on `samples` against the Earth's field (the model's, else fitted).
    /// Unweighted: MAGFit's weights by attitude (each sample by how crowded its
    /// attitude is) give the few samples of log171's final flip, whose attitude is the
    /// least sure, the most weight, and the vector error on its held-back half rose
    /// from 78 to 97 mG with them.
    fn fit(&self, samples: &[AidedSample], model: AidedModel) -> Option<AidedFit> {
        fit_aided(samples, model, self.truth.earth.model_ned_mg())
    }

    /// Why a fit cannot be written, whatever it scores: the autopilot's acceptance of
    /// its parameters (without the pre-arm field checks, which are for the whole log),
    /// and the parameters the flight did not determine.
    fn refusals(&self, fit: &AidedFit) -> Vec<String> {
        let mut reasons = self.limits.refusals(
            &candidate_of(fit.offsets, fit.soft_iron * fit.scale, fit.motor_per_a),
            None,
        );
        reasons.extend(undetermined(fit));
        reasons
    }
}

/// The parameters of a fit its samples did not determine, by their formal 1σ.
fn undetermined(fit: &AidedFit) -> Vec<String> {
    let mut reasons = Vec::new();
    if fit.offsets_sigma.amax() > MAX_OFFSET_SIGMA_MG {
        reasons.push(format!(
            "the flight does not determine the offsets (1σ up to {:.0} mG)",
            fit.offsets_sigma.amax()
        ));
    }
    if let Some(sigma) = fit.soft_iron_sigma.filter(|&sigma| sigma > MAX_IRON_SIGMA) {
        let what = if fit.model.step == Step::Scale {
            "scale"
        } else {
            "iron"
        };
        reasons.push(format!(
            "the flight does not determine the {what} (1σ up to {sigma:.3})"
        ));
    }
    reasons
}

/// The new parameters of one compass, as its autopilot names them.
fn new_params(compass: &CompassLog, log: &AutopilotLog, fit: &AidedFit) -> Vec<(String, f64)> {
    // The scale is folded into the iron: every firmware has COMPASS_DIA/ODI, and PX4's
    // scale is a matrix.
    let soft_iron = fit.soft_iron * fit.scale;
    match compass.px4_slot {
        Some((slot, rotation)) => {
            Px4Compass::from_body_form(slot, rotation, soft_iron, fit.offsets).params()
        }
        None => {
            let mut params = ArduPilotCompass {
                instance: compass.instance,
                offsets_mg: fit.offsets,
                soft_iron,
                scale: 1.0,
                motor_mg_per_a: fit.motor_per_a,
            }
            .params();
            // Compensation by throttle (COMPASS_MOTCT 1) is not modelled: its COMPASS_MOT
            // stays as in force (it applies alike before and after).
            if log.param("COMPASS_MOTCT") == Some(1.0) {
                params.retain(|(name, _)| {
                    !name.starts_with(&compass_param("MOT", compass.instance, ""))
                });
            }
            // COMPASS_SCALE is folded into M: write 1 where the log had another.
            let scale_name = compass_param("SCALE", compass.instance, "");
            if log.param(&scale_name).is_some_and(|scale| scale != 1.0) {
                params.push((scale_name, 1.0));
            }
            params
        }
    }
}

/// What the model chosen on the held-back half gives, before the rule decides.
struct Chosen {
    model: AidedModel,
    /// Fitted on the first half, and its score on the second.
    on_train: AidedFit,
    check: Score,
    /// Fitted on the whole log.
    whole: AidedFit,
}

/// A compass's result before anything is assessed.
fn unassessed(compass: &CompassLog, n_samples: usize) -> CompassResult {
    let none = Figures {
        in_force: None,
        new: None,
    };
    CompassResult {
        instance: compass.instance,
        px4_slot: compass.px4_slot.map(|(slot, _)| slot),
        source: compass.source.clone(),
        n_samples,
        coverage_regions: 0,
        turned_deg: [0.0; 2],
        candidates: Vec::new(),
        model: None,
        check: none,
        whole: none,
        kept_because: None,
        params: Vec::new(),
        sentence: String::new(),
        offsets_sigma: None,
        soft_iron_sigma: None,
        motor_sigma: None,
    }
}

/// Why the samples are too few or too short to judge a calibration on, if they are.
fn too_little(samples: &[AidedSample]) -> Option<String> {
    const RECORD: &str = "Record a flight (or a walk with the vehicle in hand) that turns \
                          through full circles with some tilt, for a minute or more";
    if samples.len() < MIN_SAMPLES {
        return Some(format!(
            "only {} samples with an attitude, fewer than {MIN_SAMPLES}. {RECORD}",
            samples.len()
        ));
    }
    let duration_s = samples.last()?.t_s - samples.first()?.t_s;
    (duration_s < MIN_DURATION_S).then(|| {
        format!(
            "the log's {duration_s:.1} s with an attitude are too few to judge a calibration \
             on (at least {MIN_DURATION_S:.0} s: half of it is held back). {RECORD}"
        )
    })
}

/// One compass assessed; `None` where the log has no raw field for it.
pub(super) fn assess(
    compass: &CompassLog,
    log: &AutopilotLog,
    attitude: &Stream<Attitude>,
    truth: &Truth,
) -> Option<CompassResult> {
    let raw = compass.raw_in_body_ut.as_ref()?;
    let samples = aided_samples(raw, attitude, &log.current_a);
    let lookup = |name: &str| log.param(name).filter(|value| value.is_finite());
    let in_force = in_body_form(compass, &lookup).unwrap_or_else(|| identity(compass.instance));
    let mut result = unassessed(compass, samples.len());
    let assessment = Assessment {
        log,
        truth,
        limits: Limits::of(log.autopilot, &lookup),
        samples,
        in_force,
    };
    let in_force_correct = |raw, current| assessment.in_force.apply(raw, current);
    let all = &assessment.samples[..];
    result.whole.in_force = assessment.score(all, all, &in_force_correct);
    if let Some(reason) = too_little(all) {
        result.kept_because = Some(reason);
        return Some(result);
    }
    let (train, check) = assessment.halves();
    result.check.in_force = assessment.score(check, train, &in_force_correct);
    (result.coverage_regions, result.turned_deg) = assessment.coverage();
    match assessment.choose(&mut result) {
        Some(chosen) => assessment.decide(compass, &chosen, &mut result),
        None => result.kept_because = Some(no_model_reason(&result, truth)),
    }
    Some(result)
}

impl Assessment<'_> {
    /// Every model the flight supports fitted on the first half and scored on the
    /// second (each a candidate in `result`); the best, where a richer model is chosen
    /// only where clearly better, fitted on the whole log too.
    fn choose(&self, result: &mut CompassResult) -> Option<Chosen> {
        let (train, check) = self.halves();
        let mut best: Option<(AidedFit, Score)> = None;
        for model in self.models(result.turned_deg) {
            let fit = self.fit(train, model);
            let (check_score, refused) = match &fit {
                Some(fit) => (
                    self.score(check, train, &|raw, current| fit.apply(raw, current)),
                    self.refusals(fit),
                ),
                None => (
                    None,
                    vec!["the first half does not fix its parameters".to_string()],
                ),
            };
            if let (Some(fit), Some(score), true) = (fit, check_score, refused.is_empty()) {
                let better = best.as_ref().is_none_or(|(_, best)| {
                    score.vector_rms_mg < best.vector_rms_mg * (1.0 - PARSIMONY_SHARE)
                });
                if better {
                    best = Some((fit, score));
                }
            }
            result.candidates.push(Candidate {
                model: model.label(),
                check: check_score,
                refused,
            });
        }
        let (on_train, check) = best?;
        Some(Chosen {
            model: on_train.model,
            whole: self.fit(&self.samples, on_train.model)?,
            on_train,
            check,
        })
    }

    /// The rule of the module header applied to the chosen model: its parameters as
    /// they would be written, read back, and kept in `result` only where the autopilot
    /// accepts them and both they and the first half's fit beat the parameters in force
    /// on the held-back half by more than the reference's own error could make them.
    fn decide(&self, compass: &CompassLog, chosen: &Chosen, result: &mut CompassResult) {
        let (train, check) = self.halves();
        let fit = &chosen.whole;
        result.model = Some(chosen.model.label());
        result.check.new = Some(chosen.check);
        result.offsets_sigma = Some(fit.offsets_sigma.into());
        result.soft_iron_sigma = fit.soft_iron_sigma;
        result.motor_sigma = chosen.model.motor.then(|| fit.motor_sigma.into());
        // The parameters as written, read back and applied as the autopilot applies them.
        let params = new_params(compass, self.log, fit);
        let mut written = parse_param_file(&param_file(&[], &params));
        if chosen.model.motor {
            written.push(("COMPASS_MOTCT".to_string(), MOTOR_BY_CURRENT));
        }
        let lookup = |name: &str| self.log.param(name).filter(|value| value.is_finite());
        let written_lookup = |name: &str| param_in(&written, name).or_else(|| lookup(name));
        let Some(read_back) = in_body_form(compass, &written_lookup) else {
            result.kept_because = Some("the written parameters do not read back".to_string());
            return;
        };
        let read_back_correct = |raw, current| read_back.apply(raw, current);
        let all = &self.samples[..];
        result.whole.new = self.score(all, all, &read_back_correct);
        let read_back_check = self.score(check, train, &read_back_correct);
        let field = self.field_seen(&read_back_correct);
        let written = candidate_of(
            read_back.offsets_mg,
            read_back.soft_iron * read_back.scale,
            read_back.motor_mg_per_a,
        );
        let mut refusals = self.limits.refusals(&written, Some(&field));
        refusals.extend(undetermined(fit));
        let in_force_check = result.check.in_force.map(|score| score.vector_rms_mg);
        let beats = |score: Option<Score>| match (score, in_force_check) {
            (Some(score), Some(in_force)) => {
                score.vector_rms_mg < in_force * (1.0 - MIN_IMPROVEMENT_SHARE)
            }
            _ => false,
        };
        // Real gains, whatever the reference's own error.
        let reference_share = match self.truth.earth {
            EarthField::Model { .. } => REFERENCE_ERROR_SHARE,
            EarthField::Fitted => FITTED_REFERENCE_ERROR_SHARE,
        };
        let reference_mg = reference_share * fit.earth_ned.norm();
        let in_force_correct = |raw, current| self.in_force.apply(raw, current);
        let real = |new: Option<Score>, correct: &dyn Fn(Vector3<f64>, f64) -> Vector3<f64>| {
            let change = score::change_seen_by_reference_mg(check, correct, &in_force_correct);
            match (new, in_force_check, change) {
                (Some(new), Some(in_force), Some(change)) => {
                    score::gain_is_real(in_force, new.vector_rms_mg, change, reference_mg)
                }
                _ => false,
            }
        };
        let on_train = &chosen.on_train;
        let real_gains = real(Some(chosen.check), &|raw, current| {
            on_train.apply(raw, current)
        }) && real(read_back_check, &read_back_correct);
        let figure = |mg: Option<f64>| {
            mg.map_or_else(|| "no figure".to_string(), |mg| format!("{mg:.1} mG"))
        };
        result.kept_because = if !refusals.is_empty() {
            Some(format!(
                "the {} fitted on the whole log would be refused: {}",
                chosen.model.label(),
                refusals.join("; ")
            ))
        } else if !beats(Some(chosen.check)) || !beats(read_back_check) {
            Some(format!(
                "on the held-back second half the best model ({}, fitted on the first half) \
                 gives {:.1} mG and the parameters as written {} against {} with the parameters \
                 in force: not clearly better",
                chosen.model.label(),
                chosen.check.vector_rms_mg,
                figure(read_back_check.map(|score| score.vector_rms_mg)),
                figure(in_force_check)
            ))
        } else if !real_gains {
            Some(format!(
                "on the held-back second half the new parameters give {:.1} mG against {} in \
                 force, a gain a reference off the truth by {reference_mg:.0} mG ({:.0} % of the \
                 field: the model's field against the local one, the autopilot's attitude) \
                 could make alone",
                chosen.check.vector_rms_mg,
                figure(in_force_check),
                100.0 * reference_share,
            ))
        } else {
            None
        };
        if result.kept_because.is_none() {
            result.params = params;
        }
    }
}

/// Why no model was chosen, and what to record.
fn no_model_reason(result: &CompassResult, truth: &Truth) -> String {
    let refused: Vec<String> = result
        .candidates
        .iter()
        .filter(|candidate| !candidate.refused.is_empty())
        .map(|candidate| format!("{}: {}", candidate.model, candidate.refused.join(", ")))
        .collect();
    let tried = if result.candidates.is_empty() {
        match truth.earth {
            EarthField::Fitted => format!(
                "without a position for the World Magnetic Model the offsets need the Earth's \
                 field to turn in the body by {MIN_SPREAD_FITTED_FIELD_DEG:.0}° (1σ) two ways; \
                 this flight turned it by {:.0}° and {:.0}°",
                result.turned_deg[0], result.turned_deg[1]
            ),
            EarthField::Model { .. } => "no model could be tried".to_string(),
        }
    } else if refused.is_empty() {
        "no model fitted on the first half could be scored on the second".to_string()
    } else {
        format!("every model was refused ({})", refused.join("; "))
    };
    format!(
        "{tried}. Record a flight (or a walk with the vehicle in hand) that turns through full \
         circles with some tilt, for a minute or more"
    )
}
