//! Counter-based random numbers.
//!
//! Every random number is a pure function of `(seed, pass, stream index, dimension)`, so a
//! sample can be recomputed anywhere (a GPU kernel, another machine) without carrying state.
//! The hash is PCG-hash (Jarzynski & Olano, "Hash Functions for GPU Rendering", JCGT 2020),
//! applied once per key word; it is a bijection on u32 so distinct keys cannot collapse early.
//! The WGSL twin must produce the same bits.

/// One round of PCG-hash: a 32-bit permutation with good avalanche.
#[inline]
pub fn pcg_hash(x: u32) -> u32 {
    let state = x.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// Hash of the four key words.
#[inline]
pub fn hash4(seed: u32, pass: u32, index: u32, dim: u32) -> u32 {
    let h = pcg_hash(seed);
    let h = pcg_hash(h ^ pass);
    let h = pcg_hash(h ^ index);
    pcg_hash(h ^ dim)
}

/// Maps 32 random bits to a float in [0, 1) with 24 bits of precision (exactly representable).
#[inline]
pub fn u32_to_unit_f32(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// A stream of samples for one `(seed, pass, index)` triple; each draw advances the dimension.
/// The hash of the three fixed key words is computed once, so a draw costs one round of
/// PCG-hash instead of four (the same bits as [`hash4`]).
#[derive(Clone, Debug)]
pub struct Sampler {
    key: u32,
    dim: u32,
}

impl Sampler {
    pub fn new(seed: u32, pass: u32, index: u32) -> Self {
        let key = pcg_hash(pcg_hash(pcg_hash(seed) ^ pass) ^ index);
        Self { key, dim: 0 }
    }

    /// Next uniform number in [0, 1).
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        let bits = pcg_hash(self.key ^ self.dim);
        self.dim = self.dim.wrapping_add(1);
        u32_to_unit_f32(bits)
    }

    #[inline]
    pub fn next_2d(&mut self) -> glam::Vec2 {
        let x = self.next_1d();
        glam::Vec2::new(x, self.next_1d())
    }

    /// The dimension the next draw will use.
    pub fn dimension(&self) -> u32 {
        self.dim
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_in_unit_interval_and_reproducible() {
        let mut a = Sampler::new(7, 3, 12345);
        let mut b = Sampler::new(7, 3, 12345);
        for _ in 0..1000 {
            let x = a.next_1d();
            assert!((0.0..1.0).contains(&x));
            assert_eq!(x.to_bits(), b.next_1d().to_bits());
        }
    }

    /// The cached key must give exactly [`hash4`]'s bits (the WGSL twin computes `hash4`).
    #[test]
    fn sampler_draws_are_hash4() {
        for (seed, pass, index) in [(0, 0, 0), (7, 3, 12345), (u32::MAX, 17, 99)] {
            let mut s = Sampler::new(seed, pass, index);
            for dim in 0..64 {
                assert_eq!(s.next_1d(), u32_to_unit_f32(hash4(seed, pass, index, dim)));
            }
        }
    }

    #[test]
    fn mean_and_variance_are_uniform() {
        let n = 200_000;
        let (mut s, mut s2) = (0.0f64, 0.0f64);
        for i in 0..n {
            let x = u32_to_unit_f32(hash4(1, 0, i, 0)) as f64;
            s += x;
            s2 += x * x;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 0.002, "var {var}");
    }

    #[test]
    fn neighbouring_keys_are_uncorrelated() {
        // Consecutive pixels and consecutive dimensions must not produce correlated streams.
        let n = 100_000u32;
        for (da, db) in [((0, 1), (0, 0)), ((0, 0), (1, 0))] {
            let mut sxy = 0.0f64;
            for i in 0..n {
                let x = u32_to_unit_f32(hash4(3, 0, i + da.0, da.1)) as f64 - 0.5;
                let y = u32_to_unit_f32(hash4(3, 0, i + db.0, db.1)) as f64 - 0.5;
                sxy += x * y;
            }
            let corr = sxy / n as f64 * 12.0;
            assert!(corr.abs() < 0.02, "correlation {corr}");
        }
    }
}
