//! The scenario of a simulated walk: [`WalkConfig`] (the phone's distortions, the
//! Earth's field, the gait, the GNSS receiver, iron near the path, the route) and its
//! named walks (`from_seed`, `turntable`, `vehicle_loop`, `paper_raw_case`, `demo`,
//! `pdr_walk`).

use nalgebra::Vector3;
use serde::Serialize;

use crate::base::rng::SplitMix64;
use crate::sim::gait::{Gait, GaitVariation};

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

    /// A vehicle's steady speed; `None` for a walk or a turntable.
    pub(super) fn vehicle_speed_mps(&self) -> Option<f64> {
        match self {
            Route::VehicleLoop { speed_mps, .. } => Some(*speed_mps),
            Route::Walk | Route::Turntable { .. } => None,
        }
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
    ) -> Result<WalkConfig, crate::earth::wmm::WmmError> {
        let date = crate::earth::wmm::date_of_unix_s(start_unix_s).ok_or_else(|| {
            crate::earth::wmm::WmmError::UnreadableDate {
                text: format!("{start_unix_s} s after 1970"),
            }
        })?;
        let field = crate::earth::wmm::expected_field(lat_deg, lon_deg, 0.0, date)?;
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

    /// The PDR scenario: the walk of [`WalkConfig::from_seed`] at
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
