//! Large NMEA files on native builds: parsed on every core, applied in order on one.
//!
//! Parsing a line (framing, checksum, fields, numbers) needs no state and is nearly all
//! the work; applying it ([`NmeaReader::apply`]: the clock across midnight, the merge of
//! RMC and GGA into one fix, the placing of untimed sentences, the counts and the
//! diagnostics) needs the lines in order and is cheap. So the file is cut at line
//! boundaries into batches; worker threads parse batches into [`LineEvent`]s, and this
//! thread applies the batches in file order, with line numbers counted on from the
//! batches before, parsing batches itself while the next one is not ready. Every line
//! goes through the same `LineEvent::of` and `apply` as on one thread, in the same
//! order, so the result is the same whatever the number of cores (a test checks it);
//! only the time differs.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{mpsc, Mutex};

use super::{for_each_line, LineEvent, NmeaReader};
use crate::io::{ImportError, ImportReport};

/// Below this size one thread is as fast.
const MIN_PARALLEL_BYTES: usize = 4 << 20;

/// Bytes per batch: large enough that handing a batch over costs nothing next to
/// parsing it, small enough that a batch's events (about three times its bytes) are
/// still in cache when the applying thread reads them: with 512 KiB batches a
/// simulated 4 MiB last-level cache missed 2.5 times as often.
const BATCH_BYTES: usize = 64 << 10;

/// How many parsed batches may wait for their turn, beyond those in flight.
const MAX_BATCHES_WAITING: usize = 4;

/// `None` when the file is better read on one thread: small, or on one core.
pub(super) fn read(file_name: &str, bytes: &[u8]) -> Option<Result<ImportReport, ImportError>> {
    let n_threads = std::thread::available_parallelism().map_or(1, usize::from);
    if bytes.len() < MIN_PARALLEL_BYTES || n_threads < 2 {
        return None;
    }
    Some(read_in_batches(file_name, bytes, n_threads, BATCH_BYTES))
}

/// One batch, parsed: its non-blank lines' events with their line numbers counted from
/// the batch's start, and its number of lines.
struct ParsedBatch<'a> {
    events: Vec<(usize, LineEvent<'a>)>,
    n_lines: usize,
}

/// Parses one batch into `events` (an emptied vector of an earlier batch, so that its
/// memory is reused rather than asked of the system again).
fn parse_batch<'a>(batch: &'a [u8], mut events: Vec<(usize, LineEvent<'a>)>) -> ParsedBatch<'a> {
    events.clear();
    // Sentences of 40 to 80 bytes are the usual case; a rough guess saves regrowing.
    events.reserve(batch.len() / 48 + 1);
    let n_lines = for_each_line(batch, |line_number, content| {
        let event = LineEvent::of(content);
        if !matches!(event, LineEvent::Blank) {
            events.push((line_number, event));
        }
    });
    ParsedBatch { events, n_lines }
}

/// Cuts `bytes` into batches of about `batch_bytes` that each end just after an LF (or
/// at the end of the input). Cutting after an LF never splits a line or a CRLF, so the
/// batches' lines, in order, are the file's lines.
fn cut_batches(bytes: &[u8], batch_bytes: usize) -> Vec<&[u8]> {
    let mut batches = Vec::with_capacity(bytes.len() / batch_bytes.max(1) + 1);
    let mut rest = bytes;
    while !rest.is_empty() {
        let tentative = batch_bytes.max(1).min(rest.len());
        let end = match rest
            .get(tentative..)
            .and_then(|tail| memchr::memchr(b'\n', tail))
        {
            Some(newline_idx) => tentative + newline_idx + 1,
            None => rest.len(),
        };
        let (batch, after) = rest.split_at(end);
        batches.push(batch);
        rest = after;
    }
    batches
}

/// Reads `bytes` as [`super::read`] does, in batches of about `batch_bytes` on
/// `n_threads` threads (this one included).
pub(super) fn read_in_batches(
    file_name: &str,
    bytes: &[u8],
    n_threads: usize,
    batch_bytes: usize,
) -> Result<ImportReport, ImportError> {
    let batches = cut_batches(bytes, batch_bytes);
    let next_to_parse = AtomicUsize::new(0);
    // The next batch nobody has started, claimed by whoever takes it.
    let claim = || {
        let batch_idx = next_to_parse.fetch_add(1, Ordering::Relaxed);
        batches.get(batch_idx).map(|batch| (batch_idx, *batch))
    };
    // Emptied event vectors, handed back for the next batches.
    let spare_events: Mutex<Vec<Vec<(usize, LineEvent<'_>)>>> = Mutex::new(Vec::new());
    let spare = || {
        spare_events
            .lock()
            .ok()
            .and_then(|mut spare| spare.pop())
            .unwrap_or_default()
    };
    let mut reader = NmeaReader::new();
    std::thread::scope(|scope| {
        let (sender, receiver) = mpsc::sync_channel::<(usize, ParsedBatch<'_>)>(n_threads);
        for _ in 1..n_threads.min(batches.len()) {
            let sender = sender.clone();
            scope.spawn(move || {
                while let Some((batch_idx, batch)) = claim() {
                    if sender
                        .send((batch_idx, parse_batch(batch, spare())))
                        .is_err()
                    {
                        break;
                    }
                }
            });
        }
        drop(sender);

        let mut waiting: BTreeMap<usize, ParsedBatch<'_>> = BTreeMap::new();
        let mut lines_before = 0usize;
        for next_idx in 0..batches.len() {
            let parsed = loop {
                if let Some(parsed) = waiting.remove(&next_idx) {
                    break parsed;
                }
                // Take what the workers have finished; if nothing, parse a batch here
                // rather than wait, unless enough are waiting already.
                match receiver.try_recv() {
                    Ok((batch_idx, parsed)) => {
                        waiting.insert(batch_idx, parsed);
                        continue;
                    }
                    Err(mpsc::TryRecvError::Empty | mpsc::TryRecvError::Disconnected) => {}
                }
                if waiting.len() < MAX_BATCHES_WAITING {
                    if let Some((batch_idx, batch)) = claim() {
                        waiting.insert(batch_idx, parse_batch(batch, spare()));
                        continue;
                    }
                }
                match receiver.recv() {
                    Ok((batch_idx, parsed)) => {
                        waiting.insert(batch_idx, parsed);
                    }
                    // Every worker has stopped without sending this batch (one
                    // panicked, which the scope reports): parse it here.
                    Err(mpsc::RecvError) => {
                        break parse_batch(
                            batches.get(next_idx).copied().unwrap_or_default(),
                            Vec::new(),
                        )
                    }
                }
            };
            let mut events = parsed.events;
            for (line_number, event) in events.drain(..) {
                reader.apply(lines_before + line_number, event);
            }
            lines_before += parsed.n_lines;
            if next_idx == 0 {
                let first_len = batches.first().map_or(0, |batch| batch.len());
                reader.reserve_for(first_len, bytes.len());
            }
            if let Ok(mut spare) = spare_events.lock() {
                spare.push(events);
            }
        }
    });
    reader.finish(file_name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::lines::decode_all;

    /// Appends the checksum a sentence body needs, `$` included.
    fn sentence(body: &str) -> String {
        let checksum = body.bytes().fold(0u8, |acc, byte| acc ^ byte);
        format!("${body}*{checksum:02X}")
    }

    /// A log with what crosses lines: a midnight with RMC dates, then GGA without any
    /// date across the next one, untimed sentences before the first timed one, RMC and
    /// GGA of one epoch, bad checksums, mixed talkers, more unknown addresses than are
    /// named, an overlong line, bytes that are not UTF-8, blank lines, and every line
    /// ending.
    fn tricky_log() -> Vec<u8> {
        let mut lines: Vec<Vec<u8>> = vec![
            b"\xef\xbb\xbf".to_vec(),
            sentence("HEHDT,10.0,T").into_bytes(),
            sentence("GPVTG,84.00,T,,M,0.446,N,0.826,K,A").into_bytes(),
        ];
        for second in 0..40u32 {
            let time = format!("2359{:02}.50", 30 + second % 30);
            let (time, date) = if second < 30 {
                (time, "311299")
            } else {
                (format!("0000{:02}.50", second - 30), "010100")
            };
            let talker = if second % 3 == 0 { "GN" } else { "GP" };
            if second % 7 != 3 {
                lines.push(
                    sentence(&format!(
                        "{talker}RMC,{time},A,4807.038,N,01131.000,E,022.4,084.4,{date},003.1,W"
                    ))
                    .into_bytes(),
                );
            }
            lines.push(
                sentence(&format!(
                    "{talker}GGA,{time},4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"
                ))
                .into_bytes(),
            );
            lines.push(sentence(&format!("HEHDT,{second}.5,T")).into_bytes());
            match second % 5 {
                0 => lines.push(b"$HEHDT,12.0,T*00".to_vec()),
                1 => lines.push(sentence(&format!("P{second}XYZ,1")).into_bytes()),
                2 => lines.push(Vec::new()),
                3 => lines.push(b"garbage \xc3\xa9\xff line".to_vec()),
                _ => lines.push(sentence("PTNTHPR,85.9,N,-0.9,N,0.8,O").into_bytes()),
            }
        }
        lines.push(format!("$GPRMC,{}", "1".repeat(MAX_LINE_BYTES_FOR_TEST)).into_bytes());
        for second in 0..30u32 {
            let time = if second < 20 {
                format!("2359{:02}", 40 + second)
            } else {
                format!("0000{:02}", second - 20)
            };
            lines.push(
                sentence(&format!(
                    "GLGGA,{time},4807.038,S,01131.000,W,2,08,0.9,1.0,M,,M,,"
                ))
                .into_bytes(),
            );
            lines.push(sentence("HCHDG,90.0,1.0,E,3.1,W").into_bytes());
        }
        lines.push(sentence("HEHDT,1.0,T").into_bytes());
        let mut bytes = Vec::new();
        for (line_idx, line) in lines.iter().enumerate() {
            bytes.extend_from_slice(line);
            bytes.extend_from_slice([&b"\r\n"[..], b"\n", b"\r\n", b"\r"][line_idx % 4]);
        }
        bytes
    }

    const MAX_LINE_BYTES_FOR_TEST: usize = super::super::MAX_LINE_BYTES + 5;

    #[test]
    fn batches_on_any_number_of_threads_read_as_one_thread_does() {
        let bytes = tricky_log();
        let mut reader = NmeaReader::new();
        decode_all(&bytes, super::super::MAX_LINE_BYTES, |line| {
            reader.read_decoded(&line)
        });
        let sequential = reader.finish("tricky.nmea").expect("readable");
        // The log exercises what it should.
        let notes = sequential.notes.join("\n");
        assert!(notes.contains("passes midnight UTC 2 times"), "{notes}");
        assert!(notes.contains("P1XYZ 1"), "{notes}");
        assert!(sequential.diagnostics.total() > 20);
        assert_eq!(
            super::super::read("tricky.nmea", &bytes),
            Ok(sequential.clone())
        );
        for n_threads in 1..=4 {
            for batch_bytes in [1, 2, 3, 10, 50, 77, 200, 1000, 5000, bytes.len()] {
                assert_eq!(
                    read_in_batches("tricky.nmea", &bytes, n_threads, batch_bytes),
                    Ok(sequential.clone()),
                    "{n_threads} threads, batches of {batch_bytes} bytes"
                );
            }
        }
    }

    #[test]
    fn batches_hold_the_lines_of_the_file() {
        let bytes = b"a\r\nb\n\nc\rd\r\r\ne";
        for batch_bytes in 1..=bytes.len() + 1 {
            let batches = cut_batches(bytes, batch_bytes);
            assert_eq!(batches.concat(), bytes.to_vec());
            let mut lines = Vec::new();
            for batch in &batches {
                for_each_line(batch, |_, content| lines.push(content.to_vec()));
            }
            let mut decoded = Vec::new();
            decode_all(bytes, 100, |line| {
                decoded.push(line.text.as_bytes().to_vec())
            });
            assert_eq!(lines, decoded, "batches of {batch_bytes}");
        }
    }

    /// Lines to draw logs from: sentences that set and cross the date and midnight,
    /// untimed ones, bad ones, unknown ones, blanks and noise.
    const POOL: &[&[u8]] = &[
        b"$GPRMC,235959.50,A,4807.038,N,01131.000,E,022.4,084.4,311299,003.1,W*5A",
        b"$GNRMC,000000.50,A,4807.038,N,01131.000,E,022.4,084.4,010100,,*78",
        b"$GPGGA,235959.50,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*72",
        b"$GPGGA,000001,4807.038,S,01131.000,W,0,08,0.9,545.4,M,46.9,M,,",
        b"$GPGGA,120000,,,,,1,,,,,,,,",
        b"$HEHDT,128.0,T*22",
        b"$HEHDT,128.0,T*23",
        b"$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48",
        b"$HCHDG,101.1,,,7.1,W*3C",
        b"$PTNTHPR,85.9,N,-0.9,N,0.8,N*2C",
        b"$PTNTHPR,,P,0.3,N,0.1,N*06",
        b"$GPGSV,3,1,11*00",
        b"$PXYZ,1",
        b"$GPRMC,bad*00",
        b"",
        b"   ",
        b"\xef\xbb\xbf$HEHDT,1.0,T",
        b"n\xffo\xc3",
    ];

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig {
            cases: 128,
            ..proptest::prelude::ProptestConfig::default()
        })]

        #[test]
        fn any_log_in_any_batches_reads_as_one_thread_does(
            picks in proptest::collection::vec((0..POOL.len(), 0usize..4), 1..120),
            n_threads in 1usize..4,
            batch_bytes in 1usize..400,
        ) {
            let mut bytes = Vec::new();
            for &(line_idx, ending_idx) in &picks {
                bytes.extend_from_slice(POOL[line_idx]);
                bytes.extend_from_slice([&b"\r\n"[..], b"\n", b"\r", b""][ending_idx]);
            }
            let mut reader = NmeaReader::new();
            decode_all(&bytes, super::super::MAX_LINE_BYTES, |line| reader.read_decoded(&line));
            let sequential = reader.finish("any.nmea");
            proptest::prop_assert_eq!(
                read_in_batches("any.nmea", &bytes, n_threads, batch_bytes),
                sequential
            );
        }
    }
}
