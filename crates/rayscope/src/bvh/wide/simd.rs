//! The instruction set the wide trees' traversals run on, detected at run time so that one
//! binary runs on any x86-64.

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
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("bmi1")
            && std::arch::is_x86_feature_detected!("bmi2")
            && std::arch::is_x86_feature_detected!("lzcnt")
            && std::arch::is_x86_feature_detected!("popcnt")
        {
            if std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512vl")
                && std::arch::is_x86_feature_detected!("avx512bw")
                && std::arch::is_x86_feature_detected!("avx512dq")
            {
                return SimdLevel::Avx512;
            }
            return SimdLevel::Avx2;
        }
        SimdLevel::Portable
    }
}
