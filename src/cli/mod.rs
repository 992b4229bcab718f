//! Argument parsing and file handling for the `compass-pdr` CLI. Everything it computes
//! comes from the core; this module reads files, writes files and prints.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use compass_pdr::analysis::{analyse_minmax_csv, MinMaxSummary, Options};
use compass_pdr::io::canonical_csv;
use compass_pdr::plot::draw_minmax_figure;
use compass_pdr::sim::walk::{simulate, WalkConfig};
use compass_pdr::stats::HeadingErrorStats;
use plotters::prelude::{IntoDrawingArea, SVGBackend};

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
        /// Where to write the canonical CSV.
        #[arg(long)]
        out: PathBuf,
        /// Where to write the simulator's parameters as JSON (the truth).
        #[arg(long)]
        truth: Option<PathBuf>,
    },
    /// Calibrate the magnetometer of a log and compare headings with its reference.
    Calibrate {
        /// A canonical CSV log.
        file: PathBuf,
        #[arg(long, value_enum, default_value_t = Method::Minmax)]
        method: Method,
        /// Declination in degrees (true north from magnetic north, east positive).
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        declination: f64,
        /// Print the result as JSON.
        #[arg(long)]
        json: bool,
        /// Also draw the circle-fit and heading-error plots to this SVG file.
        #[arg(long)]
        plot: Option<PathBuf>,
    },
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Method {
    /// Min/max autocalibration (Eq. 6-7 of the 2007 paper).
    Minmax,
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Simulate {
            seed,
            duration_s,
            out,
            truth,
        } => run_simulate(seed, duration_s, &out, truth.as_deref()),
        Command::Calibrate {
            file,
            method: Method::Minmax,
            declination,
            json,
            plot,
        } => run_calibrate(
            &file,
            Options {
                declination_deg: declination,
                ..Options::default()
            },
            json,
            plot.as_deref(),
        ),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn run_simulate(
    seed: u64,
    duration_s: f64,
    out: &Path,
    truth: Option<&Path>,
) -> Result<(), String> {
    if !(duration_s.is_finite() && duration_s > 0.0 && duration_s <= 24.0 * 3600.0) {
        return Err(format!(
            "--duration-s {duration_s} is out of range: give a number of seconds from 0 to 86400"
        ));
    }
    let config = WalkConfig::from_seed(seed, duration_s);
    let text = canonical_csv::write(&simulate(&config));
    std::fs::write(out, text)
        .map_err(|error| format!("cannot write {}: {error}", out.display()))?;
    if let Some(truth) = truth {
        let json = serde_json::to_string_pretty(&config)
            .map_err(|error| format!("cannot encode the truth: {error}"))?;
        std::fs::write(truth, json + "\n")
            .map_err(|error| format!("cannot write {}: {error}", truth.display()))?;
    }
    Ok(())
}

fn run_calibrate(
    file: &Path,
    options: Options,
    json: bool,
    plot: Option<&Path>,
) -> Result<(), String> {
    let bytes =
        std::fs::read(file).map_err(|error| format!("cannot read {}: {error}", file.display()))?;
    let file_name = file.display().to_string();
    let analysis =
        analyse_minmax_csv(&file_name, &bytes, options).map_err(|error| error.to_string())?;
    let summary = &analysis.summary;
    print_diagnostics(summary);
    if let Some(plot) = plot {
        let root = SVGBackend::new(plot, (1200, 520)).into_drawing_area();
        draw_minmax_figure(&root, &analysis)
            .map_err(|error| format!("{error} ({})", plot.display()))?;
    }
    if json {
        let text = serde_json::to_string_pretty(summary)
            .map_err(|error| format!("cannot encode the result: {error}"))?;
        print_out(&(text + "\n"))
    } else {
        print_out(&summary_text(summary))
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

/// Every skipped or suspect line goes to stderr as `file:line: message`.
fn print_diagnostics(summary: &MinMaxSummary) {
    for diagnostic in &summary.diagnostics.kept {
        match diagnostic.line {
            Some(line) => eprintln!(
                "warning: {}:{line}: {}",
                summary.file_name, diagnostic.message
            ),
            None => eprintln!("warning: {}: {}", summary.file_name, diagnostic.message),
        }
    }
    if summary.diagnostics.n_not_kept > 0 {
        eprintln!(
            "warning: {}: {} more lines had problems (not listed)",
            summary.file_name, summary.diagnostics.n_not_kept
        );
    }
}

fn summary_text(summary: &MinMaxSummary) -> String {
    use std::fmt::Write as _;
    let mut text = String::new();
    let calibration = &summary.calibration;
    let _ = writeln!(
        text,
        "{}: min/max calibration of {} magnetometer samples",
        summary.file_name, summary.n_samples_used
    );
    let _ = writeln!(
        text,
        "  scale   Sx = {:.4}, Sy = {:.4}",
        calibration.scale_x, calibration.scale_y
    );
    let _ = writeln!(
        text,
        "  bias    Bx = {:.2} µT, By = {:.2} µT",
        calibration.bias_x_ut, calibration.bias_y_ut
    );
    let _ = writeln!(
        text,
        "  centre  ({:.2}, {:.2}) µT in the level plane",
        calibration.center_x_ut, calibration.center_y_ut
    );
    let _ = writeln!(
        text,
        "  coverage {}/{} heading bins of 10°, largest gap {:.0}°",
        calibration.coverage.n_bins_covered,
        calibration.coverage.n_bins,
        calibration.coverage.largest_gap_deg
    );
    let mut print_stats = |label: &str, stats: &Option<HeadingErrorStats>| {
        if let Some(stats) = stats {
            let _ = writeln!(
                text,
                "  heading error {label}: mean {:.2}°, std {:.2}°, RMS {:.2}°, p95 {:.2}°, \
                 within ±5° {:.1}% (n = {})",
                stats.mean_deg,
                stats.std_deg,
                stats.rms_deg,
                stats.p95_abs_deg,
                stats.within_5_deg_pct,
                stats.n_samples
            );
        }
    };
    print_stats("before", &summary.heading_error_before);
    print_stats("after ", &summary.heading_error_after);
    for note in &summary.notes {
        let _ = writeln!(text, "  note: {note}");
    }
    text
}
