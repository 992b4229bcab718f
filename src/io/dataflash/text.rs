//! The text DataFlash log (`.log`, as Mission Planner or `mavlogdump.py --format log`
//! write it): one message per line, `NAME, value, value, ...`, each type defined by an
//! earlier `FMT, type, length, NAME, format, Col1,Col2,...` line. The values are
//! written already scaled (degrees, metres), so the format characters only name them.

use std::collections::HashMap;

use super::format::MessageFormat;
use super::messages::{Collector, Fields, Plan};
use crate::io::{shorten, Diagnostics};

/// The fields of one text line after its name.
struct TextFields<'a> {
    values: &'a [&'a str],
}

impl Fields for TextFields<'_> {
    fn number(&self, column: usize) -> Option<f64> {
        self.values.get(column)?.parse::<f64>().ok()
    }

    fn text(&self, column: usize) -> Option<String> {
        self.values
            .get(column)
            .map(std::string::ToString::to_string)
    }
}

/// Whether the first lines are a DataFlash text log: one of them defines `FMT` itself.
pub fn looks_like(sample: &[&str]) -> bool {
    sample.iter().any(|line| {
        let fields: Vec<&str> = line.split(',').map(str::trim).take(4).collect();
        fields.len() == 4 && fields[0] == "FMT" && fields[3] == "FMT"
    })
}

#[derive(Default)]
pub struct TextReader {
    formats: HashMap<String, (MessageFormat, Plan)>,
    pub collector: Collector,
    pub diagnostics: Diagnostics,
    pub n_messages: usize,
    /// The first line that is not a message, as the banner it usually is.
    pub banner: Option<String>,
    pub n_undefined: usize,
}

impl TextReader {
    pub fn read_line(&mut self, number: usize, text: &str) {
        let text = text.trim();
        if text.is_empty() {
            return;
        }
        let mut values: Vec<&str> = text.split(',').map(str::trim).collect();
        let name = values.remove(0);
        if name == "FMT" {
            self.read_format(number, &values);
            return;
        }
        match self.formats.get(name) {
            Some((_, plan)) => {
                self.n_messages += 1;
                if *plan != Plan::Ignored {
                    self.collector
                        .read(name, plan, &TextFields { values: &values });
                }
            }
            None if self.n_messages == 0 && self.banner.is_none() => {
                self.banner = Some(shorten(text));
            }
            None => {
                self.n_undefined += 1;
                self.diagnostics.push(
                    Some(number),
                    format!("\"{}\" has no FMT line before it: skipped", shorten(name)),
                );
            }
        }
    }

    fn read_format(&mut self, number: usize, values: &[&str]) {
        let (Some(length), Some(&name), Some(&chars)) = (
            values.get(1).and_then(|value| value.parse::<usize>().ok()),
            values.get(2),
            values.get(3),
        ) else {
            self.diagnostics.push(
                Some(number),
                "an FMT line without type, length, name and format: skipped",
            );
            return;
        };
        self.n_messages += 1;
        let columns = values.get(4..).unwrap_or_default().join(",");
        let format = MessageFormat::new(name, length, chars, &columns);
        let plan = Plan::of(&format);
        self.formats.insert(name.to_string(), (format, plan));
    }
}
