//! SplitMix64 for the shuffled layout's permutation and the unit tests' random boxes: seeded,
//! so a layout and a test are the same on every run. (quiver-scenes has the public generator
//! its scenes and ray sets use.)

/// SplitMix64: fast and seedable; not for cryptography.
#[derive(Clone, Debug)]
pub(crate) struct Rng(u64);

impl Rng {
    pub(crate) fn new(seed: u64) -> Self {
        Rng(seed)
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let z = self.0;
        let z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        let z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[lo, hi)` per axis.
    #[cfg(test)]
    pub(crate) fn in_box(&mut self, lo: glam::Vec3A, hi: glam::Vec3A) -> glam::Vec3A {
        let mut unit = || (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32);
        let u = glam::Vec3A::new(unit(), unit(), unit());
        lo + (hi - lo) * u
    }
}
