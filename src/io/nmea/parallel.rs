//! Large NMEA files on native builds and in the browser's threaded build ([`crate::base::par`]):
//! parsed on every thread, applied in order on one.
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

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use super::framing::{for_each_line, LineEvent};
use super::NmeaReader;
use crate::io::{ImportError, ImportReport};

/// Below this size one thread is as fast.
const MIN_PARALLEL_BYTES: usize = 4 << 20;

/// A block (see [`read_lines_block`]) below this size is read on one thread.
const MIN_PARALLEL_BLOCK_BYTES: usize = 1 << 20;

/// Bytes per batch: large enough that handing a batch over costs nothing next to
/// parsing it, small enough that a batch's events (about three times its bytes) are
/// still in cache when the applying thread reads them: with 512 KiB batches a
/// simulated 4 MiB last-level cache missed 2.5 times as often.
const BATCH_BYTES: usize = 64 << 10;

/// How many parsed batches may wait for their turn, beyond one per thread.
const MAX_BATCHES_WAITING: usize = 4;

/// `None` when the file is better read on one thread: small, or on one core.
pub(super) fn read(file_name: &str, bytes: &[u8]) -> Option<Result<ImportReport, ImportError>> {
    let n_threads = crate::base::par::n_threads();
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
    let mut reader = NmeaReader::new();
    apply_in_batches(&mut reader, bytes, 0, n_threads, batch_bytes, true);
    reader.finish(file_name)
}

/// A block of whole lines (a chunk of a file read in chunks, as the page reads a dropped
/// file) into `reader` on every thread, numbered on from `n_lines_before`; returns how
/// many lines there were. `None` (nothing read) when one thread is as fast: a small
/// block, or one thread.
pub(super) fn read_lines_block(
    reader: &mut NmeaReader,
    bytes: &[u8],
    n_lines_before: usize,
) -> Option<usize> {
    let n_threads = crate::base::par::n_threads();
    if bytes.len() < MIN_PARALLEL_BLOCK_BYTES || n_threads < 2 {
        return None;
    }
    Some(apply_in_batches(
        reader,
        bytes,
        n_lines_before,
        n_threads,
        BATCH_BYTES,
        false,
    ))
}

/// The lines of `bytes`, parsed in batches of about `batch_bytes` on `n_threads`
/// threads and applied to `reader` in order on this one, numbered on from
/// `n_lines_before`; returns how many lines there were. `reserve`: the streams are
/// given room for all of `bytes` once the first batch shows how dense it is.
///
/// This thread applies the batches in order; the others ([`crate::base::par::on_each_part`])
/// parse them. Nothing here makes this thread block on another: in the browser it is
/// the page's main thread, which may not, so it spins where it must wait (only when it
/// has caught up with the parsers and has nothing left to parse itself), and takes
/// locks only with `try_lock`. The parsers wait (spinning, and yielding natively) when
/// they are a batch per thread and [`MAX_BATCHES_WAITING`] more ahead of the applying,
/// so that parsed events never hold more than a few batches' worth of memory.
fn apply_in_batches(
    reader: &mut NmeaReader,
    bytes: &[u8],
    n_lines_before: usize,
    n_threads: usize,
    batch_bytes: usize,
    reserve: bool,
) -> usize {
    let batches = cut_batches(bytes, batch_bytes);
    let n_batches = batches.len();
    let slots: Vec<BatchSlot<'_>> = batches.iter().map(|_| BatchSlot::default()).collect();
    // The next batch nobody has started; the batches applied so far.
    let next_to_parse = AtomicUsize::new(0);
    let n_applied = AtomicUsize::new(0);
    let n_parsers_running = AtomicUsize::new(n_threads.min(n_batches).saturating_sub(1));
    // Emptied event vectors, handed back for the next batches (when the lock is free).
    let spare_events: Mutex<Vec<Vec<(usize, LineEvent<'_>)>>> = Mutex::new(Vec::new());
    let spare = || {
        spare_events
            .try_lock()
            .ok()
            .and_then(|mut spare| spare.pop())
            .unwrap_or_default()
    };
    // Claims the next batch if it is not too far ahead of the applying.
    let claim = |ahead_of: usize| {
        let batch_idx = next_to_parse.load(Ordering::Acquire);
        if batch_idx >= n_batches || batch_idx >= ahead_of + n_threads + MAX_BATCHES_WAITING {
            return Claim::NotNow(batch_idx >= n_batches);
        }
        match next_to_parse.compare_exchange(
            batch_idx,
            batch_idx + 1,
            Ordering::AcqRel,
            Ordering::Acquire,
        ) {
            Ok(_) => Claim::Batch(batch_idx),
            Err(_) => Claim::NotNow(false),
        }
    };
    let parse_into_slot = |batch_idx: usize| {
        if let (Some(slot), Some(batch)) = (slots.get(batch_idx), batches.get(batch_idx)) {
            slot.put(parse_batch(batch, spare()));
        }
    };

    let mut lines_before = n_lines_before;
    let failures_before = crate::base::par::n_failures();
    // `None` when a parser panicked (natively): the applier has parsed what it left, so
    // the reading is whole all the same.
    let _ = crate::base::par::on_each_part(
        std::iter::once(Role::Apply(reader, &mut lines_before))
            .chain((1..n_threads.min(n_batches)).map(|_| Role::Parse)),
        |role| {
            let Role::Apply(reader, lines_before) = role else {
                // A parser: stops when every batch is claimed.
                let _running = Running(&n_parsers_running);
                loop {
                    match claim(n_applied.load(Ordering::Acquire)) {
                        Claim::Batch(batch_idx) => parse_into_slot(batch_idx),
                        Claim::NotNow(true) => break,
                        Claim::NotNow(false) => wait_a_little(),
                    }
                }
                return;
            };
            // The applier (this thread).
            for (next_idx, slot) in slots.iter().enumerate() {
                let parsed = loop {
                    if let Some(parsed) = slot.take() {
                        break parsed;
                    }
                    match claim(next_idx) {
                        Claim::Batch(batch_idx) => parse_into_slot(batch_idx),
                        // Claimed by a parser that stopped without parsing it (it
                        // panicked: natively it has counted itself out, in the browser
                        // its worker is counted failed): parse it here.
                        Claim::NotNow(_)
                            if n_parsers_running.load(Ordering::Acquire) == 0
                                || crate::base::par::n_failures() != failures_before =>
                        {
                            break parse_batch(
                                batches.get(next_idx).copied().unwrap_or_default(),
                                Vec::new(),
                            );
                        }
                        Claim::NotNow(_) => core::hint::spin_loop(),
                    }
                };
                let mut events = parsed.events;
                for (line_number, event) in events.drain(..) {
                    reader.apply(*lines_before + line_number, event);
                }
                *lines_before += parsed.n_lines;
                if next_idx == 0 && reserve {
                    let first_len = batches.first().map_or(0, |batch| batch.len());
                    reader.reserve_for(first_len, bytes.len());
                }
                n_applied.store(next_idx + 1, Ordering::Release);
                if let Ok(mut spare) = spare_events.try_lock() {
                    spare.push(events);
                }
            }
        },
    );
    lines_before - n_lines_before
}

/// What a thread of [`apply_in_batches`] does.
enum Role<'a> {
    Apply(&'a mut NmeaReader, &'a mut usize),
    Parse,
}

/// What a thread gets when it asks for a batch: one to parse, or none now (`true`: none
/// will come, every batch is claimed).
enum Claim {
    Batch(usize),
    NotNow(bool),
}

/// Where a parsed batch waits for the applier: set once by whoever parsed it, taken
/// once by the applier, which only `try_lock`s (after `ready`, the parser has let go).
#[derive(Default)]
struct BatchSlot<'a> {
    ready: AtomicBool,
    parsed: Mutex<Option<ParsedBatch<'a>>>,
}

impl<'a> BatchSlot<'a> {
    fn put(&self, parsed: ParsedBatch<'a>) {
        if let Ok(mut slot) = self.parsed.lock() {
            *slot = Some(parsed);
        }
        self.ready.store(true, Ordering::Release);
    }

    /// The parsed batch, once it is ready.
    fn take(&self) -> Option<ParsedBatch<'a>> {
        if !self.ready.load(Ordering::Acquire) {
            return None;
        }
        self.parsed.try_lock().ok()?.take()
    }
}

/// Counts a parser out when it stops, also when it panics (natively).
struct Running<'a>(&'a AtomicUsize);

impl Drop for Running<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::AcqRel);
    }
}

/// A parser that is too far ahead of the applier waits: natively it lets the core go.
fn wait_a_little() {
    #[cfg(not(target_arch = "wasm32"))]
    std::thread::yield_now();
    core::hint::spin_loop();
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
            reader.read_decoded(&line);
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
    fn large_blocks_of_a_file_read_in_chunks_read_as_one_thread_does() {
        let mut bytes = Vec::new();
        while bytes.len() < 5 << 19 {
            bytes.extend_from_slice(&tricky_log());
            bytes.extend_from_slice(b"\n");
        }
        let mut reader = NmeaReader::new();
        decode_all(&bytes, super::super::MAX_LINE_BYTES, |line| {
            reader.read_decoded(&line);
        });
        let sequential = reader.finish("tricky.nmea").expect("readable");
        // Blocks of whole lines, as a file read in chunks gives them: two large enough
        // to be parsed in batches on every thread, then a small one.
        let mut reader = NmeaReader::new();
        let mut n_lines = 0usize;
        for block in cut_batches(&bytes, 1_100_000) {
            n_lines += reader.read_lines_block(block, n_lines);
        }
        assert_eq!(n_lines, for_each_line(&bytes, |_, _| {}));
        assert_eq!(reader.finish("tricky.nmea"), Ok(sequential));
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
                decoded.push(line.text.as_bytes().to_vec());
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
