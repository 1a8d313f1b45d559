//! The instruction set the wide trees' traversals run on, detected at run time so that one
//! binary runs on any x86-64, and the tokens that prove the CPU has it.
//!
//! A token ([`Avx2`], [`Avx512`]) is made only where the CPU has the level's features, and the
//! code compiled for those features takes one: the kernels keep it, so their safe methods can
//! run the `std::arch` instructions, and each traversal's dispatch calls its
//! `#[target_feature]` variant in one `unsafe` block whose proof is the token in hand.

/// The instruction set a traversal runs on, chosen at run time so the binary still runs on any
/// x86-64. All give bit-identical hits: the AVX2 variant is the same traversal compiled for
/// AVX2, FMA and BMI, with the 8-wide node and two-block triangle tests written in `std::arch`
/// doing the portable tests' operations lane for lane; the AVX-512 variant adds the 16-wide
/// node test in 512-bit registers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SimdLevel {
    /// The target's baseline (SSE2 on x86-64, NEON on AArch64, scalar elsewhere).
    #[default]
    Portable,
    /// x86-64 with AVX2, FMA, BMI1/2 and LZCNT (x86-64-v3).
    Avx2,
    /// x86-64-v3 and AVX-512 F, VL, BW and DQ (x86-64-v4).
    Avx512,
}

impl SimdLevel {
    /// The best level this CPU supports.
    pub fn detect() -> SimdLevel {
        Simd::detect().level()
    }
}

/// The baseline's token: code for the target's baseline needs no proof, so anyone may make one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Baseline;

/// Proof that the CPU has [`SimdLevel::Avx2`]'s features: made only by [`Avx2::new`], and
/// from an [`Avx512`] token.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Avx2(());

/// Proof that the CPU has [`SimdLevel::Avx512`]'s features: only [`Avx512::new`] makes one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Avx512(());

impl Avx2 {
    /// The token, where the CPU has AVX2, FMA, BMI1/2, LZCNT and POPCNT.
    pub fn new() -> Option<Avx2> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("bmi1")
            && std::arch::is_x86_feature_detected!("bmi2")
            && std::arch::is_x86_feature_detected!("lzcnt")
            && std::arch::is_x86_feature_detected!("popcnt")
        {
            return Some(Avx2(()));
        }
        None
    }
}

impl Avx512 {
    /// The token, where the CPU has the AVX2 level's features and AVX-512 F, VL, BW and DQ.
    pub fn new() -> Option<Avx512> {
        #[cfg(target_arch = "x86_64")]
        if Avx2::new().is_some()
            && std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
            && std::arch::is_x86_feature_detected!("avx512bw")
            && std::arch::is_x86_feature_detected!("avx512dq")
        {
            return Some(Avx512(()));
        }
        None
    }
}

/// The AVX-512 level includes the AVX2 level's features.
impl From<Avx512> for Avx2 {
    #[inline(always)]
    fn from(_: Avx512) -> Avx2 {
        Avx2(())
    }
}

impl From<Avx2> for Baseline {
    #[inline(always)]
    fn from(_: Avx2) -> Baseline {
        Baseline
    }
}

impl From<Avx512> for Baseline {
    #[inline(always)]
    fn from(_: Avx512) -> Baseline {
        Baseline
    }
}

/// A [`SimdLevel`] with the token of its features: what a tree keeps, so that its traversals
/// run the level's code without asking the CPU again.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Simd {
    /// [`SimdLevel::Portable`].
    #[default]
    Portable,
    /// [`SimdLevel::Avx2`].
    Avx2(Avx2),
    /// [`SimdLevel::Avx512`].
    Avx512(Avx512),
}

impl Simd {
    /// The best level this CPU supports.
    pub(crate) fn detect() -> Simd {
        if let Some(cpu) = Avx512::new() {
            Simd::Avx512(cpu)
        } else if let Some(cpu) = Avx2::new() {
            Simd::Avx2(cpu)
        } else {
            Simd::Portable
        }
    }

    /// The level, without its token.
    pub(crate) fn level(self) -> SimdLevel {
        match self {
            Simd::Portable => SimdLevel::Portable,
            Simd::Avx2(_) => SimdLevel::Avx2,
            Simd::Avx512(_) => SimdLevel::Avx512,
        }
    }
}
