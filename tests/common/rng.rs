//! The tests' seeded random numbers: `fastrand` with the draws the tests make. Included with
//! `#[path = "common/rng.rs"] mod rng;` by tests that need no GPU helper.
#![allow(dead_code)]

use glam::DVec3;

/// A seeded generator: the same numbers on every run.
pub struct Rng(fastrand::Rng);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(fastrand::Rng::with_seed(seed))
    }

    /// Uniform in [0, 1).
    pub fn next(&mut self) -> f64 {
        self.0.f64()
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }

    /// Uniform in the cube [lo, hi)³.
    pub fn vec(&mut self, lo: f64, hi: f64) -> DVec3 {
        DVec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }

    /// A unit vector, uniform on the sphere.
    pub fn unit(&mut self) -> DVec3 {
        loop {
            let d = self.vec(-1.0, 1.0);
            let l = d.length();
            if l > 0.1 && l <= 1.0 {
                return d / l;
            }
        }
    }
}
