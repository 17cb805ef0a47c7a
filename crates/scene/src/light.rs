//! Punctual lights (glTF `KHR_lights_punctual`).
//!
//! Units follow glTF photometry mapped one-to-one onto our radiometric units: a point or spot
//! light's `intensity` (candela) is its radiant intensity I (power per steradian), a directional
//! light's `intensity` (lux) is the irradiance E it delivers to a surface facing it. Emissive
//! surfaces use the same mapping (nits → radiance), so glTF scenes keep their relative balance.
//! The glTF `range` cut-off is not physical and is ignored (with a warning at load time).
use crate::Rgb;
use glam::Vec3;

#[derive(Clone, Debug)]
pub enum PunctualLight {
    Point {
        position: Vec3,
        /// Radiant intensity per channel (colour × intensity).
        intensity: Rgb,
    },
    Spot {
        position: Vec3,
        /// Unit direction the spot points to (the node's −Z).
        direction: Vec3,
        intensity: Rgb,
        /// cos of glTF `innerConeAngle` and `outerConeAngle`.
        cos_inner: f32,
        cos_outer: f32,
    },
    Directional {
        /// Unit direction the light travels in (the node's −Z).
        direction: Vec3,
        irradiance: Rgb,
    },
}

impl PunctualLight {
    pub fn position(&self) -> Option<Vec3> {
        match self {
            PunctualLight::Point { position, .. } | PunctualLight::Spot { position, .. } => Some(*position),
            PunctualLight::Directional { .. } => None,
        }
    }

    /// Radiant intensity towards unit direction `w` (pointing away from the light).
    /// Spot falloff is the glTF reference one: a smooth (squared linear-in-cosine) ramp between
    /// the outer and inner cone.
    pub fn intensity_towards(&self, w: Vec3) -> Rgb {
        match self {
            PunctualLight::Point { intensity, .. } => *intensity,
            PunctualLight::Spot {
                direction,
                intensity,
                cos_inner,
                cos_outer,
                ..
            } => *intensity * spot_falloff(direction.dot(w), *cos_inner, *cos_outer),
            PunctualLight::Directional { irradiance, .. } => *irradiance,
        }
    }

    /// Total emitted power (for power-proportional light selection). Directional lights need
    /// the radius of the scene's bounding sphere to have a finite power.
    pub fn power(&self, scene_radius: f32) -> f32 {
        let mean = |c: Rgb| (c.x + c.y + c.z) / 3.0;
        match self {
            PunctualLight::Point { intensity, .. } => 4.0 * std::f32::consts::PI * mean(*intensity),
            PunctualLight::Spot {
                intensity,
                cos_inner,
                cos_outer,
                ..
            } => {
                // Solid angle of the cone out to the middle of the falloff ramp.
                2.0 * std::f32::consts::PI * (1.0 - 0.5 * (cos_inner + cos_outer)) * mean(*intensity)
            }
            PunctualLight::Directional { irradiance, .. } => {
                std::f32::consts::PI * scene_radius * scene_radius * mean(*irradiance)
            }
        }
    }
}

/// glTF KHR_lights_punctual reference spot attenuation:
/// t = saturate((cosθ − cos_outer) / (cos_inner − cos_outer)), falloff = t².
pub fn spot_falloff(cos_theta: f32, cos_inner: f32, cos_outer: f32) -> f32 {
    let scale = 1.0 / (cos_inner - cos_outer).max(0.001);
    let t = ((cos_theta - cos_outer) * scale).clamp(0.0, 1.0);
    t * t
}
