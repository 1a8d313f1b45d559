//! Exact, fast parsing of the decimal numbers of mesh files and their face indices.
//!
//! Mesh exporters write short decimals (`-0.123456`); those are parsed by Clinger's fast
//! path, which is exact: an integer significand below 2^24 and a power of ten up to 10^10
//! are both f32 numbers, so one IEEE division rounds their quotient once, correctly, as
//! [`str::parse`] does. Anything else (exponents, long significands, `inf`) goes to
//! [`str::parse`] itself: the bits are always the standard library's.

/// The powers of ten that f32 holds exactly.
const POWERS_OF_TEN: [f32; 11] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10];

/// The largest significand the fast path takes: every integer up to it is an f32.
const MAX_SIGNIFICAND: u64 = 1 << 24;

/// The number `text` denotes, with the bits `str::parse::<f32>` gives, or `None` where that fails.
#[inline]
pub fn parse_f32(text: &[u8]) -> Option<f32> {
    match fast_f32(text) {
        Some(v) => Some(v),
        None => std::str::from_utf8(text).ok()?.parse().ok(),
    }
}

/// Clinger's fast path: `[+-]digits[.digits]` with a significand of at most 2^24 and at most
/// ten decimals, else `None`.
#[inline]
fn fast_f32(text: &[u8]) -> Option<f32> {
    let (negative, digits) = match text.first()? {
        b'-' => (true, &text[1..]),
        b'+' => (false, &text[1..]),
        _ => (false, text),
    };
    let (mut significand, mut decimals, mut dot, mut any) = (0u64, 0usize, false, false);
    for &b in digits {
        match b {
            b'0'..=b'9' => {
                significand = significand * 10 + u64::from(b - b'0');
                if significand > MAX_SIGNIFICAND {
                    return None;
                }
                decimals += usize::from(dot);
                any = true;
            }
            b'.' if !dot => dot = true,
            _ => return None,
        }
    }
    if !any {
        return None;
    }
    let value = significand as f32 / *POWERS_OF_TEN.get(decimals)?;
    Some(if negative { -value } else { value })
}

/// A face index, `[-]digits`, as [`str::parse::<i64>`] reads it; `None` for anything else
/// (a `+` sign, a number beyond 18 digits: the checked reader takes those).
#[inline]
pub fn parse_index(text: &[u8]) -> Option<i64> {
    let (negative, digits) = match text.first()? {
        b'-' => (true, &text[1..]),
        _ => (false, text),
    };
    if digits.is_empty() || digits.len() > 18 {
        return None;
    }
    let mut value = 0i64;
    for &b in digits {
        if !b.is_ascii_digit() {
            return None;
        }
        value = value * 10 + i64::from(b - b'0');
    }
    Some(if negative { -value } else { value })
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    fn same(text: &str) {
        let ours = parse_f32(text.as_bytes()).map(f32::to_bits);
        let std = text.parse::<f32>().ok().map(f32::to_bits);
        assert_eq!(ours, std, "{text:?}");
    }

    #[test]
    fn edge_cases_match_the_standard_library() {
        for t in [
            "0",
            "-0",
            "-0.000000",
            "+1.5",
            "1.",
            ".5",
            ".",
            "-",
            "",
            "16777216",
            "16777217",
            "0.1",
            "1e3",
            "inf",
            "-nan",
            "3.4028236e38",
            "1e-50",
            "0.00000000001",
            "1.2.3",
            "1,5",
            "0x10",
            "9999999999999999999999",
        ] {
            same(t);
        }
        assert_eq!(parse_index(b"-12"), Some(-12));
        assert_eq!(parse_index(b"+12"), None);
        assert_eq!(parse_index(b"1/"), None);
        assert_eq!(parse_index(b"-"), None);
    }

    proptest! {
        #[test]
        fn decimals_match_the_standard_library(
            sign in prop::sample::select(vec!["", "-", "+"]),
            int in "[0-9]{0,9}",
            frac in prop::option::of("[0-9]{0,12}"),
        ) {
            let text = match frac { Some(f) => format!("{sign}{int}.{f}"), None => format!("{sign}{int}") };
            same(&text);
        }

        #[test]
        fn any_float_printed_reads_back_the_same(bits in any::<u32>(), digits in 0usize..10) {
            let v = f32::from_bits(bits);
            same(&format!("{v}"));
            same(&format!("{v:.digits$}"));
            same(&format!("{v:e}"));
        }

        #[test]
        fn indices_match_the_standard_library(text in "-?[0-9]{1,18}") {
            prop_assert_eq!(parse_index(text.as_bytes()), text.parse::<i64>().ok());
        }
    }
}
