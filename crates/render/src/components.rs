//! The transport components of the paper (§2, eq. 4) and which of them a scene can produce.
//!
//! The many-light methods render the image as a sum of separately accumulated components; a
//! component a scene cannot produce is skipped entirely (no light tracing, no gather).
use beamlight_scene::{Scene, bsdf::Bsdf};
pub use beamlight_trace::components::{Component, is_sharp};

/// What the scene contains that decides which components can be non-zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SceneFeatures {
    pub emitters: bool,
    pub media: bool,
    /// Diffuse or glossy surfaces (Lambert, Phong): they receive and re-emit indirect light.
    pub rough_surfaces: bool,
    /// Mirrors or glass: they make caustic paths.
    pub specular_surfaces: bool,
}

impl SceneFeatures {
    pub fn of(scene: &Scene) -> Self {
        let used = |f: &dyn Fn(&Bsdf) -> bool| {
            scene
                .triangles
                .iter()
                .any(|t| scene.materials[t.material as usize].bsdf.as_ref().is_some_and(f))
        };
        let emissive_triangles = scene
            .triangles
            .iter()
            .any(|t| scene.materials[t.material as usize].is_emissive());
        Self {
            emitters: emissive_triangles || !scene.lights.is_empty(),
            // A medium no ray can reach (zero coefficients) produces nothing either.
            media: scene.media.iter().any(|m| m.sigma_t().max_element() > 0.0),
            rough_surfaces: used(&|b| !b.is_delta()),
            specular_surfaces: used(&|b| b.is_delta()),
        }
    }

    /// The components a scene with these features can produce.
    pub fn needed(&self) -> Vec<Component> {
        if !self.emitters {
            return Vec::new();
        }
        let f = self;
        Component::ALL
            .into_iter()
            .filter(|c| match c {
                Component::Direct => true,
                Component::Lsm => f.media && f.rough_surfaces,
                Component::Lmm => f.media,
                Component::Lms => f.media && f.rough_surfaces,
                Component::Lss => f.rough_surfaces,
                Component::CausticSurface => f.specular_surfaces && f.rough_surfaces,
                Component::CausticVolume => f.media && f.specular_surfaces,
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn components_follow_scene_features() {
        let all = SceneFeatures {
            emitters: true,
            media: true,
            rough_surfaces: true,
            specular_surfaces: true,
        };
        assert_eq!(all.needed(), Component::ALL.to_vec());
        let no_media = SceneFeatures { media: false, ..all };
        assert_eq!(
            no_media.needed(),
            vec![Component::Direct, Component::Lss, Component::CausticSurface]
        );
        let fog_only = SceneFeatures {
            rough_surfaces: false,
            specular_surfaces: false,
            ..all
        };
        assert_eq!(fog_only.needed(), vec![Component::Direct, Component::Lmm]);
        // Fog with a glass object: volume caustics, but nothing for surfaces to gather.
        let fog_and_glass = SceneFeatures {
            rough_surfaces: false,
            ..all
        };
        assert_eq!(
            fog_and_glass.needed(),
            vec![Component::Direct, Component::Lmm, Component::CausticVolume]
        );
        assert!(SceneFeatures { emitters: false, ..all }.needed().is_empty());
    }
}
