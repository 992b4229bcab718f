//! The calibration of an autopilot's compasses, written back as its parameters only
//! where it is better than the parameters in force.
//!
//! For each compass whose raw field the log gives ([`crate::io::autopilot`]):
//!
//! 1. Every raw sample is paired with the attitude of the axes it is logged in (the
//!    importer turns ArduPilot's `ATT` by `AHRS_TRIM`) and the battery current.
//! 2. The Earth's field is the World Magnetic Model's at the log's position and date
//!    ([`EarthField::Model`]); without one, each calibration's own mean field.
//! 3. The models of the attitude-aided fit ([`crate::fit::autopilot_aided`]) are
//!    climbed one [`Step`](crate::fit::autopilot_aided::Step) at a time as the flight
//!    supports them: how many of the sphere's 100 regions the Earth's field crosses in
//!    the body decides which steps are tried (one heading: the offsets or nothing),
//!    each with and without the motor term where the current varies. Each is fitted on
//!    the first half of the log and scored on the held-back second half by the vector
//!    error (`score.rs`); a fit the autopilot would refuse (`acceptance.rs`) or whose
//!    offsets the flight does not determine is out.
//! 4. The best (a richer model only where it is clearly better) is fitted on the whole
//!    log, checked against the autopilot's acceptance again, written as the autopilot's
//!    parameters, read back from that text and applied as the autopilot applies them.
//! 5. **The rule every write-back follows:** the compass's lines are written only where
//!    both the model fitted on the first half and the parameters as written beat the
//!    parameters in force on the held-back second half by more than a reference 5 % off
//!    the truth could make them (`score::gain_is_real`), and the autopilot accepts them.
//!    Otherwise the file keeps the parameters in force for that compass and says why in
//!    a comment; the console, the JSON and the page show the same sentence
//!    ([`CompassResult::sentence`]).

mod acceptance;
mod assess;
mod samples;
mod score;

use serde::Serialize;

pub use self::acceptance::{FieldSeen, Limits, ModelDifference};
pub use self::samples::InForce;
pub use self::score::{EarthField, Score};
use crate::analysis::calibration::DeclinationUsed;
use crate::earth::wmm::ExpectedField;
pub use crate::fit::autopilot_aided::AidedSample;
use crate::io::autopilot::ardupilot::{compass_param, param_file, MOTOR_BY_CURRENT};
use crate::io::autopilot::px4::params_file;
use crate::io::autopilot::{Autopilot, AutopilotLog, CompassLog};
use crate::io::recording::{Attitude, Stream};

/// One model fitted on the first half and scored on the held-back second half.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    pub model: String,
    pub check: Option<Score>,
    /// Why it cannot be written (the autopilot's acceptance, undetermined parameters);
    /// empty when it can.
    pub refused: Vec<String>,
}

/// The parameters in force and the new ones, by the same metric on the same samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Figures {
    pub in_force: Option<Score>,
    pub new: Option<Score>,
}

/// One compass: what was tried, what is written for it (or why the parameters in force
/// are kept), and the figures that decided it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompassResult {
    pub instance: usize,
    /// PX4's calibration slot (`CAL_MAGn_*`); `None` for ArduPilot.
    pub px4_slot: Option<usize>,
    pub source: String,
    pub n_samples: usize,
    /// Regions of the sphere's 100 the Earth's field crossed in the body.
    pub coverage_regions: usize,
    /// How far the Earth's field turned in the body: the standard deviation of its
    /// direction along the direction it turned most, and along the next (degrees).
    pub turned_deg: [f64; 2],
    pub candidates: Vec<Candidate>,
    /// The model chosen on the held-back half, where one could be.
    pub model: Option<String>,
    /// On the held-back second half: the parameters in force, and the chosen model
    /// fitted on the first half.
    pub check: Figures,
    /// On the whole log: the parameters in force, and the new parameters as their
    /// written lines read back give them.
    pub whole: Figures,
    /// `None` where the new parameters are written; else why the ones in force are kept.
    pub kept_because: Option<String>,
    /// The lines written for this compass (empty where kept).
    pub params: Vec<(String, f64)>,
    /// What is written for this compass or why nothing is, with the figures, in one
    /// sentence: the console, the parameter file, the JSON and the page all say it.
    pub sentence: String,
    /// Formal 1σ of the new offsets (mG), of the iron's entries or scale, and of the
    /// motor term (mG/A), where fitted.
    pub offsets_sigma: Option<[f64; 3]>,
    pub soft_iron_sigma: Option<f64>,
    pub motor_sigma: Option<[f64; 3]>,
}

impl CompassResult {
    /// "Compass 1 (MAG)" (ArduPilot's numbering), "CAL_MAG1 (vehicle_magnetometer 0)"
    /// (PX4's calibration slot): the compass as the page and the CLI name it.
    pub fn label(&self) -> String {
        match self.px4_slot {
            Some(slot) => format!("CAL_MAG{slot} ({})", self.source),
            None => format!("Compass {} ({})", self.instance + 1, self.source),
        }
    }

    pub fn is_written(&self) -> bool {
        self.kept_because.is_none()
    }

    /// One sentence: what is written for this compass or why nothing is, with the
    /// figures: [`CompassResult::sentence`], once the assessment is done.
    fn compose_sentence(&self) -> String {
        let label = self.label();
        let check = |figures: &Figures| match (figures.new, figures.in_force) {
            (Some(new), Some(in_force)) => format!(
                "; on the held-back second half {:.1} mG against {:.1} mG in force",
                new.vector_rms_mg, in_force.vector_rms_mg
            ),
            _ => String::new(),
        };
        match &self.kept_because {
            None => format!(
                "{label}: written ({}): {}{}",
                self.model.as_deref().unwrap_or("new parameters"),
                compare(&self.whole),
                check(&self.check)
            ),
            Some(reason) => {
                let in_force = self
                    .whole
                    .in_force
                    .map_or_else(String::new, |score| format!(" ({})", describe(&score)));
                format!("{label}: parameters in force kept{in_force}: {reason}")
            }
        }
    }
}

/// "65.6 mG vector error, 9.4° heading error (in force 82.8 mG, 11.0°)".
fn compare(figures: &Figures) -> String {
    match (figures.new, figures.in_force) {
        (Some(new), Some(in_force)) => format!(
            "{} (in force {})",
            describe(&new),
            describe_short(&in_force)
        ),
        (Some(new), None) => describe(&new),
        _ => "no figures".to_string(),
    }
}

/// A score as people read it.
pub fn describe(score: &Score) -> String {
    match score.heading_rms_deg {
        Some(heading) => format!(
            "{:.1} mG vector error, {heading:.1}° heading error against the autopilot's, |B| \
             spread {:.1} %",
            score.vector_rms_mg, score.spread_pct
        ),
        None => format!(
            "{:.1} mG vector error, |B| spread {:.1} %",
            score.vector_rms_mg, score.spread_pct
        ),
    }
}

fn describe_short(score: &Score) -> String {
    match score.heading_rms_deg {
        Some(heading) => format!(
            "{:.1} mG, {heading:.1}°, {:.1} %",
            score.vector_rms_mg, score.spread_pct
        ),
        None => format!("{:.1} mG, {:.1} %", score.vector_rms_mg, score.spread_pct),
    }
}

/// The calibration of every compass of an autopilot log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AutopilotCalibration {
    pub autopilot: &'static str,
    /// What every figure is measured against.
    pub earth: EarthField,
    /// Every compass assessed, written or kept.
    pub compasses: Vec<CompassResult>,
    /// The compass the answer leads with: the one whose raw field is the recording's
    /// magnetometer (the autopilot's primary), else the first.
    pub primary: usize,
    /// The parameter file to load (Mission Planner, MAVProxy, QGroundControl): the
    /// written compasses' lines, and a comment for each compass saying what was done
    /// and why; empty when nothing is written.
    pub param_file: String,
    pub notes: Vec<String>,
}

impl AutopilotCalibration {
    /// The compasses whose new parameters are written.
    pub fn written(&self) -> impl Iterator<Item = &CompassResult> {
        self.compasses.iter().filter(|compass| compass.is_written())
    }
}

/// The Earth's field and declination the figures use, as the caller knows them.
#[derive(Debug, Clone, PartialEq)]
pub struct Truth {
    pub earth: EarthField,
    /// Added to a magnetic heading to compare it with the autopilot's yaw (true).
    pub declination_rad: Option<f64>,
}

impl Truth {
    /// The World Magnetic Model's field at the log's position and date where known, and
    /// the declination the headings use where it is known.
    pub fn of(expected: Option<&ExpectedField>, declination: &DeclinationUsed) -> Truth {
        let earth = match expected {
            Some(expected) => {
                let declination_rad = expected.declination_deg.to_radians();
                // µT to mG.
                let ned_mg = [
                    10.0 * expected.horizontal_ut * declination_rad.cos(),
                    10.0 * expected.horizontal_ut * declination_rad.sin(),
                    10.0 * expected.vertical_ut,
                ];
                EarthField::Model {
                    ned_mg,
                    source: format!("{} on {}", expected.model, expected.model_date),
                }
            }
            None => EarthField::Fitted,
        };
        Truth {
            earth,
            declination_rad: declination
                .is_known()
                .then(|| declination.declination_deg.to_radians()),
        }
    }
}

/// The calibration of an autopilot log's compasses against `truth`, where it has their
/// raw fields and an attitude with yaw; `None` otherwise. ArduPilot's are written as a
/// `.param` file, PX4's as a QGroundControl `.params` file (`CAL_MAGn_*`, without power
/// compensation), each only where the rule of the module header lets it.
pub fn autopilot_calibration(
    log: &AutopilotLog,
    attitude: &Stream<Attitude>,
    truth: &Truth,
) -> Option<AutopilotCalibration> {
    if attitude.is_empty() {
        return None;
    }
    let is_px4 = log.autopilot == Autopilot::Px4;
    let mut notes = Vec::new();
    // PX4 logs a compass under several topics (sensor_mag, vehicle_magnetometer): one
    // calibration slot is assessed once, on the topic with the most raw samples.
    let n_raw = |compass: &CompassLog| {
        compass
            .raw_in_body_ut
            .as_ref()
            .map_or(0, crate::io::recording::Stream::len)
    };
    let assessed: Vec<&CompassLog> = log
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
    let compasses: Vec<CompassResult> = assessed
        .into_iter()
        .filter_map(|compass| assess::assess(compass, log, attitude, truth))
        .map(|mut result| {
            result.sentence = result.compose_sentence();
            result
        })
        .collect();
    if compasses.is_empty() {
        return None;
    }
    if log.current_a.is_empty() && !is_px4 {
        notes.push(
            "no battery current in the log (CURR, BAT): motor interference not fitted".to_string(),
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
    let main_source = log
        .main_compass
        .and_then(|idx| log.compasses.get(idx))
        .map(|compass| compass.source.as_str());
    let primary = compasses
        .iter()
        .position(|compass| Some(compass.source.as_str()) == main_source)
        .unwrap_or(0);
    let calibration = AutopilotCalibration {
        autopilot: log.autopilot.name(),
        param_file: String::new(),
        earth: truth.earth.clone(),
        compasses,
        primary,
        notes,
    };
    let param_file = parameter_file(&calibration, log);
    Some(AutopilotCalibration {
        param_file,
        ..calibration
    })
}

/// The parameter file: a header, each compass's sentence, and the written lines; empty
/// when no compass is written.
fn parameter_file(calibration: &AutopilotCalibration, log: &AutopilotLog) -> String {
    if calibration.written().next().is_none() {
        return String::new();
    }
    let is_px4 = log.autopilot == Autopilot::Px4;
    let mut header = vec![
        format!(
            "compass calibration by compass-pdr {}, attitude-aided fit on the log's {}, \
             judged against {}",
            env!("CARGO_PKG_VERSION"),
            if is_px4 {
                "vehicle_attitude"
            } else {
                "ATT (turned by AHRS_TRIM)"
            },
            calibration.earth.describe()
        ),
        if is_px4 {
            "corrected = R · S · (raw − CAL_MAGn_OFF), S from CAL_MAGn_SCALE and CAL_MAGn_ODIAG (gauss)"
        } else {
            "corrected = M · (raw + COMPASS_OFS) + COMPASS_MOT · current, M from COMPASS_DIA and COMPASS_ODI (mG)"
        }
        .to_string(),
        "a compass is written only where its new parameters beat those in force on the \
         held-back second half of the log and the autopilot accepts them; the others keep \
         the parameters in force"
            .to_string(),
    ];
    header.extend(
        calibration
            .compasses
            .iter()
            .map(|compass| compass.sentence.clone()),
    );
    let mut params = Vec::new();
    let by_current_in_force = log.param("COMPASS_MOTCT") == Some(MOTOR_BY_CURRENT);
    if calibration
        .written()
        .any(|compass| compass.motor_sigma.is_some())
        && !by_current_in_force
    {
        params.push(("COMPASS_MOTCT".to_string(), MOTOR_BY_CURRENT));
        // COMPASS_MOTCT is one for all compasses: a kept compass's COMPASS_MOT, unused
        // until now, would start to apply. It is zeroed, so that it corrects as before.
        for compass in calibration.compasses.iter().filter(|c| !c.is_written()) {
            let names = ["X", "Y", "Z"].map(|axis| compass_param("MOT", compass.instance, axis));
            if names
                .iter()
                .any(|name| log.param(name).is_some_and(|v| v != 0.0))
            {
                header.push(format!(
                    "{}: COMPASS_MOT zeroed, as COMPASS_MOTCT becomes 2 (by current), so that \
                     its correction in force stays as it was",
                    compass.label()
                ));
                params.extend(names.map(|name| (name, 0.0)));
            }
        }
    }
    for compass in calibration.written() {
        params.extend(compass.params.iter().cloned());
    }
    if is_px4 {
        params_file(&header, &params)
    } else {
        param_file(&header, &params)
    }
}

#[cfg(test)]
mod tests;
