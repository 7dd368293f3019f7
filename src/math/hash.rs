//! A hasher for the step's small integer keys (row keys, collider pairs).

/// One multiply-xorshift over keys that are integers already: the warm-start map's mixed 64-bit
/// row keys and the collision cache's collider pairs. SipHash, std's default, is built against
/// adversarial keys, which these are not; it took ~5 % of a resting stack's step for the warm
/// start, and ~1 % of a resting ragdoll's for the pair cache.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FastHasher(u64);

impl std::hash::Hasher for FastHasher {
    fn finish(&self) -> u64 {
        let x = self.0.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        x ^ (x >> 32)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8)) ^ u64::from(b);
        }
    }
    fn write_u32(&mut self, x: u32) {
        // A pair (a, b) becomes (a << 32) ^ b: distinct pairs, distinct words.
        self.0 = self.0.rotate_left(32) ^ u64::from(x);
    }
    fn write_u64(&mut self, x: u64) {
        self.0 ^= x;
    }
}

impl std::hash::BuildHasher for FastHasher {
    type Hasher = FastHasher;
    fn build_hasher(&self) -> FastHasher {
        FastHasher(0)
    }
}
