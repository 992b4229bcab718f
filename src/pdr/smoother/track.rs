//! What the filter's (or the smoother's) states say of the walk: the track, each point
//! with its σ, and what became of each fix.

use super::{
    event_time, fix_accuracy_m, repeats, Event, WalkNoise, A, ACCURACY_PER_SIGMA, D, E, N, S,
};
use crate::base::angle::wrap_to_2pi;
use crate::pdr::fusion::{FixInput, FixUse, GnssPolicy, StepInput, TrackPoint};
use crate::pdr::small_matrix::{Cov, State};

/// The GNSS error that is constant over the walk cannot be told from the position by
/// any filter: it moves the whole track and adds its variance to the position's,
/// 2·ρ_c·σ² (two axes) with σ the per-axis σ of the fix nearest in time.
pub(super) struct ConstantError {
    /// Each taken fix's time (s) and per-axis σ (m), in time order.
    taken: Vec<(f64, f64)>,
    share: f64,
}

impl ConstantError {
    pub(super) fn of(
        events: &[Event],
        fixes: &[FixInput],
        trust: f64,
        noise: WalkNoise,
    ) -> ConstantError {
        let taken = events
            .iter()
            .filter_map(|event| match *event {
                Event::Fix(j) => Some((
                    fixes[j].t_s,
                    trust * fix_accuracy_m(&fixes[j], noise) / ACCURACY_PER_SIGMA,
                )),
                _ => None,
            })
            .collect();
        ConstantError {
            taken,
            share: noise.gnss_constant_share,
        }
    }

    /// Its variance (m², both axes) at `t_s`: none without fixes.
    fn variance_m2(&self, t_s: f64) -> f64 {
        let i = self.taken.partition_point(|(t, _)| *t < t_s);
        let nearest = [i.checked_sub(1), Some(i)]
            .into_iter()
            .flatten()
            .filter_map(|k| self.taken.get(k))
            .min_by(|a, b| (a.0 - t_s).abs().total_cmp(&(b.0 - t_s).abs()));
        nearest.map_or(0.0, |(_, sigma)| 2.0 * self.share * sigma * sigma)
    }
}

/// The walk's events with the steps and the fixes they index: what the track is read along.
pub(super) struct Walk<'a> {
    pub(super) events: &'a [Event],
    pub(super) steps: &'a [StepInput],
    pub(super) fixes: &'a [FixInput],
    /// The first step's start (s).
    pub(super) start_s: f64,
}

impl Walk<'_> {
    /// The track at the events' states and covariances: the start and each step's end,
    /// each position's σ with the constant GNSS error's, and whether a fix was taken
    /// (by the pass, `pass_fix_use`) since the previous point.
    pub(super) fn track(
        &self,
        states: &[State],
        covs: &[Cov],
        constant: &ConstantError,
        pass_fix_use: &[FixUse],
    ) -> Vec<TrackPoint> {
        let (steps, fixes) = (self.steps, self.fixes);
        let mut track = Vec::with_capacity(steps.len() + 1);
        let mut gnss_used = false;
        for ((event, x), p) in self.events.iter().zip(states).zip(covs) {
            let t_s = event_time(*event, steps, fixes, self.start_s);
            let sigma_m = (p[(E, E)] + p[(N, N)] + constant.variance_m2(t_s))
                .max(0.0)
                .sqrt();
            match *event {
                Event::Start => track.push(TrackPoint {
                    t_s: self.start_s,
                    east_m: x[E],
                    north_m: x[N],
                    length_m: 0.0,
                    heading_rad: wrap_to_2pi(x[A] - x[D]),
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
                        heading_rad: wrap_to_2pi(x[A] - x[D]),
                        position_sigma_m: sigma_m,
                        gnss_used,
                    });
                    gnss_used = false;
                }
                Event::Heading(_) => {}
                Event::Fix(j) => {
                    gnss_used |= matches!(
                        pass_fix_use[j],
                        FixUse::Used | FixUse::DownWeighted | FixUse::UsedAfterReset
                    );
                }
            }
        }
        track
    }

    /// What became of each fix: as the pass took it (`pass_fix_use`), but before or
    /// after the walk when it was taken outside the steps' span, in an outage, and as
    /// its first copy when it was logged twice.
    pub(super) fn fix_use(&self, pass_fix_use: &[FixUse], policy: &GnssPolicy) -> Vec<FixUse> {
        let fixes = self.fixes;
        let mut fix_use = vec![FixUse::AfterWalk; fixes.len()];
        let last_step_s = self.steps.last().map_or(self.start_s, |step| step.t_s);
        for event in self.events {
            let Event::Fix(j) = *event else { continue };
            fix_use[j] = match pass_fix_use[j] {
                FixUse::Used | FixUse::DownWeighted | FixUse::UsedAfterReset
                    if fixes[j].t_s < self.start_s =>
                {
                    FixUse::BeforeWalk
                }
                FixUse::Used | FixUse::DownWeighted | FixUse::UsedAfterReset
                    if fixes[j].t_s > last_step_s =>
                {
                    FixUse::AfterWalk
                }
                other => other,
            };
        }
        for (j, fix) in fixes.iter().enumerate() {
            if policy.in_outage(fix.t_s) {
                fix_use[j] = FixUse::InOutage;
            } else if j > 0 && repeats(&fixes[j - 1], fix) {
                // Logged twice: it fared as its first copy.
                fix_use[j] = fix_use[j - 1];
            }
        }
        fix_use
    }
}
