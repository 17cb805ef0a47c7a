//! The transport components of the paper (§2, eq. 4): the parts of the image the many-light
//! methods accumulate separately, and the decomposition of light paths they stand for.
//!
//! A camera path x₀ (the camera) … is classified by its first two non-specular vertices v1, v2
//! (camera-side mirror/glass bounces before v1 are followed transparently):
//! * light reaching v1 straight from an emitter, and emitters seen (through specular chains)
//!   from the camera: `Direct`;
//! * light reaching v1 through a specular bounce after it (… S+ v1): `CausticSurface` when v1
//!   is on a surface, `CausticVolume` when in a medium;
//! * otherwise light arriving from v2 by a straight connection: `Lss`, `Lsm`, `Lms`, `Lmm`
//!   by the kinds (surface/medium) of v1 and v2, whatever the light path before v2.
//!
//! Every path falls in exactly one class. The many-light gathers match it: VPLs and VRLs
//! (every light-path vertex and segment) connect straight to v1; caustic photons and photon
//! beams after a specular bounce supply the caustics; direct light is next-event estimation.

/// One of the separately accumulated parts of the image (also the EXR layer names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Component {
    /// Light arriving straight from emitters, at surfaces and along camera rays in media.
    Direct,
    /// Media → surface (`L_s^m`), from virtual ray/beam lights.
    Lsm,
    /// Media → media (`L_m^m`).
    Lmm,
    /// Surface → media (`L_m^s`), from virtual point/spherical lights.
    Lms,
    /// Surface → surface (`L_s^s`).
    Lss,
    /// Caustics on surfaces (light → specular chain → diffuse/glossy surface).
    CausticSurface,
    /// Volume caustics (light → specular chain → medium). Single scattering straight from the
    /// lights is part of `Direct`.
    CausticVolume,
}

impl Component {
    pub const ALL: [Component; 7] = [
        Component::Direct,
        Component::Lsm,
        Component::Lmm,
        Component::Lms,
        Component::Lss,
        Component::CausticSurface,
        Component::CausticVolume,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Component::Direct => "direct",
            Component::Lsm => "Lsm",
            Component::Lmm => "Lmm",
            Component::Lms => "Lms",
            Component::Lss => "Lss",
            Component::CausticSurface => "caustic_surface",
            Component::CausticVolume => "caustic_volume",
        }
    }
}
