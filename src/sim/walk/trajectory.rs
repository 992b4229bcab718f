//! The true motion of a simulated walk: the route's phases (stops, legs, turns; a
//! turntable's turning; a car's octagonal loop), the gait at each sample (steady or
//! varied), and the heading, position and step truth advanced from sample to sample.

use nalgebra::Vector2;

use super::{Route, WalkConfig, WalkTruth};
use crate::base::rng::SplitMix64;
use crate::sim::gait::{Gait, GaitMotion, GaitPlan, StepBoundary, StepPositions};

/// One phase of the walk: how long, whether walking, and the turn rate.
#[derive(Debug, Clone, Copy)]
pub(super) struct Phase {
    pub(super) duration_s: f64,
    pub(super) is_walking: bool,
    pub(super) turn_rate_radps: f64,
}

/// The phases of the configured route. A walk's are drawn from `rng` (the walk's own
/// stream, before any sensor noise).
pub(super) fn route_phases(config: &WalkConfig, rng: &mut SplitMix64) -> Vec<Phase> {
    match config.route {
        Route::Walk => plan_route(config, rng),
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
    }
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

/// One sample's instant and the truth there: what the sensors and the receiver see.
#[derive(Debug, Clone, Copy)]
pub(super) struct Sample {
    pub(super) idx: usize,
    pub(super) t_s: f64,
    pub(super) dt_s: f64,
    pub(super) phase: Phase,
    pub(super) motion: GaitMotion,
    /// The walking direction, clockwise from true north.
    pub(super) heading_rad: f64,
    pub(super) position_en_m: Vector2<f64>,
}

/// The true state of the walk, advanced sample by sample.
pub(super) struct Trajectory {
    phases: Vec<Phase>,
    phase_idx: usize,
    phase_start_s: f64,
    gait: GaitState,
    vehicle_speed_mps: Option<f64>,
    /// The steady gait's step rate (rad/s) and speed.
    step_omega_radps: f64,
    walking_speed_mps: f64,
    heading_rad: f64,
    position_en_m: Vector2<f64>,
    path_length_m: f64,
    /// The varied gait's step starts and ends, in time order, the next one to pass, and
    /// the positions found for them.
    step_boundaries: Vec<StepBoundary>,
    next_boundary_idx: usize,
    step_positions: Vec<StepPositions>,
}

impl Trajectory {
    pub(super) fn new(config: &WalkConfig, phases: Vec<Phase>) -> Trajectory {
        let gait = match config.gait {
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
        let step_positions = match &gait {
            GaitState::Steady { .. } => Vec::new(),
            GaitState::Varied(plan) => vec![StepPositions::default(); plan.n_steps()],
        };
        Trajectory {
            phases,
            phase_idx: 0,
            phase_start_s: 0.0,
            gait,
            vehicle_speed_mps: config.route.vehicle_speed_mps(),
            step_omega_radps: std::f64::consts::TAU * config.step_frequency_hz,
            walking_speed_mps: config.step_length_m * config.step_frequency_hz,
            heading_rad: config.start_heading_deg.to_radians(),
            position_en_m: Vector2::zeros(),
            path_length_m: 0.0,
            step_boundaries,
            next_boundary_idx: 0,
            step_positions,
        }
    }

    /// The sample `idx` (at `idx·dt_s`): its phase of the route, the gait's motion
    /// there (a vehicle's speed alone), and the true heading and position.
    pub(super) fn sample(&mut self, idx: usize, dt_s: f64) -> Sample {
        let t_s = idx as f64 * dt_s;
        let phases = &self.phases;
        while self.phase_idx + 1 < phases.len()
            && t_s >= self.phase_start_s + phases[self.phase_idx].duration_s
        {
            self.phase_start_s += phases[self.phase_idx].duration_s;
            self.phase_idx += 1;
        }
        let phase = phases.get(self.phase_idx).copied().unwrap_or(Phase {
            duration_s: 0.0,
            is_walking: false,
            turn_rate_radps: 0.0,
        });
        let motion = match &mut self.gait {
            GaitState::Steady { weight } => {
                let target_weight = if phase.is_walking { 1.0 } else { 0.0 };
                *weight += (target_weight - *weight) * (dt_s / 0.5).min(1.0);
                let gait_phase_rad = self.step_omega_radps * t_s;
                GaitMotion {
                    weight: *weight,
                    phase_rad: gait_phase_rad,
                    phase_rate_radps: self.step_omega_radps,
                    down_mps2: *weight * 1.5 * gait_phase_rad.sin(),
                    forward_mps2: *weight * 0.8 * gait_phase_rad.cos(),
                    speed_mps: *weight * self.walking_speed_mps,
                }
            }
            GaitState::Varied(plan) => plan.motion_at(t_s),
        };
        // A vehicle: the speed alone, no step and no sway.
        let motion = match self.vehicle_speed_mps {
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
        Sample {
            idx,
            t_s,
            dt_s,
            phase,
            motion,
            heading_rad: self.heading_rad,
            position_en_m: self.position_en_m,
        }
    }

    /// Advances the truth from `sample` to the next sample.
    pub(super) fn advance(&mut self, sample: &Sample) {
        let dt_s = sample.dt_s;
        self.heading_rad += sample.phase.turn_rate_radps * dt_s;
        let direction_en = Vector2::new(self.heading_rad.sin(), self.heading_rad.cos());
        match &self.gait {
            GaitState::Steady { .. } => {
                let speed_mps = sample.motion.speed_mps;
                self.position_en_m += direction_en * speed_mps * dt_s;
                self.path_length_m += speed_mps * dt_s;
            }
            GaitState::Varied(plan) => {
                // The position moves by the exact integral of the speed, so that the
                // steps (which start and end between samples) add up to the path. A
                // step boundary within this interval is where the path has moved by
                // the distance walked up to it.
                let t_s = sample.t_s;
                let t_next_s = (sample.idx + 1) as f64 * dt_s;
                let distance_now_m = plan.distance_at(t_s);
                while let Some(boundary) = self.step_boundaries.get(self.next_boundary_idx) {
                    if boundary.t_s >= t_next_s {
                        break;
                    }
                    let at_boundary_en_m = self.position_en_m
                        + direction_en * (plan.distance_at(boundary.t_s) - distance_now_m);
                    let at_boundary = Some([at_boundary_en_m.x, at_boundary_en_m.y]);
                    if let Some(positions) = self.step_positions.get_mut(boundary.step_idx) {
                        if boundary.is_start {
                            positions.start_en_m = at_boundary;
                        } else {
                            positions.end_en_m = at_boundary;
                        }
                    }
                    self.next_boundary_idx += 1;
                }
                let advance_m = plan.distance_at(t_next_s) - distance_now_m;
                self.position_en_m += direction_en * advance_m;
                self.path_length_m += advance_m;
            }
        }
    }

    /// The walk's truth once every sample has been simulated.
    pub(super) fn into_truth(self) -> WalkTruth {
        let steps = match &self.gait {
            GaitState::Steady { .. } => Vec::new(),
            GaitState::Varied(plan) => plan.truth(&self.step_positions),
        };
        WalkTruth {
            path_length_m: self.path_length_m,
            steps,
        }
    }
}
