//! Surface scattering: Lambert, energy-conserving modified Phong, perfect mirror, smooth dielectric.
//!
//! All functions work in the local shading frame (normal = +z). Opaque materials are two-sided:
//! they reflect on whichever side `wo` lies. `eval` returns the BSDF value f (without the cosine);
//! `pdf` is a solid-angle density; delta lobes (mirror, glass) have `eval`/`pdf` zero and are
//! only reachable through `sample`.
use crate::Rgb;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug, PartialEq)]
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
/// boundary) and what it emits.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub bsdf: Option<Bsdf>,
    /// Emitted radiance (glTF emissiveFactor × KHR_materials_emissive_strength).
    pub emission: Rgb,
    /// glTF `doubleSided`: emission leaves both faces (otherwise only the front face).
    pub double_sided: bool,
}

impl Material {
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

impl Bsdf {
    /// f(wo, wi) without the cosine; zero for delta lobes. (Stub: being implemented.)
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb { todo!("{wo}{wi}") }
    /// Solid-angle pdf of `sample` producing `wi`; zero for delta lobes.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 { todo!("{wo}{wi}") }
    /// Samples an incident direction; `u` for the direction, `u_lobe` to choose a lobe.
    pub fn sample(&self, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> { todo!("{wo}{u}{u_lobe}") }
    /// True when every lobe is a delta (mirror, glass): no light sampling is useful.
    pub fn is_delta(&self) -> bool { matches!(self, Bsdf::Mirror { .. } | Bsdf::Glass { .. }) }
}
