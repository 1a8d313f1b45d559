//! A fast hash of three vertex indices, for the loader's maps of corners and triangles: one
//! folded multiply with keys drawn per map (as aHash's fallback), where std's SipHash was a
//! fifth of the dragon's load. Random keys keep a crafted file from making indices collide.

use std::hash::{BuildHasher, Hasher, RandomState};

/// Three indices as one key.
#[inline(always)]
pub fn pack(indices: [u32; 3]) -> u128 {
    u128::from(indices[0]) | u128::from(indices[1]) << 32 | u128::from(indices[2]) << 64
}

/// The [`BuildHasher`] of maps keyed by [`pack`]ed indices.
#[derive(Clone, Copy)]
pub struct IndexHash {
    keys: [u64; 2],
}

impl IndexHash {
    /// With keys drawn from std's random source.
    pub fn new() -> IndexHash {
        let random = RandomState::new();
        IndexHash { keys: [random.hash_one(1u8), random.hash_one(2u8)] }
    }
}

impl BuildHasher for IndexHash {
    type Hasher = IndexHasher;

    fn build_hasher(&self) -> IndexHasher {
        IndexHasher { keys: self.keys, hash: 0 }
    }
}

/// The [`Hasher`] of [`IndexHash`].
pub struct IndexHasher {
    keys: [u64; 2],
    hash: u64,
}

impl Hasher for IndexHasher {
    fn finish(&self) -> u64 {
        self.hash
    }

    #[inline(always)]
    fn write_u128(&mut self, v: u128) {
        let product = u128::from(v as u64 ^ self.keys[0]) * u128::from((v >> 64) as u64 ^ self.keys[1]);
        self.hash = product as u64 ^ (product >> 64) as u64;
    }

    /// Other input (none: the maps hold `u128`s), byte by byte through the same mix.
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u128(u128::from(self.hash) << 64 | u128::from(b));
        }
    }
}
