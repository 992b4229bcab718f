//! The user's column mapping for delimited text ([`super`]): a file's column names
//! renamed to names the header reader knows (`Bx=mag_x_gauss,time=t_ms`, or `ignore`),
//! for files whose header it cannot read by itself, and the targets the page's mapping
//! dialog and `--map` offer.

use super::header::resolve;

/// A user's mapping of a file's column names to names this reader knows, for files whose
/// header it cannot read by itself: `Bx=mag_x_gauss,By=mag_y_gauss,Bz=mag_z_gauss,
/// time=t_ms`. The target `ignore` leaves a column out. Column names match without
/// regard to case or surrounding quotes.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ColumnMapping {
    /// (the file's column name, the name to read it as)
    pub renames: Vec<(String, String)>,
}

/// A mapping that cannot be used, with what to write instead.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MappingError {
    #[error("the mapping entry '{entry}' is not COLUMN=NAME; write for example Bx=mag_x_gauss")]
    NotAnAssignment { entry: String },
    #[error(
        "'{target}' (for column '{column}') is not a name this tool reads; use a name such as \
         mag_x_ut, mag_x_gauss, acc_x_mps2, acc_x_g, gyro_x_radps, gyro_x_dps, t_s, t_ms, temp_c, \
         lat_deg, lon_deg, ref_heading_deg, or ignore"
    )]
    UnknownTarget { column: String, target: String },
}

impl ColumnMapping {
    /// Parses `COLUMN=NAME,COLUMN=NAME,…`, checking every name.
    pub fn parse(spec: &str) -> Result<ColumnMapping, MappingError> {
        let mut renames = Vec::new();
        for entry in spec
            .split(',')
            .map(str::trim)
            .filter(|entry| !entry.is_empty())
        {
            let Some((column, target)) = entry.split_once('=') else {
                return Err(MappingError::NotAnAssignment {
                    entry: entry.to_string(),
                });
            };
            let (column, target) = (
                column.trim().trim_matches('"').to_string(),
                target.trim().to_string(),
            );
            if !target.eq_ignore_ascii_case(IGNORE) && resolve(&target).is_none() {
                return Err(MappingError::UnknownTarget { column, target });
            }
            renames.push((column, target));
        }
        Ok(ColumnMapping { renames })
    }

    /// The name a column is to be read as, if the mapping names it.
    pub(super) fn target_of(&self, column: &str) -> Option<&str> {
        self.renames
            .iter()
            .find(|(from, _)| from.eq_ignore_ascii_case(column))
            .map(|(_, to)| to.as_str())
    }
}

/// The mapping target that leaves a column out.
pub(super) const IGNORE: &str = "ignore";

/// What a column can be mapped to, with a label for people: the choices of the page's
/// mapping dialog, and valid `--map` names.
pub const MAPPING_TARGETS: &[(&str, &str)] = &[
    ("ignore", "ignore"),
    ("t_s", "time (s)"),
    ("t_ms", "time (ms)"),
    ("mag_x_ut", "magnetometer x (µT)"),
    ("mag_y_ut", "magnetometer y (µT)"),
    ("mag_z_ut", "magnetometer z (µT)"),
    ("mag_x_gauss", "magnetometer x (gauss)"),
    ("mag_y_gauss", "magnetometer y (gauss)"),
    ("mag_z_gauss", "magnetometer z (gauss)"),
    ("mag_x_mg", "magnetometer x (mG)"),
    ("mag_y_mg", "magnetometer y (mG)"),
    ("mag_z_mg", "magnetometer z (mG)"),
    ("mag_x_nt", "magnetometer x (nT)"),
    ("mag_y_nt", "magnetometer y (nT)"),
    ("mag_z_nt", "magnetometer z (nT)"),
    ("acc_x_mps2", "accelerometer x (m/s²)"),
    ("acc_y_mps2", "accelerometer y (m/s²)"),
    ("acc_z_mps2", "accelerometer z (m/s²)"),
    ("acc_x_g", "accelerometer x (g)"),
    ("acc_y_g", "accelerometer y (g)"),
    ("acc_z_g", "accelerometer z (g)"),
    ("gyro_x_radps", "gyroscope x (rad/s)"),
    ("gyro_y_radps", "gyroscope y (rad/s)"),
    ("gyro_z_radps", "gyroscope z (rad/s)"),
    ("gyro_x_dps", "gyroscope x (deg/s)"),
    ("gyro_y_dps", "gyroscope y (deg/s)"),
    ("gyro_z_dps", "gyroscope z (deg/s)"),
    ("temp_c", "temperature (°C)"),
    ("ref_heading_deg", "reference heading (°)"),
    ("lat_deg", "latitude (°)"),
    ("lon_deg", "longitude (°)"),
];

/// The mapping target suggested for a column: the one it already reads as, where it is
/// among [`MAPPING_TARGETS`], else `ignore`.
pub fn suggested_target(column: &str) -> &'static str {
    let Some((resolved, _)) = resolve(column) else {
        return IGNORE;
    };
    MAPPING_TARGETS
        .iter()
        .find(|(target, _)| resolve(target).is_some_and(|(candidate, _)| candidate == resolved))
        .map_or(IGNORE, |(target, _)| target)
}

#[cfg(test)]
mod tests {
    use super::super::{preview, DelimitedReader, MAX_LINE_BYTES};
    use super::*;
    use crate::io::lines::decode_all;
    use nalgebra::Vector3;

    #[test]
    fn a_mapping_renames_columns_and_every_offered_target_is_valid() {
        for (target, _) in MAPPING_TARGETS {
            assert!(
                ColumnMapping::parse(&format!("c={target}")).is_ok(),
                "{target}"
            );
        }
        let mapping = ColumnMapping::parse(
            "ch1=mag_x_gauss, ch2=mag_y_gauss ,ch3=mag_z_gauss,when=t_ms,junk=ignore",
        )
        .expect("valid");
        let mut reader = DelimitedReader::new(None).with_mapping(Some(mapping));
        decode_all(
            b"when;ch1;ch2;ch3;junk\n1000;0.2;0.1;-0.4;7\n",
            MAX_LINE_BYTES,
            |line| reader.read_line(&line),
        );
        let report = reader.finish("m.csv").expect("readable").into_report();
        let mag = &report.recording.mag_in_body_ut;
        assert_eq!(mag.t_s, vec![1.0]);
        assert!((mag.values[0] - Vector3::new(20.0, 10.0, -40.0)).norm() < 1e-9);
        assert!(matches!(
            ColumnMapping::parse("x"),
            Err(MappingError::NotAnAssignment { .. })
        ));
        assert!(matches!(
            ColumnMapping::parse("x=mag"),
            Err(MappingError::UnknownTarget { .. })
        ));
    }

    #[test]
    fn suggestions_and_previews_for_the_mapping_dialog() {
        assert_eq!(suggested_target("mag_x_gauss"), "mag_x_gauss");
        assert_eq!(suggested_target("Time (s)"), "t_s");
        assert_eq!(suggested_target("ch1"), "ignore");
        let preview = preview(&["# a comment", "t;ch1;ch2", "0.5;1.25"]).expect("a header");
        assert_eq!(preview.columns, vec!["t", "ch1", "ch2"]);
        assert_eq!(preview.first_values, vec!["0.5", "1.25", ""]);
    }
}
