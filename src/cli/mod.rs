//! Argument parsing and file handling for the `compass-pdr` CLI. Everything it computes
//! comes from the core ([`compass_pdr::pipeline`] for the analyses); this module reads
//! files, writes files and prints.
//!
//! One file per command (`simulate.rs`, `inspect.rs`, `calibrate.rs`, `heading.rs`,
//! `pdr.rs` with `report`), the arguments they share in `args.rs`, the remembered
//! column mappings (`--map`) in `mapping_store.rs`, the allocator's huge-page hint in
//! `huge_pages.rs`; this file holds the command line and its dispatch. Several files are
//! one recording, read and merged by `inspect.rs`'s `import_paths`. Diagnostics go to
//! stderr as `file:line: message`; the exit code is 1 on a refused file (and, for
//! `calibrate`, on a log where no method could be fitted; the other commands then
//! answer uncalibrated).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use compass_pdr::analysis::calibration::Method;
use compass_pdr::analysis::headings::HeadingOptions;

/// Large blocks (a file's streams) are mapped in huge pages where the system allows it.
#[global_allocator]
static ALLOCATOR: huge_pages::HugePageHint = huge_pages::HugePageHint;

/// Magnetometer compass calibration, heading models and pedestrian dead reckoning.
#[derive(Debug, Parser)]
#[command(name = "compass-pdr", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Write a simulated walk (canonical CSV) with a distorted magnetometer and its truth.
    Simulate {
        /// Seed: the same seed gives the same log, byte for byte.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Length of the walk in seconds.
        #[arg(long, default_value_t = 180.0)]
        duration_s: f64,
        /// Where to write the log: the canonical CSV, or NMEA 0183 (RMC, GGA, VTG at each
        /// GNSS fix, the compass's HDG and the true HDT at 10 Hz) for a name ending in
        /// `.nmea`. The dance is always MotionCal `Raw:` lines.
        #[arg(long)]
        out: PathBuf,
        /// Where to write the simulator's parameters as JSON (the truth); for the PDR
        /// scenario, with the truth of every step.
        #[arg(long)]
        truth: Option<PathBuf>,
        /// Which scenario: the demo's walk, the PDR walk (varied steps with per-step
        /// truth, a compass error of the unified model, GNSS with 3 m noise), a steady
        /// walk without GNSS, a turntable, a car's loop, the 2007 paper's raw case, or a
        /// board's calibration dance.
        #[arg(long, value_enum, default_value_t = Scenario::Demo)]
        scenario: Scenario,
        /// Samples per second of the motion sensors (phones log at 50 or 100).
        #[arg(long, default_value_t = 50.0)]
        sample_rate_hz: f64,
    },
    /// Calibrate the magnetometer of a log and compare headings with its reference.
    Calibrate {
        #[command(flatten)]
        input: ImportArgs,
        /// Which method to run, or all of them side by side.
        #[arg(long, value_enum, default_value_t = MethodChoice::All)]
        method: MethodChoice,
        #[command(flatten)]
        analysis: AnalysisArgs,
        /// Print the result as JSON.
        #[arg(long)]
        json: bool,
        /// Also draw the circle-fit, heading-error and |B| plots to this SVG file.
        #[arg(long)]
        plot: Option<PathBuf>,
        /// Write the device calibration as a C/Arduino snippet to this file.
        #[arg(long)]
        export_c: Option<PathBuf>,
        /// Write the device calibration as a MotionCal 68-byte packet to this file.
        #[arg(long)]
        export_packet: Option<PathBuf>,
        /// Write an autopilot log's new compass calibration as an ArduPilot .param file
        /// (Mission Planner's "Load from file", MAVProxy's `param load`).
        #[arg(long)]
        param_out: Option<PathBuf>,
    },
    /// Learn the heading error from a reference (the unified Fourier model of the PDR
    /// paper, adapted online too) on top of every calibration method, and compare every
    /// heading method on one train/check split.
    Heading {
        #[command(flatten)]
        input: ImportArgs,
        #[command(flatten)]
        analysis: AnalysisArgs,
        /// Print the result as JSON.
        #[arg(long)]
        json: bool,
        /// Also draw the deviation curve, the residual histogram, the heading error over
        /// time and the online coefficients to this SVG file.
        #[arg(long)]
        plot: Option<PathBuf>,
        /// Write the attitude filter's output (the gyroscope, the accelerometer and the
        /// calibrated magnetometer fused; run forward and backward over the log and
        /// combined) as CSV to this file: `t_s,yaw_deg,pitch_deg,roll_deg,yaw_sigma_deg`.
        #[arg(long)]
        attitude_out: Option<PathBuf>,
    },
    /// Dead-reckon a walk: steps, step lengths trained on GNSS (or a known distance),
    /// headings from the best heading model, and the [E, N, l, a] EKF that bridges GNSS
    /// outages; with the paper's accuracy figures against reference positions.
    Pdr {
        #[command(flatten)]
        input: ImportArgs,
        #[command(flatten)]
        pdr: PdrArgs,
        /// Print the result as JSON.
        #[arg(long)]
        json: bool,
        /// Write the track: .csv (local metres, and latitude/longitude when the log has
        /// GNSS), .geojson or .gpx (these need GNSS).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Draw the trajectory, the step lengths and the position error to this SVG file.
        #[arg(long)]
        plot: Option<PathBuf>,
    },
    /// Analyse a log the way the page does (calibration, heading models, dead
    /// reckoning) and write the page's self-contained HTML report, with the figures as
    /// SVG.
    Report {
        #[command(flatten)]
        input: ImportArgs,
        #[command(flatten)]
        pdr: PdrArgs,
        /// Where to write the report (.html).
        #[arg(long)]
        out: PathBuf,
    },
    /// Show what a log holds: its format, streams (count, rate, duration, gaps), what
    /// was assumed, and every line that was skipped.
    Inspect {
        #[command(flatten)]
        input: ImportArgs,
        /// Print the result as JSON.
        #[arg(long)]
        json: bool,
    },
}

mod args;
mod calibrate;
mod heading;
mod huge_pages;
mod inspect;
mod mapping_store;
mod pdr;
mod simulate;

use args::{AnalysisArgs, ImportArgs, MethodChoice, PdrArgs};
use calibrate::{run_calibrate, Outputs};
use heading::{run_heading, HeadingOutputs};
use inspect::run_inspect;
use pdr::{run_pdr, run_report};
use simulate::{run_simulate, Scenario};

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Simulate {
            seed,
            duration_s,
            out,
            truth,
            scenario,
            sample_rate_hz,
        } => run_simulate(
            seed,
            duration_s,
            scenario,
            sample_rate_hz,
            &out,
            truth.as_deref(),
        ),
        Command::Inspect { input, json } => run_inspect(&input, json),
        Command::Pdr {
            input,
            pdr,
            json,
            out,
            plot,
        } => pdr
            .options()
            .and_then(|options| run_pdr(&input, &options, json, out.as_deref(), plot.as_deref())),
        Command::Report { input, pdr, out } => pdr
            .options()
            .and_then(|options| run_report(&input, &options, &out)),
        Command::Calibrate {
            input,
            method,
            analysis,
            json,
            plot,
            export_c,
            export_packet,
            param_out,
        } => analysis.options(method.methods()).and_then(|options| {
            let outputs = Outputs {
                json,
                plot: plot.as_deref(),
                export_c: export_c.as_deref(),
                export_packet: export_packet.as_deref(),
                param_out: param_out.as_deref(),
            };
            run_calibrate(&input, &options, &outputs)
        }),
        Command::Heading {
            input,
            analysis,
            json,
            plot,
            attitude_out,
        } => analysis
            .options(Method::ALL.to_vec())
            .and_then(|calibration| {
                let options = HeadingOptions {
                    calibration,
                    ..HeadingOptions::default()
                };
                let outputs = HeadingOutputs {
                    json,
                    plot: plot.as_deref(),
                    attitude_out: attitude_out.as_deref(),
                };
                run_heading(&input, &options, &outputs)
            }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

/// Prints a report as pretty JSON, or as the text `text` makes of it.
fn print_report<T: serde::Serialize>(
    report: &T,
    json: bool,
    text: impl FnOnce(&T) -> String,
) -> Result<(), String> {
    if json {
        let encoded = serde_json::to_string_pretty(report)
            .map_err(|error| format!("cannot encode the result: {error}"))?;
        print_out(&(encoded + "\n"))
    } else {
        print_out(&text(report))
    }
}

/// Writes to stdout; a closed pipe (`| head`) ends the output quietly instead of
/// panicking as `println!` would.
fn print_out(text: &str) -> Result<(), String> {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    match stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
    {
        Ok(()) => Ok(()),
        Err(error) if error.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(error) => Err(format!("cannot write to standard output: {error}")),
    }
}
