//! A small seeded generator (SplitMix64) so scenes, rays and tests are reproducible without a
//! dependency whose streams could change between versions.

use glam::Vec3A;

/// SplitMix64: fast, seedable, good enough for test data (not for cryptography).
///
/// ```
/// let mut a = quiver_scenes::rng::Rng::new(7);
/// let mut b = quiver_scenes::rng::Rng::new(7);
/// assert_eq!(a.next_u64(), b.next_u64());
/// let x = a.f32();
/// assert!((0.0..1.0).contains(&x));
/// ```
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }

    /// Uniform in the box `[lo, hi)`.
    pub fn in_box(&mut self, lo: Vec3A, hi: Vec3A) -> Vec3A {
        Vec3A::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }

    /// Uniform on the unit sphere.
    pub fn unit_vector(&mut self) -> Vec3A {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f32::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3A::new(r * phi.cos(), r * phi.sin(), z)
    }
}
