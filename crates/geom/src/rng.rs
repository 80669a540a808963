//! SplitMix64: a tiny, seedable generator that gives the same numbers on every
//! platform and version, for contact-point samples, synthetic data and tests.

use crate::{Quat, Vec3};

#[derive(Clone, Debug)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
    /// Uniform in the cube [-r, r)³.
    pub fn vec(&mut self, r: f64) -> Vec3<f64> {
        Vec3::new(self.range(-r, r), self.range(-r, r), self.range(-r, r))
    }
    /// Uniform in the box [lo, hi).
    pub fn in_box(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Vec3<f64> {
        Vec3::new(
            self.range(lo[0], hi[0]),
            self.range(lo[1], hi[1]),
            self.range(lo[2], hi[2]),
        )
    }
    /// Uniform unit vector.
    pub fn dir(&mut self) -> Vec3<f64> {
        loop {
            let v = self.vec(1.0);
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v * (1.0 / n);
            }
        }
    }
    /// Uniform rotation, `w` of either sign.
    pub fn quat(&mut self) -> Quat<f64> {
        loop {
            let a = [0; 4].map(|_| self.range(-1.0, 1.0));
            let n = a.iter().map(|v| v * v).sum::<f64>().sqrt();
            if n > 0.1 && n <= 1.0 {
                return Quat::cst(a.map(|v| v / n));
            }
        }
    }
}
