//! Sampling routines shared by every integrator.
//!
//! Every warp takes uniform numbers in [0, 1)² and has a matching `*_pdf` (solid angle for
//! directions). The warps are written so that no input in [0, 1]² produces NaN or a non-unit
//! vector: square roots get arguments clamped at zero and `1 − cos²` is formed as a product of
//! two factors whenever one of them is known exactly.
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4, TAU};

/// The largest f32 below 1; uniform numbers are clamped to it where 1 would select past the end.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Uniform direction on the unit sphere.
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    // sin²θ = (1 − z)(1 + z) = 4u(1 − u): exact near both poles, unlike 1 − z².
    let r = 2.0 * (u.x * (1.0 - u.x)).max(0.0).sqrt();
    let phi = TAU * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Solid-angle pdf of [`uniform_sphere`]: 1 / (4π).
pub fn uniform_sphere_pdf() -> f32 {
    0.25 * FRAC_1_PI
}

/// Shirley–Chiu concentric map from the square to the unit disk (keeps strata compact,
/// which plain polar mapping does not).
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, FRAC_PI_4 * (o.y / o.x))
    } else {
        (o.y, FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y))
    };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// Cosine-weighted direction on the hemisphere z ≥ 0 (local frame, z up); pdf = cos θ / π.
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    // Malley's method: lift the uniform disk point to the hemisphere.
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Solid-angle pdf of [`cosine_hemisphere`] for a direction with cos θ = `cos_theta`
/// (zero below the horizon).
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Uniform direction inside the cone around +z with cos θ ≥ `cos_max` (local frame).
/// For a degenerate cone (`cos_max` ≥ 1) it returns +z.
pub fn uniform_cone(u: Vec2, cos_max: f32) -> Vec3 {
    // 1 − cos θ is uniform on [0, 1 − cos_max]; keeping it (not cos θ) preserves precision
    // for the tiny cones subtended by distant spherical lights.
    let one_minus_cos_max = (1.0 - cos_max).clamp(0.0, 2.0);
    let one_minus_cos = u.x * one_minus_cos_max;
    let cos_theta = 1.0 - one_minus_cos;
    let sin_theta = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let phi = TAU * u.y;
    Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// Solid-angle pdf of [`uniform_cone`]: 1 / (2π (1 − cos_max)); +∞ for a degenerate cone.
pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    let one_minus_cos_max = (1.0 - cos_max).clamp(0.0, 2.0);
    if one_minus_cos_max == 0.0 {
        return f32::INFINITY;
    }
    1.0 / (TAU * one_minus_cos_max)
}

/// Barycentrics (b1, b2) uniform over a triangle: the weights of p1 and p2 (p0 gets 1 − b1 − b2).
///
/// Heitz, "A Low-Distortion Map Between Triangle and Square" (2019): area preserving like the
/// square-root map, but neighbouring samples stay neighbours, so stratification survives.
/// The area pdf is 1 / area.
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    let (b1, b2) = if u.x < u.y {
        let b1 = 0.5 * u.x;
        (b1, u.y - b1)
    } else {
        let b2 = 0.5 * u.y;
        (u.x - b2, b2)
    };
    Vec2::new(b1, b2)
}

/// Veach's power heuristic with β = 2: f² / (f² + g²), the MIS weight of the strategy with
/// pdf `f_pdf` against one with pdf `g_pdf`.
///
/// Never NaN: an infinite `f_pdf` (delta) gets weight 1, a zero (or negative/NaN) `f_pdf` gets 0
/// (including when both are zero), and the squares cannot overflow because only the ratio of
/// the smaller pdf to the larger one is squared.
pub fn power_heuristic(f_pdf: f32, g_pdf: f32) -> f32 {
    if !(f_pdf > 0.0) {
        return 0.0;
    }
    if f_pdf.is_infinite() || !(g_pdf > 0.0) {
        return 1.0;
    }
    if f_pdf >= g_pdf {
        let r = g_pdf / f_pdf;
        1.0 / (1.0 + r * r)
    } else {
        let r = f_pdf / g_pdf;
        let r2 = r * r;
        r2 / (1.0 + r2)
    }
}

/// Piecewise-constant 1-D distribution over `n` discrete items.
///
/// `cdf` has `n + 1` entries, `cdf[0] = 0` and (unless `total` is 0) `cdf[n] = 1`; item `i` is
/// chosen with probability `cdf[i + 1] − cdf[i]`. `total` is the sum of the (sanitized) weights.
///
/// **All-zero weights** (or no weights at all): `total == 0`, every `cdf` entry is 0, every
/// `pmf` is 0 and [`sample`](Self::sample) returns `(0, 0.0)`. A pmf of 0 means "nothing to
/// sample": callers must check `total > 0` (or the returned pmf) before using the index.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    pub cdf: Vec<f32>,
    pub total: f32,
}

impl Distribution1D {
    /// Builds the distribution. Weights that are negative, NaN or infinite count as 0 (a bad
    /// emitter must not poison the whole light distribution).
    pub fn new(weights: &[f32]) -> Self {
        // Accumulate in f64 so that long lists of small weights keep their share, and so that
        // a zero weight leaves the running sum bit-identical (its item can never be chosen).
        let mut cdf = Vec::with_capacity(weights.len() + 1);
        let mut sum = 0.0f64;
        cdf.push(0.0f64);
        for &w in weights {
            if w.is_finite() && w > 0.0 {
                sum += w as f64;
            }
            cdf.push(sum);
        }
        if sum <= 0.0 {
            return Self {
                cdf: vec![0.0; weights.len() + 1],
                total: 0.0,
            };
        }
        let mut cdf: Vec<f32> = cdf.iter().map(|&c| (c / sum) as f32).collect();
        // Exactly 1 at the end regardless of rounding, so any u < 1 lands on an item.
        *cdf.last_mut().unwrap() = 1.0;
        Self { cdf, total: sum as f32 }
    }

    /// Returns (index, probability of that index). Never returns an index with zero weight
    /// (unless `total` is 0, see the type's documentation).
    #[inline]
    pub fn sample(&self, u: f32) -> (usize, f32) {
        if !(self.total > 0.0) || self.is_empty() {
            return (0, 0.0);
        }
        // NaN → 0, and 1 would select past the last item.
        let u = if u >= 0.0 { u.min(ONE_MINUS_EPSILON) } else { 0.0 };
        // The largest i with cdf[i] ≤ u; then cdf[i] ≤ u < cdf[i + 1], so item i has a
        // non-empty interval, i.e. a positive weight.
        let i = if self.cdf.len() <= 16 {
            // The same index by counting, without the unpredictable branches of a binary
            // search (a scene's handful of emissive triangles).
            self.cdf.iter().filter(|&&c| c <= u).count() - 1
        } else {
            self.cdf.partition_point(|&c| c <= u) - 1
        };
        let i = i.min(self.len() - 1);
        (i, self.pmf(i))
    }

    /// Probability of choosing item `i` (0 when out of range).
    pub fn pmf(&self, i: usize) -> f32 {
        if i + 1 >= self.cdf.len() {
            return 0.0;
        }
        self.cdf[i + 1] - self.cdf[i]
    }

    pub fn len(&self) -> usize {
        self.cdf.len().saturating_sub(1)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Equiangular sampling (Kulla & Fajardo 2012) of a distance `t ∈ [t0, t1]` along the line
/// `o + t·d` (`d` unit, `t1` may be ∞) with density ∝ 1 / |o + t·d − c|²: uniform in the angle
/// the line subtends at `c`. This is the VRL paper's inverse-squared-distance sampling of a
/// point on a ray light as seen from a shading point. Returns `(t, pdf)`.
///
/// A point `c` on the line itself would make the density singular; its distance to the line
/// is clamped to a tiny fraction of the problem's scale, so the pdf stays finite. An interval
/// that subtends almost no angle at `c` (a short segment far away: [`subtends_no_angle`]) is
/// sampled uniformly instead, where the density 1/|…|² is nearly constant anyway: its angles
/// round to too few values to sample by, and to the same one (a density of 1/0, which was
/// returned as 0: a contribution lost) for the shortest.
pub fn equiangular(o: Vec3, d: Vec3, t0: f32, t1: f32, c: Vec3, u: f32) -> (f32, f32) {
    let (delta, h, theta0, theta1) = equiangular_frame(o, d, t0, t1, c);
    if subtends_no_angle(theta0, theta1) {
        return ((t0 + u * (t1 - t0)).clamp(t0, t1), uniform_density(t0, t1));
    }
    let t = (delta + h * tan(theta0 + u * (theta1 - theta0))).clamp(t0, t1);
    (t, equiangular_density(t, delta, h, theta0, theta1))
}

/// tan x for |x| ≤ π/2 and somewhat beyond, by Cephes' `tanf` (the argument reduced by π/4 in
/// three parts, a degree-13 odd polynomial, −1/tan for odd octants): the twin of
/// `precise_tan` in `shaders/lib/sampling.wgsl`, so that both backends map an angle to the same
/// point of a line, and inline, where libm's `tanf` is a call (5 % of a smoke box `Lmm` pass,
/// which maps each angular PDF's 16 vertices). Within 1.3 ulp of the true value over
/// (−π/2, π/2) (tested).
#[inline]
pub fn tan(x_in: f32) -> f32 {
    let x = x_in.abs();
    let mut j = (x * 1.273_239_5) as u32;
    let mut y = j as f32;
    if j & 1 != 0 {
        j += 1;
        y += 1.0;
    }
    let z = ((x - y * 0.785_156_25) - y * 2.418_756_5e-4) - y * 3.774_895e-8;
    let zz = z * z;
    let mut r = z;
    if x > 1e-4 {
        r = (((((9.385_402e-3 * zz + 3.119_922_3e-3) * zz + 2.443_013_5e-2) * zz + 5.341_128e-2) * zz + 1.333_88e-1)
            * zz
            + 3.333_315_7e-1)
            * zz
            * z
            + z;
    }
    if j & 2 != 0 {
        r = -1.0 / r;
    }
    if x_in < 0.0 { -r } else { r }
}

/// Whether the angles `theta0 < theta1` of an interval's ends, seen from a point, are too
/// close for f32 to sample between (a difference below 10⁻⁴ of their size: fewer than about
/// 1 000 distinct angles in between). [`equiangular`] then samples uniformly.
pub fn subtends_no_angle(theta0: f32, theta1: f32) -> bool {
    !(theta1 - theta0 > 1e-4 * theta0.abs().max(theta1.abs()))
}

/// 1 / (t1 − t0), or 0 for an empty interval (whose integral is 0).
fn uniform_density(t0: f32, t1: f32) -> f32 {
    let pdf = 1.0 / (t1 - t0);
    if pdf.is_finite() && pdf > 0.0 { pdf } else { 0.0 }
}

/// The density with which [`equiangular`] produces `t` (0 outside `[t0, t1]`).
pub fn equiangular_pdf(o: Vec3, d: Vec3, t0: f32, t1: f32, c: Vec3, t: f32) -> f32 {
    if !(t >= t0 && t <= t1) {
        return 0.0;
    }
    let (delta, h, theta0, theta1) = equiangular_frame(o, d, t0, t1, c);
    if subtends_no_angle(theta0, theta1) {
        return uniform_density(t0, t1);
    }
    equiangular_density(t, delta, h, theta0, theta1)
}

/// (t of the closest approach to `c`, its distance h, and the angles of the interval's ends).
fn equiangular_frame(o: Vec3, d: Vec3, t0: f32, t1: f32, c: Vec3) -> (f32, f32, f32, f32) {
    let delta = (c - o).dot(d);
    let scale = (c - o)
        .abs()
        .max_element()
        .max(t0.abs())
        .max(if t1.is_finite() { t1.abs() } else { 0.0 });
    let h = (c - (o + d * delta)).length().max(scale * 1e-6).max(f32::MIN_POSITIVE);
    let theta0 = (t0 - delta).atan2(h);
    let theta1 = (t1 - delta).atan2(h);
    (delta, h, theta0, theta1)
}

fn equiangular_density(t: f32, delta: f32, h: f32, theta0: f32, theta1: f32) -> f32 {
    let x = t - delta;
    let pdf = h / ((theta1 - theta0) * (h * h + x * x));
    if pdf.is_finite() { pdf } else { 0.0 }
}

/// Uniform direction inside the cone around +z given by `one_minus_cos_max` = 1 − cos θmax
/// ∈ [0, 2] (local frame); the same warp as [`uniform_cone`], but the opening is passed as
/// 1 − cos θmax so that tiny cones (a far or tiny sphere: 1 − cos θmax ≈ R²/2d²) keep their
/// size instead of rounding to a single direction. The solid angle is 2π·`one_minus_cos_max`.
pub fn uniform_cone_1mc(u: Vec2, one_minus_cos_max: f32) -> Vec3 {
    let one_minus_cos = u.x * one_minus_cos_max.clamp(0.0, 2.0);
    let cos_theta = 1.0 - one_minus_cos;
    let sin_theta = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let phi = TAU * u.y;
    Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// Point `k` of `n` of a randomly shifted rank-1 lattice in [0, 1)²: (k + ½)/n along x and
/// the golden-ratio sequence along y, both shifted (mod 1) by `shift`. Every point is uniform
/// on its own (so averages over the set are unbiased) while the set covers the square evenly
/// for any `n`; two random numbers drive the whole set.
#[inline]
pub fn shifted_lattice(k: u32, n: u32, shift: Vec2) -> Vec2 {
    const GOLDEN: f32 = 0.618_034;
    let n = n.max(1);
    let x = (k as f32 + 0.5) / n as f32 + shift.x;
    // (k·g) mod 1 in f32 loses digits for large k; the sets here are small (≤ a few hundred).
    let y = (k as f32 * GOLDEN).fract() + shift.y;
    let wrap = |v: f32| {
        let f = v - v.floor();
        f.min(ONE_MINUS_EPSILON)
    };
    Vec2::new(wrap(x), wrap(y))
}

/// Most vertices a [`PiecewiseLinear`] keeps (it lives on the stack, as it will in a GPU
/// kernel's registers).
pub const PIECEWISE_LINEAR_MAX_VERTICES: usize = 64;

/// A piecewise-linear density over `[x0, x1]`: `n` equally spaced vertices with non-negative
/// values, linearly interpolated, normalised. This is the building block of the VRL paper's and
/// the VBL paper's angular PDFs (x is then an angle).
///
/// Robustness: values that are negative, NaN or infinite count as 0; when no value is positive
/// (or fewer than two are given) the density is uniform; `uniform_share` ∈ [0, 1] mixes in that
/// much of the uniform density (a defensive floor: a mixture of a piecewise-linear and a uniform
/// density is again piecewise linear, so this only raises every vertex by a constant). A
/// degenerate interval (x1 ≤ x0, or either end not finite) has nothing to sample:
/// [`sample`](Self::sample) returns `(x0, 0.0)` and [`pdf`](Self::pdf) is 0 everywhere.
#[derive(Clone, Copy, Debug)]
pub struct PiecewiseLinear {
    x0: f32,
    x1: f32,
    n: usize,
    /// Vertex values, scaled so that they integrate to `total` in index units (width 1 per
    /// segment).
    values: [f32; PIECEWISE_LINEAR_MAX_VERTICES],
    /// `cdf[i]`: area (index units) of the segments left of vertex i.
    cdf: [f32; PIECEWISE_LINEAR_MAX_VERTICES],
    total: f32,
}

impl PiecewiseLinear {
    /// Builds the density from the first [`PIECEWISE_LINEAR_MAX_VERTICES`] of `values`.
    pub fn new(x0: f32, x1: f32, values: &[f32], uniform_share: f32) -> Self {
        let mut pl = Self {
            x0,
            x1,
            n: 0,
            values: [0.0; PIECEWISE_LINEAR_MAX_VERTICES],
            cdf: [0.0; PIECEWISE_LINEAR_MAX_VERTICES],
            total: 0.0,
        };
        if !(x0.is_finite() && x1.is_finite() && x1 > x0) {
            return pl;
        }
        let n = values.len().min(PIECEWISE_LINEAR_MAX_VERTICES);
        let clean = |v: f32| if v.is_finite() && v > 0.0 { v } else { 0.0 };
        // Area in index units, accumulated in f64 so huge and tiny values mix safely.
        let mut area = 0.0f64;
        for i in 1..n {
            area += 0.5 * (clean(values[i - 1]) as f64 + clean(values[i]) as f64);
        }
        let share = if uniform_share.is_nan() {
            0.0
        } else {
            uniform_share.clamp(0.0, 1.0)
        };
        if n < 2 || !(area > 0.0) || !area.is_finite() {
            // Nothing to go by: uniform, two vertices of 1.
            pl.n = 2;
            pl.values[0] = 1.0;
            pl.values[1] = 1.0;
            pl.cdf[1] = 1.0;
            pl.total = 1.0;
            return pl;
        }
        // Normalise to unit area, then mix: (1 − share)·v/area + share/(n − 1) per vertex.
        let segments = (n - 1) as f64;
        let floor = share as f64 / segments;
        let scale = (1.0 - share as f64) / area;
        pl.n = n;
        for i in 0..n {
            pl.values[i] = (clean(values[i]) as f64 * scale + floor) as f32;
        }
        let mut c = 0.0f64;
        for i in 1..n {
            c += 0.5 * (pl.values[i - 1] as f64 + pl.values[i] as f64);
            pl.cdf[i] = c as f32;
        }
        pl.total = c as f32;
        pl
    }

    /// Whether there is anything to sample (a proper interval).
    pub fn is_valid(&self) -> bool {
        self.n >= 2 && self.total > 0.0
    }

    fn width(&self) -> f32 {
        (self.x1 - self.x0) / (self.n - 1) as f32
    }

    /// Returns `(x, pdf)`. Never lands in a segment whose two vertices are both 0.
    pub fn sample(&self, u: f32) -> (f32, f32) {
        if !self.is_valid() {
            return (self.x0, 0.0);
        }
        let u = if u >= 0.0 { u.min(ONE_MINUS_EPSILON) } else { 0.0 };
        let a = u * self.total;
        // Last segment whose start is ≤ a and which has area (a linear scan: n is small).
        let mut i = 0;
        for k in 1..self.n - 1 {
            if self.cdf[k] <= a && self.cdf[k + 1] > self.cdf[k] {
                i = k;
            }
        }
        // Skip leading empty segments (a may be 0 while segment 0 has no area).
        while i + 1 < self.n - 1 && !(self.cdf[i + 1] > self.cdf[i]) {
            i += 1;
        }
        let (f0, f1) = (self.values[i], self.values[i + 1]);
        let seg_area = self.cdf[i + 1] - self.cdf[i];
        let area = (a - self.cdf[i]).clamp(0.0, seg_area);
        // Solve f0 s + (f1 − f0) s²/2 = area for s ∈ [0, 1] in the form without cancellation
        // (no division by f1 − f0, which may be 0).
        let disc = (f0 * f0 + 2.0 * (f1 - f0) * area).max(0.0);
        let denom = f0 + disc.sqrt();
        let s = if denom > 0.0 {
            (2.0 * area / denom).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let w = self.width();
        let x = (self.x0 + (i as f32 + s) * w).clamp(self.x0, self.x1);
        let value = f0 + (f1 - f0) * s;
        let pdf = value / (self.total * w);
        (x, if pdf.is_finite() { pdf.max(0.0) } else { 0.0 })
    }

    /// Density at `x` (0 outside `[x0, x1]`).
    pub fn pdf(&self, x: f32) -> f32 {
        if !(self.is_valid() && x >= self.x0 && x <= self.x1) {
            return 0.0;
        }
        let w = self.width();
        let idx = (x - self.x0) / w;
        let i = (idx.floor().max(0.0) as usize).min(self.n - 2);
        let s = (idx - i as f32).clamp(0.0, 1.0);
        let value = self.values[i] + (self.values[i + 1] - self.values[i]) * s;
        let pdf = value / (self.total * w);
        if pdf.is_finite() { pdf.max(0.0) } else { 0.0 }
    }

    pub fn interval(&self) -> (f32, f32) {
        (self.x0, self.x1)
    }
}

/// The angular parametrisation of a segment `o + t·d`, `t ∈ [t0, t1]` (`d` unit), as seen from
/// a point `c`: `t(θ) = delta + h·tan θ`, θ ∈ [θ0, θ1], where `delta` is the closest approach
/// to `c` and `h` its distance (floored at `h_min`, and like [`equiangular`] at a tiny fraction
/// of the scale, so a point on the line does not make the map singular). A density p(θ) in the
/// angle is the density p(θ)·dθ/dt = p(θ)·h / (h² + (t − delta)²) in t: a uniform p(θ) is
/// equiangular sampling, a piecewise-linear one the VRL/VBL papers' angular PDFs.
///
/// `h_min` > 0 makes the map the angle seen from a point `h_min` off the line: the VBL
/// estimators pass the sphere radius R, since a sphere's contribution stops growing once the
/// line comes closer than R (for R → 0 it is the true angle).
#[derive(Clone, Copy, Debug)]
pub struct LineAngles {
    pub delta: f32,
    pub h: f32,
    pub theta0: f32,
    pub theta1: f32,
}

impl LineAngles {
    pub fn new(o: Vec3, d: Vec3, t0: f32, t1: f32, c: Vec3, h_min: f32) -> Self {
        let (delta, h, _, _) = equiangular_frame(o, d, t0, t1, c);
        let h = if h_min > h { h_min } else { h };
        Self {
            delta,
            h,
            theta0: (t0 - delta).atan2(h),
            theta1: (t1 - delta).atan2(h),
        }
    }

    /// The line parameter at angle θ.
    #[inline]
    pub fn t(&self, theta: f32) -> f32 {
        self.delta + self.h * tan(theta)
    }

    /// dθ/dt at parameter `t` (the Jacobian that turns an angular density into one in t).
    #[inline]
    pub fn dtheta_dt(&self, t: f32) -> f32 {
        let x = t - self.delta;
        let j = self.h / (self.h * self.h + x * x);
        if j.is_finite() { j } else { 0.0 }
    }

    /// The angle of parameter `t`.
    #[inline]
    pub fn theta(&self, t: f32) -> f32 {
        (t - self.delta).atan2(self.h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`tan`] (the WGSL twin's polynomial) against f64's tan of the same f32 angle, over
    /// (−π/2, π/2) where the line maps use it: within 3 ulp of the true value everywhere
    /// (measured: 1.3 ulp, printed). Catches a wrong coefficient (the last one 1 % off: about
    /// 1.4·10⁴ ulp), a wrong reduction constant, or the odd octants' −1/r left out.
    #[test]
    fn tan_is_within_a_few_ulp() {
        let mut worst = 0.0f64;
        let n = 200_000;
        for i in 1..n {
            let x = -FRAC_PI_2 + std::f32::consts::PI * i as f32 / n as f32;
            let want = (x as f64).tan();
            let got = tan(x) as f64;
            let ulp = (want as f32).abs() * f32::EPSILON;
            worst = worst.max((got - want).abs() / ulp as f64);
        }
        eprintln!("tan: worst error {worst:.2} ulp");
        assert!(worst < 3.0, "tan off by {worst} ulp");
    }

    fn corner_inputs() -> Vec<Vec2> {
        let vals = [0.0, 1e-7, 0.25, 0.5, ONE_MINUS_EPSILON, 1.0];
        let mut v = Vec::new();
        for &a in &vals {
            for &b in &vals {
                v.push(Vec2::new(a, b));
            }
        }
        v
    }

    #[test]
    fn warps_produce_unit_vectors_at_the_corners_of_the_square() {
        for u in corner_inputs() {
            for (name, w) in [
                ("sphere", uniform_sphere(u)),
                ("cosine", cosine_hemisphere(u)),
                ("cone", uniform_cone(u, 0.3)),
                ("tiny cone", uniform_cone(u, 1.0 - 1e-7)),
                ("full cone", uniform_cone(u, -1.0)),
                ("degenerate cone", uniform_cone(u, 1.0)),
            ] {
                assert!(w.is_finite(), "{name} {u}: {w}");
                assert!((w.length() - 1.0).abs() < 1e-5, "{name} {u}: {w}");
            }
            assert!(cosine_hemisphere(u).z >= 0.0);
            assert!(uniform_cone(u, 0.3).z >= 0.3 - 1e-6);
        }
    }

    #[test]
    fn lattice_points_stay_in_the_square_and_cones_keep_tiny_openings() {
        for n in [1u32, 2, 16, 100] {
            for shift in [Vec2::ZERO, Vec2::splat(ONE_MINUS_EPSILON), Vec2::new(0.3, 0.9)] {
                for k in 0..n {
                    let u = shifted_lattice(k, n, shift);
                    assert!(
                        u.x >= 0.0 && u.x < 1.0 && u.y >= 0.0 && u.y < 1.0,
                        "{k}/{n} {shift}: {u}"
                    );
                }
            }
        }
        // 1 − cos θmax = 1e-12 (a sphere 1e6 radii away) rounds to a point with `uniform_cone`.
        let w = uniform_cone_1mc(Vec2::new(1.0, 0.0), 1e-12);
        let theta = w.truncate().length().atan2(w.z);
        assert!((theta / 2e-12f32.sqrt() - 1.0).abs() < 1e-3, "{theta}");
        assert_eq!(uniform_cone_1mc(Vec2::new(0.7, 0.2), 0.0), Vec3::Z);
        // Beyond a hemisphere up to the whole sphere, unit length throughout.
        for omc in [1.0, 1.5, 2.0, 3.0] {
            for u in corner_inputs() {
                assert!((uniform_cone_1mc(u, omc).length() - 1.0).abs() < 1e-5);
            }
        }
    }

    #[test]
    fn tiny_cone_keeps_its_opening_angle() {
        // cos_max = 1 − 1e-6 ⇒ θmax ≈ 1.414e-3; the edge sample must land on the edge.
        let cos_max = 1.0 - 1e-6;
        let w = uniform_cone(Vec2::new(1.0, 0.0), cos_max);
        let theta = w.truncate().length().atan2(w.z);
        let theta_max = (2.0f64 * (1.0 - cos_max as f64)).sqrt() as f32;
        assert!((theta / theta_max - 1.0).abs() < 1e-3, "{theta} vs {theta_max}");
        assert!(uniform_cone_pdf(cos_max).is_finite());
        assert_eq!(uniform_cone_pdf(1.0), f32::INFINITY);
    }

    #[test]
    fn triangle_barycentrics_stay_inside() {
        for u in corner_inputs() {
            let b = uniform_triangle(u);
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6, "{u} -> {b}");
        }
    }

    #[test]
    fn power_heuristic_is_never_nan() {
        let inf = f32::INFINITY;
        let cases = [
            (0.0, 0.0, 0.0),
            (inf, 0.0, 1.0),
            (inf, inf, 1.0),
            (inf, 3.0, 1.0),
            (3.0, inf, 0.0),
            (0.0, 5.0, 0.0),
            (5.0, 0.0, 1.0),
            (2.0, 2.0, 0.5),
            (1e30, 1e30, 0.5),
            (1e-30, 1e-30, 0.5),
            (f32::NAN, 1.0, 0.0),
            (1.0, f32::NAN, 1.0),
        ];
        for (f, g, want) in cases {
            let w = power_heuristic(f, g);
            assert!((w - want).abs() < 1e-6, "({f}, {g}) -> {w}, want {want}");
        }
        let w = power_heuristic(1.0, 3.0);
        assert!((w - 0.1).abs() < 1e-6);
        assert!((power_heuristic(1.0, 3.0) + power_heuristic(3.0, 1.0) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn distribution_never_picks_zero_weights() {
        let d = Distribution1D::new(&[0.0, 1.0, 0.0, f32::NAN, -2.0, 3.0, 0.0, f32::INFINITY]);
        assert_eq!(d.len(), 8);
        assert_eq!(d.total, 4.0);
        for u in [
            0.0,
            1e-9,
            0.25 - 1e-7,
            0.25,
            0.5,
            ONE_MINUS_EPSILON,
            1.0,
            2.0,
            -1.0,
            f32::NAN,
        ] {
            let (i, p) = d.sample(u);
            assert!(i == 1 || i == 5, "u = {u} picked {i}");
            assert_eq!(p, d.pmf(i));
        }
        assert_eq!(d.pmf(1), 0.25);
        assert_eq!(d.pmf(5), 0.75);
        assert_eq!(d.pmf(0), 0.0);
        assert_eq!(d.pmf(99), 0.0);
        let sum: f32 = (0..d.len()).map(|i| d.pmf(i)).sum();
        assert!((sum - 1.0).abs() < 1e-6);
    }

    #[test]
    fn distribution_with_nothing_to_sample() {
        for w in [&[][..], &[0.0, 0.0][..], &[f32::NAN, -1.0][..]] {
            let d = Distribution1D::new(w);
            assert_eq!(d.total, 0.0);
            assert_eq!(d.len(), w.len());
            assert_eq!(d.sample(0.3), (0, 0.0));
            assert!((0..d.len()).all(|i| d.pmf(i) == 0.0));
        }
    }

    #[test]
    fn distribution_total_is_accumulated_in_double_precision() {
        // An f32 running sum would stall at 1e8 (its ulp there is 8) and drop the ones.
        let mut w = vec![1e8f32];
        w.extend(std::iter::repeat_n(1.0f32, 1000));
        let d = Distribution1D::new(&w);
        assert_eq!(d.total, 100_001_000.0);
        assert_eq!(d.cdf[d.len()], 1.0);
    }
}
