//! A tiny counter-based generator: SplitMix64 seeded by (seed, measurement, triangle), so Monte Carlo
//! renders do not depend on thread scheduling and the adjoint replays the forward samples exactly.

#[derive(Debug, Clone, Copy)]
pub(crate) struct SplitMix64(u64);

impl SplitMix64 {
    pub(crate) fn new(seed: u64, m: u64, t: u64) -> Self {
        let mut s = Self(seed ^ 0x9E37_79B9_7F4A_7C15);
        s.0 ^= s.next_u64().wrapping_add(m.wrapping_mul(0xD1B5_4A32_D192_ED03));
        s.0 ^= s.next_u64().wrapping_add(t.wrapping_mul(0xAEF1_7502_108E_F2D9));
        Self(s.next_u64())
    }

    #[inline(always)]
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)` (24 random bits, so never 1.0).
    #[inline(always)]
    pub(crate) fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }
}
