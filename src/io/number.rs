//! Fast, exact parsing of the decimal numbers that logs are made of.
//!
//! Most numbers in sensor logs are short decimals (`-9.6864`, `1.839072609E1`). For
//! those, Clinger's fast path is exact: when the decimal mantissa `m` fits in 53 bits
//! and the power of ten `10^e` is itself exactly representable (|e| ≤ 22), then
//! `m · 10^e` (or `m / 10^−e`) is one correctly rounded IEEE operation, so the result is
//! the nearest double, the same as a full parser gives (W. D. Clinger, "How to read
//! floating point numbers accurately", PLDI 1990). Everything else — long mantissas,
//! large exponents, `NaN`, `inf`, anything unusual — goes to the standard library's
//! parser, so the answer is always the correctly rounded one.

/// Exactly representable powers of ten.
const POWERS_OF_TEN: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Parses a decimal number (`[+-]digits[.digits][(e|E)[+-]digits]`, or anything the
/// standard library accepts, such as `NaN` or `inf`). `None` when it is not a number.
#[inline]
pub fn parse_f64(text: &str) -> Option<f64> {
    fast_path(text.as_bytes()).or_else(|| text.parse::<f64>().ok())
}

/// Clinger's fast path; `None` whenever it does not apply (the caller then falls back).
#[inline]
fn fast_path(bytes: &[u8]) -> Option<f64> {
    match parse_prefix(bytes) {
        Some((value, consumed)) if consumed == bytes.len() => Some(value),
        _ => None,
    }
}

/// The number at the start of `bytes` by the fast path, with how many bytes it took;
/// `None` when the start is not a number the fast path can take exactly. The caller
/// checks what follows (a delimiter, the end of the line). Slice patterns walk the
/// bytes without bounds checks. Inlined into the field loops, so that the division's
/// latency overlaps with scanning the next field.
// Always inlined natively (the import benchmark's speed); in wasm the compiler decides,
// which keeps the page's module within its size budget (docs/development.md).
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub fn parse_prefix(bytes: &[u8]) -> Option<(f64, usize)> {
    let (negative, mut rest) = match bytes {
        [b'-', rest @ ..] => (true, rest),
        [b'+', rest @ ..] => (false, rest),
        _ => (false, bytes),
    };
    let mut mantissa: u64 = 0;
    let mut n_digits = 0usize;
    while let [digit @ b'0'..=b'9', tail @ ..] = rest {
        mantissa = mantissa
            .wrapping_mul(10)
            .wrapping_add(u64::from(digit - b'0'));
        n_digits += 1;
        rest = tail;
    }
    let mut exponent: i64 = 0;
    if let [b'.', tail @ ..] = rest {
        rest = tail;
        while let [digit @ b'0'..=b'9', tail @ ..] = rest {
            mantissa = mantissa
                .wrapping_mul(10)
                .wrapping_add(u64::from(digit - b'0'));
            n_digits += 1;
            exponent -= 1;
            rest = tail;
        }
    }
    // 19 digits always fit in a u64 without wrapping; more go to the full parser.
    if n_digits == 0 || n_digits > 19 {
        return None;
    }
    if let [b'e' | b'E', tail @ ..] = rest {
        let (exponent_negative, mut digits) = match tail {
            [b'-', digits @ ..] => (true, digits),
            [b'+', digits @ ..] => (false, digits),
            _ => (false, tail),
        };
        let mut explicit: i64 = 0;
        let mut n_exponent_digits = 0usize;
        while let [digit @ b'0'..=b'9', tail @ ..] = digits {
            if n_exponent_digits >= 5 {
                return None;
            }
            explicit = explicit * 10 + i64::from(digit - b'0');
            n_exponent_digits += 1;
            digits = tail;
        }
        if n_exponent_digits == 0 {
            return None;
        }
        exponent += if exponent_negative {
            -explicit
        } else {
            explicit
        };
        rest = digits;
    }
    if mantissa > (1u64 << 53) {
        return None;
    }
    let power = *POWERS_OF_TEN.get(exponent.unsigned_abs() as usize)?;
    let magnitude = if exponent < 0 {
        mantissa as f64 / power
    } else {
        mantissa as f64 * power
    };
    Some((
        if negative { -magnitude } else { magnitude },
        bytes.len() - rest.len(),
    ))
}

/// `10^n` for the lengths of digit runs the eight-byte parser takes (0 to 7 digits).
const POWERS_OF_TEN_U64: [u64; 8] = [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000];

/// The same as [`parse_prefix`] on `bytes[start..]` (the value and the index just after
/// the number), eight bytes at a time: runs of digits are found and converted with a
/// few word operations instead of one step per digit. Most numbers in logs
/// (`-9.7677`, `33.259`) lie in one eight-byte word with the point and the byte after
/// them; longer ones take two words, one per run of digits. Digit runs cannot cross a
/// line ending, so the words read may reach into the next line; near the end of
/// `bytes`, and for runs of eight digits or more or an exponent, it hands over to
/// [`parse_prefix`]. A test checks that both agree.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub fn parse_prefix_at(bytes: &[u8], start: usize) -> Option<(f64, usize)> {
    let rest = bytes.get(start..)?;
    // A sign, at most seven digits, a point and at most seven digits fit in 17 bytes;
    // two eight-byte reads need at most 18.
    let Some(head) = rest.first_chunk::<18>() else {
        return parse_prefix(rest).map(|(value, consumed)| (value, start + consumed));
    };
    let (negative, int_start) = match head.first() {
        Some(b'-') => (true, 1),
        Some(b'+') => (false, 1),
        _ => (false, 0),
    };
    let word = word_at(head, int_start);
    let offsets = word ^ 0x3030_3030_3030_3030;
    let non_digit = non_digit_bytes(offsets);
    let n_int_digits = (non_digit.trailing_zeros() / 8) as usize;
    let (mantissa, n_frac_digits, end) = if head.get(int_start + n_int_digits) == Some(&b'.') {
        // The point is the first non-digit byte; the next one ends the fraction.
        let after_point = non_digit & non_digit.wrapping_sub(1);
        if after_point != 0 {
            // Point and fraction inside the word: the fraction's digits are moved down
            // over the point, and all digits are converted at once.
            let n_end = (after_point.trailing_zeros() / 8) as usize;
            let int_part = offsets & low_bytes(n_int_digits);
            let frac_part = (offsets >> 8) & low_bytes(n_end - 1) & !low_bytes(n_int_digits);
            (
                digits_value(int_part | frac_part, n_end - 1),
                n_end - 1 - n_int_digits,
                int_start + n_end,
            )
        } else if n_int_digits < 8 {
            // The fraction runs past the word: a second word from the point on.
            let frac_start = int_start + n_int_digits + 1;
            let frac_offsets = word_at(head, frac_start) ^ 0x3030_3030_3030_3030;
            let n_frac_digits = (non_digit_bytes(frac_offsets).trailing_zeros() / 8) as usize;
            if n_frac_digits >= 8 {
                return parse_prefix(rest).map(|(value, consumed)| (value, start + consumed));
            }
            (
                digits_value(offsets, n_int_digits) * POWERS_OF_TEN_U64[n_frac_digits]
                    + digits_value(frac_offsets, n_frac_digits),
                n_frac_digits,
                frac_start + n_frac_digits,
            )
        } else {
            return parse_prefix(rest).map(|(value, consumed)| (value, start + consumed));
        }
    } else if n_int_digits < 8 {
        // No point: an integer.
        (
            digits_value(offsets, n_int_digits),
            0,
            int_start + n_int_digits,
        )
    } else {
        return parse_prefix(rest).map(|(value, consumed)| (value, start + consumed));
    };
    if matches!(head.get(end), Some(b'e' | b'E')) {
        return parse_prefix(rest).map(|(value, consumed)| (value, start + consumed));
    }
    if n_int_digits == 0 && n_frac_digits == 0 {
        // No digit at all: "", "-", ".", "-.".
        return None;
    }
    // At most 14 digits: below 2^53, so the conversion to f64 is exact, and dividing by
    // an exactly representable power of ten rounds once (Clinger).
    let magnitude = mantissa as i64 as f64 / POWERS_OF_TEN[n_frac_digits];
    Some((if negative { -magnitude } else { magnitude }, start + end))
}

/// The eight bytes from `offset` (at most 10) of an 18-byte window, as a little-endian
/// word: the first byte is the lowest.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
fn word_at(head: &[u8; 18], offset: usize) -> u64 {
    let mut word = [0u8; 8];
    if let Some(bytes) = head.get(offset..offset + 8) {
        word.copy_from_slice(bytes);
    }
    u64::from_le_bytes(word)
}

/// The high bit of every byte of `offsets` (a word with `'0'` xored out of every byte)
/// that was not an ASCII digit. A digit's byte is then in 0..=9 and every other byte is
/// not: adding 0x76 to the low seven bits sets the high bit of those of 10 or more
/// (without a carry into the next byte), and bytes of 0x80 or more have it already.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
fn non_digit_bytes(offsets: u64) -> u64 {
    (((offsets & 0x7F7F_7F7F_7F7F_7F7F) + 0x7676_7676_7676_7676) | offsets) & 0x8080_8080_8080_8080
}

/// The mask of the first `n_bytes` (0 to 7) bytes of a word.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
fn low_bytes(n_bytes: usize) -> u64 {
    (1u64 << ((8 * n_bytes) & 63)) - 1
}

/// The value of the first `n_digits` bytes (0 to 7) of `offsets`, digit values 0..=9
/// (the bytes after them are ignored),
/// read as a decimal integer: shifted so that they end the word (the bytes before them
/// become leading zeros), then pairs, quadruples and octets of digits are combined by
/// multiplication (D. Lemire, "Faster parsing of 8-digit integers", 2018; simdjson).
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
fn digits_value(offsets: u64, n_digits: usize) -> u64 {
    if n_digits == 0 || n_digits >= 8 {
        return 0;
    }
    let digits = offsets << (8 * (8 - n_digits));
    let pairs = (digits.wrapping_mul(10) + (digits >> 8)) & 0x00FF_00FF_00FF_00FF;
    let quads = (pairs.wrapping_mul(100) + (pairs >> 16)) & 0x0000_FFFF_0000_FFFF;
    quads.wrapping_mul(10_000).wrapping_add(quads >> 32) & 0xFFFF_FFFF
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(text: &str) {
        let expect = text.parse::<f64>().ok();
        let got = parse_f64(text);
        match (got, expect) {
            (Some(got), Some(expect)) if got.is_nan() && expect.is_nan() => {}
            (Some(got), Some(expect)) => assert_eq!(got.to_bits(), expect.to_bits(), "{text}"),
            (got, expect) => assert_eq!(got, expect, "{text}"),
        }
    }

    /// Short decimals as sensor logs write them, signs and bare points included.
    const SHORT_DECIMALS: [&str; 8] = ["0", "-0", "+1", "1.", ".5", "-.5", "9.6864", "-9.6864"];

    #[test]
    fn agrees_with_the_standard_library_bit_for_bit() {
        for text in SHORT_DECIMALS.into_iter().chain([
            "1.839072609E1",
            "3.446083327E-3",
            "1e22",
            "1e23",
            "1e-22",
            "1e-23",
            "9007199254740993",
            "9007199254740992",
            "123456789012345678901",
            "0.1",
            "0.3",
            "4.9e-324",
            "1.7976931348623157e308",
            "NaN",
            "inf",
            "-inf",
            "",
            "-",
            ".",
            "e5",
            "1e",
            "1e+",
            "1.2.3",
            "1,2",
            " 1",
            "1 ",
            "0x10",
            "1_000",
            "00012.50",
            "-0.000",
            "1E400",
            "1e-400",
        ]) {
            check(text);
        }
    }

    /// [`parse_prefix_at`] against [`parse_prefix`] on numbers followed by what follows
    /// them in a line (a delimiter, a line ending, more text) and at the end of input.
    fn check_at(text: &str) {
        for tail in ["", ",", ",1.5,2", "\n0.5,1", "\r\n", "e", "x", "..", ";-3"] {
            let line = format!("ab,{text}{tail}");
            let bytes = line.as_bytes();
            let expect =
                parse_prefix(&bytes[3..]).map(|(value, consumed)| (value.to_bits(), 3 + consumed));
            let got = parse_prefix_at(bytes, 3).map(|(value, end)| (value.to_bits(), end));
            assert_eq!(got, expect, "{line:?}");
        }
    }

    #[test]
    fn the_eight_byte_parser_agrees_with_the_digit_by_digit_one() {
        for text in SHORT_DECIMALS.into_iter().chain([
            "33.259",
            "0.00058",
            "18199.980",
            "1234567.1234567",
            "12345678.5",
            "1.12345678",
            "99999999",
            "9999999.9999999",
            "1.839072609E1",
            "3.446083327E-3",
            "1e22",
            "",
            "-",
            ".",
            "-.",
            "+",
            "1.2.3",
            "0012.50",
            "-0.000",
            "7",
            "-7.",
            "1234567",
            "12345678",
        ]) {
            check_at(text);
        }
        let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            state >> 33
        };
        for _ in 0..50_000 {
            let n_int = (next() % 10) as usize;
            let n_frac = (next() % 10) as usize;
            let mut text = String::new();
            match next() % 3 {
                0 => text.push('-'),
                1 if next() % 4 == 0 => text.push('+'),
                _ => {}
            }
            text.extend((0..n_int).map(|_| char::from(b'0' + (next() % 10) as u8)));
            if next() % 5 != 0 {
                text.push('.');
                text.extend((0..n_frac).map(|_| char::from(b'0' + (next() % 10) as u8)));
            }
            check_at(&text);
        }
    }

    #[test]
    fn agrees_with_the_standard_library_on_many_generated_numbers() {
        // A small LCG makes mantissas, decimal points and exponents of every length.
        let mut state: u64 = 0x2545_F491_4F6C_DD1D;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            state >> 33
        };
        for _ in 0..200_000 {
            let n_digits = 1 + (next() % 22) as usize;
            let digits: String = (0..n_digits)
                .map(|_| char::from(b'0' + (next() % 10) as u8))
                .collect();
            let point = (next() % (n_digits as u64 + 1)) as usize;
            let mut text = String::new();
            if next() % 2 == 0 {
                text.push('-');
            }
            text.push_str(&digits[..point]);
            text.push('.');
            text.push_str(&digits[point..]);
            if next() % 3 == 0 {
                text.push_str(&format!("e{}", (next() % 60) as i64 - 30));
            }
            check(&text);
        }
    }
}
