//! Procedural density: Perlin gradient noise, its fractal sum (fBm), and the height-faded
//! density that `density = { perlin = {…} }` bakes into a [`DensityGrid`].
//!
//! Everything here is deterministic for a seed on every platform: lattice gradients come from
//! an integer hash (PCG of the lattice coordinates and the seed, wrapping `u32` arithmetic), the
//! floating-point work uses only `+`, `−`, `×`, `/`, `floor` and integer conversion (the height
//! fade's exponential is our own [`exp`], not the platform's `libm`), and nothing is fused.
//!
//! # Definitions
//! * `perlin(p, seed)`: Perlin's improved gradient noise (Perlin 2002): at each integer lattice
//!   point one of the 12 cube-edge gradients (1, 1, 0)… chosen by the hash, quintic fade
//!   `6t⁵ − 15t⁴ + 10t³`, trilinear blend. It is 0 at lattice points, its mean is 0 and
//!   `|perlin| ≤ √3/2 · √2 ≈ 1.2247` (gradient length √2 times the largest corner distance).
//! * `fbm(p) = Σ_{o<octaves} gainᵒ · perlin(lacunarityᵒ · p, seed_o) / Σ_{o<octaves} gainᵒ`,
//!   normalised by the weight sum so it has the range of one octave whatever `octaves` and
//!   `gain` are; every octave has its own seed `seed_o` (so the octaves are not correlated at
//!   the origin).
//! * With `u = (p − lo) / (hi − lo) ∈ [0, 1]³` the position normalised to the bounds and
//!   `h = u.y` the normalised height (+Y is up; 0 at the bottom face, 1 at the top):
//!
//!   `d(p) = max(0, bias + amplitude · fbm(scale · u)) · exp(−height_falloff · h)`
//!
//!   so `scale` is the number of noise lattice cells across the bounds along each axis.
//!   Defaults ([`PerlinDensity::default`]): scale 4, octaves 4, gain 0.5, lacunarity 2,
//!   height_falloff 1.5, bias 0.5, amplitude 2.5, seed 0 — a cloudy medium with mean density
//!   ≈ 0.5 at the bottom, falling to ≈ 0.5·e^−1.5 ≈ 0.11 at the top, with clear gaps where
//!   `bias + amplitude·fbm < 0`.
//! * Baking: voxel `(i, j, k)` of a grid of resolution `n` holds `d` at the voxel centre
//!   `u = ((i, j, k) + 0.5) / n`; the grid is then sampled trilinearly like every density grid.
use crate::medium::DensityGrid;
use crate::rng::pcg_hash as pcg;
use glam::{UVec3, Vec3};

#[inline]
fn hash(x: i32, y: i32, z: i32, seed: u32) -> u32 {
    pcg((z as u32).wrapping_add(pcg((y as u32).wrapping_add(pcg((x as u32).wrapping_add(pcg(seed)))))))
}

/// Dot product of the offset with one of the 12 edge gradients of improved noise (16 slots,
/// four repeated), picked by the hash's top four bits.
#[inline]
fn grad(h: u32, x: f32, y: f32, z: f32) -> f32 {
    let h = h >> 28;
    let u = if h < 8 { x } else { y };
    let v = if h < 4 {
        y
    } else if h == 12 || h == 14 {
        x
    } else {
        z
    };
    (if h & 1 == 0 { u } else { -u }) + (if h & 2 == 0 { v } else { -v })
}

#[inline]
fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

#[inline]
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + t * (b - a)
}

/// Improved Perlin gradient noise at `p` (see the module docs); in `[−1.2248, 1.2248]`.
pub fn perlin(p: Vec3, seed: u32) -> f32 {
    let f = p.floor();
    let (x0, y0, z0) = (f.x as i32, f.y as i32, f.z as i32);
    let d = p - f;
    let (x1, y1, z1) = (x0.wrapping_add(1), y0.wrapping_add(1), z0.wrapping_add(1));
    let g = |x: i32, y: i32, z: i32, dx: f32, dy: f32, dz: f32| grad(hash(x, y, z, seed), dx, dy, dz);
    let (u, v, w) = (fade(d.x), fade(d.y), fade(d.z));
    let (dx1, dy1, dz1) = (d.x - 1.0, d.y - 1.0, d.z - 1.0);
    let x00 = lerp(g(x0, y0, z0, d.x, d.y, d.z), g(x1, y0, z0, dx1, d.y, d.z), u);
    let x10 = lerp(g(x0, y1, z0, d.x, dy1, d.z), g(x1, y1, z0, dx1, dy1, d.z), u);
    let x01 = lerp(g(x0, y0, z1, d.x, d.y, dz1), g(x1, y0, z1, dx1, d.y, dz1), u);
    let x11 = lerp(g(x0, y1, z1, d.x, dy1, dz1), g(x1, y1, z1, dx1, dy1, dz1), u);
    lerp(lerp(x00, x10, v), lerp(x01, x11, v), w)
}

/// Normalised fractal sum of `octaves` Perlin octaves (see the module docs).
pub fn fbm(p: Vec3, octaves: u32, gain: f32, lacunarity: f32, seed: u32) -> f32 {
    let (mut sum, mut norm, mut amp, mut freq) = (0.0f32, 0.0f32, 1.0f32, 1.0f32);
    for o in 0..octaves {
        let seed_o = seed.wrapping_add(o.wrapping_mul(0x9E37_79B9));
        sum += amp * perlin(p * freq, seed_o);
        norm += amp;
        amp *= gain;
        freq *= lacunarity;
    }
    if norm > 0.0 { sum / norm } else { 0.0 }
}

/// `eˣ` from `+`, `×`, `/` and `floor` only, so it gives the same bits everywhere; relative
/// error below 3·10⁻⁷ for `x ≤ 0`; `x > 0` is `1 / e⁻ˣ` (up to x = 87); NaN gives 0.
pub fn exp(x: f32) -> f32 {
    if x > 0.0 {
        return 1.0 / exp(-x.min(87.0));
    }
    if !(x > -87.0) {
        return 0.0; // also NaN → 0
    }
    let x = x.min(0.0);
    // x = k·ln2 + r, |r| ≤ ln2/2; eʳ by its Taylor series (degree 7), 2ᵏ by exponent bits.
    let k = (x * std::f32::consts::LOG2_E + 0.5).floor();
    let r = x - k * 0.693_145_75 - k * 1.428_606_8e-6;
    let mut p = 1.0 / 5040.0;
    for c in [1.0 / 720.0, 1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5, 1.0, 1.0] {
        p = p * r + c;
    }
    p * f32::from_bits(((k as i32 + 127) as u32) << 23)
}

/// The parameters of a procedural density (see the module docs for the formula).
#[derive(Clone, Debug, PartialEq)]
pub struct PerlinDensity {
    /// Noise lattice cells across the bounds (> 0).
    pub scale: f32,
    /// Number of fBm octaves (1..=16).
    pub octaves: u32,
    /// Amplitude ratio between successive octaves (≥ 0).
    pub gain: f32,
    /// Frequency ratio between successive octaves (> 0).
    pub lacunarity: f32,
    /// Rate of the exponential fade with normalised height (0 = none; negative grows upward).
    pub height_falloff: f32,
    /// Density offset before clamping at 0.
    pub bias: f32,
    /// Contrast: the factor on the normalised fBm.
    pub amplitude: f32,
    pub seed: u32,
}

impl Default for PerlinDensity {
    fn default() -> Self {
        Self {
            scale: 4.0,
            octaves: 4,
            gain: 0.5,
            lacunarity: 2.0,
            height_falloff: 1.5,
            bias: 0.5,
            amplitude: 2.5,
            seed: 0,
        }
    }
}

impl PerlinDensity {
    /// The density at normalised position `u ∈ [0, 1]³`.
    pub fn density(&self, u: Vec3) -> f32 {
        let n = fbm(u * self.scale, self.octaves, self.gain, self.lacunarity, self.seed);
        (self.bias + self.amplitude * n).max(0.0) * exp(-self.height_falloff * u.y)
    }

    /// The density at the voxel centres of a `res` grid, x fastest.
    pub fn bake_values(&self, res: UVec3) -> Vec<f32> {
        let n = res.as_vec3();
        let mut values = Vec::with_capacity((res.x * res.y * res.z) as usize);
        for z in 0..res.z {
            for y in 0..res.y {
                for x in 0..res.x {
                    let u = (UVec3::new(x, y, z).as_vec3() + Vec3::splat(0.5)) / n;
                    values.push(self.density(u));
                }
            }
        }
        values
    }

    /// Bakes the density into a grid filling `[lo, hi]`.
    pub fn bake(&self, res: UVec3, lo: Vec3, hi: Vec3) -> DensityGrid {
        DensityGrid::new(res, lo, hi, self.bake_values(res))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fixed low-discrepancy-ish set of points (no RNG dependency).
    fn points(n: u32) -> impl Iterator<Item = Vec3> {
        (0..n).map(|i| {
            let f = |a: u32| (pcg(i.wrapping_mul(3).wrapping_add(a)) >> 8) as f32 / (1u32 << 24) as f32;
            Vec3::new(f(0), f(1), f(2)) * 37.0 - Vec3::splat(18.0)
        })
    }

    #[test]
    fn exp_matches_std() {
        for i in 0..2000 {
            let x = -(i as f32) * 0.02;
            let (a, b) = (exp(x), x.exp());
            assert!((a - b).abs() <= 3e-7 * b + 1e-38, "{x}: {a} vs {b}");
        }
        assert_eq!(exp(0.0), 1.0);
        assert!((exp(2.0) - 2f32.exp()).abs() < 1e-6 * 2f32.exp());
        assert_eq!(exp(f32::NAN), 0.0);
        assert_eq!(exp(-1000.0), 0.0);
    }

    #[test]
    fn perlin_is_pinned_and_seeded() {
        // Pinned values: any change to the hash, gradients or fade shows up here.
        let p = [
            Vec3::new(0.3, 1.7, -2.2),
            Vec3::new(10.5, 0.25, 3.75),
            Vec3::new(-7.1, -0.9, 5.5),
        ];
        let got: Vec<f32> = p.iter().map(|&p| perlin(p, 7)).collect();
        let pinned = PINNED_PERLIN;
        for (g, e) in got.iter().zip(pinned) {
            assert!((g - e).abs() < 1e-6, "{got:?} vs {pinned:?}");
        }
        // Another seed changes them; lattice points are 0.
        assert!(p.iter().zip(&got).any(|(&p, g)| (perlin(p, 8) - g).abs() > 1e-3));
        assert_eq!(perlin(Vec3::new(3.0, -2.0, 5.0), 7), 0.0);
    }

    const PINNED_PERLIN: [f32; 3] = [-0.022_813_44, -0.212_897_3, -0.003_292_143_3];

    #[test]
    fn perlin_statistics() {
        let n = 200_000;
        let (mut sum, mut sum2, mut lo, mut hi) = (0.0f64, 0.0f64, f32::INFINITY, f32::NEG_INFINITY);
        for p in points(n) {
            let v = perlin(p, 3);
            assert!(v.is_finite());
            sum += v as f64;
            sum2 += (v * v) as f64;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        let mean = sum / n as f64;
        let sd = (sum2 / n as f64 - mean * mean).sqrt();
        // Range bound √3/2·√2; the values actually spread over most of [−1, 1].
        assert!(lo >= -1.2248 && hi <= 1.2248, "range [{lo}, {hi}]");
        assert!(lo < -0.7 && hi > 0.7, "range [{lo}, {hi}]");
        assert!(mean.abs() < 4.0 * sd / (n as f64).sqrt() + 2e-3, "mean {mean} sd {sd}");
        assert!(sd > 0.1 && sd < 0.5, "sd {sd}");
        // fBm keeps the range of one octave.
        for p in points(20_000) {
            let v = fbm(p, 6, 0.7, 2.1, 11);
            assert!(v.abs() <= 1.2248);
        }
    }

    #[test]
    fn baked_density_is_sane_and_fades_with_height() {
        let d = PerlinDensity::default();
        let res = UVec3::new(48, 32, 40);
        let v = d.bake_values(res);
        assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0));
        assert!(v.contains(&0.0), "some gaps");
        let slab = |y: u32| {
            let mut s = 0.0f64;
            for z in 0..res.z {
                for x in 0..res.x {
                    s += v[(x + res.x * (y + res.y * z)) as usize] as f64;
                }
            }
            s / (res.x * res.z) as f64
        };
        // Mean per 4-voxel-high slab decreases with height; the bottom is ≈ 0.5.
        let slabs: Vec<f64> = (0..8)
            .map(|b| (0..4).map(|k| slab(4 * b + k)).sum::<f64>() / 4.0)
            .collect();
        for w in slabs.windows(2) {
            assert!(w[1] < w[0], "{slabs:?}");
        }
        assert!(slabs[0] > 0.35 && slabs[0] < 0.7, "{slabs:?}");
        // Deterministic, pinned, and the seed matters.
        assert_eq!(v, d.bake_values(res));
        let other = PerlinDensity { seed: 1, ..d.clone() }.bake_values(res);
        assert_ne!(v, other);
        let pinned = [v[0], v[1000], v[30_000]];
        assert!(
            pinned.iter().zip(PINNED_BAKE).all(|(a, b)| (a - b).abs() < 1e-6),
            "{pinned:?}"
        );
    }

    const PINNED_BAKE: [f32; 3] = [0.812_943_94, 0.173_633_64, 0.106_213_495];
}
