//! Where the track and the step model get their references: the local frame's anchor
//! (the first admissible fix), reference positions in that frame (tied to the GNSS
//! frame by their mean offset from the fixes), per-step references from the GNSS speed
//! where straight stretches between fixes confirm it, straight stretches long against
//! their fixes' accuracy, and the step model trained on the first set that has any
//! (Chen et al., Section III: the step length model is trained while GNSS is good),
//! else on a K from an earlier walk, else on a default.

use crate::base::geodesy::{Geodetic, LocalFrame};
use crate::io::recording::{Recording, Stream};

use super::fusion::{FixInput, GnssPolicy};
use super::step_length::{self, SegmentReference, StepLengthModel, StepModelKind, StepReference};
use super::steps::Step;
use super::{PdrOptions, StepModelReport};

/// The first fix with a position that the policy would take (its accuracy), where the
/// local frame is anchored.
pub(super) fn first_good_fix(recording: &Recording, policy: &GnssPolicy) -> Option<Geodetic> {
    recording
        .gnss
        .t_s
        .iter()
        .zip(&recording.gnss.values)
        .find_map(|(&t_s, fix)| {
            policy.admits(t_s, fix.hacc_m).ok()?;
            Some(Geodetic {
                lat_deg: fix.lat_deg?,
                lon_deg: fix.lon_deg?,
                alt_m: fix.alt_m.unwrap_or(0.0),
            })
        })
}

/// Reference positions in the filter's frame. Latitude/longitude references go through
/// the frame; metric references are used as they are without GNSS, and with GNSS are
/// shifted by their mean offset from the fixes that are used (both frames point east
/// and north, so a shift ties them).
pub(super) fn reference_positions(
    recording: &Recording,
    frame: Option<&LocalFrame>,
    fixes: &[FixInput],
    policy: &GnssPolicy,
    notes: &mut Vec<String>,
) -> Vec<(f64, [f64; 2])> {
    let mut out: Vec<(f64, [f64; 2])> = Vec::new();
    if let Some(frame) = frame {
        let lat_lon = &recording.ref_position_lat_lon_deg;
        out.extend(
            lat_lon
                .t_s
                .iter()
                .zip(&lat_lon.values)
                .map(|(&t_s, value)| {
                    let en = frame.en_of(value.x, value.y);
                    (t_s, [en.x, en.y])
                }),
        );
    }
    let metric = &recording.ref_position_en_m;
    if metric.is_empty() {
        return out;
    }
    let mut shift = [0.0, 0.0];
    if frame.is_some() {
        let mut n = 0usize;
        for fix in fixes.iter().filter(|fix| policy.admissible(fix).is_ok()) {
            if let Some(reference) = metric.interpolate_at(fix.t_s, 1.0) {
                shift[0] += fix.en_m[0] - reference.x;
                shift[1] += fix.en_m[1] - reference.y;
                n += 1;
            }
        }
        if n == 0 {
            notes.push("The reference positions do not overlap the GNSS fixes in time, so they cannot be placed in the GNSS frame and score nothing.".to_string());
            return out;
        }
        shift = [shift[0] / n as f64, shift[1] / n as f64];
        notes.push(format!(
            "The reference positions were tied to the GNSS frame by their mean offset from {n} fixes ({:.1} m east, {:.1} m north).",
            shift[0], shift[1]
        ));
    }
    out.extend(
        metric
            .t_s
            .iter()
            .zip(&metric.values)
            .map(|(&t_s, value)| (t_s, [value.x + shift[0], value.y + shift[1]])),
    );
    crate::base::sort::sort_by_key(&mut out, |point| point.0);
    out
}

/// Per-step references from the GNSS speed while GNSS is good: the speed at the middle
/// of the step (interpolated across at most 1.5 s) times its duration. The last step of
/// a bout, whose end is a guess, has none.
// A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
#[inline(never)]
pub(super) fn gnss_step_references(
    recording: &Recording,
    steps: &[Step],
    policy: &GnssPolicy,
) -> Vec<StepReference> {
    let mut speed = Stream::default();
    for (&t_s, fix) in recording.gnss.t_s.iter().zip(&recording.gnss.values) {
        if let (Some(speed_mps), Ok(_)) = (fix.speed_mps, policy.admits(t_s, fix.hacc_m)) {
            if speed_mps.is_finite() && speed_mps >= 0.0 {
                speed.push(t_s, speed_mps);
            }
        }
    }
    steps
        .iter()
        .enumerate()
        .filter(|(_, step)| !step.ends_bout)
        .filter_map(|(step_idx, step)| {
            let speed_mps = speed.interpolate_at(step.mid_s(), 1.5)?;
            Some(StepReference {
                step_idx,
                length_m: speed_mps * step.duration_s(),
            })
        })
        .collect()
}

/// A straight stretch between fixes trains the step model only when its length is at
/// least this many times the worst reported accuracy among its fixes: 15 m for fixes
/// of 5 m, so that a fix's slowly moving error (metres over the stretch's 20 s) cannot
/// make it half or twice as long.
const CHORD_PER_ACCURACY: f64 = 3.0;

/// Where the step model's references come from, in the order they are tried.
pub(super) struct ReferenceSets<'a> {
    pub(super) known_distance: Option<Vec<SegmentReference>>,
    pub(super) reference_positions: Option<Vec<SegmentReference>>,
    pub(super) gnss_speed: &'a [StepReference],
    pub(super) gnss_positions: Vec<SegmentReference>,
    /// The straight stretches whatever the fixes' accuracy: they cannot train the step
    /// model, but they can tell a GNSS speed that reads half the walking speed.
    pub(super) gnss_stretches_any_accuracy: Vec<SegmentReference>,
}

impl<'a> ReferenceSets<'a> {
    /// Every set for these steps: the known distance, the reference positions' and the
    /// admissible fixes' straight stretches, and the GNSS speed's per-step references.
    // A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
    #[inline(never)]
    pub(super) fn of(
        steps: &[Step],
        step_headings_rad: &[f64],
        fixes: &[FixInput],
        reference_en_m: &[(f64, [f64; 2])],
        gnss_references: &'a [StepReference],
        options: &PdrOptions,
    ) -> ReferenceSets<'a> {
        let admissible: Vec<(f64, [f64; 2], f64)> = fixes
            .iter()
            .filter_map(|fix| {
                let sigma_m = options.gnss.admissible(fix).ok()?;
                Some((fix.t_s, fix.en_m, sigma_m))
            })
            .collect();
        let admissible_fixes: Vec<(f64, [f64; 2])> = admissible
            .iter()
            .map(|&(t_s, en_m, _)| (t_s, en_m))
            .collect();
        // A stretch proves a length only when it is long against the fixes' accuracy.
        let gnss_stretches_any_accuracy =
            straight_segments(&admissible_fixes, steps, step_headings_rad, 20.0, 15.0);
        let mut gnss_positions = gnss_stretches_any_accuracy.clone();
        gnss_positions.retain(|segment| {
            let (Some(first), Some(last)) = (
                steps.get(segment.steps.start),
                segment
                    .steps
                    .end
                    .checked_sub(1)
                    .and_then(|idx| steps.get(idx)),
            ) else {
                return false;
            };
            let worst_sigma_m = admissible
                .iter()
                .filter(|(t_s, _, _)| (first.t_start_s..=last.t_end_s).contains(t_s))
                .map(|&(_, _, sigma_m)| sigma_m)
                .fold(0.0, f64::max);
            segment.distance_m >= CHORD_PER_ACCURACY * worst_sigma_m
        });
        ReferenceSets {
            known_distance: options.known_distance_m.map(|distance_m| {
                vec![SegmentReference {
                    steps: 0..steps.len(),
                    distance_m,
                }]
            }),
            reference_positions: options
                .train_on_reference_positions
                .then(|| straight_segments(reference_en_m, steps, step_headings_rad, 3.0, 5.0)),
            gnss_speed: gnss_references,
            gnss_positions,
            gnss_stretches_any_accuracy,
        }
    }
}

/// A GNSS speed trains the step model only where the distance between the fixes
/// confirms it: the lengths it gives the steps of the straight stretches, against the
/// stretches' own lengths, within these bounds.
const SPEED_CONFIRMED_BY_STRETCHES: [f64; 2] = [0.8, 1.25];

/// Why a step model fitted to the GNSS speed is not believed, if it is not.
pub(super) fn unconfirmed_speed(
    model: &StepLengthModel,
    steps: &[Step],
    stretches: &[SegmentReference],
) -> Option<String> {
    let (modelled_m, chord_m) = stretches
        .iter()
        .filter_map(|stretch| {
            let run = steps.get(stretch.steps.clone())?;
            Some((
                run.iter().map(|step| model.length_m(step)).sum::<f64>(),
                stretch.distance_m,
            ))
        })
        .fold((0.0, 0.0), |(a, b), (m, c)| (a + m, b + c));
    if chord_m <= 0.0 {
        return Some(
            "no straight stretch between the fixes confirms the distance it gives (a phone's fused GNSS speed read 44-62 % of the walking speed on the IPIN 2023 walks)".to_string(),
        );
    }
    let ratio = modelled_m / chord_m;
    let [low, high] = SPEED_CONFIRMED_BY_STRETCHES;
    (!(low..=high).contains(&ratio)).then(|| {
        format!(
            "on {} straight stretches between the fixes it makes the walk {:.0} % of their length",
            stretches.len(),
            100.0 * ratio
        )
    })
}

pub(super) fn train_step_model(
    steps: &[Step],
    sets: &ReferenceSets<'_>,
    options: &PdrOptions,
    notes: &mut Vec<String>,
) -> StepModelReport {
    let requested = options.step_model;
    let rms_on = |model: &StepLengthModel, segments: &[SegmentReference]| {
        let squares: Vec<f64> = segments
            .iter()
            .filter_map(|segment| {
                let run = steps.get(segment.steps.clone())?;
                let modelled: f64 = run.iter().map(|step| model.length_m(step)).sum();
                Some(((modelled - segment.distance_m) / run.len().max(1) as f64).powi(2))
            })
            .collect();
        (!squares.is_empty()).then(|| (squares.iter().sum::<f64>() / squares.len() as f64).sqrt())
    };
    let per_step: Vec<SegmentReference> = sets
        .gnss_speed
        .iter()
        .map(|reference| SegmentReference {
            steps: reference.step_idx..reference.step_idx + 1,
            distance_m: reference.length_m,
        })
        .collect();
    // The GNSS speed gives every step a reference (the linear model and the network
    // need many), and is taken first where the stretches confirm it.
    let candidates: [(&'static str, Option<&[SegmentReference]>); 4] = [
        ("known_distance", sets.known_distance.as_deref()),
        ("reference_positions", sets.reference_positions.as_deref()),
        (
            "gnss_speed",
            (!per_step.is_empty()).then_some(per_step.as_slice()),
        ),
        (
            "gnss_positions",
            (!sets.gnss_positions.is_empty()).then_some(sets.gnss_positions.as_slice()),
        ),
    ];
    for (source, segments) in candidates {
        let Some(segments) = segments else { continue };
        // Runs of several steps fit the network only through a Weinberg model.
        let kind = if requested == StepModelKind::Neural
            && segments.iter().any(|s| s.steps.len() != 1)
        {
            notes.push(format!(
                "The {source} references are distances over several steps, which train only the Weinberg and linear models; Weinberg's was fitted."
            ));
            StepModelKind::Weinberg
        } else {
            requested
        };
        match step_length::fit_segments(kind, steps, segments, options.seed) {
            Ok(model) => {
                let unconfirmed = (source == "gnss_speed")
                    .then(|| unconfirmed_speed(&model, steps, &sets.gnss_stretches_any_accuracy))
                    .flatten();
                if let Some(why) = unconfirmed {
                    notes.push(format!(
                        "The GNSS speed did not train the step model: {why}."
                    ));
                    continue;
                }
                let train_rms_m = rms_on(&model, segments);
                return StepModelReport {
                    requested,
                    model,
                    trained_on: source,
                    n_references: segments.len(),
                    train_rms_m,
                };
            }
            Err(error) => notes.push(format!(
                "The {source} references did not train the step model: {error}."
            )),
        }
    }
    if let Some(k) = options.weinberg_k.filter(|k| k.is_finite() && *k > 0.0) {
        if requested != StepModelKind::Weinberg {
            notes.push(format!(
                "Nothing in the log trains the {} model; the given Weinberg K was used.",
                requested.key()
            ));
        }
        return StepModelReport {
            requested,
            model: StepLengthModel::Weinberg { k },
            trained_on: "given_k",
            n_references: 0,
            train_rms_m: None,
        };
    }
    notes.push(format!(
        "Nothing in the log proves a step length (no straight stretch between fixes long against their accuracy, no GNSS speed they confirm, no known distance): Weinberg's K = {} was used. Give --known-distance for a walk of known length, or --weinberg-k from an earlier walk.",
        step_length::DEFAULT_WEINBERG_K
    ));
    StepModelReport {
        requested,
        model: StepLengthModel::Weinberg {
            k: step_length::DEFAULT_WEINBERG_K,
        },
        trained_on: "default",
        n_references: 0,
        train_rms_m: None,
    }
}

/// The steps whose middle lies between two times.
pub(super) fn steps_between(steps: &[Step], start_s: f64, end_s: f64) -> std::ops::Range<usize> {
    let first = steps.partition_point(|step| step.mid_s() < start_s);
    let last = steps.partition_point(|step| step.mid_s() <= end_s);
    first..last.max(first)
}

/// The speed (m/s) of the least-squares line through timed positions.
pub(super) fn line_speed_mps(positions: &[(f64, [f64; 2])]) -> Option<f64> {
    let n = positions.len() as f64;
    let mean_t = positions.iter().map(|(t, _)| t).sum::<f64>() / n;
    let mean_e = positions.iter().map(|(_, p)| p[0]).sum::<f64>() / n;
    let mean_n = positions.iter().map(|(_, p)| p[1]).sum::<f64>() / n;
    let (mut stt, mut ste, mut stn) = (0.0, 0.0, 0.0);
    for (t, p) in positions {
        let dt = t - mean_t;
        stt += dt * dt;
        ste += dt * (p[0] - mean_e);
        stn += dt * (p[1] - mean_n);
    }
    (stt > 0.0).then(|| (ste * ste + stn * stn).sqrt() / stt)
}

/// The circular spread (rad) of the headings of a run of steps.
pub(super) fn heading_spread_rad(headings: &[f64]) -> f64 {
    let n = headings.len().max(1) as f64;
    let (sin, cos) = headings
        .iter()
        .fold((0.0, 0.0), |(s, c), h| (s + h.sin(), c + h.cos()));
    let resultant = ((sin / n).powi(2) + (cos / n).powi(2)).sqrt().min(1.0);
    (-2.0 * resultant.max(1e-12).ln()).sqrt()
}

/// Segments between positions (GNSS fixes or reference positions) on straight
/// stretches: from each position, the first one at least `span_s` later; kept when the
/// steps between them hold their heading (spread under 8°), so that the path is a line.
/// Its length is the speed of a least-squares line through all the positions of the
/// span times the span: over 20 fixes of 3 m noise that is good to about 2.3 m, where
/// the chord between the two end fixes would be good to 4.2 m. The
/// end is chosen by time, not by distance: choosing the first fix far enough away
/// would prefer fixes whose noise lengthens the chord. The next segment starts where
/// this one ended.
pub(super) fn straight_segments(
    positions: &[(f64, [f64; 2])],
    steps: &[Step],
    step_headings_rad: &[f64],
    span_s: f64,
    min_chord_m: f64,
) -> Vec<SegmentReference> {
    let mut segments = Vec::new();
    let mut start = 0usize;
    while start < positions.len() {
        let (t_a, _) = positions[start];
        let Some(offset) = positions[start + 1..]
            .iter()
            .position(|(t_b, _)| t_b - t_a >= span_s)
        else {
            break;
        };
        let end = start + 1 + offset;
        let (t_b, _) = positions[end];
        let span = positions.get(start..=end).unwrap_or(&[]);
        let chord_m = line_speed_mps(span).map_or(0.0, |speed| speed * (t_b - t_a));
        if span.len() < 3 || t_b - t_a > 2.0 * span_s || chord_m < min_chord_m {
            start += 1;
            continue;
        }
        let run = steps_between(steps, t_a, t_b);
        let straight = step_headings_rad.get(run.clone()).is_some_and(|headings| {
            !headings.is_empty() && heading_spread_rad(headings) < 8f64.to_radians()
        });
        let walking = steps
            .get(run.clone())
            .is_some_and(|run| !run.iter().any(|step| step.ends_bout));
        if straight && walking && run.len() >= 5 {
            segments.push(SegmentReference {
                steps: run,
                distance_m: chord_m,
            });
            start = end;
        } else {
            start += 1;
        }
    }
    segments
}

/// The filter's start: the first admissible fix within 5 s of the first step (σ its
/// accuracy), else the first reference position (a surveyed start, σ 0.5 m), else the
/// origin (σ 0).
pub(super) fn start_position(
    first_step: &Step,
    fixes: &[FixInput],
    reference_en_m: &[(f64, [f64; 2])],
    policy: &GnssPolicy,
) -> ([f64; 2], f64) {
    let near_start = fixes
        .iter()
        .filter(|fix| (fix.t_s - first_step.t_start_s).abs() <= 5.0)
        .find_map(|fix| {
            policy
                .admissible(fix)
                .ok()
                .map(|sigma_m| (fix.en_m, sigma_m))
        });
    if let Some(found) = near_start {
        return found;
    }
    if let Some((_, first)) = reference_en_m.first() {
        return (*first, 0.5);
    }
    ([0.0, 0.0], 0.0)
}

/// Each step's reference length: from dense reference positions (5 Hz or more: the
/// distance between the positions at its start and end), else its GNSS reference.
// A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
#[inline(never)]
pub(super) fn step_reference_lengths(
    steps: &[Step],
    reference_en_m: &[(f64, [f64; 2])],
    gnss_references: &[StepReference],
) -> Vec<Option<f64>> {
    let dense = reference_en_m.len() >= 2 && {
        let span_s = reference_en_m.last().map_or(0.0, |r| r.0) - reference_en_m[0].0;
        span_s > 0.0 && reference_en_m.len() as f64 / span_s >= 5.0
    };
    if dense {
        let stream = Stream {
            t_s: reference_en_m.iter().map(|(t, _)| *t).collect(),
            values: reference_en_m
                .iter()
                .map(|(_, en)| nalgebra::Vector2::new(en[0], en[1]))
                .collect(),
        };
        return steps
            .iter()
            .map(|step| {
                if step.ends_bout {
                    return None;
                }
                let a = stream.interpolate_at(step.t_start_s, 0.5)?;
                let b = stream.interpolate_at(step.t_end_s, 0.5)?;
                Some((b - a).norm())
            })
            .collect();
    }
    let mut out = vec![None; steps.len()];
    for reference in gnss_references {
        if let Some(slot) = out.get_mut(reference.step_idx) {
            *slot = Some(reference.length_m);
        }
    }
    out
}
