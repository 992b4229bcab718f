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
#[inline(always)]
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

    #[test]
    fn agrees_with_the_standard_library_bit_for_bit() {
        for text in [
            "0",
            "-0",
            "+1",
            "1.",
            ".5",
            "-.5",
            "9.6864",
            "-9.6864",
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
        ] {
            check(text);
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
