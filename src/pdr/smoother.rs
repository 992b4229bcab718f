//! How a log's walk is fused after the fact: an extended Kalman filter forward over the
//! steps and every GNSS fix, then the Rauch-Tung-Striebel pass backward, so that each
//! position uses the fixes before and after it (Rauch, Tung & Striebel, *Maximum
//! likelihood estimates of linear dynamic systems*, AIAA J. 1965; the extended form as
//! in Särkkä, *Bayesian Filtering and Smoothing*, 2013, Algorithm 9.1).
//!
//! The state extends the PDR paper's `[E, N, l, a]` (Chen et al., Eq. 13) by the errors
//! that are correlated along a walk, so that the stated σ holds where they are:
//!
//! ```text
//! x = [E, N, s, δ, β_E, β_N, a]
//! step k (model length l_k, measured heading h_k):
//!     h_k = a + v_k                    (v_k white: the step's own heading noise)
//!     E += s·l_k·sin(a − δ),   N += s·l_k·cos(a − δ)   (+ white length noise), then a turns
//!     a: the heading as measured, the paper's state, a random walk per step
//!     s: the step model's scale, the paper's l as a scale on the model's lengths: 1
//!        exactly where there are fixes; where there are none, 1 ± σ_s (how well the
//!        step model's training proved it), a slow random walk
//!     δ: the heading's error, first-order Gauss-Markov, time constant τ_δ, stationary σ the
//!        attitude filter's heading σ where it states one (never below a floor)
//! fix j (position z_j, reported accuracy A_j, σ_j = c·A_j / 1.51 per axis):
//!     z_j = [E, N] + β + ε_j,   ε_j white with variance (1 − ρ)·σ_j²
//!     β: the GNSS error that moves slowly (multipath, a building's shadow), metres,
//!        first-order Gauss-Markov with time constant τ_β towards the stationary
//!        variance ρ·σ_j² of the latest fix, which it follows at once (a better accuracy
//!        is a new satellite geometry: the old error is mostly forgotten)
//! ```
//!
//! Why the fixes never teach the scale: a phone's fixes move less than its walker (they
//! lag, and cut the corners of legs as short as their accuracy), so a filter that learnt
//! `s` from them shrank IPIN route 01's walks by up to 15 % (× 0.87 ± 0.045) where the
//! untrained lengths were within 7 % (ACCURACY.md). A step length is learnt only where
//! something proves it (`step_length.rs`), which sets σ_s. With fixes `s` is exact rather
//! than a consider state (a Schmidt filter's covariance does not survive the RTS pass):
//! over a gap of `d` metres its σ_s·d (5 %) adds in quadrature to the heading error's
//! ≥ sin 15°·d, under 2 % of the stated σ.
//!
//! A part of the GNSS error, ρ_c·σ_j², is constant over the walk: no filter can tell it
//! from the position, so it is not a state; it moves the whole track with the fixes and
//! is added to the stated σ.
//!
//! Android's accuracy is the radius of 68 % confidence, 1.51 σ per axis. How far to
//! trust it, `c`, is learnt from the fixes' own innovations (their median normalised
//! innovation squared against χ²₂'s, 1.386), and a fix whose innovation is beyond the χ²
//! gate is down-weighted by it, never dropped (a heavy-tailed measurement model).
//!
//! Frames and units: `E`, `N` metres east and north of the local origin; headings in
//! radians clockwise from true north; times in seconds of log time.

use serde::Serialize;

use super::fusion::{FixInput, FixUse, GnssPolicy, StepInput, TrackPoint};
use crate::base::angle::{wrap_to_2pi, wrap_to_pi};

use super::small_matrix::{Cov, State};
use track::{ConstantError, Walk};

mod track;

const E: usize = 0;
const N: usize = 1;
const S: usize = 2;
const D: usize = 3;
const BE: usize = 4;
const BN: usize = 5;
const A: usize = 6;

/// Per-axis σ over Android's accuracy (the radius of 68 % confidence of a circular
/// normal: √(−2 ln 0.32) = 1.51).
const ACCURACY_PER_SIGMA: f64 = 1.51;
/// Median of χ² with 2 degrees of freedom.
const CHI2_2_MEDIAN: f64 = 1.386;

/// The model's noise (1σ) and time constants.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WalkNoise {
    /// σ of the step-length scale's random walk per step.
    pub scale_walk_per_step: f64,
    /// White noise of one step's length, as a fraction of it.
    pub length_white_fraction: f64,
    /// White noise of one step's measured heading (rad).
    pub heading_white_rad: f64,
    /// How far the walked heading may turn in one step, 1σ of its random walk (rad).
    pub turn_per_step_rad: f64,
    /// The heading error's stationary σ where the heading states none, and the least
    /// taken where it states one (rad): indoors a phone's heading is off by more than
    /// its filter believes.
    pub heading_error_rad: f64,
    pub heading_error_floor_rad: f64,
    pub heading_error_tau_s: f64,
    pub gnss_bias_tau_s: f64,
    /// The share ρ of a fix's error variance that moves slowly.
    pub gnss_bias_share: f64,
    /// The share ρ_c of a fix's error variance that is constant over the walk: added to
    /// the stated σ, never estimated.
    pub gnss_constant_share: f64,
    /// The accuracy taken for a fix that reports none, and the least taken (m).
    pub gnss_default_accuracy_m: f64,
    pub gnss_min_accuracy_m: f64,
    /// χ²₂ beyond which a fix is down-weighted by its normalised innovation (99 %).
    pub robust_gate: f64,
    /// Bounds on the learnt factor `c` on the reported accuracy: never trusted beyond
    /// what it reports (a phone's fixes are smoother than their errors are small, so
    /// their innovations alone would trust them too far).
    pub trust_bounds: [f64; 2],
    /// The start's σ where the fixes place it, in multiples of the first fix's accuracy.
    pub start_accuracy_multiple: f64,
}

impl Default for WalkNoise {
    /// Chosen on route 01 of the IPIN 2023 walks (GNSS of 4-5 m) and checked on routes 21
    /// and 24 (indoors, 11-36 m), the msft walks and the phyphox loop: ACCURACY.md.
    fn default() -> Self {
        WalkNoise {
            scale_walk_per_step: 0.002,
            length_white_fraction: 0.10,
            heading_white_rad: 5f64.to_radians(),
            turn_per_step_rad: 10f64.to_radians(),
            heading_error_rad: 15f64.to_radians(),
            heading_error_floor_rad: 15f64.to_radians(),
            heading_error_tau_s: 20.0,
            gnss_bias_tau_s: 30.0,
            gnss_bias_share: 0.5,
            gnss_constant_share: 0.3,
            gnss_default_accuracy_m: 10.0,
            gnss_min_accuracy_m: 1.5,
            robust_gate: 9.21,
            trust_bounds: [1.0, 4.0],
            start_accuracy_multiple: 3.0,
        }
    }
}

/// Where the walk starts and how well the step model is known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WalkPrior {
    /// Where the walk starts (m) and its 1σ per axis; `None` to take it from the fixes.
    pub start: Option<([f64; 2], f64)>,
    /// 1σ of the step model's scale (0.15 for an untrained default).
    pub scale_sigma: f64,
}

/// The filtered (or smoothed) track and what became of each fix.
#[derive(Debug, Clone, PartialEq)]
pub struct WalkFusion {
    pub track: Vec<TrackPoint>,
    pub fix_use: Vec<FixUse>,
    /// The trust factor `c` learnt for the fixes' reported accuracy.
    pub trust: f64,
    /// The smoothed step-length scale and its 1σ.
    pub scale: (f64, f64),
}

#[derive(Clone, Copy)]
enum Event {
    /// The walk's first point: the state before the first step.
    Start,
    /// Step k's measured heading.
    Heading(usize),
    /// Step k's move.
    Step(usize),
    Fix(usize),
}

/// One event's filter quantities, for the backward pass.
struct Stored {
    x_prior: State,
    p_prior: Cov,
    x_post: State,
    p_post: Cov,
    /// The transition from the previous event's state into this one.
    f: Cov,
}

/// Fuses the steps and fixes (each sorted by time): forward only when `smooth` is
/// false (the causal filter: each point uses what came before it), else forward and
/// backward.
pub fn fuse_walk(
    steps: &[StepInput],
    fixes: &[FixInput],
    prior: WalkPrior,
    noise: WalkNoise,
    policy: &GnssPolicy,
    smooth: bool,
) -> WalkFusion {
    let Some(first) = steps.first() else {
        return WalkFusion {
            track: Vec::new(),
            fix_use: vec![FixUse::BeforeWalk; fixes.len()],
            trust: 1.0,
            scale: (1.0, prior.scale_sigma),
        };
    };
    let floored = super::fix_accuracy::with_neighbourhood_accuracy(fixes);
    let fixes = floored.as_slice();
    let events = events(steps, fixes, first.t_start_s, policy);
    let (prior, noise) = scale_untaught(&events, prior, noise);
    let pass_at = |trust: f64| {
        forward(
            &events,
            (steps, fixes),
            (prior, noise),
            trust,
            policy.reset_after_rejections,
        )
    };
    let trust = learnt_trust(&pass_at, noise.trust_bounds);
    let pass = pass_at(trust);
    let (states, covs): (Vec<State>, Vec<Cov>) = if smooth {
        backward(&pass.stored)
    } else {
        pass.stored.iter().map(|s| (s.x_post, s.p_post)).unzip()
    };

    let walk = Walk {
        events: &events,
        steps,
        fixes,
        start_s: first.t_start_s,
    };
    let constant = ConstantError::of(&events, fixes, trust, noise);
    let track = walk.track(&states, &covs, &constant, &pass.fix_use);
    let fix_use = walk.fix_use(&pass.fix_use, policy);
    let last = states.last().zip(covs.last());
    WalkFusion {
        track,
        fix_use,
        trust,
        scale: last.map_or((1.0, prior.scale_sigma), |(x, p)| {
            (x[S], p[(S, S)].max(0.0).sqrt())
        }),
    }
}

/// The trust in the reported accuracy, from the innovations of the passes `pass_at`
/// makes (three passes converge: each moves c² by the ratio of the median NIS to χ²₂'s),
/// within `bounds`.
fn learnt_trust(pass_at: &impl Fn(f64) -> Pass, bounds: [f64; 2]) -> f64 {
    let mut trust = 1.0f64;
    for _ in 0..3 {
        let pass = pass_at(trust);
        if pass.nis.len() < 5 {
            break;
        }
        let median = crate::base::stats::median(&mut pass.nis.clone()).unwrap_or(CHI2_2_MEDIAN);
        trust = (trust * (median / CHI2_2_MEDIAN).sqrt()).clamp(bounds[0], bounds[1]);
    }
    trust
}

/// The fixes never teach the scale (see the module's doc): where the walk takes fixes it
/// is exact; without any it keeps its prior σ and walk.
fn scale_untaught(events: &[Event], prior: WalkPrior, noise: WalkNoise) -> (WalkPrior, WalkNoise) {
    if !events.iter().any(|event| matches!(event, Event::Fix(_))) {
        return (prior, noise);
    }
    (
        WalkPrior {
            scale_sigma: 0.0,
            ..prior
        },
        WalkNoise {
            scale_walk_per_step: 0.0,
            ..noise
        },
    )
}

/// The steps, the usable fixes and the start, in time order (a fix at a step's end
/// time comes first).
fn events(
    steps: &[StepInput],
    fixes: &[FixInput],
    start_s: f64,
    policy: &GnssPolicy,
) -> Vec<Event> {
    // A fix logged twice (the same position and accuracy within 1.5 s, as
    // GetSensorData does) is one measurement, not two.
    let mut taken: Vec<(f64, Event)> = Vec::with_capacity(fixes.len());
    let mut previous: Option<&FixInput> = None;
    for (j, fix) in fixes.iter().enumerate() {
        if policy.in_outage(fix.t_s) || !fix.en_m.iter().all(|v| v.is_finite()) {
            continue;
        }
        let repeated = previous.is_some_and(|p| repeats(p, fix));
        previous = Some(fix);
        if !repeated {
            taken.push((fix.t_s, Event::Fix(j)));
        }
    }
    let walked = std::iter::once((start_s, Event::Start)).chain(
        steps
            .iter()
            .enumerate()
            .flat_map(|(k, step)| [(step.t_s, Event::Heading(k)), (step.t_s, Event::Step(k))]),
    );
    // Both are in time order: merged, a fix at a step's time comes first.
    let mut out = Vec::with_capacity(taken.len() + 2 * steps.len() + 1);
    let mut fixes_left = taken.into_iter().peekable();
    for (t_s, event) in walked {
        while let Some((_, fix)) = fixes_left.next_if(|(t_fix, _)| *t_fix <= t_s) {
            out.push(fix);
        }
        out.push(event);
    }
    out.extend(fixes_left.map(|(_, fix)| fix));
    out
}

/// Whether `fix` is `earlier` logged again.
fn repeats(earlier: &FixInput, fix: &FixInput) -> bool {
    earlier.en_m == fix.en_m && earlier.hacc_m == fix.hacc_m && fix.t_s - earlier.t_s < 1.5
}

struct Pass {
    stored: Vec<Stored>,
    fix_use: Vec<FixUse>,
    /// Each taken fix's normalised innovation squared, before any down-weighting.
    nis: Vec<f64>,
}

fn event_time(event: Event, steps: &[StepInput], fixes: &[FixInput], start_s: f64) -> f64 {
    match event {
        Event::Start => start_s,
        Event::Heading(k) | Event::Step(k) => steps[k].t_s,
        Event::Fix(j) => fixes[j].t_s,
    }
}

/// The state, its covariance and the transition into the current event, moved by one
/// model equation at a time.
struct Belief {
    x: State,
    p: Cov,
    f: Cov,
}

impl Belief {
    /// `x ← F·x`, `P ← F·P·Fᵀ + Q`, and `F` composed into this event's transition.
    fn transition(&mut self, f: Cov, q: Cov) {
        self.x = f.times(&self.x);
        self.p = f * self.p * f.transpose() + q;
        self.f = f * self.f;
    }

    /// The slow errors decay towards zero over `dt_s` (first-order Gauss-Markov).
    fn decay(&mut self, dt_s: f64, noise: &WalkNoise, heading_error_rad: f64, bias_var_m2: f64) {
        let phi_d = (-dt_s / noise.heading_error_tau_s).exp();
        let phi_b = (-dt_s / noise.gnss_bias_tau_s).exp();
        let mut f = Cov::identity();
        f[(D, D)] = phi_d;
        f[(BE, BE)] = phi_b;
        f[(BN, BN)] = phi_b;
        let mut q = Cov::zeros();
        q[(D, D)] = heading_error_rad.powi(2) * (1.0 - phi_d * phi_d);
        q[(BE, BE)] = bias_var_m2 * (1.0 - phi_b * phi_b);
        q[(BN, BN)] = q[(BE, BE)];
        self.transition(f, q);
    }

    /// One step of `length_m` along `a − δ`, after which the heading may turn.
    fn step(&mut self, length_m: f64, noise: &WalkNoise) {
        let x = self.x;
        let (sin_a, cos_a) = (x[A] - x[D]).sin_cos();
        let d_m = x[S] * length_m;
        let mut f = Cov::identity();
        f[(E, S)] = length_m * sin_a;
        f[(E, A)] = d_m * cos_a;
        f[(E, D)] = -d_m * cos_a;
        f[(N, S)] = length_m * cos_a;
        f[(N, A)] = -d_m * sin_a;
        f[(N, D)] = d_m * sin_a;
        let sl = noise.length_white_fraction * d_m;
        let mut q = Cov::zeros();
        q[(E, E)] = (sin_a * sl).powi(2);
        q[(N, N)] = (cos_a * sl).powi(2);
        q[(E, N)] = sin_a * cos_a * sl * sl;
        q[(N, E)] = q[(E, N)];
        q[(S, S)] = noise.scale_walk_per_step.powi(2);
        q[(A, A)] = noise.turn_per_step_rad.powi(2);
        // The motion is nonlinear: move the mean exactly, the covariance by F.
        self.transition(f, q);
        self.x = x;
        self.x[E] += d_m * sin_a;
        self.x[N] += d_m * cos_a;
    }

    /// The slow GNSS error's variance follows a fix's reported accuracy at once: a
    /// better one is a new satellite geometry, so the old error is mostly forgotten
    /// (`β ← k·β + w`, `k` the ratio of the σs); a worse one adds to it.
    fn follow_accuracy(&mut self, from_m2: f64, to_m2: f64) {
        let mut f = Cov::identity();
        let mut q = Cov::zeros();
        if to_m2 < from_m2 {
            let k = (to_m2 / from_m2).sqrt();
            f[(BE, BE)] = k;
            f[(BN, BN)] = k;
            q[(BE, BE)] = to_m2 * (1.0 - k * k);
        } else {
            q[(BE, BE)] = to_m2 - from_m2;
        }
        q[(BN, BN)] = q[(BE, BE)];
        self.transition(f, q);
    }

    /// The Kalman update of two measurements, rows `h` of `H`, innovation `y` and noise
    /// `r`, in Joseph form. Returns false when `S` is singular.
    fn update(&mut self, h: [State; 2], y: [f64; 2], r: [[f64; 2]; 2]) -> bool {
        let Some((ph, s)) = self.innovation(&h, r) else {
            return false;
        };
        let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
        if det.is_nan() || det.abs() <= 1e-300 {
            return false;
        }
        let s_inv = [
            [s[1][1] / det, -s[0][1] / det],
            [-s[1][0] / det, s[0][0] / det],
        ];
        // K = P·Hᵀ·S⁻¹, two columns.
        let k = [
            ph[0].scaled(s_inv[0][0]) + ph[1].scaled(s_inv[1][0]),
            ph[0].scaled(s_inv[0][1]) + ph[1].scaled(s_inv[1][1]),
        ];
        self.x += k[0].scaled(y[0]) + k[1].scaled(y[1]);
        let i_kh = Cov::identity() - k[0].outer(&h[0]) - k[1].outer(&h[1]);
        let mut krk = Cov::zeros();
        for (a, b) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
            krk = krk + k[a].outer(&k[b]).scaled(r[a][b]);
        }
        self.p = (i_kh * self.p * i_kh.transpose() + krk).symmetric();
        true
    }

    /// `P·Hᵀ` (as two columns) and `S = H·P·Hᵀ + R`.
    fn innovation(&self, h: &[State; 2], r: [[f64; 2]; 2]) -> Option<([State; 2], [[f64; 2]; 2])> {
        let ph = [self.p.times(&h[0]), self.p.times(&h[1])];
        let s = [
            [h[0].dot(&ph[0]) + r[0][0], h[0].dot(&ph[1]) + r[0][1]],
            [h[1].dot(&ph[0]) + r[1][0], h[1].dot(&ph[1]) + r[1][1]],
        ];
        s.iter().flatten().all(|v| v.is_finite()).then_some((ph, s))
    }

    /// `h_k = a + v_k`: `a` is the heading as measured, smoothed; the walk goes along
    /// `a − δ`. (A second, empty row keeps one update for both kinds.)
    fn heading(&mut self, heading_rad: f64, noise: &WalkNoise) {
        let mut h = State::zeros();
        h[A] = 1.0;
        let y = wrap_to_pi(heading_rad - self.x[A]);
        let r = noise.heading_white_rad.powi(2);
        self.update([h, State::zeros()], [y, 0.0], [[r, 0.0], [0.0, 1.0]]);
        self.x[A] = wrap_to_2pi(self.x[A]);
    }

    /// A fix's innovation `y`, its covariance `S` and its normalised square, with the
    /// white part of its noise `R`.
    fn fix_innovation(
        &self,
        fix: &FixInput,
        sigma_m: f64,
        noise: &WalkNoise,
    ) -> Option<FixInnovation> {
        let white_var = sigma_m.powi(2) * (1.0 - noise.gnss_bias_share);
        let h = fix_rows();
        let y = [
            fix.en_m[0] - h[0].dot(&self.x),
            fix.en_m[1] - h[1].dot(&self.x),
        ];
        let r = [[white_var, 0.0], [0.0, white_var]];
        let (_, s) = self.innovation(&h, r)?;
        let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
        let nis = (y[0] * (s[1][1] * y[0] - s[0][1] * y[1])
            + y[1] * (s[0][0] * y[1] - s[1][0] * y[0]))
            / det;
        Some(FixInnovation { h, y, r, s, nis })
    }

    /// The squared distance from the track to a fix when the fix is beyond the gate.
    fn gap_beyond_gate(&self, fix: &FixInput, sigma_m: f64, noise: &WalkNoise) -> Option<f64> {
        let FixInnovation { y, nis, .. } = self.fix_innovation(fix, sigma_m, noise)?;
        (nis > noise.robust_gate).then_some(y[0] * y[0] + y[1] * y[1])
    }

    /// `z = [E, N] + β + ε`. Returns the normalised innovation squared and whether the
    /// fix was down-weighted; `None` when the update could not be made.
    fn fix(&mut self, fix: &FixInput, sigma_m: f64, noise: &WalkNoise) -> Option<(f64, bool)> {
        let FixInnovation {
            h,
            y,
            mut r,
            s,
            nis,
        } = self.fix_innovation(fix, sigma_m, noise)?;
        // Heavy tails: a fix beyond the gate counts as if its whole noise were larger by
        // its own innovation (Huber's weight in the Mahalanobis norm).
        let down_weighted = nis.is_nan() || nis > noise.robust_gate;
        if down_weighted {
            let extra = nis / noise.robust_gate - 1.0;
            for (row, s_row) in r.iter_mut().zip(&s) {
                for (cell, s_cell) in row.iter_mut().zip(s_row) {
                    *cell += s_cell * extra;
                }
            }
        }
        self.update(h, y, r).then_some((nis, down_weighted))
    }
}

/// What a fix would do to the track, before it does.
struct FixInnovation {
    h: [State; 2],
    y: [f64; 2],
    r: [[f64; 2]; 2],
    s: [[f64; 2]; 2],
    nis: f64,
}

/// The rows of `H` for a fix: `E + β_E`, `N + β_N`.
fn fix_rows() -> [State; 2] {
    let mut h = [State::zeros(), State::zeros()];
    h[0][E] = 1.0;
    h[0][BE] = 1.0;
    h[1][N] = 1.0;
    h[1][BN] = 1.0;
    h
}

fn forward(
    events: &[Event],
    (steps, fixes): (&[StepInput], &[FixInput]),
    (prior, noise): (WalkPrior, WalkNoise),
    trust: f64,
    reset_after: usize,
) -> Pass {
    let start_s = steps.first().map_or(0.0, |step| step.t_start_s);
    let (x, p) = initial(events, steps, fixes, prior, noise, trust);
    let mut belief = Belief {
        x,
        p,
        f: Cov::identity(),
    };
    let mut t_prev = events
        .first()
        .map_or(start_s, |&event| event_time(event, steps, fixes, start_s));
    let mut stored = Vec::with_capacity(events.len());
    let mut fix_use = vec![FixUse::AfterWalk; fixes.len()];
    let mut nis_all = Vec::new();
    // The heading error's stationary σ (the latest step's stated one), and the GNSS
    // slow error's stationary variance (m², the latest fix's).
    let mut heading_error_rad = noise.heading_error_rad;
    let mut bias_var_m2 = belief.p[(BE, BE)];
    let mut rejected_in_row = 0usize;
    for &event in events {
        let t_s = event_time(event, steps, fixes, start_s);
        belief.f = Cov::identity();
        let mut reset = false;
        if let Event::Heading(k) = event {
            if let Some(sigma) = steps[k]
                .heading_sigma_rad
                .filter(|sigma| sigma.is_finite() && *sigma > 0.0)
            {
                heading_error_rad = sigma.max(noise.heading_error_floor_rad);
            }
        }
        belief.decay(
            (t_s - t_prev).max(0.0),
            &noise,
            heading_error_rad,
            bias_var_m2,
        );
        t_prev = t_s;
        let fix_sigma_m = |j: usize| trust * fix_accuracy_m(&fixes[j], noise) / ACCURACY_PER_SIGMA;
        match event {
            Event::Step(k) => belief.step(steps[k].length_m.max(0.0), &noise),
            Event::Fix(j) => {
                let target_m2 = fix_sigma_m(j).powi(2) * noise.gnss_bias_share;
                belief.follow_accuracy(bias_var_m2, target_m2);
                bias_var_m2 = target_m2;
                // As the paper's switching does: after `reset_after` fixes in a row
                // beyond the gate, the track is what is in doubt (a vehicle, a long
                // drift), so its position widens to take the fix.
                if rejected_in_row + 1 >= reset_after.max(1) {
                    if let Some(gap_m2) = belief.gap_beyond_gate(&fixes[j], fix_sigma_m(j), &noise)
                    {
                        let mut q = Cov::zeros();
                        q[(E, E)] = gap_m2;
                        q[(N, N)] = gap_m2;
                        belief.transition(Cov::identity(), q);
                        reset = true;
                    }
                }
            }
            Event::Start | Event::Heading(_) => {}
        }
        let (x_prior, p_prior) = (belief.x, belief.p);
        match event {
            Event::Heading(k) => belief.heading(steps[k].heading_rad, &noise),
            Event::Fix(j) => {
                if let Some((nis, down_weighted)) = belief.fix(&fixes[j], fix_sigma_m(j), &noise) {
                    nis_all.push(nis);
                    rejected_in_row = if down_weighted {
                        rejected_in_row + 1
                    } else {
                        0
                    };
                    fix_use[j] = match (down_weighted, reset) {
                        (true, _) => FixUse::DownWeighted,
                        (false, true) => FixUse::UsedAfterReset,
                        (false, false) => FixUse::Used,
                    };
                }
            }
            Event::Start | Event::Step(_) => {}
        }
        stored.push(Stored {
            x_prior,
            p_prior,
            x_post: belief.x,
            p_post: belief.p,
            f: belief.f,
        });
    }
    Pass {
        stored,
        fix_use,
        nis: nis_all,
    }
}

/// The state before the first event: at the given start, else at the first fix with
/// its σ (the slow error is then a state of its own); the scale at 1, the errors at 0.
fn initial(
    events: &[Event],
    steps: &[StepInput],
    fixes: &[FixInput],
    prior: WalkPrior,
    noise: WalkNoise,
    trust: f64,
) -> (State, Cov) {
    let mut x = State::zeros();
    x[S] = 1.0;
    let mut p = Cov::zeros();
    let first_fix = events.iter().find_map(|event| match event {
        Event::Fix(j) => Some(&fixes[*j]),
        _ => None,
    });
    let (start_en_m, start_sigma_m) = match (prior.start, first_fix) {
        (Some(start), _) => start,
        // Diffuse: the first fix places it.
        (None, Some(fix)) => (
            fix.en_m,
            noise.start_accuracy_multiple * trust * fix_accuracy_m(fix, noise),
        ),
        (None, None) => ([0.0, 0.0], 0.0),
    };
    x[E] = start_en_m[0];
    x[N] = start_en_m[1];
    p[(E, E)] = start_sigma_m.powi(2);
    p[(N, N)] = p[(E, E)];
    p[(S, S)] = prior.scale_sigma.powi(2);
    let heading_error_rad = steps
        .first()
        .and_then(|step| step.heading_sigma_rad)
        .filter(|sigma| sigma.is_finite() && *sigma > 0.0)
        .map_or(noise.heading_error_rad, |sigma| {
            sigma.max(noise.heading_error_floor_rad)
        });
    p[(D, D)] = heading_error_rad.powi(2);
    x[A] = steps
        .first()
        .map_or(0.0, |step| wrap_to_2pi(step.heading_rad));
    p[(A, A)] = noise.heading_white_rad.powi(2) + noise.turn_per_step_rad.powi(2);
    let bias_sigma_m = first_fix.map_or(0.0, |fix| {
        trust * fix_accuracy_m(fix, noise) / ACCURACY_PER_SIGMA * noise.gnss_bias_share.sqrt()
    });
    p[(BE, BE)] = bias_sigma_m.powi(2);
    p[(BN, BN)] = p[(BE, BE)];
    (x, p)
}

fn fix_accuracy_m(fix: &FixInput, noise: WalkNoise) -> f64 {
    fix.hacc_m
        .filter(|hacc| hacc.is_finite() && *hacc > 0.0)
        .unwrap_or(noise.gnss_default_accuracy_m)
        .max(noise.gnss_min_accuracy_m)
}

/// The Rauch-Tung-Striebel pass: each event's smoothed state and covariance.
fn backward(stored: &[Stored]) -> (Vec<State>, Vec<Cov>) {
    let n = stored.len();
    let mut states: Vec<State> = stored.iter().map(|s| s.x_post).collect();
    let mut covs: Vec<Cov> = stored.iter().map(|s| s.p_post).collect();
    for k in (0..n.saturating_sub(1)).rev() {
        let next = &stored[k + 1];
        // States the walk never excites (the GNSS error of a walk without fixes) have
        // no variance: a whisker on the diagonal keeps the inverse defined.
        let Some(p_prior_inv) = (next.p_prior + Cov::identity().scaled(1e-12)).try_inverse() else {
            continue;
        };
        let c = stored[k].p_post * next.f.transpose() * p_prior_inv;
        let mut difference = states[k + 1] - next.x_prior;
        difference[A] = wrap_to_pi(difference[A]);
        states[k] = stored[k].x_post + c.times(&difference);
        states[k][A] = wrap_to_2pi(states[k][A]);
        let p = stored[k].p_post + c * (covs[k + 1] - next.p_prior) * c.transpose();
        covs[k] = p.symmetric();
    }
    (states, covs)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A walk north at 0.7 m a step, two steps a second; the step model says
    /// `model_length_m` and the heading reads 10° east of the truth.
    fn walk(n: usize, model_length_m: f64) -> Vec<StepInput> {
        (0..n)
            .map(|k| StepInput {
                t_start_s: 0.5 * k as f64,
                t_s: 0.5 * (k + 1) as f64,
                length_m: model_length_m,
                heading_rad: 10f64.to_radians(),
                heading_sigma_rad: None,
            })
            .collect()
    }

    fn truth_at(t_s: f64) -> [f64; 2] {
        [0.0, 1.4 * t_s]
    }

    /// A fix a second for `seconds`, reporting `hacc_m`, at the truth plus `error(t)`.
    fn fixes(seconds: usize, hacc_m: f64, error: impl Fn(usize) -> [f64; 2]) -> Vec<FixInput> {
        (1..seconds)
            .map(|t| {
                let t_s = t as f64;
                let ([e, n], [de, dn]) = (truth_at(t_s), error(t));
                FixInput {
                    t_s,
                    en_m: [e + de, n + dn],
                    hacc_m: Some(hacc_m),
                }
            })
            .collect()
    }

    #[test]
    fn good_fixes_teach_the_heading_error_and_the_smoother_uses_them() {
        let steps = walk(240, 0.7);
        // Fixes every second, 3 m accuracy, with a deterministic ±2 m wobble.
        let fixes = fixes(120, 3.0, |t| {
            let t_s = t as f64;
            [2.0 * (0.7 * t_s).sin(), 2.0 * (1.3 * t_s).cos()]
        });
        let prior = WalkPrior {
            start: None,
            scale_sigma: 0.05,
        };
        let policy = GnssPolicy::default();
        let smoothed = fuse_walk(&steps, &fixes, prior, WalkNoise::default(), &policy, true);
        let causal = fuse_walk(&steps, &fixes, prior, WalkNoise::default(), &policy, false);
        assert_eq!(smoothed.track.len(), 241);
        let mid = &smoothed.track[120];
        let heading_deg = mid.heading_rad.to_degrees();
        assert!(!(2.0..358.0).contains(&heading_deg), "{heading_deg}");
        let error = |point: &TrackPoint| {
            let [e, n] = truth_at(point.t_s);
            ((point.east_m - e).powi(2) + (point.north_m - n).powi(2)).sqrt()
        };
        let rms = |track: &[TrackPoint]| {
            (track.iter().map(|p| error(p).powi(2)).sum::<f64>() / track.len() as f64).sqrt()
        };
        assert!(rms(&smoothed.track) < rms(&causal.track), "smoothing helps");
        assert!(rms(&smoothed.track) < 1.5, "{}", rms(&smoothed.track));
        assert!(smoothed.fix_use.iter().all(|u| *u == FixUse::Used));
    }

    /// A phone's fixes move less than its walker (here 85 % of the way, as a fused
    /// location lags and cuts corners): the steps keep their length.
    #[test]
    fn fixes_that_move_less_than_the_walker_do_not_shrink_the_walk() {
        let steps = walk(240, 0.7);
        let fixes = fixes(120, 4.0, |t| [0.0, -0.15 * 1.4 * t as f64]);
        let prior = WalkPrior {
            start: None,
            scale_sigma: 0.05,
        };
        let policy = GnssPolicy::default();
        let fused = fuse_walk(&steps, &fixes, prior, WalkNoise::default(), &policy, true);
        let walked_m: f64 = fused.track.iter().map(|p| p.length_m).sum();
        assert!((walked_m - 240.0 * 0.7).abs() < 1e-6, "{walked_m}");
        assert_eq!(fused.scale, (1.0, 0.0));
        // Without fixes nothing teaches it either, and it keeps its σ.
        let alone = fuse_walk(&steps, &[], prior, WalkNoise::default(), &policy, true);
        assert_eq!(alone.scale.0, 1.0);
        assert!(alone.scale.1 >= 0.05, "{:?}", alone.scale);
    }

    #[test]
    fn an_outlier_is_down_weighted_and_an_outage_is_bridged() {
        let steps = walk(240, 0.6);
        let fixes = fixes(120, 4.0, |t| [if t == 30 { 80.0 } else { 0.0 }, 0.0]);
        let policy = GnssPolicy {
            outages: vec![super::super::fusion::Outage {
                start_s: 60.0,
                end_s: 90.0,
            }],
            ..GnssPolicy::default()
        };
        let prior = WalkPrior {
            start: None,
            scale_sigma: 0.15,
        };
        let fused = fuse_walk(&steps, &fixes, prior, WalkNoise::default(), &policy, true);
        assert_eq!(fused.fix_use[29], FixUse::DownWeighted);
        assert_eq!(fused.fix_use[70], FixUse::InOutage);
        let at_30 = &fused.track[60];
        assert!(at_30.east_m.abs() < 3.0, "{at_30:?}");
        // Inside the outage the σ grows, and still covers the error.
        let inside = &fused.track[150];
        let [e, n] = truth_at(inside.t_s);
        let error = ((inside.east_m - e).powi(2) + (inside.north_m - n).powi(2)).sqrt();
        assert!(inside.position_sigma_m > fused.track[100].position_sigma_m);
        assert!(error < 2.0 * inside.position_sigma_m, "{error} {inside:?}");
    }

    #[test]
    fn fixes_alone_in_poor_accuracy_still_place_the_walk() {
        let steps = walk(120, 0.6);
        let fixes = fixes(60, 36.0, |_| [25.0, 10.0]);
        let prior = WalkPrior {
            start: None,
            scale_sigma: 0.15,
        };
        let fused = fuse_walk(
            &steps,
            &fixes,
            prior,
            WalkNoise::default(),
            &GnssPolicy::default(),
            true,
        );
        let mid = &fused.track[60];
        assert!(mid.east_m > 10.0, "{mid:?}");
        assert!(mid.position_sigma_m > 5.0, "{mid:?}");
        assert!(fused
            .fix_use
            .iter()
            .all(|u| matches!(u, FixUse::Used | FixUse::DownWeighted)));
    }
}
