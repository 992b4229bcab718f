//! A simulated walk with a phone held in hand, with its truth.
//!
//! The walk opens with a calibration circle (a full turn, as the 2007 paper's
//! autocalibration asks for), then alternates straight legs, turns and short stops.
//! Physics, per sample:
//!
//! - attitude: the true heading ψ, plus the hand's mean tilt and a sway at the step
//!   frequency (pitch) and half of it (roll);
//! - magnetometer: `m = S·(R_bodyᵀ·F_ned) + b_hard + noise`, Eq. 2-3 of the 2007 paper
//!   with a diagonal S (axis scale factors) and the Earth's field `F_ned` of a chosen
//!   magnitude and inclination, declination zero (so magnetic north is true north);
//! - accelerometer: specific force `f = a − g` with a vertical bounce and a fore-aft
//!   surge at the step frequency while walking, rotated into the body frame;
//! - gyroscope: the exact body rates of the Euler-angle motion, plus bias and noise.
//!
//! The gait is [`Gait::Steady`] (fixed steps, the committed demo's) or
//! [`Gait::Varied`] (steps that vary, with accelerations that follow Weinberg's
//! relation and the truth of every step: `gait.rs`). [`simulate_with_truth`] returns
//! that step truth with the log.

use nalgebra::{Rotation3, Vector2, Vector3};
use serde::Serialize;

use super::gait::{Gait, GaitMotion, GaitPlan, GaitVariation, StepPositions, StepTruth};
use super::rng::SplitMix64;
use crate::angle::wrap_to_2pi;
use crate::geo::{Geodetic, LocalFrame};
use crate::io::canonical_csv::CanonicalRow;

const G_MPS2: f64 = 9.81;

/// Everything that defines a simulated walk. [`WalkConfig::from_seed`] draws the
/// distortions from the seed, so the truth travels with the log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WalkConfig {
    pub seed: u64,
    pub duration_s: f64,
    pub sample_rate_hz: f64,
    /// Earth's field: total intensity, inclination (dip, positive down) and declination
    /// (from true north to magnetic north, positive east; the reference heading is
    /// from true north). [`WalkConfig::at_place`] takes all three from the World
    /// Magnetic Model.
    pub field_total_ut: f64,
    pub inclination_deg: f64,
    pub declination_deg: f64,
    /// When the walk starts, in seconds since 1970 (UTC): the log's times are then
    /// written as absolute times, which date it (for the World Magnetic Model), as a
    /// phone's log is. `None` writes times from 0.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start_unix_s: Option<f64>,
    /// Hard iron in the body frame.
    pub hard_iron_ut: [f64; 3],
    /// Axis scale factors (the diagonal of S).
    pub scale: [f64; 3],
    /// Soft iron: the off-diagonal terms of the symmetric S (xy, xz, yz), so that the
    /// sensor reads `S·f + b` with the full Eq. 5 distortion of the 2007 paper.
    #[serde(skip_serializing_if = "is_zero3")]
    pub soft_iron_offdiag: [f64; 3],
    pub mag_noise_ut: f64,
    pub acc_noise_mps2: f64,
    pub gyro_bias_radps: [f64; 3],
    pub gyro_noise_radps: f64,
    /// The steady gait's step frequency and length (the varied gait has its own).
    pub step_frequency_hz: f64,
    pub step_length_m: f64,
    /// How the pedestrian walks. The steady gait is not written in the JSON of the
    /// config, which therefore reads as it did before there was a choice.
    #[serde(skip_serializing_if = "Gait::is_steady")]
    pub gait: Gait,
    /// The hand's mean tilt and the sway about it while walking.
    pub mean_pitch_deg: f64,
    pub mean_roll_deg: f64,
    pub sway_pitch_deg: f64,
    pub sway_roll_deg: f64,
    pub start_heading_deg: f64,
    /// Misalignment β: the device's forward axis is this far clockwise of the walking
    /// direction (the PDR paper, Eq. 9).
    pub misalignment_deg: f64,
    /// A compass whose raw heading deviates by exactly the unified model (the PDR
    /// paper's Eq. 12, A to E in degrees) instead of by hard and soft iron: the field it
    /// senses is turned about the vertical so that true = raw + δ(raw).
    pub deviation_deg: Option<[f64; 5]>,
    /// Temperature: the walk's temperature swings by this much (°C) about 22 °C with
    /// this period (s); zero swing keeps a slow warming from 22 to 25 °C.
    pub temp_swing_c: f64,
    pub temp_period_s: f64,
    /// Hard-iron drift with temperature (µT/°C per axis, about 22 °C).
    pub hard_iron_temp_coeff_ut_per_c: [f64; 3],
    /// A GNSS receiver, if the walk has one.
    pub gnss: Option<GnssSim>,
    /// Iron near the path: a local field added to the Earth's while the walker passes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub disturbance: Option<Disturbance>,
    /// What the device does: a walk, or turns on a turntable. The walk is not written
    /// in the JSON of the config, which therefore reads as it did before.
    #[serde(skip_serializing_if = "Route::is_walk")]
    pub route: Route,
}

/// What the device does during the simulation.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Route {
    /// Stand, walk a calibration circle, then legs, turns and stops (`plan_route`).
    #[default]
    Walk,
    /// Turn on the spot at a steady rate, one turn every `period_s`, without a step:
    /// a turntable (or a person turning slowly in place).
    Turntable { period_s: f64 },
    /// Drive an octagonal loop at `speed_mps`, again and again: straight legs of
    /// `leg_s`, each followed by a 45° right turn over `turn_s`, so that eight headings
    /// 45° apart are held in turn. No steps and no sway (a fixed mount); the
    /// accelerometer feels the centripetal acceleration in the turns.
    VehicleLoop {
        speed_mps: f64,
        leg_s: f64,
        turn_s: f64,
    },
}

impl Route {
    pub fn is_walk(&self) -> bool {
        matches!(self, Route::Walk)
    }
}

fn is_zero3(values: &[f64; 3]) -> bool {
    *values == [0.0; 3]
}

/// A magnetic disturbance near iron (a steel door, a parked car, reinforced concrete):
/// from `start_s` to `end_s` an extra field, in the NED frame, rises and falls as a
/// raised cosine to `peak_ned_ut` and back. The compass turns with it; the reference
/// heading does not.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Disturbance {
    pub start_s: f64,
    pub end_s: f64,
    pub peak_ned_ut: [f64; 3],
}

impl Disturbance {
    /// The extra field at `t_s`.
    pub fn field_ned_ut(&self, t_s: f64) -> Vector3<f64> {
        // Strictly inside (so the span is positive); NaN times are not.
        let inside = t_s > self.start_s && t_s < self.end_s;
        if !inside {
            return Vector3::zeros();
        }
        let span_s = self.end_s - self.start_s;
        let weight = 0.5 - 0.5 * (std::f64::consts::TAU * (t_s - self.start_s) / span_s).cos();
        Vector3::from(self.peak_ned_ut) * weight
    }
}

/// A simulated GNSS receiver: fixes at `rate_hz` with position noise, and a course over
/// ground with noise while moving.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GnssSim {
    pub rate_hz: f64,
    pub origin_lat_deg: f64,
    pub origin_lon_deg: f64,
    pub position_noise_m: f64,
    pub course_noise_deg: f64,
    /// The accuracy the receiver reports (m).
    pub hacc_m: f64,
    /// No fixes from the first time to the second (s): under a roof, in a tunnel.
    pub outage_s: Option<(f64, f64)>,
    /// Multipath: between its times, fixes stray by a slowly wandering error.
    pub multipath: Option<Multipath>,
}

/// Multipath near tall buildings: from `start_s` to `end_s` every fix is off by an
/// error of about `error_m` (1σ per axis) that wanders slowly (a first-order process
/// with a 10 s time constant) rather than jumping from fix to fix, its course by up to
/// three times the usual noise, and the receiver reports `hacc_m`, optimistic as
/// receivers are.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Multipath {
    pub start_s: f64,
    pub end_s: f64,
    pub error_m: f64,
    pub hacc_m: f64,
}

impl Default for GnssSim {
    fn default() -> Self {
        GnssSim {
            rate_hz: 1.0,
            origin_lat_deg: 60.1699,
            origin_lon_deg: 24.9384,
            position_noise_m: 2.0,
            course_noise_deg: 2.0,
            hacc_m: 3.0,
            outage_s: None,
            multipath: None,
        }
    }
}

impl WalkConfig {
    /// A walk of `duration_s` at 50 Hz whose distortions come from `seed`: hard iron up
    /// to 30 µT per axis, scale factors 0.9-1.1, noise 0.3 µT.
    pub fn from_seed(seed: u64, duration_s: f64) -> Self {
        let mut rng = SplitMix64::new(seed ^ 0x00C0_FFEE);
        let mut draw3 = |low: f64, high: f64| {
            [
                rng.uniform_in(low, high),
                rng.uniform_in(low, high),
                rng.uniform_in(low, high),
            ]
        };
        let hard_iron_ut = draw3(-30.0, 30.0);
        let scale = draw3(0.9, 1.1);
        let gyro_bias_radps = draw3(-0.01, 0.01);
        let start_heading_deg = (seed.wrapping_mul(37) % 360) as f64;
        WalkConfig {
            seed,
            duration_s,
            sample_rate_hz: 50.0,
            field_total_ut: 50.0,
            inclination_deg: 60.0,
            declination_deg: 0.0,
            start_unix_s: None,
            hard_iron_ut,
            scale,
            soft_iron_offdiag: [0.0; 3],
            mag_noise_ut: 0.3,
            acc_noise_mps2: 0.05,
            gyro_bias_radps,
            gyro_noise_radps: 0.005,
            step_frequency_hz: 1.8,
            step_length_m: 0.7,
            gait: Gait::Steady,
            mean_pitch_deg: 6.0,
            mean_roll_deg: -3.0,
            sway_pitch_deg: 2.0,
            sway_roll_deg: 1.5,
            start_heading_deg,
            misalignment_deg: 0.0,
            deviation_deg: None,
            temp_swing_c: 0.0,
            temp_period_s: 600.0,
            hard_iron_temp_coeff_ut_per_c: [0.0; 3],
            gnss: None,
            disturbance: None,
            route: Route::Walk,
        }
    }

    /// The phone of [`WalkConfig::from_seed`] on a level turntable turning once every
    /// `period_s` (a slow, even rotation through every heading): no steps, no tilt, no
    /// sway.
    pub fn turntable(seed: u64, duration_s: f64, period_s: f64) -> WalkConfig {
        WalkConfig {
            route: Route::Turntable { period_s },
            mean_pitch_deg: 0.0,
            mean_roll_deg: 0.0,
            sway_pitch_deg: 0.0,
            sway_roll_deg: 0.0,
            ..WalkConfig::from_seed(seed, duration_s)
        }
    }

    /// The walk at a place and time: its start, and the Earth's field there (total,
    /// inclination, declination) from the World Magnetic Model; a GNSS receiver, if
    /// any, reports positions around that place.
    pub fn at_place(
        self,
        lat_deg: f64,
        lon_deg: f64,
        start_unix_s: f64,
    ) -> Result<WalkConfig, crate::calib::wmm::WmmError> {
        let date = crate::calib::wmm::date_of_unix_s(start_unix_s).ok_or_else(|| {
            crate::calib::wmm::WmmError::UnreadableDate {
                text: format!("{start_unix_s} s after 1970"),
            }
        })?;
        let field = crate::calib::wmm::expected_field(lat_deg, lon_deg, 0.0, date)?;
        Ok(WalkConfig {
            field_total_ut: field.total_ut,
            inclination_deg: field.inclination_deg,
            declination_deg: field.declination_deg,
            start_unix_s: Some(start_unix_s),
            gnss: self.gnss.map(|gnss| GnssSim {
                origin_lat_deg: lat_deg,
                origin_lon_deg: lon_deg,
                ..gnss
            }),
            ..self
        })
    }

    /// A car driving an octagonal loop at 12 m/s (legs of 15 s, 45° turns over 4 s:
    /// about 1.6 km a lap) with the phone in a fixed mount: level to within a degree, no
    /// sway. Its compass deviates as a car's does, by the PDR paper's Eq. 12 with A to E
    /// drawn from the seed (A within ±5°, B and C within ±15°, D and E within ±5°: the
    /// car's own iron), and a GNSS receiver (1 Hz, 3 m, course noise 1°) gives the course
    /// to learn it from, in Munich on 9 August 2023.
    pub fn vehicle_loop(seed: u64, duration_s: f64, sample_rate_hz: f64) -> WalkConfig {
        let mut rng = SplitMix64::new(seed ^ 0x0CA5_0000_0000_0008);
        let mut draw = |half_range_deg: f64| rng.uniform_in(-half_range_deg, half_range_deg);
        let deviation_deg = [draw(5.0), draw(15.0), draw(15.0), draw(5.0), draw(5.0)];
        let config = WalkConfig {
            sample_rate_hz,
            route: Route::VehicleLoop {
                speed_mps: 12.0,
                leg_s: 15.0,
                turn_s: 4.0,
            },
            mean_pitch_deg: 0.8,
            mean_roll_deg: -0.5,
            sway_pitch_deg: 0.0,
            sway_roll_deg: 0.0,
            deviation_deg: Some(deviation_deg),
            gnss: Some(GnssSim {
                position_noise_m: 3.0,
                course_noise_deg: 1.0,
                hacc_m: 3.0,
                ..GnssSim::default()
            }),
            ..WalkConfig::from_seed(seed, duration_s)
        };
        // 2023-08-09 12:00 UTC in Munich (inside the model).
        config
            .clone()
            .at_place(48.1374, 11.5755, 1_691_582_400.0)
            .unwrap_or(config)
    }

    /// The 2007 paper's raw case: an uncalibrated heading wrong by (12 ± 30)° (its
    /// Table 1, a land vehicle's compass before calibration), on the turntable of
    /// [`WalkConfig::turntable`] (one turn a minute), so that every heading counts
    /// alike. Hard iron in the level plane of 0.69 of the horizontal field makes the
    /// error swing by ±44° with a standard deviation of 30° over a turn, and a
    /// declination of −12° that nothing in the log reveals (no position, no date) stays
    /// in its mean: the compass reads 12° more than the true heading.
    pub fn paper_raw_case(seed: u64, duration_s: f64) -> WalkConfig {
        let base = WalkConfig::turntable(seed, duration_s, 60.0);
        let horizontal_ut = base.field_total_ut * base.inclination_deg.to_radians().cos();
        let mean_scale = (base.scale[0] + base.scale[1]) / 2.0;
        let [x, y, z] = base.hard_iron_ut;
        let direction_rad = y.atan2(x);
        let magnitude_ut = 0.69 * horizontal_ut * mean_scale;
        WalkConfig {
            hard_iron_ut: [
                magnitude_ut * direction_rad.cos(),
                magnitude_ut * direction_rad.sin(),
                z,
            ],
            declination_deg: -12.0,
            ..base
        }
    }

    /// The demo log (`assets/demo-walk.csv`): a walk that shows every part of the page.
    /// The phone of [`WalkConfig::from_seed`] (hard iron, scale factors, tilt and sway,
    /// gyro bias), with the varied gait of the PDR scenario, its hard iron drifting
    /// with a temperature that swings by 4 °C (for the neural network's temperature
    /// input), in Seattle on 14 May 2026 (the WMM's field there: declination about
    /// +15°, inclination 67°), with a GNSS receiver (1 Hz, 3 m) that loses the sky for a
    /// minute (the dead reckoning bridges it) and suffers multipath for 15 s, and a
    /// passage near iron.
    pub fn demo(seed: u64, duration_s: f64, sample_rate_hz: f64) -> WalkConfig {
        let at = |fraction: f64| (duration_s * fraction).round();
        let config = WalkConfig {
            sample_rate_hz,
            gait: Gait::Varied(GaitVariation::default()),
            temp_swing_c: 4.0,
            temp_period_s: duration_s.max(1.0),
            hard_iron_temp_coeff_ut_per_c: [0.15, -0.12, 0.08],
            gnss: Some(GnssSim {
                position_noise_m: 3.0,
                hacc_m: 3.0,
                outage_s: Some((at(0.6), at(0.6) + 60.0)),
                multipath: Some(Multipath {
                    start_s: at(0.35),
                    end_s: at(0.35) + 15.0,
                    error_m: 12.0,
                    hacc_m: 6.0,
                }),
                ..GnssSim::default()
            }),
            disturbance: Some(Disturbance {
                start_s: at(0.25),
                end_s: at(0.25) + 8.0,
                peak_ned_ut: [-5.0, 4.0, 3.0],
            }),
            ..WalkConfig::from_seed(seed, duration_s)
        };
        // 2026-05-14 16:30 UTC in Seattle (inside the model, so this cannot fail).
        let start_unix_s = 1_778_776_200.0;
        config
            .clone()
            .at_place(47.6062, -122.3321, start_unix_s)
            .unwrap_or(config)
    }

    /// The PDR scenario of issue 6: the walk of [`WalkConfig::from_seed`] at
    /// `sample_rate_hz` (50 or 100 Hz on phones), with the varied gait of
    /// [`GaitVariation::default`] and a GNSS receiver with 3 m noise (1 Hz fixes, 2°
    /// course noise, the speed with 0.05 m/s noise, a reported accuracy of 3 m).
    ///
    /// The heading error is the PDR paper's unified model, Eq. 12: the compass deviates
    /// by exactly `δ = A + B·sin ψ' + C·cos ψ' + D·sin 2ψ' + E·cos 2ψ'` (ψ' the raw
    /// heading), with A to E drawn from the seed: A within ±5°, B and C within ±6°, D and
    /// E within ±3°, so the raw heading is wrong by up to about 18°. That is the error
    /// the paper learns from GNSS courses and compensates before its EKF (the values
    /// of its Table II are larger, B up to 40°, after devices were mounted next to the
    /// compass). Hard iron, scale factors and their temperature drift are then not
    /// simulated; the hand's tilt and sway, gyro bias and sensor noise are.
    pub fn pdr_walk(seed: u64, duration_s: f64, sample_rate_hz: f64) -> Self {
        let mut rng = SplitMix64::new(seed ^ 0x0BAD_5EED_0000_0006);
        let mut draw = |half_range_deg: f64| rng.uniform_in(-half_range_deg, half_range_deg);
        let deviation_deg = [draw(5.0), draw(6.0), draw(6.0), draw(3.0), draw(3.0)];
        WalkConfig {
            sample_rate_hz,
            gait: Gait::Varied(GaitVariation::default()),
            deviation_deg: Some(deviation_deg),
            gnss: Some(GnssSim {
                position_noise_m: 3.0,
                hacc_m: 3.0,
                ..GnssSim::default()
            }),
            ..WalkConfig::from_seed(seed, duration_s)
        }
    }
}

/// The truth of a walk beyond its reference columns.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct WalkTruth {
    /// The length of the path the truth position followed, summed sample by sample.
    pub path_length_m: f64,
    /// The steps, in order (empty for [`Gait::Steady`]); their lengths add up to
    /// `path_length_m`.
    pub steps: Vec<StepTruth>,
}

/// One phase of the walk: how long, whether walking, and the turn rate.
#[derive(Debug, Clone, Copy)]
struct Phase {
    duration_s: f64,
    is_walking: bool,
    turn_rate_radps: f64,
}

/// The route: stand, walk a calibration circle, then legs, turns and stops.
fn plan_route(config: &WalkConfig, rng: &mut SplitMix64) -> Vec<Phase> {
    let circle_s = 24.0;
    let mut phases = vec![
        Phase {
            duration_s: 3.0,
            is_walking: false,
            turn_rate_radps: 0.0,
        },
        Phase {
            duration_s: circle_s,
            is_walking: true,
            turn_rate_radps: std::f64::consts::TAU / circle_s,
        },
    ];
    let mut planned_s: f64 = phases.iter().map(|phase| phase.duration_s).sum();
    let mut leg_idx = 0usize;
    while planned_s < config.duration_s {
        let leg_s = rng.uniform_in(10.0, 25.0);
        phases.push(Phase {
            duration_s: leg_s,
            is_walking: true,
            turn_rate_radps: 0.0,
        });
        let turn_deg: f64 =
            [90.0, -90.0, 45.0, -135.0, 180.0, -45.0][(rng.next_u64() % 6) as usize];
        let turn_s = 2.0 + turn_deg.abs() / 90.0;
        phases.push(Phase {
            duration_s: turn_s,
            is_walking: true,
            turn_rate_radps: f64::to_radians(turn_deg) / turn_s,
        });
        planned_s += leg_s + turn_s;
        leg_idx += 1;
        if leg_idx.is_multiple_of(4) {
            phases.push(Phase {
                duration_s: 4.0,
                is_walking: false,
                turn_rate_radps: 0.0,
            });
            planned_s += 4.0;
        }
    }
    phases
}

/// Simulates the walk: one canonical row per sample.
pub fn simulate(config: &WalkConfig) -> Vec<CanonicalRow> {
    simulate_with_truth(config).0
}

/// The walking phases of a route: start and end times (s), in order.
fn walking_phases(phases: &[Phase]) -> Vec<(f64, f64)> {
    let mut phase_start_s = 0.0;
    let mut walking = Vec::new();
    for phase in phases {
        if phase.is_walking {
            walking.push((phase_start_s, phase_start_s + phase.duration_s));
        }
        phase_start_s += phase.duration_s;
    }
    walking
}

/// The gait while the walk is simulated: the steady gait's fade, or the varied gait's
/// planned steps.
enum GaitState {
    Steady { weight: f64 },
    Varied(GaitPlan),
}

/// Simulates the walk: one canonical row per sample, and the truth of its steps. The
/// rows are those of [`simulate`].
pub fn simulate_with_truth(config: &WalkConfig) -> (Vec<CanonicalRow>, WalkTruth) {
    let mut rng = SplitMix64::new(config.seed);
    let phases = match config.route {
        Route::Walk => plan_route(config, &mut rng),
        Route::Turntable { period_s } => vec![Phase {
            duration_s: config.duration_s,
            is_walking: false,
            turn_rate_radps: std::f64::consts::TAU / period_s,
        }],
        Route::VehicleLoop { leg_s, turn_s, .. } => {
            let lap_s = 8.0 * (leg_s + turn_s);
            let n_laps = (config.duration_s / lap_s.max(1.0)).ceil() as usize;
            (0..8 * n_laps)
                .flat_map(|_| {
                    [
                        Phase {
                            duration_s: leg_s,
                            is_walking: true,
                            turn_rate_radps: 0.0,
                        },
                        Phase {
                            duration_s: turn_s,
                            is_walking: true,
                            turn_rate_radps: std::f64::consts::FRAC_PI_4 / turn_s,
                        },
                    ]
                })
                .collect()
        }
    };
    let vehicle_speed_mps = match config.route {
        Route::VehicleLoop { speed_mps, .. } => Some(speed_mps),
        Route::Walk | Route::Turntable { .. } => None,
    };
    let dt_s = 1.0 / config.sample_rate_hz;
    let n_samples = (config.duration_s * config.sample_rate_hz).round() as usize;

    let inclination_rad = config.inclination_deg.to_radians();
    let declination_rad = config.declination_deg.to_radians();
    let horizontal_ut = config.field_total_ut * inclination_rad.cos();
    let earth_field_in_ned_ut = Vector3::new(
        horizontal_ut * declination_rad.cos(),
        horizontal_ut * declination_rad.sin(),
        config.field_total_ut * inclination_rad.sin(),
    );
    let t0_s = config.start_unix_s.unwrap_or(0.0);
    let mut multipath_error_m = Vector2::zeros();
    let hard_iron_ut = Vector3::from(config.hard_iron_ut);
    let scale = Vector3::from(config.scale);
    let [xy, xz, yz] = config.soft_iron_offdiag;
    let soft_iron = (config.soft_iron_offdiag != [0.0; 3]).then(|| {
        nalgebra::Matrix3::new(
            scale.x, xy, xz, //
            xy, scale.y, yz, //
            xz, yz, scale.z,
        )
    });
    let gyro_bias_radps = Vector3::from(config.gyro_bias_radps);
    let step_omega_radps = std::f64::consts::TAU * config.step_frequency_hz;
    let walking_speed_mps = config.step_length_m * config.step_frequency_hz;

    let mut heading_rad = config.start_heading_deg.to_radians();
    let mut position_en_m = Vector2::zeros();
    let mut phase_idx = 0usize;
    let mut phase_start_s = 0.0;
    let mut gait = match config.gait {
        // The sway fades in and out over a second when walking starts and stops.
        Gait::Steady => GaitState::Steady { weight: 0.0 },
        Gait::Varied(variation) => GaitState::Varied(GaitPlan::new(
            &variation,
            &walking_phases(&phases),
            config.duration_s,
            config.seed,
        )),
    };
    let step_boundaries = match &gait {
        GaitState::Steady { .. } => Vec::new(),
        GaitState::Varied(plan) => plan.step_boundaries(),
    };
    let mut step_positions = match &gait {
        GaitState::Steady { .. } => Vec::new(),
        GaitState::Varied(plan) => vec![StepPositions::default(); plan.n_steps()],
    };
    let mut next_boundary_idx = 0usize;
    let mut path_length_m = 0.0;
    let mut rows = Vec::with_capacity(n_samples);
    let gnss_frame = config.gnss.map(|gnss| {
        LocalFrame::at(Geodetic {
            lat_deg: gnss.origin_lat_deg,
            lon_deg: gnss.origin_lon_deg,
            alt_m: 0.0,
        })
    });
    for sample_idx in 0..n_samples {
        let t_s = sample_idx as f64 * dt_s;
        while phase_idx + 1 < phases.len() && t_s >= phase_start_s + phases[phase_idx].duration_s {
            phase_start_s += phases[phase_idx].duration_s;
            phase_idx += 1;
        }
        let phase = phases.get(phase_idx).copied().unwrap_or(Phase {
            duration_s: 0.0,
            is_walking: false,
            turn_rate_radps: 0.0,
        });
        let motion = match &mut gait {
            GaitState::Steady { weight } => {
                let target_weight = if phase.is_walking { 1.0 } else { 0.0 };
                *weight += (target_weight - *weight) * (dt_s / 0.5).min(1.0);
                let gait_phase_rad = step_omega_radps * t_s;
                GaitMotion {
                    weight: *weight,
                    phase_rad: gait_phase_rad,
                    phase_rate_radps: step_omega_radps,
                    down_mps2: *weight * 1.5 * gait_phase_rad.sin(),
                    forward_mps2: *weight * 0.8 * gait_phase_rad.cos(),
                    speed_mps: *weight * walking_speed_mps,
                }
            }
            GaitState::Varied(plan) => plan.motion_at(t_s),
        };
        // A vehicle: the speed alone, no step and no sway.
        let motion = match vehicle_speed_mps {
            Some(speed_mps) => GaitMotion {
                weight: 0.0,
                phase_rad: 0.0,
                phase_rate_radps: 0.0,
                down_mps2: 0.0,
                forward_mps2: 0.0,
                speed_mps,
            },
            None => motion,
        };
        let gait_phase_rad = motion.phase_rad;

        // Attitude and its rate (for the gyroscope).
        let sway_pitch_rad = motion.weight * config.sway_pitch_deg.to_radians();
        let sway_roll_rad = motion.weight * config.sway_roll_deg.to_radians();
        let pitch_rad = config.mean_pitch_deg.to_radians() + sway_pitch_rad * gait_phase_rad.sin();
        let roll_rad =
            config.mean_roll_deg.to_radians() + sway_roll_rad * (gait_phase_rad / 2.0).sin();
        let pitch_rate_radps = sway_pitch_rad * motion.phase_rate_radps * gait_phase_rad.cos();
        let roll_rate_radps =
            sway_roll_rad * motion.phase_rate_radps / 2.0 * (gait_phase_rad / 2.0).cos();
        let yaw_rate_radps = phase.turn_rate_radps;
        // The device faces the walking direction plus the misalignment.
        let device_heading_rad = heading_rad + config.misalignment_deg.to_radians();
        let ned_from_body = Rotation3::from_euler_angles(roll_rad, pitch_rad, device_heading_rad);
        let body_from_ned = ned_from_body.inverse();

        // Specific force: body acceleration minus gravity (NED, down positive).
        let bounce_mps2 = motion.down_mps2;
        let surge_mps2 = motion.forward_mps2;
        // A vehicle in a turn feels v·ω towards the turn's centre (to the right when
        // turning clockwise); a walker's is too small to matter and is left out.
        let centripetal_mps2 = match vehicle_speed_mps {
            Some(speed_mps) => speed_mps * phase.turn_rate_radps,
            None => 0.0,
        };
        let acc_in_ned_mps2 = Vector3::new(
            surge_mps2 * heading_rad.cos() - centripetal_mps2 * heading_rad.sin(),
            surge_mps2 * heading_rad.sin() + centripetal_mps2 * heading_rad.cos(),
            bounce_mps2,
        );
        let f_in_ned_mps2 = acc_in_ned_mps2 - Vector3::new(0.0, 0.0, G_MPS2);
        let f_in_body_mps2 =
            body_from_ned * f_in_ned_mps2 + noise3(&mut rng, config.acc_noise_mps2);

        // Body rates of a yaw-pitch-roll motion.
        let (sin_roll, cos_roll) = roll_rad.sin_cos();
        let (sin_pitch, cos_pitch) = pitch_rad.sin_cos();
        let rate_in_body_radps = Vector3::new(
            roll_rate_radps - yaw_rate_radps * sin_pitch,
            pitch_rate_radps * cos_roll + yaw_rate_radps * sin_roll * cos_pitch,
            -pitch_rate_radps * sin_roll + yaw_rate_radps * cos_roll * cos_pitch,
        );
        let gyro_radps =
            rate_in_body_radps + gyro_bias_radps + noise3(&mut rng, config.gyro_noise_radps);

        let temp_c = if config.temp_swing_c > 0.0 {
            22.0 + config.temp_swing_c
                * (std::f64::consts::TAU * t_s / config.temp_period_s.max(1.0)).sin()
        } else {
            22.0 + 3.0 * t_s / config.duration_s.max(1.0)
        };
        let field_in_ned_ut = earth_field_in_ned_ut
            + config
                .disturbance
                .map_or_else(Vector3::zeros, |disturbance| disturbance.field_ned_ut(t_s));
        let mag_ut = match config.deviation_deg {
            Some(coefficients_deg) => {
                // Turn the sensed field so that the level heading reads ψ' with
                // ψ = ψ' + δ(ψ'): the sensed field's azimuth is δ(ψ').
                let deviation_rad = deviation_of(device_heading_rad, &coefficients_deg);
                let turned =
                    Rotation3::from_axis_angle(&Vector3::z_axis(), deviation_rad) * field_in_ned_ut;
                body_from_ned * turned + noise3(&mut rng, config.mag_noise_ut)
            }
            None => {
                let drift_ut =
                    Vector3::from(config.hard_iron_temp_coeff_ut_per_c) * (temp_c - 22.0);
                let field_in_body_ut = body_from_ned * field_in_ned_ut;
                // A diagonal S is applied axis by axis (the committed logs' arithmetic).
                soft_iron.map_or_else(
                    || field_in_body_ut.component_mul(&scale),
                    |soft_iron| soft_iron * field_in_body_ut,
                ) + hard_iron_ut
                    + drift_ut
                    + noise3(&mut rng, config.mag_noise_ut)
            }
        };

        rows.push(CanonicalRow {
            t_s: t0_s + t_s,
            acc_mps2: Some(f_in_body_mps2),
            gyro_radps: Some(gyro_radps),
            mag_ut: Some(mag_ut),
            temp_c: Some(temp_c),
            ref_heading_deg: Some(wrap_to_2pi(device_heading_rad).to_degrees()),
            ref_en_m: Some(position_en_m),
            ..CanonicalRow::default()
        });
        if let (Some(gnss), Some(frame), Some(row)) =
            (config.gnss, gnss_frame.as_ref(), rows.last_mut())
        {
            let every = (config.sample_rate_hz / gnss.rate_hz).round().max(1.0) as usize;
            let in_outage = gnss
                .outage_s
                .is_some_and(|(start_s, end_s)| (start_s..end_s).contains(&t_s));
            let multipath = gnss
                .multipath
                .filter(|multipath| (multipath.start_s..multipath.end_s).contains(&t_s));
            if sample_idx % every == 0 && !in_outage {
                let fix_dt_s = every as f64 * dt_s;
                // The multipath error wanders (first order, 10 s), and is gone after.
                multipath_error_m = match multipath {
                    Some(multipath) => {
                        let keep = (-fix_dt_s / 10.0).exp();
                        let drive = multipath.error_m * (1.0 - keep * keep).sqrt();
                        multipath_error_m * keep
                            + Vector2::new(rng.gaussian(), rng.gaussian()) * drive
                    }
                    None => Vector2::zeros(),
                };
                let noisy_en_m = position_en_m
                    + multipath_error_m
                    + Vector2::new(rng.gaussian(), rng.gaussian()) * gnss.position_noise_m;
                let position = frame.geodetic_of(Vector3::new(noisy_en_m.x, noisy_en_m.y, 0.0));
                let speed_mps = motion.speed_mps;
                row.lat_deg = Some(position.lat_deg);
                row.lon_deg = Some(position.lon_deg);
                row.gps_hacc_m = Some(multipath.map_or(gnss.hacc_m, |multipath| multipath.hacc_m));
                row.gps_speed_mps = Some(speed_mps + 0.05 * rng.gaussian());
                // A receiver's course follows the velocity: the walking direction.
                let course_noise_deg =
                    gnss.course_noise_deg * if multipath.is_some() { 3.0 } else { 1.0 };
                row.gps_course_deg = Some(
                    wrap_to_2pi(heading_rad + course_noise_deg.to_radians() * rng.gaussian())
                        .to_degrees(),
                );
            }
        }

        // Advance the truth to the next sample.
        heading_rad += yaw_rate_radps * dt_s;
        let direction_en = Vector2::new(heading_rad.sin(), heading_rad.cos());
        match &gait {
            GaitState::Steady { .. } => {
                let speed_mps = motion.speed_mps;
                position_en_m += direction_en * speed_mps * dt_s;
                path_length_m += speed_mps * dt_s;
            }
            GaitState::Varied(plan) => {
                // The position moves by the exact integral of the speed, so that the
                // steps (which start and end between samples) add up to the path. A
                // step boundary within this interval is where the path has moved by
                // the distance walked up to it.
                let t_next_s = (sample_idx + 1) as f64 * dt_s;
                let distance_now_m = plan.distance_at(t_s);
                while let Some(boundary) = step_boundaries.get(next_boundary_idx) {
                    if boundary.t_s >= t_next_s {
                        break;
                    }
                    let at_boundary_en_m = position_en_m
                        + direction_en * (plan.distance_at(boundary.t_s) - distance_now_m);
                    let at_boundary = Some([at_boundary_en_m.x, at_boundary_en_m.y]);
                    if let Some(positions) = step_positions.get_mut(boundary.step_idx) {
                        if boundary.is_start {
                            positions.start_en_m = at_boundary;
                        } else {
                            positions.end_en_m = at_boundary;
                        }
                    }
                    next_boundary_idx += 1;
                }
                let advance_m = plan.distance_at(t_next_s) - distance_now_m;
                position_en_m += direction_en * advance_m;
                path_length_m += advance_m;
            }
        }
    }
    let steps = match &gait {
        GaitState::Steady { .. } => Vec::new(),
        GaitState::Varied(plan) => plan.truth(&step_positions),
    };
    let truth = WalkTruth {
        path_length_m,
        steps,
    };
    (rows, truth)
}

/// δ(ψ') for a true heading ψ: solves ψ = ψ' + δ(ψ') by Newton's method (δ' > −1 for
/// any deviation a compass can have, so the root is unique).
fn deviation_of(true_heading_rad: f64, coefficients_deg: &[f64; 5]) -> f64 {
    let [a, b, c, d, e] = coefficients_deg.map(f64::to_radians);
    let delta = |raw: f64| {
        a + b * raw.sin() + c * raw.cos() + d * (2.0 * raw).sin() + e * (2.0 * raw).cos()
    };
    let slope = |raw: f64| {
        b * raw.cos() - c * raw.sin() + 2.0 * d * (2.0 * raw).cos() - 2.0 * e * (2.0 * raw).sin()
    };
    let mut raw_rad = true_heading_rad - a;
    for _ in 0..30 {
        let residual = raw_rad + delta(raw_rad) - true_heading_rad;
        let derivative = 1.0 + slope(raw_rad);
        if derivative.abs() < 1e-6 {
            break;
        }
        raw_rad -= residual / derivative;
        if residual.abs() < 1e-13 {
            break;
        }
    }
    delta(raw_rad)
}

fn noise3(rng: &mut SplitMix64, sigma: f64) -> Vector3<f64> {
    Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * sigma
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::analyse_file;
    use crate::calibration::{CalibrationOptions, Method, MethodParameters};
    use crate::io::canonical_csv;

    #[test]
    fn the_demo_config_writes_the_committed_demo_byte_for_byte() {
        let committed = include_str!("../../assets/demo-walk.csv");
        let config = WalkConfig::demo(1, 240.0, 50.0);
        let (rows, truth) = simulate_with_truth(&config);
        assert!(
            canonical_csv::write(&rows) == committed,
            "WalkConfig::demo no longer writes assets/demo-walk.csv: regenerate it with the command in docs/development.md"
        );
        assert!(truth.steps.len() > 300);
        // Dated, placed, with the WMM's field there.
        assert_eq!(config.start_unix_s, Some(1_778_776_200.0));
        assert!((config.declination_deg - 15.0).abs() < 1.0, "{config:?}");
    }

    /// A level, still-handed walk with a perfect sensor, for the field's geometry.
    fn ideal(config: WalkConfig) -> WalkConfig {
        WalkConfig {
            hard_iron_ut: [0.0; 3],
            scale: [1.0; 3],
            mag_noise_ut: 0.0,
            mean_pitch_deg: 0.0,
            mean_roll_deg: 0.0,
            sway_pitch_deg: 0.0,
            sway_roll_deg: 0.0,
            ..config
        }
    }

    #[test]
    fn the_compass_points_to_magnetic_north_the_declination_east_of_true_north() {
        let config = ideal(WalkConfig::from_seed(5, 60.0))
            .at_place(47.6062, -122.3321, 1_778_776_200.0)
            .expect("inside the model");
        let expected = crate::calib::wmm::expected_field(
            47.6062,
            -122.3321,
            0.0,
            crate::calib::wmm::CalendarDate::new(2026, 5, 14).expect("a date"),
        )
        .expect("inside the model");
        assert_eq!(config.declination_deg, expected.declination_deg);
        let rows = simulate(&config);
        assert_eq!(rows.first().map(|row| row.t_s), Some(1_778_776_200.0));
        for row in rows.iter().step_by(97) {
            let (Some(mag), Some(true_heading_deg)) = (row.mag_ut, row.ref_heading_deg) else {
                panic!("a full row");
            };
            // Level: the magnetic heading is atan2(−m_y, m_x); true = magnetic + D.
            let magnetic_deg = (-mag.y).atan2(mag.x).to_degrees();
            let error_deg = crate::angle::wrap_to_pi(
                (magnetic_deg + config.declination_deg - true_heading_deg).to_radians(),
            )
            .to_degrees();
            assert!(error_deg.abs() < 1e-6, "{error_deg}° at {}", row.t_s);
            assert!((mag.norm() - expected.total_ut).abs() < 1e-6);
        }
    }

    #[test]
    fn gnss_outages_have_no_fix_and_multipath_strays_with_an_optimistic_accuracy() {
        let config = WalkConfig::demo(2, 240.0, 50.0);
        let Some(gnss) = config.gnss else {
            panic!("the demo has GNSS")
        };
        let (Some((outage_start_s, outage_end_s)), Some(multipath)) =
            (gnss.outage_s, gnss.multipath)
        else {
            panic!("an outage and multipath: {gnss:?}")
        };
        let frame = LocalFrame::at(Geodetic {
            lat_deg: gnss.origin_lat_deg,
            lon_deg: gnss.origin_lon_deg,
            alt_m: 0.0,
        });
        let t0_s = config.start_unix_s.unwrap_or(0.0);
        let (mut clean_m2, mut n_clean, mut stray_m2, mut n_stray) = (0.0, 0, 0.0, 0);
        for row in simulate(&config) {
            let t_s = row.t_s - t0_s;
            let (Some(lat_deg), Some(lon_deg), Some(truth)) =
                (row.lat_deg, row.lon_deg, row.ref_en_m)
            else {
                continue;
            };
            assert!(
                !(outage_start_s..outage_end_s).contains(&t_s),
                "a fix at {t_s} s"
            );
            let error_m2 = (frame.en_of(lat_deg, lon_deg) - truth).norm_squared();
            if (multipath.start_s..multipath.end_s).contains(&t_s) {
                assert_eq!(row.gps_hacc_m, Some(multipath.hacc_m));
                stray_m2 += error_m2;
                n_stray += 1;
            } else {
                assert_eq!(row.gps_hacc_m, Some(gnss.hacc_m));
                clean_m2 += error_m2;
                n_clean += 1;
            }
        }
        assert_eq!(n_stray, 15);
        let (clean_rms_m, stray_rms_m) = (
            (clean_m2 / n_clean as f64).sqrt(),
            (stray_m2 / n_stray as f64).sqrt(),
        );
        // 3 m per axis is 4.2 m of horizontal RMS; multipath adds about 12 m per axis.
        assert!((3.0..5.5).contains(&clean_rms_m), "{clean_rms_m}");
        assert!(
            stray_rms_m > 2.0 * clean_rms_m,
            "{stray_rms_m} vs {clean_rms_m}"
        );
    }

    #[test]
    fn the_paper_raw_case_is_wrong_by_about_12_plus_or_minus_30_degrees() {
        let config = WalkConfig::paper_raw_case(3, 600.0);
        assert_eq!(config.route, Route::Turntable { period_s: 60.0 });
        let analysis = analyse_file(
            "paper.csv",
            canonical_csv::write(&simulate(&config)).as_bytes(),
            &CalibrationOptions::default(),
        )
        .expect("the walk analyses");
        let Some(raw) = analysis.report.raw_heading_error_train else {
            panic!("a raw heading error on the train part");
        };
        // The paper's (12 ± 30)°: the unknown declination in the mean, the hard iron in
        // the spread (scale factors and noise move it a little).
        assert!((raw.mean_deg - 12.0).abs() < 1.0, "{raw:?}");
        assert!((raw.std_deg - 30.0).abs() < 2.0, "{raw:?}");
        // Min/max undoes the hard iron (the paper's (0.4 ± 3)° on training data); the
        // unknown declination stays.
        let min_max = analysis
            .report
            .method(Method::MinMax)
            .and_then(|method| method.heading_error_train)
            .expect("min/max fitted");
        assert!(
            (min_max.mean_deg - 12.0).abs() < 1.0 && min_max.std_deg < 3.0,
            "{min_max:?}"
        );
    }

    #[test]
    fn soft_iron_off_the_diagonal_is_what_the_level_ellipse_fit_removes() {
        // S with cross terms in the level plane: min/max (centre and axis scales only)
        // cannot undo them, the ellipse fit (a general conic) can.
        let config = WalkConfig {
            soft_iron_offdiag: [0.12, 0.0, 0.0],
            ..WalkConfig::from_seed(5, 300.0)
        };
        let analysis = analyse_file(
            "soft.csv",
            canonical_csv::write(&simulate(&config)).as_bytes(),
            &CalibrationOptions::default(),
        )
        .expect("the walk analyses");
        let check_rms = |method: Method| {
            analysis
                .report
                .method(method)
                .and_then(|result| result.heading_error_check)
                .map_or(f64::NAN, |stats| stats.rms_deg)
        };
        let (min_max, ellipse) = (check_rms(Method::MinMax), check_rms(Method::Ellipse));
        assert!(
            ellipse < 3.0 && min_max > ellipse + 2.0,
            "min/max {min_max}°, ellipse {ellipse}°"
        );
    }

    #[test]
    fn iron_near_the_path_changes_the_field_only_while_passing() {
        let base = ideal(WalkConfig::from_seed(5, 60.0));
        let disturbed = WalkConfig {
            disturbance: Some(Disturbance {
                start_s: 20.0,
                end_s: 28.0,
                peak_ned_ut: [-5.0, 4.0, 3.0],
            }),
            ..base.clone()
        };
        let (quiet, passing) = (simulate(&base), simulate(&disturbed));
        let mut largest_ut: f64 = 0.0;
        for (quiet, passing) in quiet.iter().zip(&passing) {
            let change_ut =
                (passing.mag_ut.unwrap_or_default() - quiet.mag_ut.unwrap_or_default()).norm();
            if (20.0..=28.0).contains(&quiet.t_s) {
                largest_ut = largest_ut.max(change_ut);
            } else {
                assert!(change_ut < 1e-12, "{change_ut} µT at {} s", quiet.t_s);
            }
        }
        // The peak, |(−5, 4, 3)| µT, at the middle of the passage.
        assert!((largest_ut - 50f64.sqrt()).abs() < 0.01, "{largest_ut}");
    }

    #[cfg(not(target_arch = "wasm32"))]
    #[test]
    fn the_steady_config_json_has_no_gait_and_the_varied_one_says_varied() {
        // The steady walk's truth file is this JSON: it reads as before there was a gait.
        let json = serde_json::to_value(WalkConfig::from_seed(1, 180.0)).expect("serialisable");
        assert!(json.get("gait").is_none(), "{json}");
        assert_eq!(json["step_length_m"], 0.7);
        let json =
            serde_json::to_value(WalkConfig::pdr_walk(1, 180.0, 50.0)).expect("serialisable");
        assert_eq!(json["gait"]["kind"], "varied");
        assert_eq!(json["gait"]["weinberg_k"], 0.48);
    }

    /// The truth speed at each sample: the distance to the next sample over dt.
    fn truth_speeds_mps(rows: &[CanonicalRow]) -> Vec<f64> {
        rows.windows(2)
            .map(|pair| {
                let (Some(from), Some(to)) = (pair[0].ref_en_m, pair[1].ref_en_m) else {
                    return f64::NAN;
                };
                (to - from).norm() / (pair[1].t_s - pair[0].t_s)
            })
            .collect()
    }

    /// The properties every varied walk has, whatever its sample rate.
    fn check_varied_walk(config: &WalkConfig) -> (Vec<CanonicalRow>, WalkTruth) {
        let Gait::Varied(variation) = config.gait else {
            panic!("a varied gait: {config:?}");
        };
        let (rows, truth) = simulate_with_truth(config);
        let steps = &truth.steps;
        assert_eq!(
            rows.len(),
            (config.duration_s * config.sample_rate_hz).round() as usize
        );
        assert!(steps.len() > 100, "{}", steps.len());

        // The steps account for the whole path, and each one's positions for its length.
        let sum_of_lengths_m: f64 = steps.iter().map(|step| step.length_m).sum();
        assert!(
            (sum_of_lengths_m - truth.path_length_m).abs() < 1e-6,
            "{sum_of_lengths_m} vs {}",
            truth.path_length_m
        );
        let path_from_rows_m: f64 = rows
            .windows(2)
            .filter_map(|pair| Some((pair[1].ref_en_m? - pair[0].ref_en_m?).norm()))
            .sum();
        assert!(
            (path_from_rows_m - truth.path_length_m).abs() < 1e-6,
            "{path_from_rows_m} vs {}",
            truth.path_length_m
        );
        let last_position = rows.last().and_then(|row| row.ref_en_m).unwrap_or_default();
        let last_end = steps.last().map(|step| step.end_en_m).unwrap_or_default();
        assert!((last_position - Vector2::from(last_end)).norm() < 1e-9);
        for pair in steps.windows(2) {
            assert!(pair[0].t_end_s <= pair[1].t_start_s + 1e-12);
            if pair[0].t_end_s == pair[1].t_start_s {
                assert_eq!(pair[0].end_en_m, pair[1].start_en_m);
            }
        }
        for step in steps {
            let chord_m = (Vector2::from(step.end_en_m) - Vector2::from(step.start_en_m)).norm();
            // A chord is shorter than the arc only within a turn: by 1 % in the
            // sharpest (180° in 4 s, about 29° per step).
            assert!(
                chord_m <= step.length_m + 1e-9 && chord_m > 0.985 * step.length_m,
                "{step:?}"
            );
            assert!(step.t_start_s > 0.0 && step.t_end_s < config.duration_s);
        }

        // Frequencies and lengths within the configured ranges.
        let [low_hz, high_hz] = variation.frequency_range_hz;
        let (min_hz, max_hz) = (
            low_hz * (1.0 - variation.frequency_jitter),
            high_hz * (1.0 + variation.frequency_jitter),
        );
        let full_length_m = |frequency_hz: f64| {
            variation.length_intercept_m + variation.length_per_frequency_m_s * frequency_hz
        };
        for step in steps {
            assert!(
                (min_hz - 1e-9..=max_hz + 1e-9).contains(&step.frequency_hz),
                "{step:?}"
            );
            let nominal_m = full_length_m(step.frequency_hz);
            // First and last steps of a bout cover 3/4 of a full one.
            assert!(
                step.length_m <= nominal_m * (1.0 + variation.length_jitter) + 1e-9
                    && step.length_m >= 0.75 * nominal_m * (1.0 - variation.length_jitter) - 1e-9,
                "{step:?}"
            );
            let weinberg_mps2 = (step.length_m / variation.weinberg_k).powi(4);
            assert!((step.vertical_peak_to_peak_mps2 - weinberg_mps2).abs() < 1e-9);
        }
        // Speeds: the truth never walks faster than the fastest step, and the GNSS
        // speed follows it (0.05 m/s noise).
        let speeds_mps = truth_speeds_mps(&rows);
        let fastest_mps = max_hz * full_length_m(max_hz) * (1.0 + variation.length_jitter);
        assert!(speeds_mps.iter().all(|speed| *speed <= fastest_mps + 1e-9));
        let mut n_fixes = 0;
        for (row, truth_speed_mps) in rows.iter().zip(&speeds_mps) {
            if let Some(gps_speed_mps) = row.gps_speed_mps {
                n_fixes += 1;
                assert!(
                    (gps_speed_mps - truth_speed_mps).abs() < 0.3,
                    "{gps_speed_mps} vs {truth_speed_mps} at {} s",
                    row.t_s
                );
            }
        }
        if config.gnss.is_some() {
            assert!(n_fixes as f64 >= config.duration_s - 1.0, "{n_fixes}");
        }
        (rows, truth)
    }

    fn describe(truth: &WalkTruth, duration_s: f64) -> String {
        let steps = &truth.steps;
        let range = |values: Vec<f64>| {
            let min = values.iter().copied().fold(f64::INFINITY, f64::min);
            let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            format!("{min:.3}-{max:.3}")
        };
        format!(
            "{} steps in {duration_s} s ({:.1} per minute), {:.1} m; SF {} Hz, SL {} m, Amax-Amin {} m/s²",
            steps.len(),
            steps.len() as f64 * 60.0 / duration_s,
            truth.path_length_m,
            range(steps.iter().map(|step| step.frequency_hz).collect()),
            range(steps.iter().map(|step| step.length_m).collect()),
            range(steps.iter().map(|step| step.vertical_peak_to_peak_mps2).collect()),
        )
    }

    #[test]
    fn the_pdr_walk_has_varied_steps_that_add_up_to_its_path() {
        let config = WalkConfig::pdr_walk(21, 900.0, 50.0);
        let (rows, truth) = check_varied_walk(&config);
        eprintln!("pdr_walk(21, 900 s, 50 Hz): {}", describe(&truth, 900.0));
        let per_minute = truth.steps.len() as f64 * 60.0 / 900.0;
        assert!((85.0..125.0).contains(&per_minute), "{per_minute}");
        // The pace varies from leg to leg.
        let frequencies_hz: Vec<f64> = truth.steps.iter().map(|step| step.frequency_hz).collect();
        let min_hz = frequencies_hz.iter().copied().fold(f64::INFINITY, f64::min);
        let max_hz = frequencies_hz.iter().copied().fold(0.0, f64::max);
        assert!(min_hz < 1.6 && max_hz > 2.0, "{min_hz}-{max_hz}");
        let gps_speeds_mps: Vec<f64> = rows.iter().filter_map(|row| row.gps_speed_mps).collect();
        let fast = gps_speeds_mps.iter().filter(|speed| **speed > 1.4).count();
        let slow = gps_speeds_mps
            .iter()
            .filter(|speed| (0.5..1.1).contains(*speed))
            .count();
        assert!(fast > 30 && slow > 30, "{fast} fast and {slow} slow fixes");
        // The compass deviates by the unified model; the GNSS fixes carry 3 m noise.
        assert!(config.deviation_deg.is_some());
        assert_eq!(config.gnss.map(|gnss| gnss.position_noise_m), Some(3.0));
    }

    #[test]
    fn the_varied_gait_works_at_100_hz_with_the_same_steps() {
        let (_, truth_50) = check_varied_walk(&WalkConfig::pdr_walk(5, 300.0, 50.0));
        let (rows_100, truth_100) = check_varied_walk(&WalkConfig::pdr_walk(5, 300.0, 100.0));
        eprintln!(
            "pdr_walk(5, 300 s, 100 Hz): {}",
            describe(&truth_100, 300.0)
        );
        assert_eq!(rows_100.len(), 30_000);
        // The steps do not depend on the sample rate; the path, by a hair (the heading
        // is integrated per sample in turns).
        assert_eq!(truth_50.steps.len(), truth_100.steps.len());
        for (step_50, step_100) in truth_50.steps.iter().zip(&truth_100.steps) {
            assert_eq!(step_50.t_start_s, step_100.t_start_s);
            assert_eq!(step_50.length_m, step_100.length_m);
            assert!((step_50.heading_rad - step_100.heading_rad).abs() < 0.02);
        }
    }

    /// Amax − Amin of `values` over the samples of each step.
    fn peak_to_peak_per_step(
        rows: &[CanonicalRow],
        steps: &[StepTruth],
        value: impl Fn(&CanonicalRow) -> f64,
    ) -> Vec<f64> {
        steps
            .iter()
            .map(|step| {
                let in_step = rows
                    .iter()
                    .filter(|row| (step.t_start_s..step.t_end_s).contains(&row.t_s))
                    .map(&value);
                let (min, max) = in_step
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(min, max), v| {
                        (min.min(v), max.max(v))
                    });
                max - min
            })
            .collect()
    }

    #[test]
    fn the_vertical_specific_force_follows_weinberg_step_by_step() {
        // A level, noise-free device: acc_z is the vertical specific force.
        for sample_rate_hz in [50.0, 100.0] {
            let config = WalkConfig {
                acc_noise_mps2: 0.0,
                mean_pitch_deg: 0.0,
                mean_roll_deg: 0.0,
                sway_pitch_deg: 0.0,
                sway_roll_deg: 0.0,
                ..WalkConfig::pdr_walk(8, 240.0, sample_rate_hz)
            };
            let Gait::Varied(variation) = config.gait else {
                panic!("varied");
            };
            let (rows, truth) = simulate_with_truth(&config);
            let measured = peak_to_peak_per_step(&rows, &truth.steps, |row| {
                row.acc_mps2.unwrap_or_default().z
            });
            let mut worst: f64 = 0.0;
            for (step, peak_to_peak_mps2) in truth.steps.iter().zip(measured) {
                let weinberg_mps2 = (step.length_m / variation.weinberg_k).powi(4);
                let ratio = peak_to_peak_mps2 / weinberg_mps2;
                worst = worst.max((ratio - 1.0).abs());
                // Sampling misses the very top of the peaks by a little (csv rounding
                // to 1e-4 m/s² is below that).
                assert!(
                    (0.97..=1.0 + 1e-3).contains(&ratio),
                    "{step:?}: {peak_to_peak_mps2}"
                );
            }
            eprintln!(
                "{sample_rate_hz} Hz: sampled Amax-Amin within {:.2} % of (SL/K)^4",
                100.0 * worst
            );
        }
    }

    #[test]
    fn weinberg_fitted_on_the_noisy_accelerometer_magnitude_gives_back_k() {
        let config = WalkConfig::pdr_walk(13, 300.0, 50.0);
        let (rows, truth) = simulate_with_truth(&config);
        let measured = peak_to_peak_per_step(&rows, &truth.steps, |row| {
            row.acc_mps2.unwrap_or_default().norm()
        });
        // K = SL / (Amax − Amin)^(1/4), step by step.
        let mut k_per_step: Vec<f64> = truth
            .steps
            .iter()
            .zip(&measured)
            .map(|(step, peak_to_peak_mps2)| step.length_m / peak_to_peak_mps2.powf(0.25))
            .collect();
        k_per_step.sort_by(f64::total_cmp);
        let median_k = k_per_step[k_per_step.len() / 2];
        let (low_k, high_k) = (k_per_step[0], k_per_step[k_per_step.len() - 1]);
        eprintln!("K from |acc|: median {median_k:.4}, range {low_k:.4}-{high_k:.4}");
        assert!((median_k - 0.48).abs() < 0.01, "{median_k}");
        assert!(low_k > 0.45 && high_k < 0.5, "{low_k}-{high_k}");
    }

    #[test]
    fn the_same_seed_gives_the_same_log() {
        let config = WalkConfig::from_seed(3, 20.0);
        assert_eq!(simulate(&config), simulate(&config));
        assert_ne!(simulate(&config), simulate(&WalkConfig::from_seed(4, 20.0)));
    }

    #[test]
    fn the_walk_has_the_requested_length_and_a_level_rest_reading() {
        let config = WalkConfig::from_seed(1, 60.0);
        let rows = simulate(&config);
        assert_eq!(rows.len(), 3000);
        let first_acc = rows[0].acc_mps2.unwrap_or_default();
        assert!((first_acc.norm() - G_MPS2).abs() < 0.3, "{first_acc:?}");
        assert!(
            first_acc.z < -9.0,
            "a nearly level device reads z ≈ −g: {first_acc:?}"
        );
    }

    #[test]
    fn minmax_recovers_the_simulated_heading() {
        let config = WalkConfig::from_seed(11, 120.0);
        let text = canonical_csv::write(&simulate(&config));
        let analysis = analyse_file("sim.csv", text.as_bytes(), &CalibrationOptions::default())
            .expect("analysable");
        let report = &analysis.report;
        let raw = report.raw_heading_error_check.expect("reference present");
        let min_max = report.method(Method::MinMax).expect("min/max ran");
        let after = min_max.heading_error_check.expect("reference present");
        assert!(raw.rms_deg > 10.0, "{raw:?}");
        assert!(after.rms_deg < 3.0, "{after:?}");
        // The level-plane centre is the hard iron's horizontal part, tilted slightly.
        let Some(MethodParameters::MinMax(calibration)) = &min_max.parameters else {
            panic!("min/max parameters: {min_max:?}");
        };
        let hard_iron_ut = config.hard_iron_ut;
        assert!(
            (calibration.center_x_ut - hard_iron_ut[0]).abs() < 6.0,
            "{calibration:?} vs {hard_iron_ut:?}"
        );
        assert!(
            (calibration.center_y_ut - hard_iron_ut[1]).abs() < 6.0,
            "{calibration:?} vs {hard_iron_ut:?}"
        );
    }
}
