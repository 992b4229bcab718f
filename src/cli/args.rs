//! The arguments the commands share: the files to read (`ImportArgs`), the analysis
//! choices (`AnalysisArgs`), dead reckoning's (`PdrArgs`), and their parsing into the
//! core's options.

use std::path::PathBuf;

use clap::ValueEnum;
use compass_pdr::analysis::calibration::{CalibrationOptions, DeclinationChoice, Method};
use compass_pdr::analysis::headings::HeadingOptions;
use compass_pdr::io::recording::GyroBias;
use compass_pdr::pdr::fusion::{GnssPolicy, Outage};
use compass_pdr::pdr::step_length::StepModelKind;
use compass_pdr::pdr::{FilterKind, HeadingChoice, PdrOptions};
use compass_pdr::reference::{ReferenceChoice, ReferenceOptions};

/// The files to read, and how to read their columns.
#[derive(Debug, clap::Args)]
pub(super) struct ImportArgs {
    /// The log: one file, or the files of one recording (e.g. phyphox's per-sensor CSVs),
    /// merged by time. The format is told from the content.
    #[arg(required = true)]
    pub(super) files: Vec<PathBuf>,
    /// Read columns of a delimited file under other names, `COLUMN=NAME,…`, for example
    /// `Bx=mag_x_gauss,By=mag_y_gauss,Bz=mag_z_gauss,time=t_ms` (the unit in the name
    /// overrides a guessed one; `ignore` leaves a column out). It is remembered for
    /// files with the same header, in $XDG_CONFIG_HOME/compass-pdr/mappings.json.
    #[arg(long)]
    pub(super) map: Option<String>,
    /// What the device did to the gyroscope's rates before logging them: `removed` (the
    /// OS subtracted its own bias estimate, as Android's TYPE_GYROSCOPE and iOS's
    /// device-motion rate do) or `raw`. By default what the log says: Android sensor
    /// dumps, GetSensorData, phyphox, TYREX's files and Sensor Logger's Gyroscope.csv say
    /// `removed`, and other logs are taken as raw. It sets how large a bias the attitude
    /// filter expects.
    #[arg(long, value_enum)]
    pub(super) gyro_bias: Option<GyroBiasArg>,
}

/// `--gyro-bias`.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub(super) enum GyroBiasArg {
    Removed,
    Raw,
}

impl GyroBiasArg {
    pub(super) fn gyro_bias(self) -> GyroBias {
        match self {
            GyroBiasArg::Removed => GyroBias::RemovedByDevice,
            GyroBiasArg::Raw => GyroBias::Unknown,
        }
    }

    pub(super) fn note(self) -> &'static str {
        match self {
            GyroBiasArg::Removed => {
                "--gyro-bias removed: the gyroscope's rates are taken as having the OS's bias estimate removed"
            }
            GyroBiasArg::Raw => "--gyro-bias raw: the gyroscope's rates are taken as raw, their bias in them",
        }
    }
}

/// The choices every analysis shares: the split, the reference, the declination.
#[derive(Debug, clap::Args)]
pub(super) struct AnalysisArgs {
    /// Samples up to this time (s) train the methods, later ones check them
    /// (default: half-way through the part that has a reference heading).
    #[arg(long)]
    pub(super) train_until: Option<f64>,
    /// The reference heading: `auto` (the log's reference column, else an autopilot's
    /// own heading, else GPS course, else map legs between reference positions, else
    /// the gyro over a --closed-loop), `column`, `autopilot`, `gps`, `legs`, or `gyro`
    /// (the integrated gyro, anchored to the best of the others).
    #[arg(long, value_enum, default_value_t = ReferenceArg::Auto)]
    pub(super) reference: ReferenceArg,
    /// The walk ends where and as it started: the gyro's turn over it is whole turns,
    /// and the remainder is drift.
    #[arg(long)]
    pub(super) closed_loop: bool,
    /// GPS course counts as a reference only at this speed (m/s) or faster (default:
    /// 5 for a vehicle's log, 0.8 for a pedestrian's).
    #[arg(long)]
    pub(super) min_course_speed: Option<f64>,
    /// Declination: `auto` (the World Magnetic Model at the log's first position and
    /// date), or degrees, east positive (true north from magnetic north).
    #[arg(long, default_value = "auto", allow_hyphen_values = true)]
    pub(super) declination: String,
    /// Where the log was recorded, `LAT,LON` in degrees, for logs without GNSS
    /// (indoors): the magnetic model needs a place for the expected field.
    #[arg(long, allow_hyphen_values = true)]
    pub(super) position: Option<String>,
}

/// The choices of dead reckoning.
#[derive(Debug, clap::Args)]
pub(super) struct PdrArgs {
    /// Ignore GNSS from START to END (seconds of log time), as the paper's evaluation
    /// does; repeat for several outages.
    #[arg(long = "outage", value_name = "START:END")]
    pub(super) outages: Vec<String>,
    /// How the steps and the fixes are fused: `smoother` (every fix weighted by its
    /// accuracy and innovation, forward and backward, so each position uses the fixes
    /// before and after it), `causal` (its forward pass: what a live track would show)
    /// or `paper` (the PDR paper's EKF with GNSS/PDR switching)
    #[arg(long, default_value = "smoother", value_parser = ["smoother", "causal", "paper"])]
    pub(super) filter: String,
    /// The step-length model: linear (SL = A + B·SF + C·SV), weinberg
    /// (SL = K·(Amax − Amin)^¼) or mlp (16 tanh neurons).
    #[arg(long, default_value = "weinberg")]
    pub(super) step_model: String,
    /// The heading: auto (the heading model with the lowest check error against GNSS
    /// course, else the best calibration), a model key from `compass-pdr heading`
    /// (ellipse, ellipse+fourier, mlp, ...), gyro (the gyro aligned to the compass), or
    /// device (the device's own fused yaw, e.g. Android's rotation vector).
    #[arg(long, default_value = "auto")]
    pub(super) heading_model: String,
    /// The walk is known to be this long (m): fits Weinberg's K.
    #[arg(long)]
    pub(super) known_distance: Option<f64>,
    /// Weinberg's K from an earlier walk (this command prints the K it fitted), used
    /// when nothing in this log trains the step model.
    #[arg(long)]
    pub(super) weinberg_k: Option<f64>,
    /// Train the step model on the log's reference positions (straight stretches
    /// between them); without this they only score the track.
    #[arg(long)]
    pub(super) train_on_reference: bool,
    /// The walk ends where it started: report the loop-closure error.
    #[arg(long)]
    pub(super) closed_loop: bool,
    /// Declination: `auto` (the World Magnetic Model at the log's first position and
    /// date), or degrees, east positive.
    #[arg(long, default_value = "auto", allow_hyphen_values = true)]
    pub(super) declination: String,
    /// Where the log was recorded, `LAT,LON` in degrees, for logs without GNSS.
    #[arg(long, allow_hyphen_values = true)]
    pub(super) position: Option<String>,
}

impl PdrArgs {
    pub(super) fn options(&self) -> Result<PdrOptions, String> {
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
            filter: FilterKind::parse(&self.filter).unwrap_or(defaults.filter),
            ..defaults
        })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(super) enum ReferenceArg {
    Auto,
    Column,
    Autopilot,
    Gps,
    Legs,
    Gyro,
}

impl AnalysisArgs {
    /// The calibration options these arguments give, for `methods`.
    pub(super) fn options(&self, methods: Vec<Method>) -> Result<CalibrationOptions, String> {
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
                    ReferenceArg::Autopilot => ReferenceChoice::Autopilot,
                    ReferenceArg::Gyro => ReferenceChoice::Gyro,
                },
                min_course_speed_mps: self.min_course_speed,
                closed_loop: self.closed_loop,
            },
            ..CalibrationOptions::default()
        })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(super) enum MethodChoice {
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
    pub(super) fn methods(self) -> Vec<Method> {
        match self {
            MethodChoice::Minmax => vec![Method::MinMax],
            MethodChoice::Ellipse => vec![Method::Ellipse],
            MethodChoice::Ellipsoid => vec![Method::Ellipsoid],
            MethodChoice::Refls => vec![Method::RefLs],
            MethodChoice::All => Method::ALL.to_vec(),
        }
    }
}

pub(super) fn parse_position(text: &str) -> Result<(f64, f64), String> {
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

pub(super) fn parse_declination(text: &str) -> Result<DeclinationChoice, String> {
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
