//! beamlight-scene: the scene model and everything that describes it without rendering it.
//!
//! * [`scene`]: the flattened, world-space [`Scene`] every renderer consumes.
//! * [`load`]: glTF 2.0 + TOML sidecar → [`Scene`], with errors that name the file and the problem.
//! * [`bsdf`], [`texture`], [`phase`], [`medium`], [`light`], [`camera`]: what the scene is made of.
//! * [`sampling`], [`frame`], [`rng`]: the shared Monte Carlo toolbox (also mirrored in WGSL later).
//!
//! Conventions used everywhere: directions are unit vectors pointing *away* from the point
//! being shaded (`wo` towards the viewer / previous vertex, `wi` towards the light); colours are
//! linear RGB [`Rgb`]; lengths are in scene units and coefficients in 1/scene unit.

pub mod bsdf;
pub mod camera;
pub mod error;
pub mod frame;
pub mod light;
pub mod load;
pub mod medium;
pub mod noise;
pub mod phase;
pub mod rng;
pub mod sampling;
pub mod scene;
pub mod texture;
pub mod vdb;

pub use error::SceneError;
pub use scene::Scene;

/// Linear RGB triple (radiance, albedo, coefficients...).
pub type Rgb = glam::Vec3;

/// Mean of the three channels.
#[inline]
pub fn luminance_mean(c: Rgb) -> f32 {
    (c.x + c.y + c.z) * (1.0 / 3.0)
}
