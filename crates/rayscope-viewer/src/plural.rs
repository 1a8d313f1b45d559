//! Counts in words, singular for one: "1 ray", "2 rays", never "1 rays".

/// `n` and the noun, singular (`one`) for one and plural (`many`) otherwise.
pub fn counted(n: u64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_is_singular() {
        assert_eq!(counted(1, "ray", "rays"), "1 ray");
        assert_eq!(counted(0, "ray", "rays"), "0 rays");
        assert_eq!(counted(2, "box", "boxes"), "2 boxes");
    }
}
