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
//!
//! **Sharp media** ([`is_sharp`]) are the one exception to "connect straight to v1". Where v1
//! lies in a medium whose phase function is a near-delta, a straight connection carries light
//! only where the lobe, a few 10⁻³ rad wide at |g| = 0.999, holds the line to the light
//! vertex, which position sampling practically never draws (the furnace at g = 0.999 gave
//! 0.85 instead of 2.0 after 1024 passes). So a camera point in a sharp medium connects
//! to no virtual light ([`gathers_in_medium`]); direct light there samples the phase function
//! too (`direct::direct_in_medium`), and the camera path *walks* on from v1 by sampling the
//! phase function, as a path tracer does ([`crate::camera_paths`]). What the walk's ray meets
//! is v2: its media stretches are gathered like camera media segments and its first surface
//! like a shading point, each credited to the class of (v1, v2): `Lmm` along the stretches,
//! `Lms` at the surface (`Lmm` again once the walk has scattered twice, since v2 was then in a
//! medium). The classes above are unchanged, so the split still matches the path tracer's.

/// Henyey–Greenstein asymmetry from which a medium's phase function counts as sharp: its lobe
/// is then narrower than about (1 − |g|) = 0.05 rad, and its light is found by direction
/// sampling (a walk), not by connecting positions. The WGSL twin is
/// `SHARP_PHASE_G` in `shaders/lib/gather.wgsl`.
pub const SHARP_PHASE_G: f32 = 0.95;

/// Whether a medium of asymmetry `g` has a sharp phase function ([`SHARP_PHASE_G`]).
pub fn is_sharp(g: f32) -> bool {
    g.abs() >= SHARP_PHASE_G
}

/// Whether a camera point in a medium of asymmetry `g` connects to virtual lights: unless its
/// phase function is sharp, when the camera path's walk supplies that light.
pub fn gathers_in_medium(g: f32) -> bool {
    !is_sharp(g)
}

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
