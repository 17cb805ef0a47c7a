//! Henyey–Greenstein phase function. (Stub: being implemented.)
use glam::{Vec2, Vec3};

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

impl HenyeyGreenstein {
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        todo!("{wo}{wi}")
    }
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval(wo, wi)
    }
    pub fn sample(&self, wo: Vec3, u: Vec2) -> PhaseSample {
        todo!("{wo}{u}")
    }
}
