//! Numbers in English sentences: plurals ("1 step", "2 steps"), ordinals ("every 2nd
//! sample") and durations as a person says them. Shared by every sentence the core
//! writes for the page, the CLI and the report.

/// "2nd", "3rd", "11th", "22nd": an ordinal as English writes it.
pub fn ordinal(number: usize) -> String {
    let suffix = match (number % 10, number % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{number}{suffix}")
}

/// `singular` for one, else `plural`.
pub fn plural<'a>(count: usize, singular: &'a str, plural: &'a str) -> &'a str {
    if count == 1 {
        singular
    } else {
        plural
    }
}

/// "A", "A and B", "A, B and C".
pub fn list(items: &[String]) -> String {
    match items {
        [] => String::new(),
        [one] => one.clone(),
        [rest @ .., last] => format!("{} and {last}", rest.join(", ")),
    }
}

/// How often something happened: "once", "twice", "3 times".
pub fn times(count: usize) -> String {
    match count {
        1 => "once".to_string(),
        2 => "twice".to_string(),
        _ => format!("{count} times"),
    }
}

/// A duration as a person says it: seconds, minutes or hours.
pub fn duration_text(duration_s: f64) -> String {
    if duration_s < 120.0 {
        format!("{duration_s:.0} s")
    } else if duration_s < 2.0 * 3600.0 {
        format!("{:.1} min", duration_s / 60.0)
    } else {
        format!("{:.1} h", duration_s / 3600.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plurals_and_durations_read_as_english() {
        assert_eq!(plural(1, "step", "steps"), "step");
        assert_eq!(plural(2, "step", "steps"), "steps");
        assert_eq!(plural(0, "bout", "bouts"), "bouts");
        let ordinals: Vec<String> = [1, 2, 3, 4, 11, 12, 13, 21, 22, 101, 111]
            .map(ordinal)
            .into();
        assert_eq!(
            ordinals,
            [
                "1st", "2nd", "3rd", "4th", "11th", "12th", "13th", "21st", "22nd", "101st",
                "111th"
            ]
        );
        assert_eq!(duration_text(42.4), "42 s");
        assert_eq!(duration_text(600.0), "10.0 min");
        assert_eq!(duration_text(3.0 * 3600.0), "3.0 h");
        let names = |names: &[&str]| {
            names
                .iter()
                .map(std::string::ToString::to_string)
                .collect::<Vec<_>>()
        };
        assert_eq!(list(&names(&["A"])), "A");
        assert_eq!(list(&names(&["A", "B", "C"])), "A, B and C");
        assert_eq!(list(&[]), "");
    }
}
