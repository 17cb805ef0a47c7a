//! The estimator families a render can use (`--method`): what sets them apart and the pass
//! sources each renders with ([`Method::sources`]). This is where an estimator is registered;
//! the loop (`progressive::setup`) only picks the schedule (`auto`'s, or every pass averaged).
use crate::{
    auto,
    components::SceneFeatures,
    many_lights::{self, ManyLightSettings, VirtualLights},
    radius,
    source::{ManyLights, PassSource, PathTracer, SourceInputs},
};
use beamlight_trace::TraceScene;

/// Estimator family (`--method`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Unbiased volumetric path tracer (ground truth).
    Pt,
    /// Unclamped virtual ray lights + virtual point lights.
    Vrl,
    /// Clamped VRLs + VPLs.
    VrlClamped,
    /// Progressive virtual beam lights + virtual spherical lights.
    Vbl,
    /// Each component from `pt` and `vbl`, combined by their measured errors, with the time
    /// going where it lowers the error most ([`crate::auto`]).
    Auto,
}

impl Method {
    /// Every method, in the order `--help` lists them.
    pub const ALL: [Method; 5] = [Method::Pt, Method::Vrl, Method::VrlClamped, Method::Vbl, Method::Auto];

    /// One line on what it is (`--help`).
    pub fn summary(self) -> &'static str {
        match self {
            Method::Pt => "Unbiased volumetric path tracer (the ground truth)",
            Method::Vrl => "Unclamped virtual ray lights and virtual point lights",
            Method::VrlClamped => "Virtual ray and point lights with a clamped inverse-square falloff (biased)",
            Method::Vbl => "Progressive virtual beam lights and virtual spherical lights (consistent)",
            Method::Auto => "Each component from `pt` and `vbl`, combined by their measured errors",
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Method::Pt => "pt",
            Method::Vrl => "vrl",
            Method::VrlClamped => "vrl-clamped",
            Method::Vbl => "vbl",
            Method::Auto => "auto",
        }
    }

    /// The virtual lights its many-light passes gather (`None`: it has none, `pt`).
    pub fn virtual_lights(self) -> Option<VirtualLights> {
        match self {
            Method::Pt => None,
            Method::Vrl | Method::VrlClamped => Some(VirtualLights::Rays),
            Method::Vbl | Method::Auto => Some(VirtualLights::Beams),
        }
    }

    /// The pass sources a render with this method draws from: one for every method but
    /// `auto`, whose are the path tracer (its components apart), `vbl` (with the seed `vbl`
    /// alone uses, [`many_lights::stream_seed`]) and the same `vbl` on a small image (its probe
    /// of a pass's cost), in the order of [`auto::PT`], [`auto::VBL`] and [`auto::PROBE`].
    pub fn sources<'a>(self, inputs: SourceInputs<'a>) -> Vec<Box<dyn PassSource + 'a>> {
        let path_tracer = |split| -> Box<dyn PassSource + 'a> {
            Box::new(PathTracer {
                ts: inputs.ts,
                settings: inputs.path_tracer,
                width: inputs.width,
                height: inputs.height,
                seed: inputs.seed,
                split,
            })
        };
        // Every many-light source draws from the same stream, alone or inside `auto`.
        let many_light_source = |method: Method, (width, height): (u32, u32)| -> Box<dyn PassSource + 'a> {
            Box::new(ManyLights {
                ts: inputs.ts,
                settings: method.many_light_settings(inputs.ts, inputs.many_lights),
                width,
                height,
                seed: many_lights::stream_seed(inputs.seed),
                gpu: inputs.gpu,
            })
        };
        let size = (inputs.width, inputs.height);
        match self {
            Method::Pt => vec![path_tracer(inputs.split)],
            Method::Vrl | Method::VrlClamped | Method::Vbl => vec![many_light_source(self, size)],
            Method::Auto => vec![
                path_tracer(true),
                many_light_source(Method::Vbl, size),
                many_light_source(Method::Vbl, auto::probe_size(size)),
            ],
        }
    }

    /// Whether the GPU has kernels for every gather of this method.
    pub fn has_gpu_kernels(self) -> bool {
        self.virtual_lights().is_some_and(many_lights::gpu_has_kernels)
    }

    /// The many-light settings of a render with this method: the `given` ones with what they
    /// leave to the method (rays or beams, the clamp) and to the scene (radii, caustic paths)
    /// filled in.
    pub fn many_light_settings(self, ts: &TraceScene, given: &ManyLightSettings) -> ManyLightSettings {
        // Without mirrors or glass there are no caustics: no light paths for them.
        let specular = SceneFeatures::of(&ts.scene).specular_surfaces;
        ManyLightSettings {
            lights: self.virtual_lights().unwrap_or_default(),
            // `vrl` is unclamped by definition; `vrl-clamped` uses the given distance or the
            // default.
            clamp: match self {
                Method::VrlClamped if given.clamp > 0.0 => given.clamp,
                Method::VrlClamped => many_lights::default_clamp(&ts.scene),
                _ => 0.0,
            },
            radius: if given.radius > 0.0 {
                given.radius
            } else {
                radius::default_radius(&ts.scene)
            },
            caustic_paths: if specular { given.caustic_paths } else { Some(0) },
            beam_paths: if specular { given.beam_paths } else { 0 },
            photon_radius: if given.photon_radius > 0.0 {
                given.photon_radius
            } else {
                radius::default_photon_radius(&ts.scene)
            },
            ..*given
        }
    }
}
