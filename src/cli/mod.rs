//! Argument parsing and file handling for the `compass-pdr` CLI. Everything it computes
//! comes from the core; this module reads files, writes files and prints.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use compass_pdr::analysis::{analyse_minmax, MinMaxSummary, Options};
use compass_pdr::io::canonical_csv;
use compass_pdr::io::delimited::ColumnMapping;
use compass_pdr::io::import::{header_signature, merge, ChunkedImport, Inspection};
use compass_pdr::io::{Diagnostics, ImportReport};
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
        #[command(flatten)]
        input: ImportArgs,
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

/// The files to read, and how to read their columns.
#[derive(Debug, clap::Args)]
struct ImportArgs {
    /// The log: one file, or the files of one recording (e.g. phyphox's per-sensor CSVs),
    /// merged by time. The format is told from the content.
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Read columns of a delimited file under other names, `COLUMN=NAME,…`, for example
    /// `Bx=mag_x_gauss,By=mag_y_gauss,Bz=mag_z_gauss,time=t_ms` (the unit in the name
    /// overrides a guessed one; `ignore` leaves a column out). It is remembered for
    /// files with the same header, in $XDG_CONFIG_HOME/compass-pdr/mappings.json.
    #[arg(long)]
    map: Option<String>,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Method {
    /// Min/max autocalibration (Eq. 6-7 of the 2007 paper).
    Minmax,
}

mod mapping_store;

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Simulate {
            seed,
            duration_s,
            out,
            truth,
        } => run_simulate(seed, duration_s, &out, truth.as_deref()),
        Command::Inspect { input, json } => run_inspect(&input, json),
        Command::Calibrate {
            input,
            method: Method::Minmax,
            declination,
            json,
            plot,
        } => run_calibrate(
            &input,
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

/// Reads the files of one recording in chunks (memory holds the samples, not the
/// text) and merges them. A file that cannot be opened ends the command with its name;
/// one that cannot be parsed is left out with a diagnostic unless all fail. A column
/// mapping given with `--map` is remembered for the file's header; without one, a
/// remembered mapping is used and said so.
fn import_paths(input: &ImportArgs) -> Result<ImportReport, String> {
    use std::io::Read as _;
    const CHUNK_BYTES: usize = 1 << 20;
    let given_mapping = input
        .map
        .as_deref()
        .map(ColumnMapping::parse)
        .transpose()
        .map_err(|error| format!("--map: {error}"))?;
    let mut store = mapping_store::MappingStore::load();
    let mut results = Vec::with_capacity(input.files.len());
    let mut buffer = vec![0u8; CHUNK_BYTES];
    for path in &input.files {
        let file_name = path.display().to_string();
        let cannot_read = |error: std::io::Error| format!("cannot read {file_name}: {error}");
        let mut file = std::fs::File::open(path).map_err(cannot_read)?;
        let size_hint = file
            .metadata()
            .ok()
            .and_then(|metadata| usize::try_from(metadata.len()).ok());
        let mut n_read = file.read(&mut buffer).map_err(cannot_read)?;
        let first_chunk = buffer.get(..n_read).unwrap_or_default();
        let signature = header_signature(first_chunk);
        let mapping = match (&given_mapping, &signature) {
            (Some(mapping), Some(signature)) => {
                store.remember(signature, mapping);
                Some(mapping.clone())
            }
            (Some(mapping), None) => Some(mapping.clone()),
            (None, Some(signature)) => store.recall(signature).inspect(|_| {
                eprintln!(
                    "note: {file_name}: using the column mapping remembered for this header ({}); pass --map to change it",
                    store.path_text()
                );
            }),
            (None, None) => None,
        };
        let mut import = ChunkedImport::new(&file_name, size_hint).with_mapping(mapping);
        let mut result = Ok(());
        while n_read > 0 {
            let Some(chunk) = buffer.get(..n_read) else {
                break;
            };
            result = import.feed(chunk);
            if result.is_err() {
                break;
            }
            n_read = file.read(&mut buffer).map_err(cannot_read)?;
        }
        results.push((file_name, result.and_then(|()| import.finish())));
    }
    if let Err(message) = store.save_if_changed() {
        eprintln!("warning: {message}");
    }
    merge(results).map_err(|error| error.to_string())
}

fn run_inspect(input: &ImportArgs, json: bool) -> Result<(), String> {
    let report = import_paths(input)?;
    let inspection = Inspection::of(&report);
    print_import_diagnostics(&inspection.file_name, &inspection.diagnostics);
    if json {
        let text = serde_json::to_string_pretty(&inspection)
            .map_err(|error| format!("cannot encode the result: {error}"))?;
        return print_out(&(text + "\n"));
    }
    use std::fmt::Write as _;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{}: {}, {} data lines, {} lines skipped or suspect",
        inspection.file_name,
        inspection.format,
        inspection.n_data_lines,
        inspection.diagnostics.total()
    );
    let _ = writeln!(
        text,
        "  {:<34} {:>9} {:>9} {:>10} {:>5} {:>9} {:>8} {:>11}",
        "stream", "samples", "rate Hz", "duration s", "gaps", "max gap s", "repeats", "mean |v|"
    );
    for stream in &inspection.streams {
        let _ = writeln!(
            text,
            "  {:<34} {:>9} {:>9} {:>10.2} {:>5} {:>9.3} {:>8} {:>11}",
            stream.stream,
            stream.n_samples,
            stream
                .rate_hz
                .map_or("—".to_string(), |rate_hz| format!("{rate_hz:.2}")),
            stream.duration_s,
            stream.n_gaps,
            stream.largest_gap_s,
            stream.n_repeated_times,
            stream
                .mean_magnitude
                .map_or(String::new(), |magnitude| format!(
                    "{magnitude:.3} {}",
                    stream.unit
                )),
        );
    }
    for note in &inspection.notes {
        let _ = writeln!(text, "  note: {note}");
    }
    print_out(&text)
}

fn run_calibrate(
    input: &ImportArgs,
    options: Options,
    json: bool,
    plot: Option<&Path>,
) -> Result<(), String> {
    let report = import_paths(input)?;
    let analysis = analyse_minmax(report, options).map_err(|error| error.to_string())?;
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
    print_import_diagnostics(&summary.file_name, &summary.diagnostics);
}

fn print_import_diagnostics(file_name: &str, diagnostics: &Diagnostics) {
    for diagnostic in &diagnostics.kept {
        let file_name = diagnostic.file_name.as_deref().unwrap_or(file_name);
        match diagnostic.line {
            Some(line) => eprintln!("warning: {file_name}:{line}: {}", diagnostic.message),
            None => eprintln!("warning: {file_name}: {}", diagnostic.message),
        }
    }
    if diagnostics.n_not_kept > 0 {
        eprintln!(
            "warning: {file_name}: {} more lines had problems (not listed)",
            diagnostics.n_not_kept
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
