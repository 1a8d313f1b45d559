//! Exact sums of floats, for the film's rare pixels whose running `f64` sum lost bits (see
//! [`super::Film`]): a fixed-point accumulator wide enough for every `f64`, so that the sum
//! does not depend on the order of its terms, and one deterministic way back to an `f64`.

/// Limbs of 32 bits: every `f64` is an integer multiple of 2^-1074 below 2^1024, 2098 bits,
/// plus room for the carries of 2^31 terms.
const LIMBS: usize = 2098 / 32 + 3;

/// The exact sum of finite `f64` terms, as a signed fixed-point number with unit 2^-1074.
#[derive(Clone, Debug)]
pub struct ExactSum {
    /// Base-2^32 digits, least significant first, each kept within `i64` between
    /// normalisations (a term adds less than 2^32 to each of three limbs).
    limbs: [i64; LIMBS],
}

impl Default for ExactSum {
    fn default() -> Self {
        ExactSum { limbs: [0; LIMBS] }
    }
}

impl ExactSum {
    /// Add the finite `v` exactly (NaN and infinities are not terms of a film's sums: the
    /// film adds black in their place).
    pub fn add(&mut self, v: f64) {
        debug_assert!(v.is_finite());
        let bits = v.to_bits();
        let biased = ((bits >> 52) & 0x7ff) as u32;
        let frac = bits & ((1 << 52) - 1);
        // v = m * 2^(p - 1074), p >= 0.
        let (m, p) = if biased == 0 { (frac, 0) } else { (frac | 1 << 52, biased - 1) };
        if m == 0 {
            return;
        }
        let shifted = u128::from(m) << (p % 32);
        let i = (p / 32) as usize;
        let sign = if bits >> 63 == 1 { -1 } else { 1 };
        for j in 0..3 {
            self.limbs[i + j] += sign * ((shifted >> (32 * j)) & 0xffff_ffff) as i64;
        }
    }

    /// The sum truncated (towards zero) to an `f64`: the sum itself whenever an `f64` holds
    /// it, and in any case the same `f64` for the same terms in any order or grouping.
    pub fn to_f64(&self) -> f64 {
        let (negative, digits) = magnitude(self.limbs);
        let Some(top) = digits.iter().rposition(|&d| d != 0) else { return 0.0 };
        let length = top as u32 * 32 + (64 - digits[top].leading_zeros());
        // The 53 leading bits (fewer for a subnormal), truncated; a digit's bits are found at
        // `bit / 32` and `bit % 32`.
        let shift = length.saturating_sub(53);
        let mut m: u64 = 0;
        for bit in (shift..length).rev() {
            m = (m << 1) | (digits[(bit / 32) as usize] >> (bit % 32)) & 1;
        }
        // Below 2^53 units the bits of the f64 are the integer itself (subnormal, or the
        // smallest normal exponent); above, the exponent field is `shift + 1`.
        let bits = if shift == 0 {
            m
        } else if shift + 1 >= 0x7ff {
            f64::INFINITY.to_bits()
        } else {
            (u64::from(shift + 1) << 52) | (m & ((1 << 52) - 1))
        };
        let v = f64::from_bits(bits);
        if negative { -v } else { v }
    }
}

/// The sign and the base-2^32 digits (each below 2^32) of the number `limbs` holds.
fn magnitude(mut limbs: [i64; LIMBS]) -> (bool, [u64; LIMBS]) {
    let carry = normalise(&mut limbs);
    let negative = carry < 0;
    if negative {
        for l in &mut limbs {
            *l = -*l;
        }
        normalise(&mut limbs);
    }
    (negative, limbs.map(|l| l as u64))
}

/// Propagate carries so that every limb is in `0..2^32`; returns the carry out of the top
/// (-1 for a negative number, 0 otherwise).
fn normalise(limbs: &mut [i64; LIMBS]) -> i64 {
    let mut carry = 0;
    for l in limbs.iter_mut() {
        let v = *l + carry;
        *l = v.rem_euclid(1 << 32);
        carry = v.div_euclid(1 << 32);
    }
    carry
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    fn sum(terms: &[f64]) -> f64 {
        let mut s = ExactSum::default();
        for &t in terms {
            s.add(t);
        }
        s.to_f64()
    }

    #[test]
    fn representable_sums_are_themselves() {
        assert_eq!(sum(&[]), 0.0);
        assert_eq!(sum(&[1.5, 2.25, -0.75]), 3.0);
        assert_eq!(sum(&[f64::MAX, -f64::MAX, 5e-324]), 5e-324);
        assert_eq!(sum(&[f64::MIN_POSITIVE, -5e-324]), f64::MIN_POSITIVE - 5e-324);
        assert_eq!(sum(&[1e300, 1.0, -1e300]), 1.0);
        assert_eq!(sum(&[-3.0]), -3.0);
        assert_eq!(sum(&[f64::MAX]), f64::MAX);
    }

    #[test]
    fn other_sums_are_truncated() {
        // 1 + 2^-60 is 1 truncated; -(1 + 2^-60) is -1.
        assert_eq!(sum(&[1.0, 2f64.powi(-60)]), 1.0);
        assert_eq!(sum(&[-1.0, -(2f64.powi(-60))]), -1.0);
        // 2 - 2^-60 truncates to the f64 below 2.
        assert_eq!(sum(&[2.0, -(2f64.powi(-60))]), 2.0f64.next_down());
    }

    proptest! {
        /// Any order, any grouping of the same terms: the same f64; and the f64 sum of
        /// terms of a narrow range, which is exact, is that f64.
        #[test]
        fn order_does_not_matter(terms in prop::collection::vec(-1e6..1e6f64, 0..40), k in any::<usize>()) {
            let forward = sum(&terms);
            let mut rotated = terms.clone();
            if !terms.is_empty() {
                rotated.rotate_left(k % terms.len());
            }
            rotated.reverse();
            prop_assert_eq!(forward.to_bits(), sum(&rotated).to_bits());
            let f32s: Vec<f64> = terms.iter().map(|&t| f64::from((t as f32).round())).collect();
            prop_assert_eq!(sum(&f32s), f32s.iter().sum::<f64>());
        }
    }
}
