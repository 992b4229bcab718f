//! Large delimited files ([`super`]) on native builds and the browser's threaded build
//! ([`crate::base::par`]): the data lines are cut into one part per thread at line boundaries,
//! parsed side by side, and joined in order, with line numbers counted on across the
//! parts. The result is the same as reading line by line (a test checks it); only the
//! time differs. The browser's default build reads on one thread.
//!
//! The dense streams' vectors are made once for the whole file, with room for at most
//! one sample per line of each part, and each part writes into its own share of that
//! room (so that each thread touches, and the system maps, its own memory, and no part
//! is copied after the others); the shares are then closed up. GNSS fixes and attitudes
//! (few, or absent) are gathered per part and appended.

use std::mem::MaybeUninit;

use nalgebra::{Vector2, Vector3};

use super::header::Header;
use super::reader::{Plan, RowTimes};
use super::sinks::{FilledStreams, SampleSink, SampleSinks, Targets};
use super::{read_up_to_header, ColumnMapping, DelimitedReader, RawImport};
use crate::io::recording::{Attitude, GnssFix, Recording, Stream};
use crate::io::{Diagnostics, ImportError};

/// Below this size one thread is as fast.
const MIN_PARALLEL_BYTES: usize = 4 << 20;

/// A block (see [`read_lines_block`]) below this size is read on one thread.
const MIN_PARALLEL_BLOCK_BYTES: usize = 1 << 20;

/// `None` when the file is better read on one thread: small, on one core, or without
/// a time column (the sample number is then counted across the whole file).
pub(super) fn read_raw(
    file_name: &str,
    bytes: &[u8],
    mapping: Option<&ColumnMapping>,
) -> Option<Result<RawImport, ImportError>> {
    let n_threads = crate::base::par::n_threads();
    if bytes.len() < MIN_PARALLEL_BYTES || n_threads < 2 {
        return None;
    }
    // Read up to the header on this thread.
    let (mut reader, data_offset, n_header_lines) = read_up_to_header(bytes, mapping, None)?;
    // (Data lines read with the header, after lone CRs, would have to come first.)
    if reader.plan.time.is_none() || reader.n_data_lines > 0 {
        return None;
    }
    let header = reader.header.clone()?;
    let parts = cut_into_parts(bytes.get(data_offset..)?, n_threads);
    let max_rows = crate::base::par::on_each_part(parts.iter(), |part| count_lines(part))?;
    let filled = reader.plan.filled_streams();
    // Two rows of spare room, given back by `finish`. (Measured with glibc's malloc
    // in the import benchmark's loop: with exact capacities the columns' memory went
    // back to the system after every import, and the next import faulted it in
    // again, 34,000 page faults per import instead of 14,000. The shrink's small
    // remainders keep the heap in place. An allocator's detail, not a guarantee.)
    let mut columns = Columns::new(filled, max_rows.iter().sum::<usize>() + 2);
    let results = crate::base::par::on_each_part(
        columns.shares(&max_rows).into_iter().zip(&parts),
        |(share, part)| {
            let mut part_reader = part_reader(&header, share);
            // Numbered from 2, so that no part's first line is taken for the file's
            // first (where a byte-order mark is dropped).
            let n_lines = part_reader.read_data_bytes(part, 1);
            PartResult::of(part_reader, n_lines)
        },
    )?;
    if results.iter().any(|result| result.overflowed) {
        return None;
    }
    let share_lens: Vec<[usize; N_COLUMNS]> = results.iter().map(|result| result.lens).collect();
    columns.close_up(&max_rows, &share_lens, &mut reader.recording);
    // Join in order; each part's line numbers count on from the lines before it.
    let mut lines_before = n_header_lines;
    for result in results {
        let part = Joined {
            diagnostics: result.diagnostics,
            n_data_lines: result.n_data_lines,
            row_times: result.row_times,
            recording: result.sparse,
        };
        part.join_into(&mut reader, lines_before);
        lines_before += result.n_lines;
    }
    Some(reader.finish(file_name))
}

/// A block of whole data lines (a chunk of a file read in chunks, as the page reads
/// a dropped file) on every thread: each part into a reader of its own, joined in
/// order into `reader` (samples appended, line numbers counted on), as
/// [`read_raw`] joins a whole file's parts. `None` (nothing read) when the block is
/// better read on one thread: small, on one thread, or without a time column.
pub(super) fn read_lines_block(
    reader: &mut DelimitedReader,
    bytes: &[u8],
    n_lines_before: usize,
) -> Option<usize> {
    let n_threads = crate::base::par::n_threads();
    if bytes.len() < MIN_PARALLEL_BLOCK_BYTES || n_threads < 2 || reader.plan.time.is_none() {
        return None;
    }
    let header = reader.header.clone()?;
    let parts = cut_into_parts(bytes, n_threads);
    let results = crate::base::par::on_each_part(parts.iter(), |part| {
        let mut part_reader = part_reader(&header, Recording::default());
        // Numbered from 2, as in `read_raw`.
        let n_lines = part_reader.read_data_bytes(part, 1);
        (part_reader, n_lines)
    })?;
    let mut lines_before = n_lines_before;
    for (part_reader, n_lines) in results {
        let part = Joined {
            diagnostics: part_reader.diagnostics,
            n_data_lines: part_reader.n_data_lines,
            row_times: part_reader.row_times,
            recording: part_reader.recording,
        };
        part.join_into(reader, lines_before);
        lines_before += n_lines;
    }
    Some(lines_before - n_lines_before)
}

/// A reader of one part's data lines, under the file's header, writing into
/// `recording`.
fn part_reader<S>(header: &Header, recording: S) -> DelimitedReader<S> {
    DelimitedReader {
        header: Some(header.clone()),
        plan: Plan::of(header),
        row: vec![f64::NAN; header.columns.len()],
        recording,
        diagnostics: Diagnostics::default(),
        n_data_lines: 0,
        size_hint_bytes: None,
        mapping: None,
        problems: Vec::new(),
        row_times: RowTimes::default(),
        settings: Vec::new(),
        xyz_columns: None,
    }
}

/// What a part adds to the whole file's reader once it is read.
struct Joined {
    diagnostics: Diagnostics,
    n_data_lines: usize,
    row_times: RowTimes,
    /// Samples to append (a whole file's parts: only their GNSS fixes and
    /// attitudes; the dense streams are in the shared columns already).
    recording: Recording,
}

impl Joined {
    /// Joins the part after the ones before it, its line numbers (counted from 2 in
    /// the part) counted on from the `lines_before` lines before it.
    fn join_into(self, reader: &mut DelimitedReader, lines_before: usize) {
        for diagnostic in self.diagnostics.kept {
            reader.diagnostics.push(
                diagnostic.line.map(|line| line - 1 + lines_before),
                diagnostic.message,
            );
        }
        reader.diagnostics.n_not_kept += self.diagnostics.n_not_kept;
        reader.n_data_lines += self.n_data_lines;
        reader.row_times = reader.row_times.then(self.row_times);
        reader.recording.append(self.recording);
    }
}

/// The data bytes cut into about `n_parts` parts that end just after a newline. A
/// lone CR never ends a part, so every part starts a line, as when the file is read
/// line by line.
fn cut_into_parts(rest: &[u8], n_parts: usize) -> Vec<&[u8]> {
    let part_len = rest.len() / n_parts + 1;
    let mut parts: Vec<&[u8]> = Vec::with_capacity(n_parts);
    let mut start = 0usize;
    while start < rest.len() {
        let tentative = (start + part_len).min(rest.len());
        let end = match rest
            .get(tentative..)
            .and_then(|tail| memchr::memchr(b'\n', tail))
        {
            Some(newline) if tentative < rest.len() => tentative + newline + 1,
            _ => rest.len(),
        };
        parts.push(rest.get(start..end).unwrap_or_default());
        start = end;
    }
    parts
}

/// The lines of a part: a line ends at an LF, a CRLF or a lone CR, or at the end of
/// the part. No stream gets more samples than this from the part.
fn count_lines(part: &[u8]) -> usize {
    let (n_lf, n_cr) = count_lf_cr(part);
    let n_endings = if n_cr == 0 {
        n_lf
    } else {
        memchr::memchr2_iter(b'\n', b'\r', part)
            .filter(|&idx| part.get(idx) == Some(&b'\n') || part.get(idx + 1) != Some(&b'\n'))
            .count()
    };
    let ends_a_line = matches!(part.last(), Some(b'\n' | b'\r') | None);
    n_endings + usize::from(!ends_a_line)
}

/// The LF and CR bytes of `bytes`, counted in one pass over them: 32 byte-wide
/// counters per kind, which the compiler keeps in vector registers. Looking for a CR
/// first (`memchr`) and then counting the LFs (`memchr::memchr_iter(..).count()`) read
/// a part twice, and took twice as long: 8.4 ms against 4.4 ms for a 100 MB CSV in
/// memory, one thread (2026-11-28).
fn count_lf_cr(bytes: &[u8]) -> (usize, usize) {
    const LANES: usize = 32;
    // A counter takes at most one byte from each of 255 chunks.
    const CHUNKS_PER_BLOCK: usize = 255;
    let (mut n_lf, mut n_cr) = (0usize, 0usize);
    for block in bytes.chunks(LANES * CHUNKS_PER_BLOCK) {
        let (mut lf, mut cr) = ([0u8; LANES], [0u8; LANES]);
        let mut chunks = block.chunks_exact(LANES);
        for chunk in &mut chunks {
            for ((lf, cr), &byte) in lf.iter_mut().zip(cr.iter_mut()).zip(chunk) {
                *lf += u8::from(byte == b'\n');
                *cr += u8::from(byte == b'\r');
            }
        }
        n_lf += lf.iter().map(|&count| usize::from(count)).sum::<usize>();
        n_cr += cr.iter().map(|&count| usize::from(count)).sum::<usize>();
        for &byte in chunks.remainder() {
            n_lf += usize::from(byte == b'\n');
            n_cr += usize::from(byte == b'\r');
        }
    }
    (n_lf, n_cr)
}

/// What a part's reader leaves once its share is written.
struct PartResult {
    /// Samples written in each column's share, in [`Columns`] order.
    lens: [usize; N_COLUMNS],
    overflowed: bool,
    /// The part's GNSS fixes and attitudes.
    sparse: Recording,
    diagnostics: Diagnostics,
    n_data_lines: usize,
    n_lines: usize,
    row_times: RowTimes,
}

impl PartResult {
    fn of(reader: DelimitedReader<Share<'_>>, n_lines: usize) -> PartResult {
        let share = reader.recording;
        let streams = [
            (share.acc.len, share.acc.overflowed),
            (share.gyro.len, share.gyro.overflowed),
            (share.mag.len, share.mag.overflowed),
            (share.temp.len, share.temp.overflowed),
            (share.pressure.len, share.pressure.overflowed),
            (share.ref_heading.len, share.ref_heading.overflowed),
            (share.ref_position.len, share.ref_position.overflowed),
        ];
        PartResult {
            lens: streams.map(|(len, _)| len),
            overflowed: streams.iter().any(|(_, overflowed)| *overflowed),
            sparse: Recording {
                gnss: share.gnss,
                attitude: share.attitude,
                ..Recording::default()
            },
            diagnostics: reader.diagnostics,
            n_data_lines: reader.n_data_lines,
            n_lines,
            row_times: reader.row_times,
        }
    }
}

/// The dense streams, in the order of [`PartResult::lens`].
const N_COLUMNS: usize = 7;

/// The dense streams' vectors for the whole file, empty, with room for every part.
struct Columns {
    acc: Stream<Vector3<f64>>,
    gyro: Stream<Vector3<f64>>,
    mag: Stream<Vector3<f64>>,
    temp: Stream<f64>,
    pressure: Stream<f64>,
    ref_heading: Stream<f64>,
    ref_position: Stream<Vector2<f64>>,
}

impl Columns {
    fn new(filled: FilledStreams, n_rows: usize) -> Columns {
        fn stream<T>(filled: bool, n_rows: usize) -> Stream<T> {
            let n_rows = if filled { n_rows } else { 0 };
            Stream {
                t_s: Vec::with_capacity(n_rows),
                values: Vec::with_capacity(n_rows),
            }
        }
        Columns {
            acc: stream(filled.acc, n_rows),
            gyro: stream(filled.gyro, n_rows),
            mag: stream(filled.mag, n_rows),
            temp: stream(filled.temp, n_rows),
            pressure: stream(filled.pressure, n_rows),
            ref_heading: stream(filled.ref_heading, n_rows),
            ref_position: stream(filled.ref_position, n_rows),
        }
    }

    /// One share of every column per part, of `max_rows[part_idx]` samples (fewer
    /// where a column has less room: a stream the plan does not fill has none).
    fn shares(&mut self, max_rows: &[usize]) -> Vec<Share<'_>> {
        let mut acc = ShareRoom::of(&mut self.acc);
        let mut gyro = ShareRoom::of(&mut self.gyro);
        let mut mag = ShareRoom::of(&mut self.mag);
        let mut temp = ShareRoom::of(&mut self.temp);
        let mut pressure = ShareRoom::of(&mut self.pressure);
        let mut ref_heading = ShareRoom::of(&mut self.ref_heading);
        let mut ref_position = ShareRoom::of(&mut self.ref_position);
        max_rows
            .iter()
            .map(|&size| Share {
                acc: acc.next_share(size),
                gyro: gyro.next_share(size),
                mag: mag.next_share(size),
                temp: temp.next_share(size),
                pressure: pressure.next_share(size),
                ref_heading: ref_heading.next_share(size),
                ref_position: ref_position.next_share(size),
                gnss: Stream::default(),
                attitude: Stream::default(),
            })
            .collect()
    }

    /// Closes up the shares (part after part, each with `share_lens[part_idx]`
    /// samples written at its start) and moves the columns into `recording`.
    fn close_up(
        self,
        max_rows: &[usize],
        share_lens: &[[usize; N_COLUMNS]],
        recording: &mut Recording,
    ) {
        let lens_of = |column_idx: usize| -> Vec<usize> {
            share_lens
                .iter()
                .map(|lens| lens.get(column_idx).copied().unwrap_or(0))
                .collect()
        };
        let Columns {
            mut acc,
            mut gyro,
            mut mag,
            mut temp,
            mut pressure,
            mut ref_heading,
            mut ref_position,
        } = self;
        close_up_stream(&mut acc, max_rows, &lens_of(0));
        close_up_stream(&mut gyro, max_rows, &lens_of(1));
        close_up_stream(&mut mag, max_rows, &lens_of(2));
        close_up_stream(&mut temp, max_rows, &lens_of(3));
        close_up_stream(&mut pressure, max_rows, &lens_of(4));
        close_up_stream(&mut ref_heading, max_rows, &lens_of(5));
        close_up_stream(&mut ref_position, max_rows, &lens_of(6));
        recording.acc_in_body_mps2 = acc;
        recording.gyro_in_body_radps = gyro;
        recording.mag_in_body_ut = mag;
        recording.temp_c = temp;
        recording.pressure_hpa = pressure;
        recording.ref_heading_rad = ref_heading;
        recording.ref_position_en_m = ref_position;
    }
}

fn close_up_stream<T: Copy>(stream: &mut Stream<T>, max_rows: &[usize], lens: &[usize]) {
    close_up(&mut stream.t_s, max_rows, lens);
    close_up(&mut stream.values, max_rows, lens);
}

/// The unused room of a vector, handed out in consecutive shares.
struct ShareRoom<'a, T> {
    t_s: &'a mut [MaybeUninit<f64>],
    values: &'a mut [MaybeUninit<T>],
}

impl<'a, T> ShareRoom<'a, T> {
    fn of(stream: &'a mut Stream<T>) -> Self {
        ShareRoom {
            t_s: stream.t_s.spare_capacity_mut(),
            values: stream.values.spare_capacity_mut(),
        }
    }

    /// The next `size` samples of room (fewer where the room runs out).
    fn next_share(&mut self, size: usize) -> ShareStream<'a, T> {
        let t_s = std::mem::take(&mut self.t_s);
        let (share_t_s, rest_t_s) = t_s.split_at_mut(size.min(t_s.len()));
        self.t_s = rest_t_s;
        let values = std::mem::take(&mut self.values);
        let (share_values, rest_values) = values.split_at_mut(size.min(values.len()));
        self.values = rest_values;
        ShareStream {
            t_s: share_t_s,
            values: share_values,
            len: 0,
            overflowed: false,
        }
    }
}

/// One part's share of a dense stream: samples are written from its start.
struct ShareStream<'a, T> {
    t_s: &'a mut [MaybeUninit<f64>],
    values: &'a mut [MaybeUninit<T>],
    len: usize,
    /// A sample found no room (it cannot happen: a share has room for one sample per
    /// line; the file is then read on one thread rather than lose it).
    overflowed: bool,
}

impl<T> SampleSink<T> for ShareStream<'_, T> {
    #[inline(always)]
    fn push(&mut self, t_s: f64, value: T) {
        match (self.t_s.get_mut(self.len), self.values.get_mut(self.len)) {
            (Some(t_slot), Some(value_slot)) => {
                t_slot.write(t_s);
                value_slot.write(value);
                self.len += 1;
            }
            _ => self.overflowed = true,
        }
    }
}

/// One part's shares of every dense stream, and its own sparse streams.
struct Share<'a> {
    acc: ShareStream<'a, Vector3<f64>>,
    gyro: ShareStream<'a, Vector3<f64>>,
    mag: ShareStream<'a, Vector3<f64>>,
    temp: ShareStream<'a, f64>,
    pressure: ShareStream<'a, f64>,
    ref_heading: ShareStream<'a, f64>,
    ref_position: ShareStream<'a, Vector2<f64>>,
    gnss: Stream<GnssFix>,
    attitude: Stream<Attitude>,
}

impl<'a> SampleSinks for Share<'a> {
    type Vector = ShareStream<'a, Vector3<f64>>;
    type Scalar = ShareStream<'a, f64>;
    type Position = ShareStream<'a, Vector2<f64>>;

    #[inline(always)]
    fn targets(&mut self) -> Targets<'_, Self::Vector, Self::Scalar, Self::Position> {
        Targets {
            acc: &mut self.acc,
            gyro: &mut self.gyro,
            mag: &mut self.mag,
            temp: &mut self.temp,
            pressure: &mut self.pressure,
            ref_heading: &mut self.ref_heading,
            ref_position: &mut self.ref_position,
            gnss: &mut self.gnss,
            attitude: &mut self.attitude,
        }
    }

    /// The room was made for the whole file beforehand.
    fn reserve_rows(&mut self, _plan: &Plan, _n_rows: usize) {}
}

/// Closes up an empty vector whose unused room was handed out in consecutive shares
/// of `max_rows[part_idx]` elements (fewer where the room ran out), each written at
/// its start with `lens[part_idx]` elements: moves every share's elements down to
/// follow the previous share's and sets the length to their total.
fn close_up<T: Copy>(vec: &mut Vec<T>, max_rows: &[usize], lens: &[usize]) {
    if !vec.is_empty() {
        return;
    }
    let room = vec.spare_capacity_mut();
    let mut share_start = 0usize;
    let mut n_closed = 0usize;
    for (&max_rows, &len) in max_rows.iter().zip(lens) {
        let share_size = max_rows.min(room.len() - share_start);
        let len = len.min(share_size);
        if share_start != n_closed {
            room.copy_within(share_start..share_start + len, n_closed);
        }
        n_closed += len;
        share_start += share_size;
    }
    // SAFETY: `n_closed` ≤ capacity, and elements 0..n_closed are initialised: the
    // shares were consecutive slices of this room, of the sizes computed the same
    // way here as in `ShareRoom::next_share`, and each share's writer wrote its
    // first `len` slots (`ShareStream::push` counts only slots it wrote); each share's
    // written elements were just moved to follow the previous share's.
    unsafe { vec.set_len(n_closed) };
}

#[cfg(test)]
mod tests {
    use super::super::MAX_LINE_BYTES;
    use super::*;

    /// Across the byte-wide counters' blocks (8,160 bytes), where a counter would wrap
    /// if a block were longer, and with a remainder.
    #[test]
    fn line_endings_are_counted_across_blocks() {
        for len in [0, 1, 31, 32, 33, 8_159, 8_160, 8_161, 20_000, 65_537] {
            let bytes: Vec<u8> = (0..len)
                .map(|idx: usize| match (idx * 7 + idx / 3) % 5 {
                    0 => b'\n',
                    1 if idx.is_multiple_of(2) => b'\r',
                    _ => b'1',
                })
                .collect();
            let expected = (
                bytes.iter().filter(|&&byte| byte == b'\n').count(),
                bytes.iter().filter(|&&byte| byte == b'\r').count(),
            );
            assert_eq!(count_lf_cr(&bytes), expected, "{len} bytes");
            let all_lf = vec![b'\n'; len];
            assert_eq!(count_lf_cr(&all_lf), (len, 0), "{len} LFs");
        }
    }

    #[test]
    fn lines_are_counted_as_the_line_decoder_counts_them() {
        for text in [
            &b""[..],
            b"a",
            b"a\n",
            b"a\r\nb",
            b"a\rb\r",
            b"a\r\r\nb\n\n",
            b"\r\n\r\n",
        ] {
            let mut n_lines = 0;
            crate::io::lines::decode_all(text, MAX_LINE_BYTES, |_| n_lines += 1);
            assert_eq!(count_lines(text), n_lines, "{text:?}");
        }
    }

    #[test]
    fn shares_written_in_part_are_closed_up_in_order() {
        let max_rows = [4usize, 3, 5];
        let mut stream: Stream<f64> = Stream {
            t_s: Vec::with_capacity(12),
            values: Vec::with_capacity(12),
        };
        let mut room = ShareRoom::of(&mut stream);
        let mut shares: Vec<ShareStream<'_, f64>> =
            max_rows.iter().map(|&size| room.next_share(size)).collect();
        for (share_idx, (share, n_written)) in shares.iter_mut().zip([2, 3, 0]).enumerate() {
            for sample_idx in 0..n_written {
                let t_s = (share_idx * 10 + sample_idx) as f64;
                share.push(t_s, -t_s);
            }
        }
        // A share that is full refuses (and flags) a sample instead of spilling over.
        shares[1].push(99.0, -99.0);
        assert!(shares[1].overflowed && !shares[0].overflowed);
        let lens: Vec<usize> = shares.iter().map(|share| share.len).collect();
        close_up_stream(&mut stream, &max_rows, &lens);
        assert_eq!(stream.t_s, vec![0.0, 1.0, 10.0, 11.0, 12.0]);
        assert_eq!(stream.values, vec![-0.0, -1.0, -10.0, -11.0, -12.0]);
        // A column without room (a stream the plan does not fill) closes up empty.
        let mut empty: Stream<f64> = Stream::default();
        let mut room = ShareRoom::of(&mut empty);
        let mut share = room.next_share(4);
        share.push(1.0, 1.0);
        assert!(share.overflowed);
        close_up_stream(&mut empty, &max_rows, &[0, 0, 0]);
        assert!(empty.is_empty());
    }
}
