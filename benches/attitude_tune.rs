//! The attitude filter's tuning judged across the nine TYREX trials at once, with
//! leave-one-trial-out figures (issue 43): every combination of a few values of its
//! noise settings ([`AttitudeOptions`]) runs on every trial, each scored against the
//! motion capture as `bench/attitude_peers.py` scores it (the heading of body x, RMS
//! after removing one constant offset per trial). For each trial, the setting with the
//! lowest geometric-mean RMS over the other eight is run on it: what a tuning on eight
//! trials would give on a ninth that it never saw.
//!
//! Each trial runs as `heading --attitude-out` runs it (`attitude::track::attitude_of`
//! with the analysis's device calibration, or the phone's own hard-iron estimate where
//! that lets the gates pass more field), so the defaults' row is ACCURACY.md's.
//!
//!   bash bench/attitude.sh      # writes target/bench-results/tyrex-truth/ (once)
//!   cargo bench --bench attitude_tune --profile bench-import
//!
//! Under `cargo test` it does nothing (the truth is written by the benchmark script).

#[cfg(not(target_arch = "wasm32"))]
#[path = "../tests/common/mod.rs"]
mod common;

#[cfg(not(target_arch = "wasm32"))]
mod native {
    use std::path::Path;

    use compass_pdr::analysis::attitude_track::attitude_of;
    use compass_pdr::analysis::headings::HeadingOptions;
    use compass_pdr::attitude::smoother::Runs;
    use compass_pdr::attitude::AttitudeOptions;
    use compass_pdr::base::angle::wrap_to_pi;
    use compass_pdr::io::recording::Stream;
    use compass_pdr::pipeline;

    use super::common;

    /// Attitude outputs further apart than this (s) are not interpolated across.
    const MAX_GAP_S: f64 = 0.5;

    /// `(t_s, heading_deg)` rows of a truth file written by `attitude_peers.py`.
    fn read_truth(path: &Path) -> Option<Vec<(f64, f64)>> {
        let text = std::fs::read_to_string(path).ok()?;
        Some(
            text.lines()
                .filter(|line| !line.starts_with('#'))
                .filter_map(|line| {
                    let (t, heading) = line.split_once(',')?;
                    Some((t.trim().parse().ok()?, heading.trim().parse().ok()?))
                })
                .collect(),
        )
    }

    /// RMS (degrees) of the yaw against the truth after removing the constant offset
    /// that minimises it (the mocap room's north is not the Earth's).
    fn offset_removed_rms_deg(yaw_rad: &Stream<f64>, truth: &[(f64, f64)]) -> f64 {
        let errors: Vec<f64> = truth
            .iter()
            .filter_map(|&(t_s, truth_deg)| {
                let yaw = yaw_rad.interpolate_angle_at(t_s, MAX_GAP_S)?;
                Some(wrap_to_pi(yaw - truth_deg.to_radians()))
            })
            .collect();
        let n = errors.len().max(1) as f64;
        let (sin, cos) = errors
            .iter()
            .fold((0.0, 0.0), |(s, c), e| (s + e.sin(), c + e.cos()));
        // The circular mean, refined to the offset that minimises the RMS, as
        // bench/attitude_peers.py's offset_removed_rms does.
        let mut offset = sin.atan2(cos);
        for _ in 0..3 {
            offset += errors.iter().map(|e| wrap_to_pi(e - offset)).sum::<f64>() / n;
        }
        (errors
            .iter()
            .map(|e| wrap_to_pi(e - offset).powi(2))
            .sum::<f64>()
            / n)
            .sqrt()
            .to_degrees()
    }

    /// The settings tried: the magnetic heading's noise density (half to four times the
    /// default), the gyroscope's angle random walk and gravity's direction noise (each
    /// at half, once and twice the default).
    fn settings(base: AttitudeOptions) -> Vec<(String, AttitudeOptions)> {
        let mut all = Vec::new();
        for heading in [0.5, 1.0, 1.5, 2.0, 3.0, 4.0] {
            for arw in [0.5, 1.0, 2.0] {
                for gravity in [0.5, 1.0, 2.0] {
                    let mut options = base;
                    options.heading_noise_rad_sqrt_s *= heading;
                    options.noise.gyro_arw_rad_per_sqrt_s *= arw;
                    options.gravity_sigma_rad *= gravity;
                    all.push((
                        format!("field ×{heading} arw ×{arw} gravity ×{gravity}"),
                        options,
                    ));
                }
            }
        }
        all
    }

    pub fn main() {
        if !std::env::args().any(|arg| arg == "--bench") {
            return;
        }
        let Some(data) = common::shared_data() else {
            return;
        };
        let truth_dir =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-results/tyrex-truth");
        let mut trials = common::tyrex_trials(&data);
        trials.extend(common::tyrex_trials_in(&data, "tyrex-attitude-more"));
        let mut names = Vec::new();
        // rms[setting][trial]
        let mut rms: Vec<Vec<f64>> = Vec::new();
        let mut labels = Vec::new();
        for (name, paths) in &trials {
            let Some(truth) = read_truth(&truth_dir.join(format!("{name}.csv"))) else {
                eprintln!(
                    "{name}: no truth in {}: run bash bench/attitude.sh first",
                    truth_dir.display()
                );
                return;
            };
            let import = common::import_paths(paths);
            let (calibration, _) =
                pipeline::headings(&import, &HeadingOptions::default()).expect("an analysis");
            let device = calibration.device_calibration().map(|(_, field)| field);
            let recording = &import.recording;
            let all = settings(AttitudeOptions::for_gyro(recording.gyro_bias));
            if rms.is_empty() {
                rms = vec![Vec::new(); all.len()];
                labels = all.iter().map(|(label, _)| label.clone()).collect();
            }
            for (idx, (_, options)) in all.iter().enumerate() {
                let (track, _) = attitude_of(recording, device.as_ref(), options, Runs::BothWays)
                    .expect("a track");
                let mut yaw = Stream::default();
                for (&t_s, estimate) in track.attitude.t_s.iter().zip(&track.attitude.values) {
                    yaw.push(t_s, estimate.yaw_rad);
                }
                rms[idx].push(offset_removed_rms_deg(&yaw, &truth));
            }
            names.push(name.replace("Thibaud_Nexus5_", ""));
        }
        let log_mean = |row: &[f64], skip: Option<usize>| {
            let kept: Vec<f64> = row
                .iter()
                .enumerate()
                .filter(|(idx, _)| Some(*idx) != skip)
                .map(|(_, rms)| rms.ln())
                .collect();
            (kept.iter().sum::<f64>() / kept.len() as f64).exp()
        };
        let default = labels
            .iter()
            .position(|label| label == "field ×1 arw ×1 gravity ×1")
            .expect("the defaults are among the settings");
        let mut order: Vec<usize> = (0..labels.len()).collect();
        order.sort_by(|&a, &b| log_mean(&rms[a], None).total_cmp(&log_mean(&rms[b], None)));
        println!("| setting | geometric mean | {} |", names.join(" | "));
        println!("|---|---:|{}", "---:|".repeat(names.len()));
        for &idx in order.iter().take(8).chain(std::iter::once(&default)) {
            let cells: Vec<String> = rms[idx].iter().map(|r| format!("{r:.1}")).collect();
            println!(
                "| {}{} | {:.2}° | {} |",
                labels[idx],
                if idx == default { " (default)" } else { "" },
                log_mean(&rms[idx], None),
                cells.join(" | ")
            );
        }
        println!("\nLeave one trial out: the setting best on the other eight, on the ninth.\n");
        println!("| trial | chosen on the other eight | its RMS | the default's |");
        println!("|---|---|---:|---:|");
        for (trial, name) in names.iter().enumerate() {
            let chosen = (0..labels.len())
                .min_by(|&a, &b| {
                    log_mean(&rms[a], Some(trial)).total_cmp(&log_mean(&rms[b], Some(trial)))
                })
                .expect("settings");
            println!(
                "| {name} | {} | {:.1}° | {:.1}° |",
                labels[chosen], rms[chosen][trial], rms[default][trial]
            );
        }
    }
}

#[cfg(not(target_arch = "wasm32"))]
fn main() {
    native::main();
}

#[cfg(target_arch = "wasm32")]
fn main() {}
