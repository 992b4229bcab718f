//! The core's sentences name the CLI's flags where a setting would help ("give
//! --declination DEG"); on the page the same setting is a field under Analysis settings
//! or a dialog. [`for_page`] rewrites those phrases, at the one place text reaches the
//! DOM ([`super::dom`]), so the page never tells a person to type a flag.

/// Each CLI phrase and what the page says instead (the core's wording, exactly).
const PAGE_WORDING: &[(&str, &str)] = &[
    (
        "give --declination DEG for true headings",
        "enter the declination under Analysis settings for true headings",
    ),
    (
        "Give --declination DEG if you know a better value.",
        "Enter a better declination under Analysis settings if you know one.",
    ),
    (
        "or give --declination DEG.",
        "or enter the declination under Analysis settings.",
    ),
    (
        "Give --declination DEG (NOAA's",
        "Enter the declination under Analysis settings (NOAA's",
    ),
    (
        "Give --known-distance for a walk of known length, or --weinberg-k from an earlier walk.",
        "Enter the walk's length under Analysis settings (Known distance) if you know it.",
    ),
    (
        "in the page's column dialog, or with --map, for example --map 'column 1=t_s,column 2=mag_x_ut,column 3=mag_y_ut,column 4=mag_z_ut'.",
        "in the column dialog, which opens when such a file is dropped.",
    ),
];

/// `text` with the CLI's phrases in the page's words.
pub fn for_page(text: &str) -> std::borrow::Cow<'_, str> {
    if !text.contains("--") {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut text = text.to_string();
    for (cli, page) in PAGE_WORDING {
        text = text.replace(cli, page);
    }
    std::borrow::Cow::Owned(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every phrase is the core's own: each message that names a flag, rewritten, names
    /// none.
    #[wasm_bindgen_test::wasm_bindgen_test]
    fn the_core_s_messages_name_no_flag_on_the_page() {
        use crate::earth::wmm::{WmmError, WmmWarning, FIRST_MODEL_DATE, LAST_MODEL_DATE};
        let messages = [
            WmmError::LatitudeOutOfRange { lat_deg: 95.0 }.to_string(),
            WmmError::LongitudeOutOfRange { lon_deg: 200.0 }.to_string(),
            WmmWarning::Extrapolated {
                requested_date: FIRST_MODEL_DATE,
                years: -4.1,
                declination_uncertainty_deg: 0.5,
            }
            .to_string(),
            WmmError::DateOutsideModel {
                date: FIRST_MODEL_DATE,
                first: FIRST_MODEL_DATE,
                last: LAST_MODEL_DATE,
            }
            .to_string(),
            crate::io::ImportError::NoHeaderLine {
                file_name: "a.txt".to_string(),
                line: 1,
                n_columns: 4,
            }
            .to_string(),
        ];
        for message in messages {
            let page = for_page(&message);
            assert!(!page.contains("--"), "{page}");
        }
    }
}
