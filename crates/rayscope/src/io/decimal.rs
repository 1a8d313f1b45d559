//! Decimal numbers of text files read as `f32` fast, bit for bit as [`str::parse`] reads them.
//!
//! A mesh file is mostly numbers: `str::parse::<f32>` was a third of an OBJ's parse. The
//! common form (`-0.123456`, `1.5e3`, at most 19 significant digits, a power of ten up to
//! 10^22) is exact in `f64` as two integers, and one `f64` multiplication or division rounds
//! their quotient correctly (Clinger's fast path). Rounding that `f64` to `f32` rounds once
//! more; it agrees with rounding the exact value straight to `f32` unless the `f64` lies on
//! an `f32` midpoint (any other `f32` midpoint between the exact value and its nearest `f64`
//! would be nearer still), and that case, like every other form, goes to `str::parse`.

/// The powers of ten exact in `f64`.
const POWERS: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20,
    1e21, 1e22,
];

/// `text` as `f32`, exactly as `text.parse::<f32>().ok()`.
#[inline]
pub fn parse_f32(text: &str) -> Option<f32> {
    fast(text.as_bytes()).or_else(|| text.parse().ok())
}

/// The fast path: `None` for any form it does not take (including every error).
#[inline]
fn fast(bytes: &[u8]) -> Option<f32> {
    let (negative, mut rest) = match bytes.first()? {
        b'-' => (true, &bytes[1..]),
        b'+' => (false, &bytes[1..]),
        _ => (false, bytes),
    };
    let mut mantissa: u64 = 0;
    let mut digits = 0usize;
    let mut exponent: i64 = 0;
    let mut seen_point = false;
    while let Some((&b, tail)) = rest.split_first() {
        match b {
            b'0'..=b'9' => {
                // More than 19 significant digits may not fit: the slow path.
                if mantissa >= 1_000_000_000_000_000_000 {
                    return None;
                }
                mantissa = mantissa * 10 + u64::from(b - b'0');
                digits += 1;
                exponent -= i64::from(seen_point);
            }
            b'.' if !seen_point => seen_point = true,
            _ => break,
        }
        rest = tail;
    }
    if digits == 0 {
        return None;
    }
    if let Some((&(b'e' | b'E'), tail)) = rest.split_first() {
        let (sign, mut tail) = match tail.first() {
            Some(b'-') => (-1, &tail[1..]),
            Some(b'+') => (1, &tail[1..]),
            _ => (1, tail),
        };
        let mut e: i64 = 0;
        if tail.is_empty() || tail.len() > 4 {
            return None;
        }
        while let Some((&b, t)) = tail.split_first() {
            if !b.is_ascii_digit() {
                return None;
            }
            e = e * 10 + i64::from(b - b'0');
            tail = t;
        }
        exponent += sign * e;
        rest = tail;
    }
    if !rest.is_empty() {
        return None;
    }
    let value = if mantissa == 0 {
        0.0
    } else {
        if mantissa >= 1 << 53 || exponent.unsigned_abs() as usize >= POWERS.len() {
            return None;
        }
        let m = mantissa as f64;
        let p = POWERS[exponent.unsigned_abs() as usize];
        let d = if exponent < 0 { m / p } else { m * p };
        // An f32 midpoint: rounding it again might not be the exact value's rounding.
        if d.to_bits() & ((1 << 29) - 1) == 1 << 28 {
            return None;
        }
        d
    };
    let f = value as f32;
    Some(if negative { -f } else { f })
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    fn same(text: &str) {
        let want = text.parse::<f32>().ok().map(f32::to_bits);
        assert_eq!(parse_f32(text).map(f32::to_bits), want, "{text:?}");
    }

    #[test]
    fn forms_and_errors_read_as_std_reads_them() {
        for t in [
            "0",
            "-0",
            "+0",
            "1",
            "-1.5",
            "0.1",
            ".5",
            "5.",
            "1e5",
            "1E-5",
            "1e+5",
            "-.0",
            "3.4028235e38",
            "3.4028236e38",
            "1e39",
            "1e-46",
            "1.17549435e-38",
            "inf",
            "-infinity",
            "NaN",
            "",
            "-",
            ".",
            "e5",
            "1e",
            "1e+",
            "1.2.3",
            "1,5",
            " 1",
            "1 ",
            "0x10",
            "1_0",
            "00000000000000000000000001.5",
            "12345678901234567890123",
            "0.70710678118654757",
            "16777217",
            "33554435",
            "1.00000005960464477539062",
            "9007199254740993",
            "-0.000000",
            "1e-22",
            "1e22",
            "1e23",
            "0.000000000000000000000000000000000000000000001",
        ] {
            same(t);
        }
    }

    proptest! {
        #[test]
        fn floats_printed_any_way_read_back_as_std_reads_them(bits in any::<u32>(), digits in 0usize..12) {
            let f = f32::from_bits(bits);
            same(&format!("{f}"));
            same(&format!("{f:e}"));
            same(&format!("{:.*}", digits, f));
            same(&format!("{:.*}", digits, f as f64 * 1.000_000_1));
        }

        #[test]
        fn digit_strings_read_as_std_reads_them(s in "[-+]?[0-9]{0,20}(\\.[0-9]{0,20})?([eE][-+]?[0-9]{1,3})?") {
            same(&s);
        }

        #[test]
        fn any_text_reads_as_std_reads_it(s in "\\PC{0,12}") {
            same(&s);
        }
    }
}
