//! The tests' seeded random numbers (`fastrand` with the draws the tests make), the seeds a
//! randomized test runs, and the relative error the reference tests compare colours by.

use glam::DVec3;

/// A seeded generator: the same numbers on every run.
pub struct Rng(fastrand::Rng);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(fastrand::Rng::with_seed(seed))
    }

    /// Uniform in [0, 1). (Not `Iterator::next`: a generator never ends, and the tests call it
    /// by this name.)
    #[allow(clippy::should_implement_trait)]
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

/// The seeds a randomized test runs: `all`, or only the one in `VOLSHADOW_SEED` (to reproduce a
/// printed failing seed alone).
pub fn seeds(all: std::ops::Range<u64>) -> Vec<u64> {
    match std::env::var("VOLSHADOW_SEED") {
        Ok(s) => vec![s.parse().expect("VOLSHADOW_SEED must be a number")],
        Err(_) => all.collect(),
    }
}

/// The largest relative error over the channels, skipping channels where both values are 0.
pub fn rel_err(a: DVec3, b: DVec3) -> f64 {
    (0..3)
        .filter(|&c| !(a[c] == 0.0 && b[c] == 0.0))
        .map(|c| (a[c] - b[c]).abs() / a[c].abs().max(b[c].abs()))
        .fold(0.0, f64::max)
}
