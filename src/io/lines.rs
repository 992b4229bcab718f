//! The incremental line decoder shared by files and the serial port ([`crate::live`]).
//!
//! It accepts CR, LF and CRLF line endings, and chunk boundaries anywhere, including
//! between the CR and LF of one CRLF: the same bytes split into any chunks give the
//! same lines. Memory per line is bounded: a line longer than the limit is cut and
//! flagged. Bytes that are not UTF-8 are replaced (U+FFFD) rather than aborting.

use std::borrow::Cow;

/// One decoded line.
#[derive(Debug, Clone, PartialEq)]
pub struct Line<'a> {
    /// 1-based line number.
    pub number: usize,
    pub text: Cow<'a, str>,
    /// The line was longer than the limit and its end was dropped.
    pub truncated: bool,
}

#[derive(Debug, Clone)]
pub struct LineDecoder {
    buffer: Vec<u8>,
    max_line_bytes: usize,
    n_lines_emitted: usize,
    truncated: bool,
    /// The previous chunk ended with CR, so an LF at the start of the next one belongs
    /// to that CRLF and ends no line.
    after_cr: bool,
}

impl LineDecoder {
    /// A decoder that keeps at most `max_line_bytes` of any line.
    pub fn new(max_line_bytes: usize) -> Self {
        Self {
            buffer: Vec::new(),
            max_line_bytes: max_line_bytes.max(1),
            n_lines_emitted: 0,
            truncated: false,
            after_cr: false,
        }
    }

    /// A decoder for text that continues after `n_lines_before` lines: its first line is
    /// numbered `n_lines_before + 1`.
    pub fn continuing(max_line_bytes: usize, n_lines_before: usize) -> Self {
        Self {
            n_lines_emitted: n_lines_before,
            ..Self::new(max_line_bytes)
        }
    }

    /// Feeds one chunk, calling `on_line` for each line it completes. A line that lies
    /// wholly inside the chunk is handed over without a copy.
    pub fn feed(&mut self, chunk: &[u8], mut on_line: impl FnMut(Line<'_>)) {
        let mut rest = chunk;
        if self.after_cr {
            if let Some(stripped) = rest.strip_prefix(b"\n") {
                rest = stripped;
            }
            if !chunk.is_empty() {
                self.after_cr = false;
            }
        }
        while let Some(end_idx) = memchr::memchr2(b'\n', b'\r', rest) {
            let (content, tail) = rest.split_at(end_idx);
            if self.buffer.is_empty() && !self.truncated {
                let kept = &content[..content.len().min(self.max_line_bytes)];
                self.n_lines_emitted += 1;
                on_line(Line {
                    number: self.n_lines_emitted,
                    text: decode_utf8(kept),
                    truncated: kept.len() < content.len(),
                });
            } else {
                self.append(content);
                self.emit(&mut on_line);
            }
            let terminator = tail.first().copied();
            let mut tail = tail.get(1..).unwrap_or_default();
            if terminator == Some(b'\r') {
                if let Some(stripped) = tail.strip_prefix(b"\n") {
                    tail = stripped;
                } else if tail.is_empty() {
                    self.after_cr = true;
                }
            }
            rest = tail;
        }
        self.append(rest);
    }

    /// Ends the input: emits a last line that had no line ending.
    pub fn finish(&mut self, mut on_line: impl FnMut(Line<'_>)) {
        if !self.buffer.is_empty() || self.truncated {
            self.emit(&mut on_line);
        }
        self.after_cr = false;
    }

    /// Lines emitted so far.
    pub fn n_lines(&self) -> usize {
        self.n_lines_emitted
    }

    fn append(&mut self, bytes: &[u8]) {
        let room = self.max_line_bytes.saturating_sub(self.buffer.len());
        if bytes.len() > room {
            self.truncated = true;
        }
        self.buffer
            .extend_from_slice(&bytes[..bytes.len().min(room)]);
    }

    fn emit(&mut self, on_line: &mut impl FnMut(Line<'_>)) {
        self.n_lines_emitted += 1;
        on_line(Line {
            number: self.n_lines_emitted,
            text: decode_utf8(&self.buffer),
            truncated: self.truncated,
        });
        self.buffer.clear();
        self.truncated = false;
    }
}

/// Text of a line: borrowed when it is valid UTF-8 (the usual case, checked by the
/// standard library's fast validator), otherwise with U+FFFD for the invalid bytes.
fn decode_utf8(bytes: &[u8]) -> Cow<'_, str> {
    match std::str::from_utf8(bytes) {
        Ok(text) => Cow::Borrowed(text),
        Err(_) => String::from_utf8_lossy(bytes),
    }
}

/// Decodes a whole byte slice at once.
pub fn decode_all(bytes: &[u8], max_line_bytes: usize, mut on_line: impl FnMut(Line<'_>)) {
    let mut decoder = LineDecoder::new(max_line_bytes);
    decoder.feed(bytes, &mut on_line);
    decoder.finish(&mut on_line);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines_of_chunks(chunks: &[&[u8]], max_line_bytes: usize) -> Vec<(usize, String, bool)> {
        let mut lines = Vec::new();
        let mut decoder = LineDecoder::new(max_line_bytes);
        for chunk in chunks {
            decoder.feed(chunk, |line| {
                lines.push((line.number, line.text.into_owned(), line.truncated));
            });
        }
        decoder.finish(|line| lines.push((line.number, line.text.into_owned(), line.truncated)));
        lines
    }

    #[test]
    fn every_line_ending_is_accepted() {
        let got: Vec<String> = lines_of_chunks(&[b"a\nb\r\nc\rd"], 100)
            .into_iter()
            .map(|l| l.1)
            .collect();
        assert_eq!(got, ["a", "b", "c", "d"]);
    }

    #[test]
    fn empty_lines_are_lines() {
        let got: Vec<String> = lines_of_chunks(&[b"a\n\nb\r\n\r\n"], 100)
            .into_iter()
            .map(|l| l.1)
            .collect();
        assert_eq!(got, ["a", "", "b", ""]);
    }

    #[test]
    fn every_chunking_gives_the_same_lines() {
        let input: &[u8] = b"t_s,x\r\n1,2\r\n\r3,4\n5,\xff6\r";
        let whole = lines_of_chunks(&[input], 100);
        for split_a in 0..=input.len() {
            for split_b in split_a..=input.len() {
                let chunks = [
                    &input[..split_a],
                    &input[split_a..split_b],
                    &input[split_b..],
                ];
                assert_eq!(
                    lines_of_chunks(&chunks, 100),
                    whole,
                    "split at {split_a}, {split_b}"
                );
            }
        }
    }

    #[test]
    fn long_lines_are_cut_and_flagged() {
        let got = lines_of_chunks(&[b"abcdefgh\nxy\n"], 4);
        assert_eq!(
            got,
            vec![(1, "abcd".to_string(), true), (2, "xy".to_string(), false)]
        );
    }

    #[test]
    fn invalid_utf8_is_replaced_not_fatal() {
        let got = lines_of_chunks(&[b"a\xffb\n"], 100);
        assert_eq!(got[0].1, "a\u{fffd}b");
    }
}
