//! A small counter-based PRNG, bit-identical on every target.
//!
//! Output `n` of stream `key` is `mix64(key + n·φ)` with the SplitMix64 finaliser
//! (φ = 0x9E37_79B9_7F4A_7C15). Being counter-based, any output can be reached in
//! O(1) ([`Rng::at`]) and independent streams are derived by [`Rng::fork`].
//! Floats are built from integer bits (24 bits for `f32`), never from platform
//! routines, so sequences match on x86_64, Cortex-M, RISC-V and AArch64.
//!
//! Statistical sanity (tested below): a chi-square test of 64 equiprobable bins
//! over 64k draws stays below the 0.1 % critical value (≈ 103.4 for 63 d.o.f.),
//! and the mean of `next_f32` is within 0.01 of 0.5.

use crate::geom::Vec3;

const PHI: u64 = 0x9E37_79B9_7F4A_7C15;

#[inline]
const fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Counter-based pseudo-random generator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Rng {
    key: u64,
    counter: u64,
}

impl Rng {
    /// A generator for `seed`, positioned at its first output.
    pub const fn new(seed: u64) -> Self {
        Self {
            key: mix64(seed ^ 0x5654_534D_5F52_4E47),
            counter: 0,
        }
    }

    /// The same stream positioned at output `counter`.
    pub const fn at(self, counter: u64) -> Self {
        Self {
            key: self.key,
            counter,
        }
    }

    /// An independent stream derived from this one and `stream`.
    pub const fn fork(&self, stream: u64) -> Self {
        Self {
            key: mix64(self.key ^ mix64(stream.wrapping_add(PHI))),
            counter: 0,
        }
    }

    /// How many outputs have been drawn.
    pub const fn counter(&self) -> u64 {
        self.counter
    }

    /// Next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.counter = self.counter.wrapping_add(1);
        mix64(self.key.wrapping_add(self.counter.wrapping_mul(PHI)))
    }

    /// Next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }

    /// Uniform in `[0, 1)` with 24 bits of resolution.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Uniform in `[lo, hi)`.
    #[inline]
    pub fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next_f32()
    }

    /// Uniform integer in `[0, n)` (`0` when `n == 0`), by multiply-high: one draw,
    /// no rejection loop, bias below 2⁻³².
    #[inline]
    pub fn below(&mut self, n: u32) -> u32 {
        ((u64::from(self.next_u32()) * u64::from(n)) >> 32) as u32
    }

    /// Uniform direction on the unit sphere (Archimedes: z uniform, azimuth uniform).
    pub fn unit_vector3(&mut self) -> Vec3 {
        let z = self.uniform(-1.0, 1.0);
        let phi = self.uniform(0.0, core::f32::consts::TAU);
        let r = libm::sqrtf((1.0 - z * z).max(0.0));
        Vec3::new(r * libm::cosf(phi), r * libm::sinf(phi), z)
    }

    /// Standard normal draw (Box–Muller, one of the pair).
    pub fn normal(&mut self) -> f32 {
        let u1 = 1.0 - self.next_f32(); // (0, 1]
        let u2 = self.next_f32();
        libm::sqrtf(-2.0 * libm::logf(u1)) * libm::cosf(core::f32::consts::TAU * u2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Golden vector: the first outputs of seed 42. Changing the generator breaks
    /// determinism of every recorded run, so this must never change silently.
    const GOLDEN_SEED_42: [u64; 4] = [
        0x7a50_c61a_bc02_6c40,
        0xe5ed_93cd_79d6_fdf4,
        0x08c6_e2c2_eb91_6ddc,
        0x4b7d_e00a_57f8_e6ea,
    ];

    /// Verifies: VTSM-RNG-001
    #[test]
    fn same_seed_gives_same_sequence_and_golden_vector() {
        let mut a = Rng::new(42);
        let mut b = Rng::new(42);
        let first: [u64; 4] = core::array::from_fn(|_| a.next_u64());
        for v in first {
            assert_eq!(v, b.next_u64());
        }
        assert_eq!(first, GOLDEN_SEED_42, "{first:#x?}");
        assert_eq!(Rng::new(42).at(2).next_u64(), first[2]);
        assert_ne!(Rng::new(43).next_u64(), first[0]);
        assert_ne!(
            Rng::new(42).fork(1).next_u64(),
            Rng::new(42).fork(2).next_u64()
        );
    }

    /// Verifies: VTSM-RNG-002
    #[test]
    fn uniformity_chi_square_and_mean() {
        let mut rng = Rng::new(7);
        let mut bins = [0u32; 64];
        let n = 65_536u32;
        let mut sum = 0.0f64;
        for _ in 0..n {
            bins[rng.below(64) as usize] += 1;
            sum += f64::from(rng.next_f32());
        }
        let e = f64::from(n) / 64.0;
        let chi2: f64 = bins.iter().map(|&o| (f64::from(o) - e).powi(2) / e).sum();
        assert!(chi2 < 103.4, "chi2 = {chi2}");
        assert!((sum / f64::from(n) - 0.5).abs() < 0.01);
        for _ in 0..1000 {
            let v = rng.unit_vector3();
            assert!((v.norm() - 1.0).abs() < 1e-5);
            let u = rng.uniform(-2.0, 3.0);
            assert!((-2.0..3.0).contains(&u));
        }
    }
}
