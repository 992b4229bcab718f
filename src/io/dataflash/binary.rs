//! The binary DataFlash log (`.bin`), read in chunks: messages `0xA3 0x95 type
//! payload`, each type's length and fields defined by an earlier `FMT` message.
//!
//! There is no checksum, so the reader keeps in step by the two head bytes: where they
//! are not where the last message ended (a corrupt byte, a cut, an unknown type), it
//! skips to the next head whose message is followed by another head (or by the end of
//! the data), and says which bytes it skipped.

use super::format::{self, FieldType, MessageFormat, FMT_LENGTH, FMT_TYPE, HEAD, HEADER_LEN};
use super::messages::{Collector, Fields, Plan};
use crate::io::Diagnostics;

/// A binary payload read through its format's field layout.
struct BinaryFields<'a> {
    payload: &'a [u8],
    fields: &'a [(FieldType, usize)],
}

impl Fields for BinaryFields<'_> {
    fn number(&self, column: usize) -> Option<f64> {
        format::number(self.payload, *self.fields.get(column)?)
    }

    fn text(&self, column: usize) -> Option<String> {
        format::text(self.payload, *self.fields.get(column)?)
    }
}

/// Bytes kept unread before the buffer is compacted.
const COMPACT_BYTES: usize = 1 << 16;

pub struct BinaryReader {
    /// Bytes not yet read, from `buffer[start]` on.
    buffer: Vec<u8>,
    start: usize,
    /// The file offset of `buffer[0]`.
    buffer_offset: usize,
    formats: Vec<Option<(MessageFormat, Plan)>>,
    pub collector: Collector,
    pub diagnostics: Diagnostics,
    pub n_messages: usize,
    /// Where the bytes being skipped began, while out of step.
    skipping_from: Option<usize>,
    pub n_bytes_skipped: usize,
}

impl Default for BinaryReader {
    fn default() -> Self {
        BinaryReader {
            buffer: Vec::new(),
            start: 0,
            buffer_offset: 0,
            formats: vec![None; 256],
            collector: Collector::default(),
            diagnostics: Diagnostics::default(),
            n_messages: 0,
            skipping_from: None,
            n_bytes_skipped: 0,
        }
    }
}

impl BinaryReader {
    pub fn feed(&mut self, chunk: &[u8]) {
        if self.start > COMPACT_BYTES && self.start * 2 > self.buffer.len() {
            self.buffer.drain(..self.start);
            self.buffer_offset += self.start;
            self.start = 0;
        }
        self.buffer.extend_from_slice(chunk);
        self.read(false);
    }

    /// Reads what is left; an unfinished last message is reported.
    pub fn finish(&mut self) {
        self.read(true);
        let left = self.buffer.len() - self.start;
        if left > 0 {
            let offset = self.buffer_offset + self.start;
            self.end_skip(offset);
            self.diagnostics.push(
                None,
                format!(
                    "byte {offset}: the last {left} bytes are an unfinished message (the log \
                     was cut); everything before it was read"
                ),
            );
            self.start = self.buffer.len();
        }
        let end = self.buffer_offset + self.buffer.len();
        self.end_skip(end);
    }

    /// The length of a message of type `type_id`, where its format is known.
    fn length_of(&self, type_id: u8) -> Option<usize> {
        if type_id == FMT_TYPE {
            return Some(FMT_LENGTH);
        }
        let (format, _) = self.formats[type_id as usize].as_ref()?;
        (format.length >= HEADER_LEN).then_some(format.length)
    }

    fn read(&mut self, at_end: bool) {
        loop {
            let available = &self.buffer[self.start..];
            if available.len() < HEADER_LEN {
                return;
            }
            if available[..2] != HEAD {
                self.skip_to_next_head(at_end);
                continue;
            }
            let Some(length) = self.length_of(available[2]) else {
                self.skip_one();
                continue;
            };
            if available.len() < length {
                if at_end && self.skipping_from.is_some() {
                    // Out of step at the end: this head was never a message.
                    self.skip_one();
                    continue;
                }
                return;
            }
            // Out of step, accept a message only where another head follows it.
            if self.skipping_from.is_some() {
                match available.get(length..length + 2) {
                    Some(next) if next == HEAD => {}
                    None if at_end => {}
                    None => return,
                    Some(_) => {
                        self.skip_one();
                        continue;
                    }
                }
                let offset = self.buffer_offset + self.start;
                self.end_skip(offset);
            }
            let end = self.start + length;
            self.read_message(self.start, end);
            self.start = end;
        }
    }

    fn read_message(&mut self, start: usize, end: usize) {
        let type_id = self.buffer[start + 2];
        let payload = &self.buffer[start + HEADER_LEN..end];
        self.n_messages += 1;
        if type_id == FMT_TYPE {
            let fmt = MessageFormat::new("FMT", FMT_LENGTH, "BBnNZ", "Type,Length,Name");
            let Some(fields) = fmt.fields.as_deref() else {
                return;
            };
            let read = BinaryFields { payload, fields };
            let (Some(defined), Some(length), Some(name), Some(chars), Some(columns)) = (
                read.number(0),
                read.number(1),
                read.text(2),
                read.text(3),
                read.text(4),
            ) else {
                return;
            };
            let format = MessageFormat::new(&name, length as usize, &chars, &columns);
            if format.fields.is_none() && !name.is_empty() {
                self.diagnostics.push(
                    None,
                    format!(
                        "byte {}: FMT of {name} has format \"{chars}\", which is unknown or longer \
                         than its {length} bytes: its messages are skipped",
                        self.buffer_offset + start
                    ),
                );
            }
            let plan = Plan::of(&format);
            if (defined as usize) < 256 && defined as u8 != FMT_TYPE {
                self.formats[defined as usize] = Some((format, plan));
            }
            return;
        }
        if let Some((format, plan)) = &self.formats[type_id as usize] {
            if let (Some(fields), false) = (format.fields.as_deref(), *plan == Plan::Ignored) {
                let read = BinaryFields { payload, fields };
                self.collector.read(&format.name, plan, &read);
            }
        }
    }

    fn skip_one(&mut self) {
        self.begin_skip();
        self.start += 1;
        self.n_bytes_skipped += 1;
    }

    /// Skips to the next `0xA3 0x95`, or to the last byte when there is none yet.
    fn skip_to_next_head(&mut self, at_end: bool) {
        self.begin_skip();
        let available = &self.buffer[self.start..];
        let next = available
            .windows(2)
            .skip(1)
            .position(|pair| pair == HEAD)
            .map(|idx| idx + 1);
        let n = match next {
            Some(idx) => idx,
            None if at_end => available.len(),
            None => available.len().saturating_sub(1),
        };
        self.start += n;
        self.n_bytes_skipped += n;
    }

    fn begin_skip(&mut self) {
        if self.skipping_from.is_none() {
            self.skipping_from = Some(self.buffer_offset + self.start);
        }
    }

    fn end_skip(&mut self, offset: usize) {
        if let Some(from) = self.skipping_from.take() {
            if offset > from {
                self.diagnostics.push(
                    None,
                    format!(
                        "bytes {from}-{}: {} bytes skipped, not a message this log defines \
                         (corrupt or cut data); reading went on at the next message",
                        offset - 1,
                        offset - from
                    ),
                );
            }
        }
    }
}
