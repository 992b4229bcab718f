//! The end of an NMEA input ([`super`]): the untimed samples before the first and after
//! the last timed sentence placed in time, every stream sorted, and the notes that say
//! what was read, skipped and assumed (how times were made, midnights passed, invalid
//! fixes, merged epochs, HDG deviation, PTNTHPR's conventions).

use super::clock::{hms, SECONDS_PER_DAY};
use super::reader::{set_time, StreamId};
use super::{NmeaReader, FORMAT_NAME, KIND_NAMES, READ_SENTENCES};
use crate::io::{thousands, ImportError, ImportReport};

impl NmeaReader {
    /// Ends the input: places the untimed samples in time, sorts every stream and
    /// writes the notes. Fails when no line gave a sample.
    pub fn finish(mut self, file_name: &str) -> Result<ImportReport, ImportError> {
        let file_name = file_name.to_string();
        if self.n_data_lines == 0 {
            return Err(ImportError::Empty { file_name });
        }
        let mut notes = Vec::new();
        self.note_counts(&mut notes);
        let s_per_line = self.note_time(&mut notes);
        // t_s = 0 is the first timed sentence, on the day the first RMC date fixes.
        self.recording.start_unix_s = self.clock.first_date.map(|(first_days, first_day)| {
            (first_days - first_day) as f64 * SECONDS_PER_DAY
                + self.clock.first_time_of_day_s.unwrap_or(0.0)
        });
        let (leading, trailing) = self
            .untimed
            .split_at(self.n_leading.min(self.untimed.len()));
        for untimed in leading {
            let t_s = match self.first_anchor {
                Some(after) => {
                    after.t_s - after.line.saturating_sub(untimed.line) as f64 * s_per_line
                }
                None => untimed.number as f64,
            };
            set_time(&mut self.recording, untimed, t_s);
        }
        for untimed in trailing {
            let t_s = match self.last_anchor {
                Some(before) => {
                    before.t_s + untimed.line.saturating_sub(before.line) as f64 * s_per_line
                }
                None => untimed.number as f64,
            };
            set_time(&mut self.recording, untimed, t_s);
        }

        let mut recording = self.recording;
        let mut diagnostics = self.diagnostics;
        if recording.gnss.is_empty()
            && recording.device_heading.is_empty()
            && recording.attitude.is_empty()
        {
            let first_problem = if let Some(first) = diagnostics.kept.first() {
                match first.line {
                    Some(line) => format!(" (line {line}: {})", first.message),
                    None => format!(" ({})", first.message),
                }
            } else if let Some((line, reason)) = self.first_unused {
                format!(" (line {line}: {reason})")
            } else if let (Some(line), Some((address, _))) =
                (self.first_unknown_line, self.unknown.first())
            {
                format!(
                    " (line {line}: {address} sentences are not read by this tool; \
                     it reads {READ_SENTENCES})"
                )
            } else {
                String::new()
            };
            return Err(ImportError::NothingRecognised {
                file_name,
                format: FORMAT_NAME,
                n_lines: self.n_data_lines,
                first_problem,
            });
        }

        let n_out_of_order = recording.gnss.sort_by_time()
            + recording.device_heading.sort_by_time()
            + recording.attitude.sort_by_time();
        diagnostics.push_sorted_by_time(None, n_out_of_order);
        Ok(ImportReport {
            autopilot: None,
            file_name,
            format: FORMAT_NAME,
            recording,
            diagnostics,
            header: None,
            n_data_lines: self.n_data_lines,
            notes,
            // NMEA carries headings, never a magnetometer vector.
            mag_frame: None,
        })
    }

    fn note_counts(&self, notes: &mut Vec<String>) {
        let read: Vec<String> = KIND_NAMES
            .iter()
            .zip(self.n_read)
            .filter(|(_, count)| *count > 0)
            .map(|(name, count)| format!("{} {name}", thousands(count)))
            .collect();
        let mut summary = if read.is_empty() {
            "read no sentence of the types this tool reads".to_string()
        } else {
            format!("read {} sentences", read.join(", "))
        };
        if self.n_without_checksum > 0 {
            summary.push_str(&format!(
                "; {} lines without checksum (accepted unchecked)",
                thousands(self.n_without_checksum)
            ));
        }
        notes.push(summary);
        if self.n_unknown > 0 {
            let named: Vec<String> = self
                .unknown
                .iter()
                .map(|(address, count)| format!("{address} {}", thousands(*count)))
                .collect();
            notes.push(format!(
                "skipped {} sentences of types this tool does not read ({})",
                thousands(self.n_unknown),
                named.join(", ")
            ));
        }
        if self.n_rmc_invalid > 0 {
            notes.push(format!(
                "{} RMC sentences had status V (no valid fix): their time was kept, their \
                 position, speed and course were not used",
                thousands(self.n_rmc_invalid)
            ));
        }
        if self.n_gga_invalid > 0 {
            notes.push(format!(
                "{} GGA sentences had fix quality 0 (invalid): their time was kept, their \
                 position was not used",
                thousands(self.n_gga_invalid)
            ));
        }
        if self.n_vtg_empty > 0 {
            notes.push(format!(
                "{} VTG sentences had no valid true course or speed and were not used",
                thousands(self.n_vtg_empty)
            ));
        }
        if self.n_merged > 0 {
            notes.push(format!(
                "RMC and GGA sentences with the same time were merged into one fix ({} times)",
                thousands(self.n_merged)
            ));
        }
        if self.n_read[1] > 0 {
            notes.push(
                "GGA HDOP is a geometry factor, not an accuracy in metres, so no horizontal \
                 accuracy was set"
                    .to_string(),
            );
        }
        if let Some(variation_rad) = self.rmc_variation_rad {
            let variation_deg = variation_rad.to_degrees();
            let direction = if variation_deg < 0.0 { "W" } else { "E" };
            notes.push(format!(
                "the receiver reports a magnetic variation (declination) of {:.1}° \
                 {direction} (RMC)",
                variation_deg.abs()
            ));
        }
        if self.n_hdg_with_deviation > 0 {
            notes.push(format!(
                "HDG deviation was added to the sensor heading to give the magnetic heading \
                 ({} sentences); variation was not added",
                thousands(self.n_hdg_with_deviation)
            ));
        }
        if self.n_read[6] > 0 {
            let mut hpr_note = "PTNTHPR headings are taken as magnetic; pitch is taken as \
                                positive nose up and roll as positive right side down"
                .to_string();
            if self.hdg_reports_variation {
                hpr_note.push_str(
                    "; but this compass also reports a variation in HDG, and the HMR3000 \
                     adds a programmed variation to its PTNTHPR heading, which would make \
                     it true, not magnetic",
                );
            }
            notes.push(hpr_note);
        }
    }

    /// Decides how untimed samples get their times (returning the time per line for
    /// extrapolation), and says so in the notes.
    fn note_time(&self, notes: &mut Vec<String>) -> f64 {
        let (first, last) = (self.first_anchor, self.last_anchor);
        let s_per_line = match (first, last) {
            (Some(first), Some(last)) if last.line > first.line => {
                let s_per_line = (last.t_s - first.t_s) / (last.line - first.line) as f64;
                (s_per_line.is_finite() && s_per_line > 0.0).then_some(s_per_line)
            }
            _ => None,
        };
        let s_per_line_or_one = s_per_line.unwrap_or(1.0);

        if let Some(first) = first {
            let (hours, minutes, seconds) = hms(self.clock.first_time_of_day_s.unwrap_or(0.0));
            let mut time_note = format!(
                "t_s counts seconds from the first timed sentence (RMC or GGA, line {}) at \
                 {hours:02}:{minutes:02}:{seconds:05.2} UTC",
                first.line
            );
            if let Some((first_days, first_day)) = self.clock.first_date {
                let (year, month, day) =
                    crate::base::calendar::civil_from_days(first_days - first_day);
                time_note.push_str(&format!(" on {year:04}-{month:02}-{day:02}"));
            }
            notes.push(time_note);
        }
        if self.clock.n_midnights > 0 {
            let how = if self.clock.first_date.is_some() {
                "from the RMC date and the time of day"
            } else {
                "from the time of day wrapping round (no RMC date)"
            };
            notes.push(format!(
                "the log passes midnight UTC {} times; t_s keeps counting across it ({how})",
                self.clock.n_midnights
            ));
        }

        let untimed: Vec<&str> = KIND_NAMES
            .iter()
            .zip(self.untimed_kinds)
            .filter(|(_, untimed)| *untimed)
            .map(|(name, _)| *name)
            .collect();
        let n_untimed = self.n_untimed_sentences;
        if n_untimed == 0 {
            return s_per_line_or_one;
        }
        if first.is_none() {
            notes.push(format!(
                "no sentence carries a time (RMC or GGA with a time field), so the sample \
                 number stands in for time: t_s = 0, 1, 2, … over the {} {} samples",
                thousands(n_untimed),
                untimed.join(", ")
            ));
            return s_per_line_or_one;
        }
        // What is left unplaced lies outside the timed sentences. An HPR sentence has an
        // entry in two streams; its attitude entry is not counted.
        let n_outside = self
            .untimed
            .iter()
            .filter(|untimed| untimed.stream != StreamId::Attitude)
            .count();
        notes.push(format!(
            "{} sentences ({}) carry no time: each was placed evenly, by its line number, \
             between the timed sentences before and after it",
            thousands(n_untimed),
            untimed.join(", ")
        ));
        if n_outside > 0 {
            notes.push(match s_per_line {
                Some(s_per_line) => format!(
                    "{} of them lie before the first or after the last timed sentence; \
                     their times were extrapolated at the log's mean of {s_per_line:.4} s per line",
                    thousands(n_outside)
                ),
                None => format!(
                    "{} of them lie before the first or after the last timed sentence, and \
                     the log has a single timed epoch, so each line stands for one second there",
                    thousands(n_outside)
                ),
            });
        }
        s_per_line_or_one
    }
}
