//! When to fuse: GNSS/PDR switching around the EKF of [`super::ekf`].
//!
//! Chen et al., *A unified heading error model and step length estimation for PDR*,
//! Fig. 2: while GNSS is good the solution follows it (and the step and heading models
//! train on it); during outages the steps dead-reckon. Here one filter runs throughout:
//! every step updates it, and each GNSS fix is used or not by [`GnssPolicy`]:
//!
//! - inside a user-marked outage (the paper's evaluation ignores GNSS over chosen
//!   spans), never;
//! - with a reported accuracy worse than `max_hacc_m`, never (indoor fixes of 20-600 m);
//! - when its normalised innovation is beyond the χ² gate, not at first; after
//!   `reset_after_rejections` such fixes in a row of good accuracy, the dead-reckoned
//!   position is the one in doubt (a long outage drifted), so the filter widens its
//!   position uncertainty and takes the fix.

use serde::Serialize;
use thiserror::Error;

use super::ekf::{EkfNoise, PdrEkf};

/// A span of time in which GNSS is ignored (s, log time).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Outage {
    pub start_s: f64,
    pub end_s: f64,
}

impl Outage {
    pub fn contains(&self, t_s: f64) -> bool {
        (self.start_s..=self.end_s).contains(&t_s)
    }

    /// Parses `START:END` (or `START-END`) in seconds.
    pub fn parse(text: &str) -> Option<Outage> {
        let text = text.trim();
        let (start, end) = text.split_once(':').or_else(|| text.split_once('-'))?;
        let start_s: f64 = start.trim().parse().ok()?;
        let end_s: f64 = end.trim().parse().ok()?;
        (start_s.is_finite() && end_s.is_finite() && end_s > start_s)
            .then_some(Outage { start_s, end_s })
    }
}

/// An item of an outage list ([`parse_outages`]) that is not `START-END` in seconds,
/// START before END.
#[derive(Debug, Clone, PartialEq, Error)]
#[error(
    "\"{item}\" is not an outage: write START-END in seconds of log time, START before END, \
     e.g. 240-840"
)]
pub struct OutageError {
    /// The item as written, trimmed.
    pub item: String,
}

/// Outages written as a list, `START:END` or `START-END` in seconds, separated by commas
/// or semicolons (`240:840, 900-960`); an empty text is no outage. The error names the
/// item that could not be read.
pub fn parse_outages(text: &str) -> Result<Vec<Outage>, OutageError> {
    text.split([',', ';'])
        .map(str::trim)
        .filter(|item| !item.is_empty())
        .map(|item| {
            Outage::parse(item).ok_or_else(|| OutageError {
                item: item.to_string(),
            })
        })
        .collect()
}

/// Which fixes the filter takes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GnssPolicy {
    pub outages: Vec<Outage>,
    /// Fixes reporting a worse horizontal accuracy (m) are not used.
    pub max_hacc_m: f64,
    /// The 1 σ used for a fix: its reported accuracy, never below this (m), and this
    /// when it reports none.
    pub min_sigma_m: f64,
    pub default_sigma_m: f64,
    /// χ² gate on the normalised innovation (2 degrees of freedom; 13.8 is 99.9 %).
    pub nis_gate: f64,
    pub reset_after_rejections: usize,
}

impl Default for GnssPolicy {
    fn default() -> Self {
        GnssPolicy {
            outages: Vec::new(),
            max_hacc_m: 15.0,
            min_sigma_m: 1.0,
            default_sigma_m: 5.0,
            nis_gate: 13.8,
            reset_after_rejections: 5,
        }
    }
}

impl GnssPolicy {
    pub fn in_outage(&self, t_s: f64) -> bool {
        self.outages.iter().any(|outage| outage.contains(t_s))
    }

    /// Whether a fix is usable before the filter sees it: outside outages, accurate
    /// enough. Returns its σ (m).
    pub fn admissible(&self, fix: &FixInput) -> Result<f64, FixUse> {
        self.admits(fix.t_s, fix.hacc_m)
    }

    /// [`GnssPolicy::admissible`] for a fix at `t_s` reporting `hacc_m`, wherever it is.
    pub fn admits(&self, t_s: f64, hacc_m: Option<f64>) -> Result<f64, FixUse> {
        if self.in_outage(t_s) {
            return Err(FixUse::InOutage);
        }
        match hacc_m {
            Some(hacc_m) if hacc_m <= self.max_hacc_m => Ok(hacc_m.max(self.min_sigma_m)),
            Some(_) => Err(FixUse::PoorAccuracy),
            None => Ok(self.default_sigma_m),
        }
    }
}

/// A step as the filter takes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepInput {
    /// When the step starts and ends (s).
    pub t_start_s: f64,
    pub t_s: f64,
    pub length_m: f64,
    pub heading_rad: f64,
    /// The heading's 1σ (rad) where its source states one (the attitude filter), else
    /// the filter's [`EkfNoise::heading_measurement_rad`].
    pub heading_sigma_rad: Option<f64>,
}

/// A GNSS fix in the local frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixInput {
    pub t_s: f64,
    pub en_m: [f64; 2],
    pub hacc_m: Option<f64>,
}

/// What became of one fix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FixUse {
    Used,
    /// Used after the filter widened its position uncertainty (see the module header).
    UsedAfterReset,
    InOutage,
    PoorAccuracy,
    /// Beyond the χ² gate.
    Rejected,
    /// Beyond the smoother's χ² gate: taken with its noise inflated by its own
    /// normalised innovation ([`super::smoother`]).
    DownWeighted,
    /// Before the first step: the start position comes from it or its like.
    BeforeWalk,
    /// After the last step: nothing is dead-reckoned after it.
    AfterWalk,
}

/// The filter's estimate after one step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TrackPoint {
    pub t_s: f64,
    pub east_m: f64,
    pub north_m: f64,
    /// The filtered step length (m) and heading (rad) of the step that ended here.
    pub length_m: f64,
    pub heading_rad: f64,
    /// √(σ_E² + σ_N²) (m).
    pub position_sigma_m: f64,
    /// Whether GNSS was taken since the previous step.
    pub gnss_used: bool,
}

/// The track and the use of each fix.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Fused {
    pub track: Vec<TrackPoint>,
    pub fix_use: Vec<FixUse>,
}

/// Runs the filter through `steps` and `fixes` (each sorted by time) from `start_en_m`
/// (with `start_sigma_m`), the start of the first step.
pub fn fuse(
    steps: &[StepInput],
    fixes: &[FixInput],
    start_en_m: [f64; 2],
    start_sigma_m: f64,
    noise: EkfNoise,
    policy: &GnssPolicy,
) -> Fused {
    let mut fix_use = Vec::with_capacity(fixes.len());
    let Some(first) = steps.first() else {
        fix_use.resize(fixes.len(), FixUse::BeforeWalk);
        return Fused {
            track: Vec::new(),
            fix_use,
        };
    };
    let mut ekf = PdrEkf::new(
        start_en_m,
        start_sigma_m,
        first.length_m,
        first.heading_rad,
        noise,
    );
    let mut track = Vec::with_capacity(steps.len() + 1);
    track.push(TrackPoint {
        t_s: first.t_start_s,
        east_m: start_en_m[0],
        north_m: start_en_m[1],
        length_m: 0.0,
        heading_rad: first.heading_rad,
        position_sigma_m: std::f64::consts::SQRT_2 * start_sigma_m,
        gnss_used: false,
    });
    let mut fix_idx = 0usize;
    let mut n_rejected_in_row = 0usize;
    let mut gnss_used = false;
    let walk_start_s = track[0].t_s;
    for step in steps {
        while let Some(fix) = fixes.get(fix_idx).filter(|fix| fix.t_s <= step.t_s) {
            fix_idx += 1;
            if fix.t_s < walk_start_s {
                fix_use.push(FixUse::BeforeWalk);
                continue;
            }
            let decision = match policy.admissible(fix) {
                Err(reason) => reason,
                Ok(sigma_m) => {
                    let nis = ekf.position_nis(fix.en_m, sigma_m);
                    if nis <= policy.nis_gate {
                        ekf.update_position(fix.en_m, sigma_m);
                        n_rejected_in_row = 0;
                        gnss_used = true;
                        FixUse::Used
                    } else {
                        n_rejected_in_row += 1;
                        if n_rejected_in_row >= policy.reset_after_rejections {
                            let gap_m = ((fix.en_m[0] - ekf.x[0]).powi(2)
                                + (fix.en_m[1] - ekf.x[1]).powi(2))
                            .sqrt();
                            ekf.widen_position(gap_m.max(sigma_m));
                            ekf.update_position(fix.en_m, sigma_m);
                            n_rejected_in_row = 0;
                            gnss_used = true;
                            FixUse::UsedAfterReset
                        } else {
                            FixUse::Rejected
                        }
                    }
                }
            };
            fix_use.push(decision);
        }
        ekf.step(step.length_m, step.heading_rad, step.heading_sigma_rad);
        track.push(TrackPoint {
            t_s: step.t_s,
            east_m: ekf.x[0],
            north_m: ekf.x[1],
            length_m: ekf.x[2],
            heading_rad: ekf.x[3],
            position_sigma_m: (ekf.p[0][0] + ekf.p[1][1]).max(0.0).sqrt(),
            gnss_used,
        });
        gnss_used = false;
    }
    // Fixes after the last step change nothing that was dead-reckoned.
    fix_use.resize(fixes.len(), FixUse::AfterWalk);
    Fused { track, fix_use }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outage_lists_are_read_with_either_separator() {
        let outages = parse_outages(" 240:840, 900-960;1000 : 1010 ,").expect("three outages");
        let pairs: Vec<(f64, f64)> = outages.iter().map(|o| (o.start_s, o.end_s)).collect();
        assert_eq!(
            pairs,
            vec![(240.0, 840.0), (900.0, 960.0), (1000.0, 1010.0)]
        );
        assert_eq!(parse_outages("  "), Ok(Vec::new()));
        let error = parse_outages("240-840, 9-3").expect_err("end before start");
        assert_eq!(
            error.to_string(),
            "\"9-3\" is not an outage: write START-END in seconds of log time, START before \
             END, e.g. 240-840"
        );
    }

    fn walk_north(n: usize) -> Vec<StepInput> {
        (0..n)
            .map(|k| StepInput {
                t_start_s: 0.5 * k as f64,
                t_s: 0.5 * (k + 1) as f64,
                length_m: 0.7,
                heading_rad: 0.0,
                heading_sigma_rad: None,
            })
            .collect()
    }

    #[test]
    fn outages_and_poor_fixes_are_not_used_and_a_drifted_track_recovers() {
        let steps = walk_north(400);
        // The truth walks 0.7 m per half second north, the steps say so too, but the
        // GNSS says the walker is 30 m east from 100 s on (as if the dead reckoning had
        // drifted during an outage from 60 s to 100 s).
        let fixes: Vec<FixInput> = (1..200)
            .map(|t| {
                let t_s = t as f64;
                let east = if t_s >= 100.0 { 30.0 } else { 0.0 };
                FixInput {
                    t_s,
                    en_m: [east, 1.4 * t_s],
                    hacc_m: Some(if t == 20 { 80.0 } else { 3.0 }),
                }
            })
            .collect();
        let policy = GnssPolicy {
            outages: vec![Outage {
                start_s: 60.0,
                end_s: 99.5,
            }],
            ..GnssPolicy::default()
        };
        let fused = fuse(
            &steps,
            &fixes,
            [0.0, 0.0],
            3.0,
            EkfNoise::default(),
            &policy,
        );
        assert_eq!(fused.track.len(), 401);
        assert_eq!(fused.fix_use[19], FixUse::PoorAccuracy);
        assert_eq!(fused.fix_use[70], FixUse::InOutage);
        assert_eq!(fused.fix_use[58], FixUse::Used);
        assert_eq!(fused.fix_use[98], FixUse::InOutage);
        assert!(fused.fix_use[99..104].contains(&FixUse::Rejected));
        assert!(fused.fix_use[99..110].contains(&FixUse::UsedAfterReset));
        let last = fused.track.last().expect("track");
        assert!((last.east_m - 30.0).abs() < 2.0, "{last:?}");
    }

    #[test]
    fn outages_parse_from_start_colon_end() {
        assert_eq!(
            Outage::parse("60:660.5"),
            Some(Outage {
                start_s: 60.0,
                end_s: 660.5
            })
        );
        assert_eq!(Outage::parse("60"), None);
        assert_eq!(Outage::parse("70:60"), None);
        assert_eq!(Outage::parse("a:b"), None);
    }

    #[test]
    fn no_steps_is_an_empty_track() {
        let fused = fuse(
            &[],
            &[],
            [0.0, 0.0],
            1.0,
            EkfNoise::default(),
            &GnssPolicy::default(),
        );
        assert!(fused.track.is_empty());
    }
}
