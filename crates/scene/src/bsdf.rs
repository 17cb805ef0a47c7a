//! Surface scattering: Lambert, energy-conserving modified Phong, perfect mirror, smooth dielectric.
//!
//! All functions work in the local shading frame (normal = +z). Opaque materials are two-sided:
//! they reflect on whichever side `wo` lies. `eval` returns the BSDF value f (without the cosine);
//! `pdf` is a solid-angle density; delta lobes (mirror, glass) have `eval`/`pdf` zero and are
//! only reachable through `sample`.
use crate::frame::Frame;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::{Rgb, luminance_mean};
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, TAU};

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    /// f = albedo / π.
    Lambert { albedo: Rgb },
    /// Modified Phong (Lafortune & Willems 1994): f = kd/π + ks (n+2)/(2π) cos^n α,
    /// α the angle between `wi` and the mirror direction of `wo`. Energy conserving when kd + ks ≤ 1.
    Phong { diffuse: Rgb, specular: Rgb, exponent: f32 },
    /// Perfect specular reflection scaled by `reflectance`.
    Mirror { reflectance: Rgb },
    /// Smooth dielectric interface with relative index `ior` (inside / outside), exact Fresnel.
    /// `tint` scales both reflection and transmission (1 for clear glass).
    Glass { ior: f32, tint: Rgb },
}

/// Result of sampling a BSDF.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Sampled direction (local frame, unit).
    pub wi: Vec3,
    /// f · |cos θi| / pdf (for delta lobes: the lobe's weight divided by its selection probability).
    pub weight: Rgb,
    /// Solid-angle pdf of `wi` (for delta lobes: the discrete probability of the chosen lobe).
    pub pdf: f32,
    pub is_delta: bool,
}

/// A surface material: how it scatters (or `None` for an invisible, index-matched medium
/// boundary) and what it emits. With a base-colour texture, `bsdf` holds the untextured BSDF
/// (the glTF factor alone); [`crate::Scene::bsdf_at`] gives the BSDF at a hit.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub bsdf: Option<Bsdf>,
    /// Emitted radiance (glTF emissiveFactor × KHR_materials_emissive_strength).
    pub emission: Rgb,
    /// glTF `doubleSided`: emission leaves both faces (otherwise only the front face).
    pub double_sided: bool,
    /// Index into [`crate::Scene::textures`]: the base-colour texture that multiplies the
    /// Lambert albedo or the Phong diffuse colour (see [`crate::Scene::bsdf_at`]). Always
    /// `None` for other kinds.
    pub base_color_texture: Option<u32>,
}

impl Material {
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

impl Bsdf {
    /// This BSDF with its base colour (Lambert albedo, Phong diffuse) multiplied by `c`; mirror
    /// and glass are returned unchanged. Used to apply a base-colour texture.
    #[inline]
    pub fn with_base_color_scaled(self, c: Rgb) -> Bsdf {
        match self {
            Bsdf::Lambert { albedo } => Bsdf::Lambert { albedo: albedo * c },
            Bsdf::Phong {
                diffuse,
                specular,
                exponent,
            } => Bsdf::Phong {
                diffuse: diffuse * c,
                specular,
                exponent,
            },
            other => other,
        }
    }

    /// f(wo, wi) without the cosine; zero for delta lobes.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        match self {
            Bsdf::Lambert { albedo } => {
                if same_side(wo, wi) {
                    *albedo * FRAC_1_PI
                } else {
                    Rgb::ZERO
                }
            }
            Bsdf::Phong {
                diffuse,
                specular,
                exponent,
            } => {
                if !same_side(wo, wi) {
                    return Rgb::ZERO;
                }
                let (wo, wi) = (upper(wo), upper(wi));
                phong_f(*diffuse, *specular, phong_exponent(*exponent), wo, wi)
            }
            Bsdf::Mirror { .. } | Bsdf::Glass { .. } => Rgb::ZERO,
        }
    }

    /// Solid-angle pdf of `sample` producing `wi`; zero for delta lobes.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Bsdf::Lambert { .. } => {
                if same_side(wo, wi) {
                    cosine_hemisphere_pdf(wi.z.abs())
                } else {
                    0.0
                }
            }
            Bsdf::Phong {
                diffuse,
                specular,
                exponent,
            } => {
                if !same_side(wo, wi) {
                    return 0.0;
                }
                let p_spec = phong_specular_probability(*diffuse, *specular);
                phong_pdf(p_spec, phong_exponent(*exponent), upper(wo), upper(wi))
            }
            Bsdf::Mirror { .. } | Bsdf::Glass { .. } => 0.0,
        }
    }

    /// Samples an incident direction; `u` for the direction, `u_lobe` to choose a lobe.
    /// Radiance transport (paths started at the camera); see [`Bsdf::sample_mode`].
    #[inline]
    pub fn sample(&self, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        self.sample_mode(wo, u, u_lobe, TransportMode::Radiance)
    }

    /// [`Bsdf::sample`] for either transport direction. Only refraction differs between the
    /// two modes (see [`TransportMode`]); every other lobe is symmetric.
    ///
    /// Returns `None` when nothing is scattered: a black material, a grazing `wo`
    /// (`wo.z == 0`) on an opaque material, or a sampled direction on the wrong side.
    pub fn sample_mode(&self, wo: Vec3, u: Vec2, u_lobe: f32, mode: TransportMode) -> Option<BsdfSample> {
        match self {
            Bsdf::Lambert { albedo } => {
                if wo.z == 0.0 || albedo.max_element() <= 0.0 {
                    return None;
                }
                let wi = cosine_hemisphere(u);
                let pdf = cosine_hemisphere_pdf(wi.z);
                if !(pdf > 0.0) {
                    return None;
                }
                // f·cos/pdf = (albedo/π)·cos / (cos/π).
                Some(BsdfSample {
                    wi: to_side_of(wi, wo),
                    weight: *albedo,
                    pdf,
                    is_delta: false,
                })
            }
            Bsdf::Phong {
                diffuse,
                specular,
                exponent,
            } => {
                if wo.z == 0.0 {
                    return None;
                }
                let n = phong_exponent(*exponent);
                let p_spec = phong_specular_probability(*diffuse, *specular);
                let (kd, ks) = (diffuse.max(Rgb::ZERO), specular.max(Rgb::ZERO));
                if kd.max_element() <= 0.0 && ks.max_element() <= 0.0 {
                    return None;
                }
                let wo_up = upper(wo);
                let wi = if u_lobe < p_spec {
                    sample_phong_lobe(n, mirror(wo_up), u)
                } else {
                    cosine_hemisphere(u)
                };
                // Specular samples below the horizon are dropped, so the density of the
                // returned directions is exactly the mixture `phong_pdf` on the upper side.
                if !(wi.z > 0.0) {
                    return None;
                }
                let pdf = phong_pdf(p_spec, n, wo_up, wi);
                if !(pdf > 0.0) {
                    return None;
                }
                let weight = phong_f(kd, ks, n, wo_up, wi) * (wi.z / pdf);
                Some(BsdfSample {
                    wi: to_side_of(wi, wo),
                    weight,
                    pdf,
                    is_delta: false,
                })
            }
            Bsdf::Mirror { reflectance } => Some(BsdfSample {
                wi: mirror(wo),
                weight: *reflectance,
                pdf: 1.0,
                is_delta: true,
            }),
            Bsdf::Glass { ior, tint } => Some(sample_glass(*ior, *tint, wo, u_lobe, mode)),
        }
    }

    /// True when every lobe is a delta (mirror, glass): no light sampling is useful.
    pub fn is_delta(&self) -> bool {
        matches!(self, Bsdf::Mirror { .. } | Bsdf::Glass { .. })
    }
}

/// What a path carries, which decides how refraction scales it.
///
/// Radiance is not conserved across an interface between indices n₁ and n₂: L/n² is (Veach's
/// thesis §5.2, "basic radiance"). Light crossing from the side of `wi` (index n_i) to the
/// side of `wo` (index n_o) therefore arrives with radiance scaled by (n_o/n_i)² on top of the
/// Fresnel transmittance, and a camera path must multiply by exactly that. Flux (what photons
/// and light-tracing particles carry, and what importance transports) is conserved, so the
/// adjoint direction gets no such factor. This is pbrt-v4's convention (`TransportMode`,
/// `DielectricBxDF::Sample_f`: `ft /= Sqr(etap)` in radiance mode only).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportMode {
    /// Camera paths: `wo` points to the camera, the path gathers radiance arriving along `wi`.
    Radiance,
    /// Light paths / photons / importance: `wo` points back to the light, `wi` is where the
    /// particle goes next.
    Importance,
}

/// Unpolarized Fresnel reflectance of a smooth dielectric interface.
///
/// `cos_theta_i` ≥ 0 is the cosine of the incident angle, `eta` = n_t / n_i the index on the
/// far side over the index on the incident side. Returns 1 under total internal reflection
/// and at grazing incidence; never NaN for `eta` > 0.
pub fn fresnel_dielectric(cos_theta_i: f32, eta: f32) -> f32 {
    fresnel_and_cos_t(cos_theta_i, eta).0
}

/// Fresnel reflectance and the cosine of the transmitted direction (0 under TIR).
fn fresnel_and_cos_t(cos_i: f32, eta: f32) -> (f32, f32) {
    let cos_i = cos_i.clamp(0.0, 1.0);
    // Snell: sin²θt = sin²θi / η²; sin²θi as (1 − c)(1 + c) keeps digits near normal incidence.
    let sin2_t = (1.0 - cos_i) * (1.0 + cos_i) / (eta * eta);
    // `>=` also catches η = 1 at grazing, where both formulas below would be 0/0.
    if !(sin2_t < 1.0) {
        return (1.0, 0.0);
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    (0.5 * (r_parl * r_parl + r_perp * r_perp).min(2.0), cos_t)
}

/// Smooth dielectric: reflect with probability F, refract otherwise; both are delta lobes, so
/// the weights are the lobe values divided by their selection probabilities.
fn sample_glass(ior: f32, tint: Rgb, wo: Vec3, u_lobe: f32, mode: TransportMode) -> BsdfSample {
    // A non-positive or NaN index would make Snell's law meaningless: treat it as index-matched.
    let ior = if ior > 0.0 && ior.is_finite() { ior } else { 1.0 };
    // The normal points outside; a grazing wo (z = 0) counts as outside.
    let outside = wo.z >= 0.0;
    // η = index on wi's (transmitted) side / index on wo's side.
    let eta = if outside { ior } else { 1.0 / ior };
    let (f, cos_t) = fresnel_and_cos_t(wo.z.abs(), eta);
    if f >= 1.0 || u_lobe < f {
        return BsdfSample {
            wi: mirror(wo),
            weight: tint,
            pdf: f,
            is_delta: true,
        };
    }
    // Refraction: the tangential part shrinks by 1/η (Snell), the normal part flips side.
    let wi = Vec3::new(-wo.x / eta, -wo.y / eta, if outside { -cos_t } else { cos_t });
    let weight = match mode {
        TransportMode::Radiance => tint / (eta * eta),
        TransportMode::Importance => tint,
    };
    BsdfSample {
        wi: wi.normalize(),
        weight,
        pdf: 1.0 - f,
        is_delta: true,
    }
}

/// True when both directions are strictly on the same side of the surface (a sign test, not
/// a product, so tiny z components cannot underflow to "grazing").
#[inline]
fn same_side(a: Vec3, b: Vec3) -> bool {
    (a.z > 0.0 && b.z > 0.0) || (a.z < 0.0 && b.z < 0.0)
}

/// `w` mirrored into the upper hemisphere: two-sided materials work in the flipped frame.
#[inline]
fn upper(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, w.z.abs())
}

/// `w` (sampled in the upper hemisphere) moved to the side of `wo`.
#[inline]
fn to_side_of(w: Vec3, wo: Vec3) -> Vec3 {
    if wo.z < 0.0 { Vec3::new(w.x, w.y, -w.z) } else { w }
}

/// Mirror reflection about the normal (+z).
#[inline]
fn mirror(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

/// Sanitized Phong exponent: NaN → 0, clamped to [0, 1e7] (beyond that the lobe is a mirror
/// in f32 anyway, and an infinite exponent would make 0·∞ = NaN).
#[inline]
fn phong_exponent(n: f32) -> f32 {
    if n.is_nan() { 0.0 } else { n.clamp(0.0, 1e7) }
}

/// Probability of sampling the specular lobe: mean(ks) / (mean(kd) + mean(ks)).
#[inline]
fn phong_specular_probability(kd: Rgb, ks: Rgb) -> f32 {
    let d = luminance_mean(kd.max(Rgb::ZERO));
    let s = luminance_mean(ks.max(Rgb::ZERO));
    if d + s > 0.0 { s / (d + s) } else { 0.0 }
}

/// max(cos α, 0)^n for `r` the mirror direction, computed as exp(n ln(1 − x)) with
/// x = 1 − cos α = |wi − r|²/2: no cancellation for narrow lobes (1 − cos α ≈ 1e-5 at
/// n = 1e5, below the resolution of an f32 dot product near 1) and no overflow.
#[inline]
fn phong_lobe(n: f32, r: Vec3, wi: Vec3) -> f32 {
    let x = 0.5 * (wi - r).length_squared();
    if !(x < 1.0) {
        return 0.0;
    }
    (n * (-x).ln_1p()).exp()
}

/// Modified Phong f for `wo`, `wi` both in the upper hemisphere.
#[inline]
fn phong_f(kd: Rgb, ks: Rgb, n: f32, wo: Vec3, wi: Vec3) -> Rgb {
    let lobe = phong_lobe(n, mirror(wo), wi);
    kd.max(Rgb::ZERO) * FRAC_1_PI + ks.max(Rgb::ZERO) * ((n + 2.0) * 0.5 * FRAC_1_PI * lobe)
}

/// Density of the directions `sample` returns, for `wo`, `wi` both in the upper hemisphere:
/// (1 − p_s)·cos θi/π + p_s·(n + 1)/(2π)·cos^n α.
#[inline]
fn phong_pdf(p_spec: f32, n: f32, wo: Vec3, wi: Vec3) -> f32 {
    let diffuse = if p_spec < 1.0 {
        (1.0 - p_spec) * cosine_hemisphere_pdf(wi.z)
    } else {
        0.0
    };
    let specular = if p_spec > 0.0 {
        p_spec * (n + 1.0) * 0.5 * FRAC_1_PI * phong_lobe(n, mirror(wo), wi)
    } else {
        0.0
    };
    diffuse + specular
}

/// Direction with density (n + 1)/(2π) cos^n α around `r`.
fn sample_phong_lobe(n: f32, r: Vec3, u: Vec2) -> Vec3 {
    // cos α = ξ^(1/(n+1)) with ξ = 1 − u ∈ (0, 1]; 1 − cos α via expm1 keeps the digits that
    // ξ.powf(...) would round away for large n.
    let ln_cos = (1.0 - u.x).max(f32::MIN_POSITIVE).ln() / (n + 1.0);
    let one_minus_cos = -ln_cos.exp_m1();
    let cos_alpha = ln_cos.exp();
    let sin_alpha = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let phi = TAU * u.y;
    let local = Vec3::new(sin_alpha * phi.cos(), sin_alpha * phi.sin(), cos_alpha);
    Frame::from_normal(r).to_world(local).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(x: f32, y: f32, z: f32) -> Vec3 {
        Vec3::new(x, y, z).normalize()
    }

    /// Directions including grazing ones, exactly tangent ones and both sides.
    fn awkward_dirs() -> Vec<Vec3> {
        vec![
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            dir(1.0, 0.0, 1e-7),
            dir(0.3, -0.8, 1e-4),
            dir(0.3, -0.8, -1e-4),
            dir(0.2, 0.3, 0.9),
            dir(-0.5, 0.1, -0.6),
            Vec3::new(0.0, 0.0, 1.0 - 1e-7),
        ]
    }

    fn materials() -> Vec<Bsdf> {
        let c = Rgb::new(0.8, 0.5, 0.2);
        let mut v = vec![
            Bsdf::Lambert { albedo: c },
            Bsdf::Lambert { albedo: Rgb::ZERO },
            Bsdf::Mirror { reflectance: c },
            Bsdf::Glass {
                ior: 1.5,
                tint: Rgb::ONE,
            },
            Bsdf::Glass {
                ior: 1.0,
                tint: Rgb::ONE,
            },
            Bsdf::Glass { ior: 0.6, tint: c },
        ];
        for n in [0.0, 1.0, 20.0, 1e3, 1e5, 1e7, f32::INFINITY, f32::NAN] {
            v.push(Bsdf::Phong {
                diffuse: c * 0.3,
                specular: c * 0.6,
                exponent: n,
            });
            v.push(Bsdf::Phong {
                diffuse: Rgb::ZERO,
                specular: c,
                exponent: n,
            });
        }
        v.push(Bsdf::Phong {
            diffuse: Rgb::ZERO,
            specular: Rgb::ZERO,
            exponent: 10.0,
        });
        v
    }

    #[test]
    fn nothing_is_nan_for_awkward_directions_and_parameters() {
        let us = [0.0, 1e-7, 0.3, 0.7, 1.0 - 6e-8];
        for m in materials() {
            for &wo in &awkward_dirs() {
                for &wi in &awkward_dirs() {
                    let f = m.eval(wo, wi);
                    let p = m.pdf(wo, wi);
                    assert!(f.is_finite() && f.min_element() >= 0.0, "{m:?} {wo} {wi}: f = {f}");
                    assert!(p.is_finite() && p >= 0.0, "{m:?} {wo} {wi}: pdf = {p}");
                }
                for &a in &us {
                    for &b in &us {
                        for &l in &us {
                            let Some(s) = m.sample(wo, Vec2::new(a, b), l) else {
                                continue;
                            };
                            let ok = s.wi.is_finite()
                                && (s.wi.length() - 1.0).abs() < 1e-5
                                && s.weight.is_finite()
                                && s.weight.min_element() >= 0.0
                                && s.pdf.is_finite()
                                && s.pdf > 0.0;
                            assert!(ok, "{m:?} wo={wo} u=({a},{b},{l}): {s:?}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn opaque_materials_are_two_sided_and_never_transmit() {
        let c = Rgb::splat(0.5);
        for m in [
            Bsdf::Lambert { albedo: c },
            Bsdf::Phong {
                diffuse: c * 0.5,
                specular: c,
                exponent: 30.0,
            },
        ] {
            let (wo, wi) = (dir(0.3, 0.2, 0.8), dir(-0.2, -0.1, 0.9));
            let flip = |w: Vec3| Vec3::new(w.x, w.y, -w.z);
            assert_eq!(m.eval(wo, wi), m.eval(flip(wo), flip(wi)));
            assert_eq!(m.pdf(wo, wi), m.pdf(flip(wo), flip(wi)));
            assert_eq!(m.eval(wo, flip(wi)), Rgb::ZERO);
            assert_eq!(m.pdf(wo, flip(wi)), 0.0);
            for k in 0..64 {
                let u = Vec2::new((k as f32 + 0.5) / 64.0, (k * 37 % 64) as f32 / 64.0);
                for wo in [wo, flip(wo)] {
                    if let Some(s) = m.sample(wo, u, (k * 13 % 64) as f32 / 64.0) {
                        assert!(s.wi.z * wo.z > 0.0, "{m:?}: {wo} -> {}", s.wi);
                    }
                }
            }
        }
    }

    #[test]
    fn lambert_and_phong_are_reciprocal() {
        let dirs = [dir(0.3, 0.2, 0.8), dir(-0.7, 0.1, 0.3), dir(0.0, 0.9, 0.05), Vec3::Z];
        for m in [
            Bsdf::Lambert {
                albedo: Rgb::new(0.1, 0.5, 0.9),
            },
            Bsdf::Phong {
                diffuse: Rgb::splat(0.2),
                specular: Rgb::new(0.7, 0.5, 0.3),
                exponent: 3.0,
            },
            Bsdf::Phong {
                diffuse: Rgb::ZERO,
                specular: Rgb::ONE,
                exponent: 150.0,
            },
        ] {
            for &a in &dirs {
                for &b in &dirs {
                    let (fab, fba) = (m.eval(a, b), m.eval(b, a));
                    assert!(
                        (fab - fba).abs().max_element() <= 1e-5 * fab.max_element(),
                        "{m:?} {a} {b}"
                    );
                }
            }
        }
    }

    #[test]
    fn phong_peak_value_for_huge_exponents() {
        // In the mirror direction cos α = 1, so f = kd/π + ks (n+2)/(2π) exactly.
        let wo = dir(0.4, -0.3, 0.5);
        for n in [1.0f32, 100.0, 1e4, 1e5] {
            let m = Bsdf::Phong {
                diffuse: Rgb::ZERO,
                specular: Rgb::ONE,
                exponent: n,
            };
            let f = m.eval(wo, mirror(wo)).x;
            let want = (n + 2.0) / (2.0 * std::f32::consts::PI);
            assert!((f / want - 1.0).abs() < 1e-4, "n={n}: {f} vs {want}");
            // Samples of a narrow lobe stay next to the mirror direction and keep a finite weight.
            let s = m.sample(wo, Vec2::new(0.5, 0.25), 0.5).unwrap();
            let alpha = (s.wi - mirror(wo)).length();
            // Chord length |wi − r| = √(2(1 − cos α)) with cos α = ξ^(1/(n+1)), ξ = 1/2.
            let width = (2.0 * (1.0 - 0.5f64.powf(1.0 / (n as f64 + 1.0)))).sqrt() as f32;
            assert!((alpha / width - 1.0).abs() < 1e-2, "n={n}: α = {alpha}, want {width}");
            assert!((s.pdf / m.pdf(wo, s.wi) - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn fresnel_at_normal_incidence_and_beyond_the_critical_angle() {
        for eta in [1.0f32, 1.33, 1.5, 2.4, 1.0 / 1.5] {
            let want = ((eta - 1.0) / (eta + 1.0)).powi(2);
            assert!((fresnel_dielectric(1.0, eta) - want).abs() < 1e-6, "η = {eta}");
        }
        // Inside glass (η = 1/1.5) the critical angle is asin(1/1.5) ≈ 41.8°.
        let eta = 1.0 / 1.5;
        let crit = (1.0f32 / 1.5).asin();
        assert_eq!(fresnel_dielectric((crit + 0.01).cos(), eta), 1.0);
        assert!(fresnel_dielectric((crit - 0.01).cos(), eta) < 1.0);
        assert_eq!(fresnel_dielectric(0.0, 1.5), 1.0);
        assert_eq!(fresnel_dielectric(0.0, 1.0), 1.0);
        // Brewster's angle: the parallel component vanishes, F = r_perp²/2.
        let tb = 1.5f32.atan();
        let f = fresnel_dielectric(tb.cos(), 1.5);
        let tt = std::f32::consts::FRAC_PI_2 - tb;
        let r_perp = (tb - tt).sin() / (tb + tt).sin();
        assert!((f - 0.5 * r_perp * r_perp).abs() < 1e-5);
    }

    #[test]
    fn glass_total_internal_reflection_always_reflects() {
        let glass = Bsdf::Glass {
            ior: 1.5,
            tint: Rgb::ONE,
        };
        let wo = dir(0.9, 0.0, -0.3); // inside, beyond the critical angle
        for u_lobe in [0.0, 0.5, 1.0 - 6e-8, 1.0] {
            let s = glass.sample(wo, Vec2::ZERO, u_lobe).unwrap();
            assert_eq!(s.wi, mirror(wo));
            assert_eq!((s.pdf, s.weight, s.is_delta), (1.0, Rgb::ONE, true));
        }
    }

    #[test]
    fn glass_refraction_scales_radiance_only_in_radiance_mode() {
        let tint = Rgb::new(1.0, 0.9, 0.8);
        let glass = Bsdf::Glass { ior: 1.5, tint };
        // Camera outside looking in: η = 1.5, radiance from inside is divided by 1.5².
        let s = glass.sample(dir(0.2, 0.1, 0.9), Vec2::ZERO, 0.99).unwrap();
        assert!(s.wi.z < 0.0);
        assert!((s.weight - tint / 2.25).abs().max_element() < 1e-6);
        // Camera inside looking out: η = 1/1.5, radiance from outside is multiplied by 1.5².
        let s = glass.sample(dir(0.2, 0.1, -0.9), Vec2::ZERO, 0.99).unwrap();
        assert!(s.wi.z > 0.0);
        assert!((s.weight - tint * 2.25).abs().max_element() < 1e-5);
        // Photons carry flux: no scaling either way.
        for wo in [dir(0.2, 0.1, 0.9), dir(0.2, 0.1, -0.9)] {
            let s = glass
                .sample_mode(wo, Vec2::ZERO, 0.99, TransportMode::Importance)
                .unwrap();
            assert!(s.wi.z * wo.z < 0.0);
            assert_eq!(s.weight, tint);
        }
    }

    #[test]
    fn glass_handles_exactly_grazing_and_normal_directions() {
        for ior in [1.5, 1.0, 0.7] {
            let glass = Bsdf::Glass { ior, tint: Rgb::ONE };
            for wo in [Vec3::X, dir(1.0, 1.0, 0.0)] {
                let s = glass.sample(wo, Vec2::ZERO, 0.5).unwrap();
                assert!(s.wi.is_finite() && s.weight.is_finite() && s.pdf == 1.0, "{s:?}");
            }
            // Normal incidence: refraction goes straight through.
            let s = glass.sample(Vec3::Z, Vec2::ZERO, 0.999).unwrap();
            assert_eq!(s.wi, -Vec3::Z);
            let r = ((ior - 1.0) / (ior + 1.0)).powi(2);
            assert!((s.pdf - (1.0 - r)).abs() < 1e-6);
        }
    }

    #[test]
    fn mirror_reflects_about_the_normal() {
        let m = Bsdf::Mirror {
            reflectance: Rgb::splat(0.9),
        };
        for wo in awkward_dirs() {
            let s = m.sample(wo, Vec2::new(0.3, 0.3), 0.3).unwrap();
            assert_eq!(s.wi, Vec3::new(-wo.x, -wo.y, wo.z));
            assert_eq!((s.weight, s.pdf, s.is_delta), (Rgb::splat(0.9), 1.0, true));
            assert_eq!(m.eval(wo, s.wi), Rgb::ZERO);
            assert_eq!(m.pdf(wo, s.wi), 0.0);
        }
        assert!(m.is_delta());
    }
}
