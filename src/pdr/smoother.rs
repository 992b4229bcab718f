//! How a log's walk is fused after the fact: an extended Kalman filter forward over the
//! steps and every GNSS fix, then the Rauch-Tung-Striebel pass backward, so that each
//! position uses the fixes before and after it (Rauch, Tung & Striebel, *Maximum
//! likelihood estimates of linear dynamic systems*, AIAA J. 1965; the extended form as
//! in Särkkä, *Bayesian Filtering and Smoothing*, 2013, Algorithm 9.1).
//!
//! The state extends the PDR paper's `[E, N, l, a]` (Chen et al., Eq. 13) by the three
//! errors that are correlated along a walk, so that the stated σ holds where they are:
//!
//! ```text
//! x = [E, N, s, δ, β_E, β_N]
//! step k (model length l_k, measured heading h_k):
//!     E += s·l_k·sin(h_k − δ),   N += s·l_k·cos(h_k − δ)      (+ white length and heading noise)
//!     s: the step model's scale, prior 1 ± σ_s (how well its training proved it), a slow random walk
//!     δ: the heading's error, first-order Gauss-Markov, time constant τ_δ, stationary σ the
//!        attitude filter's heading σ where it states one
//! fix j (position z_j, reported accuracy A_j, σ_j = c·A_j / 1.51 per axis):
//!     z_j = [E, N] + β + ε_j,   ε_j white with variance (1 − ρ)·σ_j²
//!     β: the GNSS error that moves slowly (multipath, a building's shadow), metres,
//!        first-order Gauss-Markov with time constant τ_β towards the stationary
//!        variance ρ·σ_j² of the latest fix (not scaled by each fix's accuracy: fixes of
//!        different accuracy would then tell the error from the position)
//! ```
//!
//! Android's accuracy is the radius of 68 % confidence, 1.51 σ per axis. How far to
//! trust it, `c`, is learnt from the fixes' own innovations (their median normalised
//! innovation squared against χ²₂'s, 1.386), and a fix whose innovation is beyond the χ²
//! gate is down-weighted by it, never dropped (a heavy-tailed measurement model).
//!
//! Frames and units: `E`, `N` metres east and north of the local origin; headings in
//! radians clockwise from true north; times in seconds of log time.

use nalgebra::{SMatrix, SVector};
use serde::Serialize;

use super::fusion::{FixInput, FixUse, GnssPolicy, StepInput, TrackPoint};
use crate::angle::wrap_to_2pi;

type State = SVector<f64, 6>;
type Cov = SMatrix<f64, 6, 6>;
const E: usize = 0;
const N: usize = 1;
const S: usize = 2;
const D: usize = 3;
const BE: usize = 4;
const BN: usize = 5;

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
    /// White noise of one step's heading (rad).
    pub heading_white_rad: f64,
    /// The heading error's stationary σ where the heading states none (rad).
    pub heading_error_rad: f64,
    pub heading_error_tau_s: f64,
    pub gnss_bias_tau_s: f64,
    /// The share ρ of a fix's error variance that moves slowly.
    pub gnss_bias_share: f64,
    /// The accuracy taken for a fix that reports none, and the least taken (m).
    pub gnss_default_accuracy_m: f64,
    pub gnss_min_accuracy_m: f64,
    /// χ²₂ beyond which a fix is down-weighted by its normalised innovation (99 %).
    pub robust_gate: f64,
    /// Bounds on the learnt factor `c` on the reported accuracy: never trusted beyond
    /// what it reports (a phone's fixes are smoother than their errors are small, so
    /// their innovations alone would trust them too far).
    pub trust_bounds: [f64; 2],
}

/// WORK IN PROGRESS (issue 42): tuning hooks read from the environment, to be removed
/// before this filter leaves its branch (the core reads no environment).
fn tune(name: &str, default: f64) -> f64 {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

impl Default for WalkNoise {
    fn default() -> Self {
        WalkNoise {
            scale_walk_per_step: tune("T_SW", 0.002),
            length_white_fraction: tune("T_LW", 0.10),
            heading_white_rad: tune("T_HW", 3.0).to_radians(),
            heading_error_rad: tune("T_HE", 10.0).to_radians(),
            heading_error_tau_s: tune("T_HT", 60.0),
            gnss_bias_tau_s: tune("T_BT", 30.0),
            gnss_bias_share: tune("T_BS", 0.5),
            gnss_default_accuracy_m: 10.0,
            gnss_min_accuracy_m: 1.5,
            robust_gate: tune("T_G", 9.21),
            trust_bounds: [tune("T_TL", 1.0), 4.0],
        }
    }
}
impl WalkNoise {
    fn _old() -> Self {
        WalkNoise {
            scale_walk_per_step: 0.002,
            length_white_fraction: 0.10,
            heading_white_rad: 3f64.to_radians(),
            heading_error_rad: 10f64.to_radians(),
            heading_error_tau_s: 60.0,
            gnss_bias_tau_s: 60.0,
            gnss_bias_share: 0.8,
            gnss_default_accuracy_m: 10.0,
            gnss_min_accuracy_m: 1.5,
            robust_gate: 9.21,
            trust_bounds: [1.0, 4.0],
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
    let events = events(steps, fixes, first.t_start_s, policy);
    // The trust in the reported accuracy, from the innovations (three passes converge:
    // each moves c² by the ratio of the median NIS to χ²₂'s).
    let mut trust = 1.0f64;
    for _ in 0..3 {
        let pass = forward(&events, steps, fixes, prior, noise, trust);
        if pass.nis.len() < 5 {
            break;
        }
        let median = crate::stats::median(&mut pass.nis.clone()).unwrap_or(CHI2_2_MEDIAN);
        trust = (trust * (median / CHI2_2_MEDIAN).sqrt())
            .clamp(noise.trust_bounds[0], noise.trust_bounds[1]);
    }
    let pass = forward(&events, steps, fixes, prior, noise, trust);
    let (states, covs): (Vec<State>, Vec<Cov>) = if smooth {
        backward(&pass.stored)
    } else {
        pass.stored.iter().map(|s| (s.x_post, s.p_post)).unzip()
    };

    let mut track = Vec::with_capacity(steps.len() + 1);
    let mut gnss_used = false;
    let mut fix_use = vec![FixUse::AfterWalk; fixes.len()];
    let last_step_s = steps.last().map_or(first.t_s, |step| step.t_s);
    for ((event, x), p) in events.iter().zip(&states).zip(&covs) {
        let sigma_m = (p[(E, E)] + p[(N, N)]).max(0.0).sqrt();
        match *event {
            Event::Start => track.push(TrackPoint {
                t_s: first.t_start_s,
                east_m: x[E],
                north_m: x[N],
                length_m: 0.0,
                heading_rad: wrap_to_2pi(first.heading_rad - x[D]),
                position_sigma_m: sigma_m,
                gnss_used: false,
            }),
            Event::Step(k) => {
                let step = &steps[k];
                track.push(TrackPoint {
                    t_s: step.t_s,
                    east_m: x[E],
                    north_m: x[N],
                    length_m: x[S] * step.length_m,
                    heading_rad: wrap_to_2pi(step.heading_rad - x[D]),
                    position_sigma_m: sigma_m,
                    gnss_used,
                });
                gnss_used = false;
            }
            Event::Fix(j) => {
                let used = pass.fix_use[j];
                fix_use[j] = match used {
                    FixUse::Used | FixUse::DownWeighted if fixes[j].t_s < first.t_start_s => {
                        FixUse::BeforeWalk
                    }
                    FixUse::Used | FixUse::DownWeighted if fixes[j].t_s > last_step_s => {
                        FixUse::AfterWalk
                    }
                    other => other,
                };
                gnss_used |= matches!(used, FixUse::Used | FixUse::DownWeighted);
            }
        }
    }
    for (j, fix) in fixes.iter().enumerate() {
        if policy.in_outage(fix.t_s) {
            fix_use[j] = FixUse::InOutage;
        } else if j > 0 && repeats(&fixes[j - 1], fix) {
            // Logged twice: it fared as its first copy.
            fix_use[j] = fix_use[j - 1];
        }
    }
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

/// The steps, the usable fixes and the start, in time order (a fix at a step's end
/// time comes first).
fn events(steps: &[StepInput], fixes: &[FixInput], start_s: f64, policy: &GnssPolicy) -> Vec<Event> {
    let mut timed: Vec<(f64, u8, Event)> = Vec::with_capacity(steps.len() + fixes.len() + 1);
    timed.push((start_s, 1, Event::Start));
    timed.extend(
        steps
            .iter()
            .enumerate()
            .map(|(k, step)| (step.t_s, 2, Event::Step(k))),
    );
    // A fix logged twice (the same position and accuracy within 1.5 s, as
    // GetSensorData does) is one measurement, not two.
    let mut previous: Option<&FixInput> = None;
    for (j, fix) in fixes.iter().enumerate() {
        if policy.in_outage(fix.t_s) || !fix.en_m.iter().all(|v| v.is_finite()) {
            continue;
        }
        let repeated = previous.is_some_and(|p| repeats(p, fix));
        previous = Some(fix);
        if !repeated {
            timed.push((fix.t_s, 0, Event::Fix(j)));
        }
    }
    timed.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    timed.into_iter().map(|(_, _, event)| event).collect()
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
        Event::Step(k) => steps[k].t_s,
        Event::Fix(j) => fixes[j].t_s,
    }
}

fn forward(
    events: &[Event],
    steps: &[StepInput],
    fixes: &[FixInput],
    prior: WalkPrior,
    noise: WalkNoise,
    trust: f64,
) -> Pass {
    let start_s = steps.first().map_or(0.0, |step| step.t_start_s);
    let (mut x, mut p) = initial(events, steps, fixes, prior, noise, trust);
    let mut t_prev = events
        .first()
        .map_or(start_s, |&event| event_time(event, steps, fixes, start_s));
    let mut stored = Vec::with_capacity(events.len());
    let mut fix_use = vec![FixUse::AfterWalk; fixes.len()];
    let mut nis_all = Vec::new();
    // The heading error's stationary σ: the latest step's stated one.
    let mut heading_error_rad = noise.heading_error_rad;
    // The GNSS slow error's stationary variance (m²): the latest fix's.
    let mut bias_var_m2 = p[(BE, BE)];
    for &event in events {
        let t_s = event_time(event, steps, fixes, start_s);
        let dt_s = (t_s - t_prev).max(0.0);
        t_prev = t_s;
        if let Event::Step(k) = event {
            if let Some(sigma) = steps[k]
                .heading_sigma_rad
                .filter(|sigma| sigma.is_finite() && *sigma > 0.0)
            {
                heading_error_rad = sigma.max(tune("T_HF", 0.0).to_radians());
            }
        }
        // The slow errors decay towards zero over the time since the last event.
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
        x = f * x;
        p = f * p * f.transpose() + q;
        if let Event::Step(k) = event {
            let step = &steps[k];
            let length_m = step.length_m.max(0.0);
            let (sin_a, cos_a) = (step.heading_rad - x[D]).sin_cos();
            let d_m = x[S] * length_m;
            let mut fm = Cov::identity();
            fm[(E, S)] = length_m * sin_a;
            fm[(E, D)] = -d_m * cos_a;
            fm[(N, S)] = length_m * cos_a;
            fm[(N, D)] = d_m * sin_a;
            // White noise of this step's length and heading, into E and N.
            let sl = noise.length_white_fraction * d_m;
            let sh = noise.heading_white_rad * d_m;
            let mut qm = Cov::zeros();
            qm[(E, E)] = (sin_a * sl).powi(2) + (cos_a * sh).powi(2);
            qm[(N, N)] = (cos_a * sl).powi(2) + (sin_a * sh).powi(2);
            qm[(E, N)] = sin_a * cos_a * (sl * sl - sh * sh);
            qm[(N, E)] = qm[(E, N)];
            qm[(S, S)] = noise.scale_walk_per_step.powi(2);
            x[E] += d_m * sin_a;
            x[N] += d_m * cos_a;
            p = fm * p * fm.transpose() + qm;
            f = fm * f;
        }
        if let Event::Fix(j) = event {
            // The slow error's variance follows the accuracy the fix reports at once:
            // a better one means a new satellite geometry, so the old error is mostly
            // forgotten (b ← k·b + w, k the ratio of the σs); a worse one adds to it.
            let sigma_m = trust * fix_accuracy_m(&fixes[j], noise) / ACCURACY_PER_SIGMA;
            let target_m2 = sigma_m.powi(2) * noise.gnss_bias_share;
            let mut fa = Cov::identity();
            let mut qa = Cov::zeros();
            if target_m2 < bias_var_m2 {
                let k = (target_m2 / bias_var_m2).sqrt();
                fa[(BE, BE)] = k;
                fa[(BN, BN)] = k;
                qa[(BE, BE)] = target_m2 * (1.0 - k * k);
            } else {
                qa[(BE, BE)] = target_m2 - bias_var_m2;
            }
            qa[(BN, BN)] = qa[(BE, BE)];
            x = fa * x;
            p = fa * p * fa.transpose() + qa;
            f = fa * f;
            bias_var_m2 = target_m2;
        }
        let (x_prior, p_prior) = (x, p);
        if let Event::Fix(j) = event {
            let fix = &fixes[j];
            let sigma_m = trust * fix_accuracy_m(fix, noise) / ACCURACY_PER_SIGMA;
            let g = 1.0;
            let white_var = sigma_m.powi(2) * (1.0 - noise.gnss_bias_share);
            let mut h = SMatrix::<f64, 2, 6>::zeros();
            h[(0, E)] = 1.0;
            h[(1, N)] = 1.0;
            h[(0, BE)] = g;
            h[(1, BN)] = g;
            let y = SVector::<f64, 2>::new(fix.en_m[0], fix.en_m[1]) - h * x;
            let mut r = SMatrix::<f64, 2, 2>::identity() * white_var;
            let s = h * p * h.transpose() + r;
            let nis = s
                .try_inverse()
                .map_or(f64::INFINITY, |s_inv| (y.transpose() * s_inv * y)[(0, 0)]);
            nis_all.push(nis);
            // Heavy tails: a fix beyond the gate counts as if its noise were larger by
            // its own innovation (Huber's weight in the Mahalanobis norm).
            let down_weighted = nis > noise.robust_gate;
            if std::env::var("T_DBG").is_ok() {
                eprintln!("fix t {:.1} z ({:.1},{:.1}) x ({:.1},{:.1}) b ({:.2},{:.2}) s {:.2} d {:.1} sigE {:.1} nis {:.1} acc {:?} trust {trust:.2}", fix.t_s, fix.en_m[0], fix.en_m[1], x[E], x[N], x[BE]*g, x[BN]*g, x[S], x[D].to_degrees(), p[(E,E)].sqrt(), nis, fix.hacc_m);
            }
            if down_weighted {
                // Inflate the whole measurement (slow and white parts alike).
                let inflation = nis / noise.robust_gate;
                r += (h * p * h.transpose() + r) * (inflation - 1.0);
            }
            let s = h * p * h.transpose() + r;
            if let Some(s_inv) = s.try_inverse() {
                let k = p * h.transpose() * s_inv;
                x += k * y;
                let i_kh = Cov::identity() - k * h;
                p = i_kh * p * i_kh.transpose() + k * r * k.transpose();
                fix_use[j] = if down_weighted {
                    FixUse::DownWeighted
                } else {
                    FixUse::Used
                };
            }
        }
        stored.push(Stored {
            x_prior,
            p_prior,
            x_post: x,
            p_post: p,
            f,
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
        (None, Some(fix)) => (fix.en_m, tune("T_SM", 3.0) * trust * fix_accuracy_m(fix, noise)),
        (None, None) => ([0.0, 0.0], 0.0),
    };
    x[E] = start_en_m[0];
    x[N] = start_en_m[1];
    p[(E, E)] = start_sigma_m.powi(2);
    p[(N, N)] = p[(E, E)];
    p[(S, S)] = (prior.scale_sigma * tune("T_SS", 0.33)).powi(2);
    let heading_error_rad = steps
        .first()
        .and_then(|step| step.heading_sigma_rad)
        .filter(|sigma| sigma.is_finite() && *sigma > 0.0)
        .unwrap_or(noise.heading_error_rad);
    p[(D, D)] = heading_error_rad.powi(2);
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
        let Some(p_prior_inv) = next.p_prior.try_inverse() else {
            continue;
        };
        let c = stored[k].p_post * next.f.transpose() * p_prior_inv;
        states[k] = stored[k].x_post + c * (states[k + 1] - next.x_prior);
        let p = stored[k].p_post + c * (covs[k + 1] - next.p_prior) * c.transpose();
        covs[k] = (p + p.transpose()) * 0.5;
    }
    (states, covs)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A walk north at 0.7 m a step, two steps a second; the step model says 0.6 m
    /// (scale 7/6) and the heading reads 10° east of the truth.
    fn walk(n: usize) -> Vec<StepInput> {
        (0..n)
            .map(|k| StepInput {
                t_start_s: 0.5 * k as f64,
                t_s: 0.5 * (k + 1) as f64,
                length_m: 0.6,
                heading_rad: 10f64.to_radians(),
                heading_sigma_rad: None,
            })
            .collect()
    }

    fn truth_at(t_s: f64) -> [f64; 2] {
        [0.0, 1.4 * t_s]
    }

    #[test]
    fn good_fixes_teach_the_scale_and_the_heading_error_and_the_smoother_uses_them() {
        let steps = walk(240);
        // Fixes every second, 3 m accuracy, with a deterministic ±2 m wobble.
        let fixes: Vec<FixInput> = (1..120)
            .map(|t| {
                let t_s = t as f64;
                let [e, n] = truth_at(t_s);
                FixInput {
                    t_s,
                    en_m: [e + 2.0 * (0.7 * t_s).sin(), n + 2.0 * (1.3 * t_s).cos()],
                    hacc_m: Some(3.0),
                }
            })
            .collect();
        let prior = WalkPrior {
            start: None,
            scale_sigma: 0.15,
        };
        let policy = GnssPolicy::default();
        let smoothed = fuse_walk(&steps, &fixes, prior, WalkNoise::default(), &policy, true);
        let causal = fuse_walk(&steps, &fixes, prior, WalkNoise::default(), &policy, false);
        assert_eq!(smoothed.track.len(), 241);
        assert!((smoothed.scale.0 - 7.0 / 6.0).abs() < 0.03, "{:?}", smoothed.scale);
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

    #[test]
    fn an_outlier_is_down_weighted_and_an_outage_is_bridged() {
        let steps = walk(240);
        let fixes: Vec<FixInput> = (1..120)
            .map(|t| {
                let t_s = t as f64;
                let [e, n] = truth_at(t_s);
                FixInput {
                    t_s,
                    en_m: [e + if t == 30 { 80.0 } else { 0.0 }, n],
                    hacc_m: Some(4.0),
                }
            })
            .collect();
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
        let steps = walk(120);
        let fixes: Vec<FixInput> = (1..60)
            .map(|t| FixInput {
                t_s: t as f64,
                en_m: [25.0, 1.4 * t as f64 + 10.0],
                hacc_m: Some(36.0),
            })
            .collect();
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
        assert!(fused.fix_use.iter().all(|u| matches!(u, FixUse::Used | FixUse::DownWeighted)));
    }
}
