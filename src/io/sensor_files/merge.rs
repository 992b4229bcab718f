//! The choices made when several per-sensor files are merged into one recording
//! ([`super`]): an alternative accelerometer or gyroscope is used only without the
//! other; the raw magnetometer is the magnetometer, and an OS-calibrated one beside it
//! gives the OS's hard-iron estimate, paired sample by sample; and the files' clocks
//! are noted once for all the files of each kind.

use nalgebra::Vector3;

use super::{base_name, Role, SensorImport, HEADERLESS_TEXT, SENSOR_LOGGER};
use crate::base::calendar::utc_text;
use crate::io::delimited::RawImport;
use crate::io::recording::{GyroBias, Recording, Stream};

/// The merge's choices among per-sensor files, in file order: an alternative
/// accelerometer or gyroscope is used only without the other; a raw magnetometer is the
/// magnetometer, and an OS-calibrated one beside it gives the OS's hard-iron estimate
/// (raw − calibrated, paired sample by sample) where the raw one has none; alone, the
/// calibrated one is the magnetometer. Hands back the imports, and notes on the choices.
pub fn choose(files: Vec<(String, SensorImport)>) -> (Vec<(String, RawImport)>, Vec<String>) {
    let mut notes = clock_notes(&files);
    let name_of = |role: Role| {
        files
            .iter()
            .find(|(_, import)| import.role == role && has_stream(&import.raw, role))
            .map(|(name, _)| base_name(name).to_string())
    };
    let main_acc = name_of(Role::Accelerometer { alternative: false });
    let main_gyro = name_of(Role::Gyroscope { alternative: false });
    let raw_mag_idx = files.iter().position(|(_, import)| {
        import.role == Role::RawMagnetometer && has_stream(&import.raw, import.role)
    });
    // The calibrated field, to pair with the raw one.
    let calibrated: Option<(String, Stream<Vector3<f64>>)> = files
        .iter()
        .find(|(_, import)| {
            import.role == Role::CalibratedMagnetometer && has_stream(&import.raw, import.role)
        })
        .map(|(name, import)| {
            (
                base_name(name).to_string(),
                import.raw.report.recording.mag_in_body_ut.clone(),
            )
        });
    let raw_mag_name = raw_mag_idx
        .and_then(|idx| files.get(idx))
        .map(|(name, _)| base_name(name).to_string());
    // Whether the raw magnetometer's file has the OS's bias beside it already (then the
    // calibrated file gives nothing).
    let raw_has_bias = raw_mag_idx
        .and_then(|idx| files.get(idx))
        .is_some_and(|(_, import)| !import.raw.report.recording.mag_bias_in_body_ut.is_empty());

    let mut chosen = Vec::with_capacity(files.len());
    for (idx, (name, mut import)) in files.into_iter().enumerate() {
        let recording = &mut import.raw.report.recording;
        match import.role {
            Role::Accelerometer { alternative: true } if main_acc.is_some() => {
                recording.acc_in_body_mps2 = Stream::default();
                notes.push(format!(
                    "{}: not used, {} is the accelerometer",
                    base_name(&name),
                    main_acc.as_deref().unwrap_or_default()
                ));
            }
            Role::Gyroscope { alternative: true } if main_gyro.is_some() => {
                recording.gyro_in_body_radps = Stream::default();
                recording.gyro_bias = GyroBias::default();
                notes.push(format!(
                    "{}: not used, {} is the gyroscope",
                    base_name(&name),
                    main_gyro.as_deref().unwrap_or_default()
                ));
            }
            Role::RawMagnetometer if Some(idx) == raw_mag_idx => {
                if let (true, Some((calibrated_name, calibrated))) =
                    (recording.mag_bias_in_body_ut.is_empty(), &calibrated)
                {
                    let (bias, n_paired) = paired_difference(&recording.mag_in_body_ut, calibrated);
                    notes.push(bias_note(
                        base_name(&name),
                        calibrated_name,
                        &bias,
                        n_paired,
                        recording.mag_in_body_ut.len(),
                    ));
                    recording.mag_bias_in_body_ut = bias;
                }
            }
            Role::RawMagnetometer => {
                recording.mag_in_body_ut = Stream::default();
                recording.mag_bias_in_body_ut = Stream::default();
                import.raw.mag_unit = None;
                notes.push(format!(
                    "{}: not used, {} is the magnetometer",
                    base_name(&name),
                    raw_mag_name.as_deref().unwrap_or_default()
                ));
            }
            Role::CalibratedMagnetometer if raw_mag_idx.is_some() => {
                recording.mag_in_body_ut = Stream::default();
                import.raw.mag_unit = None;
                if raw_has_bias {
                    notes.push(format!(
                        "{}: not used, {} is the magnetometer and has the OS's bias beside it",
                        base_name(&name),
                        raw_mag_name.as_deref().unwrap_or_default()
                    ));
                }
            }
            Role::CalibratedMagnetometer => notes.push(format!(
                "{}: the OS-calibrated field is the magnetometer (there is no raw one); the OS \
                 has already removed its hard-iron estimate, so a fit should find little offset",
                base_name(&name)
            )),
            _ => {}
        }
        chosen.push((name, import.raw));
    }
    (chosen, notes)
}

/// The files' clocks, said once for all the files of each kind.
fn clock_notes(files: &[(String, SensorImport)]) -> Vec<String> {
    let mut notes = Vec::new();
    let of_format = |format: &'static str| {
        files
            .iter()
            .filter(move |(_, import)| import.raw.report.format == format)
            .map(|(_, import)| &import.raw.report.recording)
    };
    if of_format(SENSOR_LOGGER).any(has_samples) {
        let start = of_format(SENSOR_LOGGER).find_map(|recording| recording.start_unix_s);
        notes.push(format!(
            "Sensor Logger: times are seconds_elapsed, the clock the app's files share{}",
            start.map_or(String::new(), |start_unix_s| format!(
                "; the recording started at {} (time − seconds_elapsed of a file's first row)",
                utc_text(start_unix_s)
            ))
        ));
    }
    if of_format(HEADERLESS_TEXT).any(has_samples) {
        notes.push(
            "headerless sensor files: t in seconds on the phone's clock, which the files \
             share"
                .to_string(),
        );
    }
    notes
}

/// Whether a recording holds any vector or GNSS sample (a file that gives more than
/// notes).
fn has_samples(recording: &Recording) -> bool {
    !(recording.acc_in_body_mps2.is_empty()
        && recording.gyro_in_body_radps.is_empty()
        && recording.mag_in_body_ut.is_empty()
        && recording.gnss.is_empty()
        && recording.pressure_hpa.is_empty())
}

/// Whether an import has the stream its role is about.
fn has_stream(raw: &RawImport, role: Role) -> bool {
    let recording = &raw.report.recording;
    match role {
        Role::Accelerometer { .. } => !recording.acc_in_body_mps2.is_empty(),
        Role::Gyroscope { .. } => !recording.gyro_in_body_radps.is_empty(),
        Role::RawMagnetometer | Role::CalibratedMagnetometer => {
            !recording.mag_in_body_ut.is_empty()
        }
        Role::Other => false,
    }
}

/// `raw − calibrated` at the raw samples' times, each raw sample paired with the
/// calibrated sample nearest in time when that is within half the raw stream's median
/// sample interval (both streams sorted by time). The OS's hard-iron estimate is
/// piecewise constant, and the two files hold the same sensor events with timestamps a
/// fraction of a millisecond apart, so pairing (not interpolating, which would mix in
/// the field's own change between samples) gives it exactly. Returns the difference and
/// how many samples were paired.
fn paired_difference(
    raw: &Stream<Vector3<f64>>,
    calibrated: &Stream<Vector3<f64>>,
) -> (Stream<Vector3<f64>>, usize) {
    let tolerance_s = raw.median_interval_s().map_or(0.0, |median| 0.5 * median);
    let mut bias = Stream::default();
    let mut next_idx = 0usize;
    for (&t_s, raw_value) in raw.t_s.iter().zip(&raw.values) {
        while calibrated.t_s.get(next_idx).is_some_and(|&t| t < t_s) {
            next_idx += 1;
        }
        let nearest = [next_idx.checked_sub(1), Some(next_idx)]
            .into_iter()
            .flatten()
            .filter_map(|idx| Some((calibrated.t_s.get(idx)?, calibrated.values.get(idx)?)))
            .min_by(|(a, _), (b, _)| (*a - t_s).abs().total_cmp(&(*b - t_s).abs()));
        if let Some((&t, calibrated_value)) = nearest {
            if (t - t_s).abs() <= tolerance_s {
                bias.push(t_s, raw_value - calibrated_value);
            }
        }
    }
    let n_paired = bias.len();
    (bias, n_paired)
}

fn bias_note(
    raw_name: &str,
    calibrated_name: &str,
    bias: &Stream<Vector3<f64>>,
    n_paired: usize,
    n_raw: usize,
) -> String {
    let median = |axis: usize| {
        let mut values: Vec<f64> = bias.values.iter().map(|value| value[axis]).collect();
        values.sort_by(f64::total_cmp);
        values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
    };
    format!(
        "{raw_name} is the magnetometer (the raw field); the OS's own hard-iron estimate is \
         {raw_name} − {calibrated_name}, paired sample by sample ({n_paired} of {n_raw} raw \
         samples within half a sample interval; median ({:.2}, {:.2}, {:.2}) µT in device \
         axes x, y, z), kept as the device bias",
        median(0),
        median(1),
        median(2)
    )
}
