//! Henyey–Greenstein phase function.
//!
//! Numerics: for |g| → 1 the lobe is very narrow (its width is about 1 − |g|), so the textbook
//! formulas cancel catastrophically in f32: both `1 + g² − 2g cos θ` in the evaluation and
//! `1 − cos θ` in the sampling lose all their digits near the peak. Here every quantity near
//! the peak is written as a sum of non-negative terms:
//!
//! * evaluation: `1 + g² − 2g cos θ = (1 − g)² + 2g (1 − cos θ)` for g ≥ 0 (and the mirror form
//!   for g < 0), with `1 − cos θ = |wo + wi|² / 2` formed from the vectors, not from a dot product;
//! * sampling: closed forms for `1 − cos θ` and `1 + cos θ` derived from the inverted CDF
//!   (see [`hg_sample_cos_theta`]); they contain no 1/g, so the same code is exact for g = 0 and
//!   no isotropic special case is needed (and no switch-over discontinuity at small |g|).
use crate::frame::Frame;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, TAU};

/// |g| is clamped to this: at |g| = 1 the lobe is a delta and the density 0/0.
pub const HG_MAX_ABS_G: f32 = 0.999_999;

/// HG phase function. `wo`, `wi` both point away from the scattering point; the scattering
/// angle θ is between the light's travel directions, cos θ = −wo·wi; g > 0 scatters forward.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HenyeyGreenstein {
    pub g: f32,
}

/// Result of sampling a phase function.
#[derive(Clone, Copy, Debug)]
pub struct PhaseSample {
    pub wi: Vec3,
    /// Phase value / pdf (1 for exact importance sampling).
    pub weight: f32,
    pub pdf: f32,
}

/// `g` clamped to the supported open interval (NaN becomes 0, i.e. isotropic).
#[inline]
fn clamp_g(g: f32) -> f32 {
    if g.is_nan() {
        0.0
    } else {
        g.clamp(-HG_MAX_ABS_G, HG_MAX_ABS_G)
    }
}

/// HG density as a function of `one_minus_cos` = 1 − cos θ and `one_plus_cos` = 1 + cos θ
/// (both ≥ 0; only the one on the side of the peak needs to be accurate).
#[inline]
fn hg_density(g: f32, one_minus_cos: f32, one_plus_cos: f32) -> f32 {
    let g = clamp_g(g);
    // 1 + g² − 2g cos θ without cancellation: both terms are non-negative.
    let denom = if g >= 0.0 {
        (1.0 - g) * (1.0 - g) + 2.0 * g * one_minus_cos.max(0.0)
    } else {
        (1.0 + g) * (1.0 + g) - 2.0 * g * one_plus_cos.max(0.0)
    };
    // (1 − g²) as a product: exact factors, no cancellation for |g| → 1.
    (1.0 - g) * (1.0 + g) * (0.25 * FRAC_1_PI) / (denom * denom.sqrt())
}

/// Inverts the HG CDF in cos θ for the uniform number `u`, returning (1 − cos θ, 1 + cos θ).
///
/// With D = 1 − g + 2gu the classic inversion is cos θ = (1 + g² − ((1 − g²)/D)²) / (2g);
/// simplifying exactly gives
///   1 − cos θ = 2 (1 − g)² (1 − u) (1 + g u) / D²,
///   1 + cos θ = 2 (1 + g)² u (1 − g + g u) / D²,
/// and every factor is computed as a sum of non-negative terms. u = 0 gives backscatter
/// (cos θ = −1), u → 1 forward scatter (cos θ = 1), for every g.
pub fn hg_sample_cos_theta(g: f32, u: f32) -> (f32, f32) {
    let g = clamp_g(g);
    let u = u.clamp(0.0, 1.0);
    let v = 1.0 - u; // exact for u in [0.5, 1]; for smaller u it is ≥ 0.5 anyway
    let (d, one_plus_gu, one_minus_g_plus_gu) = if g >= 0.0 {
        ((1.0 - g) + 2.0 * g * u, 1.0 + g * u, (1.0 - g) + g * u)
    } else {
        ((1.0 + g) - 2.0 * g * v, (1.0 + g) - g * v, 1.0 - g * v)
    };
    let d2 = d * d;
    let one_minus_cos = 2.0 * (1.0 - g) * (1.0 - g) * v * one_plus_gu / d2;
    let one_plus_cos = 2.0 * (1.0 + g) * (1.0 + g) * u * one_minus_g_plus_gu / d2;
    (one_minus_cos.clamp(0.0, 2.0), one_plus_cos.clamp(0.0, 2.0))
}

impl HenyeyGreenstein {
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        // cos θ = −wo·wi, so 1 − cos θ = |wo + wi|²/2 and 1 + cos θ = |wo − wi|²/2 (unit
        // vectors): accurate even when wi ≈ ∓wo, where the dot product is not.
        let one_minus_cos = 0.5 * (wo + wi).length_squared();
        let one_plus_cos = 0.5 * (wo - wi).length_squared();
        hg_density(self.g, one_minus_cos, one_plus_cos)
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval(wo, wi)
    }

    #[inline]
    pub fn sample(&self, wo: Vec3, u: Vec2) -> PhaseSample {
        let (one_minus_cos, one_plus_cos) = hg_sample_cos_theta(self.g, u.x);
        // Take cos θ from whichever of the two is small (and therefore accurate).
        let cos_theta = if one_minus_cos <= one_plus_cos {
            1.0 - one_minus_cos
        } else {
            one_plus_cos - 1.0
        };
        let sin_theta = (one_minus_cos * one_plus_cos).max(0.0).sqrt();
        let phi = TAU * u.y;
        // θ is measured from the forward direction of the light's travel, −wo.
        let frame = Frame::from_normal(-wo);
        let local = Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta);
        let wi = frame.to_world(local).normalize();
        // pdf from the final vector (not from cos θ) so it equals `pdf(wo, wi)` bit for bit,
        // which MIS relies on.
        PhaseSample {
            wi,
            weight: 1.0,
            pdf: self.pdf(wo, wi),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    const GS: [f32; 12] = [
        -0.99999, -0.999, -0.9, -0.3, -1e-7, 0.0, 1e-7, 1e-3, 0.5, 0.95, 0.999, 0.99999,
    ];

    fn wo() -> Vec3 {
        Vec3::new(0.3, -0.5, 0.8).normalize()
    }

    #[test]
    fn samples_are_finite_unit_and_positive_for_extreme_g() {
        let us = [0.0, 1e-7, 1e-3, 0.25, 0.5, 0.75, 0.999, 1.0 - 6e-8, 1.0];
        for g in GS.into_iter().chain([1.0, -1.0, 2.0, f32::NAN]) {
            let hg = HenyeyGreenstein { g };
            for &ux in &us {
                for uy in [0.0, 0.3, 0.99] {
                    let s = hg.sample(wo(), Vec2::new(ux, uy));
                    assert!(s.wi.is_finite() && (s.wi.length() - 1.0).abs() < 1e-5, "g={g} u={ux}");
                    assert!(s.pdf.is_finite() && s.pdf > 0.0, "g={g} u={ux}: pdf {}", s.pdf);
                    assert_eq!(s.weight, 1.0);
                    assert_eq!(s.pdf, hg.pdf(wo(), s.wi));
                }
            }
            // Evaluation in the exact peak and anti-peak directions.
            for wi in [wo(), -wo(), Vec3::Z, -Vec3::X] {
                let p = hg.eval(wo(), wi);
                assert!(p.is_finite() && p > 0.0, "g={g} wi={wi}: {p}");
            }
        }
    }

    #[test]
    fn cos_theta_inversion_hits_both_ends() {
        for g in GS {
            let (m, p) = hg_sample_cos_theta(g, 0.0);
            assert!((m - 2.0).abs() < 1e-6 && p == 0.0, "g={g} u=0 -> ({m}, {p})");
            let (m, p) = hg_sample_cos_theta(g, 1.0);
            assert!(m == 0.0 && (p - 2.0).abs() < 1e-6, "g={g} u=1 -> ({m}, {p})");
            for u in [0.1, 0.5, 0.9] {
                let (m, p) = hg_sample_cos_theta(g, u);
                assert!((m + p - 2.0).abs() < 1e-5, "g={g} u={u}: {m} + {p}");
            }
        }
    }

    #[test]
    fn sampled_cos_theta_matches_the_f64_inverse_cdf() {
        // Reference: the textbook inversion in f64, where cancellation is harmless for these g.
        for g in [-0.9f64, -0.3, 0.5, 0.95, 0.999] {
            for u in [0.01f64, 0.2, 0.5, 0.8, 0.99] {
                let d = 1.0 - g + 2.0 * g * u;
                let s = (1.0 - g * g) / d;
                let cos_ref = (1.0 + g * g - s * s) / (2.0 * g);
                let (m, p) = hg_sample_cos_theta(g as f32, u as f32);
                let (m_ref, p_ref) = (1.0 - cos_ref, 1.0 + cos_ref);
                assert!(
                    ((m as f64) - m_ref).abs() <= 1e-5 * m_ref + 1e-7,
                    "g={g} u={u}: {m} vs {m_ref}"
                );
                assert!(
                    ((p as f64) - p_ref).abs() <= 1e-5 * p_ref + 1e-7,
                    "g={g} u={u}: {p} vs {p_ref}"
                );
            }
        }
    }

    #[test]
    fn eval_matches_the_textbook_formula_and_scatters_forward_for_positive_g() {
        for g in [-0.9f32, -0.3, 0.0, 0.5, 0.95] {
            let hg = HenyeyGreenstein { g };
            for wi in [Vec3::Z, -Vec3::Z, Vec3::X, Vec3::new(0.2, 0.3, -0.9).normalize()] {
                let cos = -wo().dot(wi) as f64;
                let g = g as f64;
                let want = (1.0 - g * g) / (4.0 * std::f64::consts::PI * (1.0 + g * g - 2.0 * g * cos).powf(1.5));
                let got = hg.eval(wo(), wi) as f64;
                assert!((got / want - 1.0).abs() < 1e-4, "g={g} wi={wi}: {got} vs {want}");
            }
        }
        let hg = HenyeyGreenstein { g: 0.8 };
        assert!(hg.eval(wo(), -wo()) > hg.eval(wo(), wo()));
        // Isotropic value for vanishing g.
        for g in [0.0, 1e-7, -1e-7] {
            let p = HenyeyGreenstein { g }.eval(wo(), Vec3::Z);
            assert!((p * 4.0 * PI - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn forward_peak_value_is_accurate_for_g_near_one() {
        // p(cos θ = 1) = (1 + g) / (4π (1 − g)²): the naive formula returns inf or garbage in f32.
        for g in [0.999f32, 0.99999] {
            let gd = g as f64;
            let want = (1.0 + gd) / (4.0 * std::f64::consts::PI * (1.0 - gd).powi(2));
            let got = HenyeyGreenstein { g }.eval(wo(), -wo()) as f64;
            assert!((got / want - 1.0).abs() < 1e-4, "g={g}: {got} vs {want}");
            let got = HenyeyGreenstein { g: -g }.eval(wo(), wo()) as f64;
            assert!((got / want - 1.0).abs() < 1e-4, "g={}: {got} vs {want}", -g);
        }
    }
}
