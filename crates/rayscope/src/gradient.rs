//! The colour curve of the toon-style [`crate::settings::ShadingModel::Gradient`]: colours at
//! positions in [0, 1], read by the cosine `n.l`.

use serde::{Deserialize, Serialize};

use crate::math::Color;

/// One key of a gradient: its colour at a position. Written in scene files as
/// `[position, [r, g, b]]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "(f32, Color)", into = "(f32, Color)")]
pub struct GradientKey {
    /// Where on the curve, in [0, 1].
    pub at: f32,
    /// The colour there.
    pub color: Color,
}

impl From<(f32, Color)> for GradientKey {
    fn from((at, color): (f32, Color)) -> Self {
        GradientKey { at, color }
    }
}

impl From<GradientKey> for (f32, Color) {
    fn from(k: GradientKey) -> Self {
        (k.at, k.color)
    }
}

/// A colour curve over [0, 1]: linear between its keys, the first key's colour before it and
/// the last's after it. Two keys at one position make a hard step (the toon look's bands).
/// Made only by [`Gradient::new`], which checks the keys.
#[derive(Clone, Debug, PartialEq)]
pub struct Gradient {
    keys: Vec<GradientKey>,
}

impl Gradient {
    /// The curve through `keys`, which must be at least one, at finite positions in [0, 1] in
    /// increasing order (equal positions allowed: a step), with finite colours not negative.
    /// The error says which key is wrong and why.
    pub fn new(keys: Vec<GradientKey>) -> Result<Gradient, String> {
        if keys.is_empty() {
            return Err("a gradient needs at least one key ([position, [r, g, b]])".into());
        }
        for (i, k) in keys.iter().enumerate() {
            if !(0.0..=1.0).contains(&k.at) {
                return Err(format!("gradient key {}: position {} is not in [0, 1]", i + 1, k.at));
            }
            if !(k.color.is_finite() && k.color.min_element() >= 0.0) {
                return Err(format!("gradient key {}: the colour must be finite and not negative", i + 1));
            }
            if i > 0 && k.at < keys[i - 1].at {
                return Err(format!(
                    "gradient key {}: position {} comes after {}: keys must be in increasing order",
                    i + 1,
                    k.at,
                    keys[i - 1].at
                ));
            }
        }
        Ok(Gradient { keys })
    }

    /// Its keys, in order.
    pub fn keys(&self) -> &[GradientKey] {
        &self.keys
    }

    /// The colour at `x`: linear between the two keys around it, the end keys' colours
    /// outside them (and at a NaN, the first key's).
    pub fn at(&self, x: f32) -> Color {
        // The first key past `x`; keys at `x` itself are behind it, so a step at `x` reads
        // its upper colour.
        let next = self.keys.partition_point(|k| k.at <= x);
        match (next.checked_sub(1).map(|i| self.keys[i]), self.keys.get(next)) {
            (Some(a), Some(b)) => a.color.lerp(b.color, (x - a.at) / (b.at - a.at)),
            (Some(a), None) => a.color,
            (None, _) => self.keys[0].color,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(at: f32, c: f32) -> GradientKey {
        GradientKey { at, color: Color::splat(c) }
    }

    #[test]
    fn linear_between_keys_and_flat_outside() {
        let g = Gradient::new(vec![key(0.25, 0.2), key(0.75, 0.6)]).unwrap();
        assert_eq!(g.at(0.0), Color::splat(0.2));
        assert_eq!(g.at(1.0), Color::splat(0.6));
        assert!((g.at(0.5) - Color::splat(0.4)).abs().max_element() < 1e-6);
        assert_eq!(g.at(f32::NAN), Color::splat(0.2));
    }

    #[test]
    fn equal_positions_make_a_step() {
        let g = Gradient::new(vec![key(0.0, 0.1), key(0.5, 0.1), key(0.5, 0.9), key(1.0, 0.9)]).unwrap();
        assert_eq!(g.at(0.49), Color::splat(0.1));
        assert_eq!(g.at(0.5), Color::splat(0.9));
        assert_eq!(g.at(0.51), Color::splat(0.9));
    }

    #[test]
    fn bad_keys_are_named() {
        assert!(Gradient::new(vec![]).unwrap_err().contains("at least one key"));
        assert!(Gradient::new(vec![key(0.5, 0.1), key(0.2, 0.1)]).unwrap_err().contains("key 2"));
        assert!(Gradient::new(vec![key(1.5, 0.1)]).unwrap_err().contains("not in [0, 1]"));
        assert!(Gradient::new(vec![key(f32::NAN, 0.1)]).unwrap_err().contains("key 1"));
        assert!(Gradient::new(vec![key(0.5, f32::NAN)]).unwrap_err().contains("finite"));
    }
}
