//! Argument parsing and file handling for the `compass-pdr` CLI. Everything it computes
//! comes from the core; this module reads files, writes files and prints.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use compass_pdr::calib::export::{c_snippet, motioncal_packet};
use compass_pdr::calib::plane::SoftIronModel;
use compass_pdr::calibration::{
    CalibrationOptions, CalibrationReport, DeclinationChoice, Method, MethodParameters,
};
use compass_pdr::deviation::{HeadingOptions, HeadingReport};
use compass_pdr::io::canonical_csv;
use compass_pdr::io::delimited::ColumnMapping;
use compass_pdr::io::import::{header_signature, merge, ChunkedImport, Inspection};
use compass_pdr::io::{Diagnostics, ImportReport};
use compass_pdr::pdr::export::{track_text, TrackFormat};
use compass_pdr::pdr::fusion::{GnssPolicy, Outage};
use compass_pdr::pdr::step_length::StepModelKind;
use compass_pdr::pdr::{HeadingChoice, PdrOptions, PdrReport};
use compass_pdr::pipeline;
use compass_pdr::plot::{draw_calibration_figure, draw_deviation_figure, draw_pdr_figure};
use compass_pdr::reference::{ReferenceChoice, ReferenceOptions};
use compass_pdr::report::{
    device_calibration_lines, device_export, html_report, svg_figures, DeviceExport,
};
use compass_pdr::sim::dance::{motioncal_raw_lines, DanceConfig};
use compass_pdr::sim::gait::StepTruth;
use compass_pdr::sim::walk::{simulate_with_truth, WalkConfig};
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

/// The choices every analysis shares: the split, the reference, the declination.
#[derive(Debug, clap::Args)]
struct AnalysisArgs {
    /// Samples up to this time (s) train the methods, later ones check them
    /// (default: half-way through the part that has a reference heading).
    #[arg(long)]
    train_until: Option<f64>,
    /// The reference heading: `auto` (the log's reference column, else GPS course, else
    /// map legs between reference positions, else the gyro over a --closed-loop),
    /// `column`, `gps`, `legs`, or `gyro` (the integrated gyro, anchored to the best
    /// of the others).
    #[arg(long, value_enum, default_value_t = ReferenceArg::Auto)]
    reference: ReferenceArg,
    /// The walk ends where and as it started: the gyro's turn over it is whole turns,
    /// and the remainder is drift.
    #[arg(long)]
    closed_loop: bool,
    /// GPS course counts as a reference only at this speed (m/s) or faster (default:
    /// 5 for a vehicle's log, 0.8 for a pedestrian's).
    #[arg(long)]
    min_course_speed: Option<f64>,
    /// Declination: `auto` (the World Magnetic Model at the log's first position and
    /// date), or degrees, east positive (true north from magnetic north).
    #[arg(long, default_value = "auto", allow_hyphen_values = true)]
    declination: String,
    /// Where the log was recorded, `LAT,LON` in degrees, for logs without GNSS
    /// (indoors): the magnetic model needs a place for the expected field.
    #[arg(long, allow_hyphen_values = true)]
    position: Option<String>,
}

/// The choices of dead reckoning.
#[derive(Debug, clap::Args)]
struct PdrArgs {
    /// Ignore GNSS from START to END (seconds of log time), as the paper's evaluation
    /// does; repeat for several outages.
    #[arg(long = "outage", value_name = "START:END")]
    outages: Vec<String>,
    /// The step-length model: linear (SL = A + B·SF + C·SV), weinberg
    /// (SL = K·(Amax − Amin)^¼) or mlp (16 tanh neurons).
    #[arg(long, default_value = "weinberg")]
    step_model: String,
    /// The heading: auto (the heading model with the lowest check error against GNSS
    /// course, else the best calibration), a model key from `compass-pdr heading`
    /// (ellipse, ellipse+fourier, mlp, ...), gyro (the gyro aligned to the compass), or
    /// device (the device's own fused yaw, e.g. Android's rotation vector).
    #[arg(long, default_value = "auto")]
    heading_model: String,
    /// The walk is known to be this long (m): fits Weinberg's K.
    #[arg(long)]
    known_distance: Option<f64>,
    /// Weinberg's K from an earlier walk (this command prints the K it fitted), used
    /// when nothing in this log trains the step model.
    #[arg(long)]
    weinberg_k: Option<f64>,
    /// Train the step model on the log's reference positions (straight stretches
    /// between them); without this they only score the track.
    #[arg(long)]
    train_on_reference: bool,
    /// The walk ends where it started: report the loop-closure error.
    #[arg(long)]
    closed_loop: bool,
    /// Declination: `auto` (the World Magnetic Model at the log's first position and
    /// date), or degrees, east positive.
    #[arg(long, default_value = "auto", allow_hyphen_values = true)]
    declination: String,
    /// Where the log was recorded, `LAT,LON` in degrees, for logs without GNSS.
    #[arg(long, allow_hyphen_values = true)]
    position: Option<String>,
}

impl PdrArgs {
    fn options(&self) -> Result<PdrOptions, String> {
        let mut outages = Vec::new();
        for text in &self.outages {
            outages.push(Outage::parse(text).ok_or_else(|| {
                format!("--outage {text}: give START:END in seconds of log time, START before END, e.g. --outage 240:840")
            })?);
        }
        let step_model = StepModelKind::parse(&self.step_model).ok_or_else(|| {
            format!(
                "--step-model {}: choose linear, weinberg or mlp",
                self.step_model
            )
        })?;
        if let Some(distance) = self
            .known_distance
            .filter(|distance| !(distance.is_finite() && *distance > 0.0))
        {
            return Err(format!(
                "--known-distance {distance}: give the walk's length in metres"
            ));
        }
        if let Some(k) = self.weinberg_k.filter(|k| !(k.is_finite() && *k > 0.0)) {
            return Err(format!("--weinberg-k {k}: give a positive K, e.g. 0.45"));
        }
        let calibration = CalibrationOptions {
            declination: parse_declination(&self.declination)?,
            position_deg: self.position.as_deref().map(parse_position).transpose()?,
            ..CalibrationOptions::default()
        };
        let defaults = PdrOptions::default();
        Ok(PdrOptions {
            step_model,
            heading: HeadingChoice::parse(&self.heading_model),
            heading_options: HeadingOptions {
                calibration,
                ..HeadingOptions::default()
            },
            known_distance_m: self.known_distance,
            weinberg_k: self.weinberg_k,
            train_on_reference_positions: self.train_on_reference,
            closed_loop: self.closed_loop,
            gnss: GnssPolicy {
                outages,
                ..defaults.gnss.clone()
            },
            ..defaults
        })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ReferenceArg {
    Auto,
    Column,
    Gps,
    Legs,
    Gyro,
}

impl AnalysisArgs {
    /// The calibration options these arguments give, for `methods`.
    fn options(&self, methods: Vec<Method>) -> Result<CalibrationOptions, String> {
        let position_deg = self.position.as_deref().map(parse_position).transpose()?;
        let declination = parse_declination(&self.declination)?;
        if let Some(speed) = self
            .min_course_speed
            .filter(|speed| !(speed.is_finite() && *speed >= 0.0))
        {
            return Err(format!(
                "--min-course-speed {speed}: give a speed in m/s, 0 or more"
            ));
        }
        Ok(CalibrationOptions {
            methods,
            train_until_s: self.train_until,
            declination,
            position_deg,
            reference: ReferenceOptions {
                choice: match self.reference {
                    ReferenceArg::Auto => ReferenceChoice::Auto,
                    ReferenceArg::Column => ReferenceChoice::Column,
                    ReferenceArg::Gps => ReferenceChoice::Gps,
                    ReferenceArg::Legs => ReferenceChoice::Legs,
                    ReferenceArg::Gyro => ReferenceChoice::Gyro,
                },
                min_course_speed_mps: self.min_course_speed,
                closed_loop: self.closed_loop,
                ..ReferenceOptions::default()
            },
            ..CalibrationOptions::default()
        })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Scenario {
    /// The demo log (`assets/demo-walk.csv`): a walk in Seattle with hard iron, scale
    /// factors and their temperature drift, varied steps, GNSS with an outage and
    /// multipath, and a passage near iron.
    Demo,
    /// A steady walk with hard iron and scale factors, no GNSS (the demo before 2026-11).
    Steady,
    /// The phone of the steady walk on a level turntable, one turn a minute.
    Turntable,
    /// A car's octagonal loop at 12 m/s, the phone in a fixed mount, its compass
    /// deviating by Eq. 12 (the car's iron), GNSS with its course.
    Vehicle,
    /// The 2007 paper's raw case on the turntable: a raw heading error of (12 ± 30)°
    /// (hard iron of 0.69 of the horizontal field, and a declination of −12° that the log
    /// does not reveal).
    Paper,
    /// Issue 6's PDR walk: varied steps, unified-model compass error, 3 m GNSS noise.
    Pdr,
    /// A board's sphere "calibration dance", written as MotionCal `Raw:` lines (what a
    /// calibration sketch prints over the serial port), with an Eq. 5 distortion (hard
    /// iron, symmetric soft iron) as its truth. `--sample-rate-hz` is its line rate.
    Dance,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum MethodChoice {
    /// Min/max autocalibration (Eq. 6-7 of the 2007 paper).
    Minmax,
    /// The tilt-aware level-plane fit (a general conic): for flat, circle-only data.
    Ellipse,
    /// The 3D ellipsoid fit (Eq. 5): for data turned through many orientations.
    Ellipsoid,
    /// Reference-heading least squares (Eq. 8): needs a reference heading.
    Refls,
    /// Every method, side by side.
    All,
}

impl MethodChoice {
    fn methods(self) -> Vec<Method> {
        match self {
            MethodChoice::Minmax => vec![Method::MinMax],
            MethodChoice::Ellipse => vec![Method::Ellipse],
            MethodChoice::Ellipsoid => vec![Method::Ellipsoid],
            MethodChoice::Refls => vec![Method::RefLs],
            MethodChoice::All => Method::ALL.to_vec(),
        }
    }
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
        } => analysis.options(method.methods()).and_then(|options| {
            let outputs = Outputs {
                json,
                plot: plot.as_deref(),
                export_c: export_c.as_deref(),
                export_packet: export_packet.as_deref(),
            };
            run_calibrate(&input, &options, &outputs)
        }),
        Command::Heading {
            input,
            analysis,
            json,
            plot,
        } => analysis
            .options(Method::ALL.to_vec())
            .and_then(|calibration| {
                let options = HeadingOptions {
                    calibration,
                    ..HeadingOptions::default()
                };
                run_heading(&input, &options, json, plot.as_deref())
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

/// The truth file of the PDR scenario: the config and every step.
#[derive(serde::Serialize)]
struct PdrTruth<'a> {
    config: &'a WalkConfig,
    path_length_m: f64,
    steps: &'a [StepTruth],
}

fn run_simulate(
    seed: u64,
    duration_s: f64,
    scenario: Scenario,
    sample_rate_hz: f64,
    out: &Path,
    truth: Option<&Path>,
) -> Result<(), String> {
    if !(duration_s.is_finite() && duration_s > 0.0 && duration_s <= 24.0 * 3600.0) {
        return Err(format!(
            "--duration-s {duration_s} is out of range: give a number of seconds from 0 to 86400"
        ));
    }
    if !(sample_rate_hz.is_finite() && (10.0..=1000.0).contains(&sample_rate_hz)) {
        return Err(format!(
            "--sample-rate-hz {sample_rate_hz} is out of range: give a rate from 10 to 1000 Hz"
        ));
    }
    if scenario == Scenario::Dance {
        let config = DanceConfig {
            rate_hz: sample_rate_hz,
            ..DanceConfig::from_seed(seed, duration_s)
        };
        let (text, dance_truth) = motioncal_raw_lines(&config);
        std::fs::write(out, text)
            .map_err(|error| format!("cannot write {}: {error}", out.display()))?;
        if let Some(truth) = truth {
            let json = serde_json::to_string_pretty(&dance_truth)
                .map_err(|error| format!("cannot encode the truth: {error}"))?;
            std::fs::write(truth, json + "\n")
                .map_err(|error| format!("cannot write {}: {error}", truth.display()))?;
        }
        return Ok(());
    }
    let config = match scenario {
        Scenario::Demo => WalkConfig::demo(seed, duration_s, sample_rate_hz),
        Scenario::Steady => WalkConfig {
            sample_rate_hz,
            ..WalkConfig::from_seed(seed, duration_s)
        },
        Scenario::Turntable => WalkConfig {
            sample_rate_hz,
            ..WalkConfig::turntable(seed, duration_s, 60.0)
        },
        Scenario::Vehicle => WalkConfig::vehicle_loop(seed, duration_s, sample_rate_hz),
        Scenario::Paper => WalkConfig {
            sample_rate_hz,
            ..WalkConfig::paper_raw_case(seed, duration_s)
        },
        Scenario::Pdr | Scenario::Dance => WalkConfig::pdr_walk(seed, duration_s, sample_rate_hz),
    };
    let (rows, walk_truth) = simulate_with_truth(&config);
    let is_nmea = out
        .extension()
        .is_some_and(|extension| extension.eq_ignore_ascii_case("nmea"));
    let text = if is_nmea {
        // Absolute rows (a config with a start) are written at their own times.
        let origin_unix_s = match config.start_unix_s {
            Some(_) => 0.0,
            None => compass_pdr::sim::nmea::DEFAULT_START_UNIX_S,
        };
        compass_pdr::sim::nmea::write(&rows, origin_unix_s, 10.0)
    } else {
        canonical_csv::write(&rows)
    };
    std::fs::write(out, text)
        .map_err(|error| format!("cannot write {}: {error}", out.display()))?;
    if let Some(truth) = truth {
        // The steady walk's truth is its config alone; a varied gait's has its steps.
        let encoded = match scenario {
            Scenario::Steady | Scenario::Turntable | Scenario::Paper | Scenario::Vehicle => {
                serde_json::to_string_pretty(&config)
            }
            Scenario::Demo | Scenario::Pdr | Scenario::Dance => {
                serde_json::to_string_pretty(&PdrTruth {
                    config: &config,
                    path_length_m: walk_truth.path_length_m,
                    steps: &walk_truth.steps,
                })
            }
        };
        let json = encoded.map_err(|error| format!("cannot encode the truth: {error}"))?;
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
        return print_report(&inspection, true, |_| String::new());
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
    if let Some(frame) = &inspection.mag_frame {
        let _ = writeln!(text, "  {}", frame.describe());
    }
    for note in &inspection.notes {
        let _ = writeln!(text, "  note: {note}");
    }
    print_out(&text)
}

/// What `calibrate` writes besides its summary.
struct Outputs<'a> {
    json: bool,
    plot: Option<&'a Path>,
    export_c: Option<&'a Path>,
    export_packet: Option<&'a Path>,
}

fn parse_position(text: &str) -> Result<(f64, f64), String> {
    let parsed = text.split_once(',').and_then(|(lat, lon)| {
        Some((
            lat.trim().parse::<f64>().ok()?,
            lon.trim().parse::<f64>().ok()?,
        ))
    });
    match parsed {
        Some((lat_deg, lon_deg))
            if (-90.0..=90.0).contains(&lat_deg) && (-180.0..=180.0).contains(&lon_deg) =>
        {
            Ok((lat_deg, lon_deg))
        }
        _ => Err(format!(
            "--position {text}: give LAT,LON in degrees, e.g. 30.3,120.1"
        )),
    }
}

fn parse_declination(text: &str) -> Result<DeclinationChoice, String> {
    if text.eq_ignore_ascii_case("auto") {
        return Ok(DeclinationChoice::Auto);
    }
    match text.parse::<f64>() {
        Ok(degrees) if degrees.is_finite() && degrees.abs() <= 180.0 => {
            Ok(DeclinationChoice::Degrees(degrees))
        }
        _ => Err(format!(
            "--declination {text}: give `auto` or degrees from -180 to 180 (east positive)"
        )),
    }
}

fn run_calibrate(
    input: &ImportArgs,
    options: &CalibrationOptions,
    outputs: &Outputs<'_>,
) -> Result<(), String> {
    let report = import_paths(input)?;
    // The heading stage too: the best and the device calibration are the analysis's one
    // choice, the same as `heading`, `report` and the page give.
    let heading_options = HeadingOptions {
        calibration: options.clone(),
        ..HeadingOptions::default()
    };
    let (analysis, _) =
        pipeline::headings(&report, &heading_options).map_err(|error| error.to_string())?;
    let report = &analysis.report;
    print_import_diagnostics(&report.file_name, &report.diagnostics);
    if let Some(plot) = outputs.plot {
        let root = SVGBackend::new(plot, (1800, 540)).into_drawing_area();
        draw_calibration_figure(&root, &analysis)
            .map_err(|error| format!("{error} ({})", plot.display()))?;
    }
    let export = device_export(&analysis);
    let mut written = Vec::new();
    if outputs.export_c.is_some() || outputs.export_packet.is_some() {
        let Some(export) = &export else {
            return Err("no 3D calibration to export: the ellipse and ellipsoid methods both failed (see above)".to_string());
        };
        let frame = &export.calibration.frame;
        if let Some(path) = outputs.export_c {
            let text = format!(
                "// {} calibration of {}\n{}",
                export.method.label(),
                report.file_name,
                c_snippet(&export.calibration)
            );
            std::fs::write(path, text)
                .map_err(|error| format!("cannot write {}: {error}", path.display()))?;
            written.push(format!(
                "C snippet written to {}: {}, raw values in {}",
                path.display(),
                frame.axes,
                frame.unit.label()
            ));
        }
        if let Some(path) = outputs.export_packet {
            // MotionCal's floats are µT by definition: the raw axes, in µT.
            let Some(in_ut) = export.calibration.in_ut() else {
                return Err(format!(
                    "no MotionCal packet: its floats are µT, but the magnetometer's raw values \
                     are in {}; export the JSON or the C snippet, which are in the raw values' unit",
                    frame.unit.label()
                ));
            };
            std::fs::write(path, motioncal_packet(&in_ut))
                .map_err(|error| format!("cannot write {}: {error}", path.display()))?;
            written.push(format!(
                "MotionCal packet written to {}: in µT along {}",
                path.display(),
                frame.axes
            ));
        }
    }
    if outputs.json {
        let output = CalibrateOutput {
            report,
            device_calibration: export.as_ref(),
            written: &written,
        };
        return print_report(&output, true, |_| String::new());
    }
    let mut text = calibration_text(report);
    text.push_str("  device calibration:\n");
    for line in device_calibration_lines(&analysis) {
        text.push_str(&format!("    {line}\n"));
    }
    for line in &written {
        text.push_str(&format!("  {line}\n"));
    }
    print_out(&text)
}

/// What `calibrate --json` prints: the report, the device calibration in the sensor's
/// own axes and unit (and in body axes and µT), and the files written.
#[derive(serde::Serialize)]
struct CalibrateOutput<'a> {
    #[serde(flatten)]
    report: &'a CalibrationReport,
    device_calibration: Option<&'a DeviceExport>,
    #[serde(skip_serializing_if = "<[String]>::is_empty")]
    written: &'a [String],
}

fn run_heading(
    input: &ImportArgs,
    options: &HeadingOptions,
    json: bool,
    plot: Option<&Path>,
) -> Result<(), String> {
    let report = import_paths(input)?;
    let (_, analysis) = pipeline::headings(&report, options).map_err(|error| error.to_string())?;
    let report = &analysis.report;
    print_import_diagnostics(&report.file_name, &report.calibration.diagnostics);
    if let Some(plot) = plot {
        let root = SVGBackend::new(plot, (1400, 1000)).into_drawing_area();
        draw_deviation_figure(&root, &analysis)
            .map_err(|error| format!("{error} ({})", plot.display()))?;
    }
    print_report(report, json, heading_text)
}

fn run_report(input: &ImportArgs, options: &PdrOptions, out: &Path) -> Result<(), String> {
    let report = import_paths(input)?;
    let file_name = report.file_name.clone();
    let analysis = pipeline::analyse(&report, options).map_err(|error| error.to_string())?;
    print_import_diagnostics(&file_name, &analysis.calibration.report.diagnostics);
    let pdr = match analysis.pdr {
        Some(Ok(pdr)) => Ok(pdr),
        Some(Err(error)) => Err(error.to_string()),
        None => Err("no dead reckoning was asked for".to_string()),
    };
    let (calibration, heading) = (&analysis.calibration, &analysis.headings);
    let figures = svg_figures(calibration, Some(heading), pdr.as_ref().ok());
    let html = html_report(
        calibration,
        Some(heading),
        pdr.as_ref().map_err(String::as_str),
        &figures,
    );
    std::fs::write(out, html).map_err(|error| format!("{}: {error}", out.display()))?;
    print_out(&format!(
        "{file_name}: report written to {}\n",
        out.display()
    ))
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

fn run_pdr(
    input: &ImportArgs,
    options: &PdrOptions,
    json: bool,
    out: Option<&Path>,
    plot: Option<&Path>,
) -> Result<(), String> {
    let report = import_paths(input)?;
    print_import_diagnostics(&report.file_name, &report.diagnostics);
    let analysis = pipeline::dead_reckoning(&report, options).map_err(|error| error.to_string())?;
    if let Some(out) = out {
        let name = out.to_string_lossy();
        let format = TrackFormat::from_file_name(&name).ok_or_else(|| {
            format!("--out {name}: end the file name with .csv, .geojson or .gpx")
        })?;
        let text =
            track_text(&analysis, format).map_err(|error| format!("--out {name}: {error}"))?;
        std::fs::write(out, text).map_err(|error| format!("cannot write {name}: {error}"))?;
    }
    if let Some(plot) = plot {
        let root = SVGBackend::new(plot, (1400, 1000)).into_drawing_area();
        draw_pdr_figure(&root, &analysis)
            .map_err(|error| format!("{error} ({})", plot.display()))?;
    }
    print_report(&analysis.report, json, pdr_text)
}

/// The PDR result as the paper's tables: steps, the step model, and the errors.
fn pdr_text(report: &PdrReport) -> String {
    use std::fmt::Write as _;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{}: {} steps in {} bouts over {:.0} s{}, {:.1} m dead-reckoned",
        report.file_name,
        report.n_steps,
        report.n_bouts,
        report.duration_s,
        report
            .mean_step_frequency_hz
            .map_or(String::new(), |hz| format!(" ({hz:.2} steps/s)")),
        report.pdr_distance_m
    );
    let _ = writeln!(text, "  step model: {}", report.step_model.describe());
    let _ = writeln!(
        text,
        "  heading: {} ({})",
        report.heading_label, report.heading_key
    );
    match report.fixes.describe() {
        Some(fixes) => {
            let _ = writeln!(text, "  GNSS fixes: {fixes}");
        }
        None => {
            let _ = writeln!(text, "  GNSS: none in the log");
        }
    }
    let position_row =
        |text: &mut String, name: &str, errors: &compass_pdr::pdr::metrics::PositionErrors| {
            let _ = writeln!(
            text,
            "  {name:<26} {:>5} pts {:>8.1} m {:>7.2} m {:>6.2} % {:>7.2} m {:>6.2} % {:>+7.2} %",
            errors.n_points,
            errors.distance_m,
            errors.rms_m,
            errors.rms_pct,
            errors.max_m,
            errors.max_pct,
            errors.distance_error_pct
        );
        };
    let gap_errors: Vec<&compass_pdr::pdr::metrics::PositionErrors> = report
        .gnss_gaps
        .iter()
        .filter_map(|gap| gap.position_error.as_ref())
        .collect();
    if report.position_error.is_some()
        || !report.outage_position_errors.is_empty()
        || !gap_errors.is_empty()
    {
        let _ = writeln!(
            text,
            "  {:<26} {:>9} {:>10} {:>9} {:>8} {:>9} {:>8} {:>9}",
            "position error", "points", "distance", "RMS", "RMS", "max", "max", "distance"
        );
    }
    if let Some(errors) = &report.position_error {
        position_row(&mut text, "whole walk", errors);
    }
    for errors in &report.outage_position_errors {
        position_row(
            &mut text,
            &format!("outage {:.0}-{:.0} s", errors.start_s, errors.end_s),
            errors,
        );
    }
    for errors in gap_errors {
        position_row(
            &mut text,
            &format!("no GNSS {:.0}-{:.0} s", errors.start_s, errors.end_s),
            errors,
        );
    }
    for gap in report
        .gnss_gaps
        .iter()
        .filter(|gap| gap.position_error.is_none())
    {
        let _ = writeln!(text, "  {}", compass_pdr::report::gap_sentence(gap));
    }
    if let Some(error) = &report.step_length_error_m {
        let _ = writeln!(
            text,
            "  step length error: {:+.3} ± {:.3} m over {} steps",
            error.mean, error.std, error.n
        );
    }
    if let Some(error) = &report.heading_error_deg {
        let _ = writeln!(
            text,
            "  heading error: {:+.2} ± {:.2}° over {} steps",
            error.mean, error.std, error.n
        );
    }
    if let Some(closure) = &report.loop_closure {
        let _ = writeln!(
            text,
            "  loop closure: {:.2} m, {:.2} % of {:.1} m",
            closure.gap_m, closure.gap_pct, closure.length_m
        );
    }
    for note in &report.notes {
        let _ = writeln!(text, "  note: {note}");
    }
    text
}

/// The heading comparison as a table, then each Fourier model as the paper's Table II.
fn heading_text(report: &HeadingReport) -> String {
    use std::fmt::Write as _;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{}: {} samples with a reference on train, {} on check{}",
        report.file_name,
        report.n_train_referenced,
        report.n_check_referenced,
        report
            .train_until_s
            .map_or(String::new(), |until_s| format!(
                ", split at {until_s:.1} s"
            ))
    );
    let _ = writeln!(
        text,
        "  reference heading: {}",
        report.reference_description.as_deref().unwrap_or("none")
    );
    let _ = writeln!(
        text,
        "  declination: {:.2}° ({})",
        report.calibration.declination.declination_deg, report.calibration.declination.source
    );
    let _ = writeln!(
        text,
        "  {:<36} {:>9} {:>16} {:>9} {:>9} {:>8}",
        "heading method", "train RMS", "check mean±std", "check RMS", "check p95", "±5°"
    );
    let cell = |stats: Option<HeadingErrorStats>, pick: fn(&HeadingErrorStats) -> String| {
        stats.as_ref().map_or("—".to_string(), pick)
    };
    for row in &report.rows {
        if let Some(error) = &row.error {
            let _ = writeln!(text, "  {:<36} not fitted: {error}", row.label);
            continue;
        }
        let best = if report.best.as_deref() == Some(row.key.as_str()) {
            " ← best"
        } else {
            ""
        };
        let _ = writeln!(
            text,
            "  {:<36} {:>9} {:>16} {:>9} {:>9} {:>8}{best}",
            row.label,
            cell(row.train, |stats| format!("{:.2}°", stats.rms_deg)),
            cell(row.check, |stats| format!(
                "{:.2}±{:.2}°",
                stats.mean_deg, stats.std_deg
            )),
            cell(row.check, |stats| format!("{:.2}°", stats.rms_deg)),
            cell(row.check, |stats| format!("{:.2}°", stats.p95_abs_deg)),
            cell(row.check, |stats| format!(
                "{:.0} %",
                stats.within_5_deg_pct
            )),
        );
    }
    let _ = writeln!(text, "  best: {}", report.choice.sentence());
    if !report.fourier.is_empty() {
        let _ = writeln!(
            text,
            "  Fourier model on each base (train), as the PDR paper's Table II:\n  {:<36} {:>7} {:>7} {:>7} {:>7} {:>7} {:>14} {:>6}",
            "base", "A °", "B °", "C °", "D °", "E °", "resid mean±std", "±5°"
        );
        for fourier in &report.fourier {
            let model = fourier.fit.model;
            let _ = writeln!(
                text,
                "  {:<36} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>14} {:>5.0}%",
                fourier.base_label,
                model.a_deg,
                model.b_deg,
                model.c_deg,
                model.d_deg,
                model.e_deg,
                format!(
                    "{:.2}±{:.2}°",
                    fourier.fit.residual_mean_deg, fourier.fit.residual_std_deg
                ),
                fourier.fit.within_5_deg_pct
            );
        }
    }
    for neural in &report.neural {
        let _ = writeln!(
            text,
            "  MLP on {}: inputs {}; {} pairs, {} hidden neurons, {} L-BFGS iterations ({:?}), train MSE {:.2} deg², \
             validation MSE {}",
            neural.base_label,
            neural.inputs.join(", "),
            neural.n_pairs,
            neural.n_hidden,
            neural.iterations,
            neural.stop,
            neural.train_mse_deg2,
            neural
                .validation_mse_deg2
                .map_or("—".to_string(), |mse| format!("{mse:.2} deg²"))
        );
    }
    if let Some(online) = &report.online {
        let model = online.model;
        let _ = writeln!(
            text,
            "  online on {} (RLS, memory {:.0} s, {} updates): A {:.2}° B {:.2}° C {:.2}° D {:.2}° E {:.2}°",
            online.base_label,
            online.memory_s, online.n_updates, model.a_deg, model.b_deg, model.c_deg, model.d_deg, model.e_deg
        );
    }
    for note in report.notes.iter().chain(&report.calibration.notes) {
        let _ = writeln!(text, "  note: {note}");
    }
    text
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

fn calibration_text(report: &CalibrationReport) -> String {
    use std::fmt::Write as _;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{}: {} magnetometer samples ({} train, {} check{})",
        report.file_name,
        report.n_samples_used,
        report.n_train,
        report.n_check,
        report
            .train_until_s
            .map_or(String::new(), |until_s| format!(
                ", split at {until_s:.1} s"
            ))
    );
    let reference = report
        .reference
        .map_or_else(|| "none".to_string(), |source| source.describe());
    let _ = writeln!(text, "  reference heading: {reference}");
    let _ = writeln!(
        text,
        "  declination: {:.2}° ({})",
        report.declination.declination_deg, report.declination.source
    );
    // Raw counts of unknown sensitivity were kept as they are: the measured field is in
    // counts.
    let raw_unit = report
        .mag_frame
        .map(|frame| frame.unit)
        .filter(|unit| unit.ut_per_unit.is_none())
        .map_or("µT", |unit| unit.name);
    match &report.expected_field {
        Some(expected) => {
            let _ = writeln!(
                text,
                "  field: measured {:.1} {raw_unit} raw, expected {:.1} µT (inclination {:.1}°)",
                report.mean_raw_field_ut, expected.total_ut, expected.inclination_deg
            );
        }
        None => {
            let _ = writeln!(
                text,
                "  field: measured {:.1} {raw_unit} raw (no model value: no position or date)",
                report.mean_raw_field_ut
            );
        }
    }
    // Where the device estimated its own hard iron, the fitted ones go beside it.
    if let Some(device) = &report.device_hard_iron {
        let vector = |v_ut: &nalgebra::Vector3<f64>| {
            format!("({:.1}, {:.1}, {:.1})", v_ut.x, v_ut.y, v_ut.z)
        };
        let _ = writeln!(
            text,
            "  hard iron (µT, body x forward, y right, z down): device's own {} (moved {:.1} µT during the log)",
            vector(&device.mean_ut),
            device.max_change_ut
        );
        for method in &report.methods {
            let fitted = match &method.parameters {
                Some(MethodParameters::Ellipse(fit)) => Some((
                    fit.hard_iron_ut,
                    match fit.soft_iron_model {
                        SoftIronModel::Full => "full soft iron",
                        SoftIronModel::Isotropic { .. } => "isotropic soft iron",
                    },
                )),
                Some(MethodParameters::Ellipsoid(fit)) => {
                    Some((fit.calibration.hard_iron_ut, "ellipsoid"))
                }
                _ => None,
            };
            if let Some((hard_iron_ut, model)) = fitted {
                let _ = writeln!(
                    text,
                    "    {}: {} ({model}), minus the device's {}",
                    method.label,
                    vector(&hard_iron_ut),
                    vector(&(hard_iron_ut - device.mean_ut))
                );
            }
        }
    }
    let _ = writeln!(
        text,
        "  {:<26} {:>17} {:>17} {:>10}",
        "heading error (RMS)", "train", "check", "check p95"
    );
    let row = |label: &str, train: Option<HeadingErrorStats>, check: Option<HeadingErrorStats>| {
        let cell = |stats: Option<HeadingErrorStats>| {
            stats.map_or("—".to_string(), |stats| {
                format!("{:.2}° ({:+.2}°)", stats.rms_deg, stats.mean_deg)
            })
        };
        format!(
            "  {label:<26} {:>17} {:>17} {:>10}\n",
            cell(train),
            cell(check),
            check.map_or("—".to_string(), |stats| format!(
                "{:.2}°",
                stats.p95_abs_deg
            ))
        )
    };
    text.push_str(&row(
        "uncalibrated",
        report.raw_heading_error_train,
        report.raw_heading_error_check,
    ));
    for method in &report.methods {
        match &method.error {
            None => text.push_str(&row(
                method.label,
                method.heading_error_train,
                method.heading_error_check,
            )),
            Some(error) => {
                let _ = writeln!(text, "  {:<26} not fitted: {error}", method.label);
            }
        }
    }
    if let Some(choice) = &report.choice {
        let _ = writeln!(text, "  best: {}", choice.sentence());
    }
    for note in &report.notes {
        let _ = writeln!(text, "  note: {note}");
    }
    text
}
