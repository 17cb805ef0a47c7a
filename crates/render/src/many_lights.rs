//! One pass of the unclamped VRL/VPL method (`--method vrl`) on the CPU: camera gather data and
//! a fresh set of light paths, then every gather point against every virtual light, each
//! transport component kept apart (`Component::ALL` order).
//!
//! Caustics (progressive photon mapping and photon beams) are not implemented yet, so scenes
//! with mirrors or glass are refused before rendering (see [`check_supported`]).
use crate::components::SceneFeatures;
use beamlight_scene::{Rgb, rng::Sampler};
use beamlight_trace::{
    TraceScene,
    camera_paths::{CameraPathSettings, trace_camera_paths},
    components::Component,
    direct,
    light_paths::{LightTracerSettings, trace_light_paths},
    vpl, vrl,
};
use rayon::prelude::*;

/// Settings of the many-light methods.
#[derive(Clone, Copy, Debug)]
pub struct ManyLightSettings {
    /// Light paths traced per pass (each leaves several VPLs and VRLs).
    pub light_paths_per_pass: u32,
    /// Minimum distance in the inverse-square falloff (`vrl-clamped`); 0 for unclamped `vrl`.
    pub clamp: f32,
}

impl Default for ManyLightSettings {
    fn default() -> Self {
        Self {
            light_paths_per_pass: 64,
            clamp: 0.0,
        }
    }
}

/// The default clamp distance of `vrl-clamped`: 5 % of the diagonal of the scene's bounds (the
/// VRL paper leaves the choice to the user; a fixed share of the scene keeps it scale-free).
pub fn default_clamp(scene: &beamlight_scene::Scene) -> f32 {
    let (lo, hi) = scene.bounds();
    let diagonal = (hi - lo).length();
    if diagonal.is_finite() { 0.05 * diagonal } else { 0.0 }
}

/// Refuses scenes whose light needs components this version cannot compute.
pub fn check_supported(features: &SceneFeatures) -> Result<(), String> {
    if features.specular_surfaces {
        return Err(
            "this scene has mirror or glass surfaces, whose caustics need photon mapping and photon beams, \
                    which the many-light methods do not have yet; render it with --method pt"
                .into(),
        );
    }
    Ok(())
}

const N: usize = Component::ALL.len();

/// Renders one pass: `out[c][pixel]` receives component `c`'s estimate for each pixel.
pub fn many_light_pass(
    ts: &TraceScene,
    settings: &ManyLightSettings,
    w: u32,
    h: u32,
    seed: u32,
    pass: u32,
    out: &mut [Vec<Rgb>; N],
) {
    let gather = trace_camera_paths(ts, &CameraPathSettings::default(), w, h, seed, pass);
    let lights = trace_light_paths(
        ts,
        &LightTracerSettings::default(),
        settings.light_paths_per_pass,
        seed,
        pass,
    );
    let m = lights.paths.max(1) as f32;
    for buffer in out.iter_mut() {
        buffer.iter_mut().for_each(|v| *v = Rgb::ZERO);
    }
    out[Component::Direct as usize].copy_from_slice(&gather.emitted);
    // Independent random streams for the gathers (the camera and light paths use their own).
    let stream = |kind: u32, i: usize| Sampler::new(seed ^ 0x5bd1_e995, pass, (i as u32).wrapping_mul(2) + kind);

    let at_points: Vec<(u32, [Rgb; N])> = gather
        .shading_points
        .par_iter()
        .enumerate()
        .map(|(i, sp)| {
            let mut s = stream(0, i);
            let mut c = [Rgb::ZERO; N];
            c[Component::Direct as usize] = direct::direct_at_surface(ts, sp, &mut s);
            c[Component::Lss as usize] = lights
                .vpls
                .iter()
                .map(|v| vpl::vpl_to_surface(ts, sp, v, settings.clamp, &mut s))
                .sum::<Rgb>()
                / m;
            c[Component::Lsm as usize] = lights
                .vrls
                .iter()
                .map(|v| vrl::vrl_to_surface(ts, sp, v, settings.clamp, &mut s))
                .sum::<Rgb>()
                / m;
            (sp.pixel, c)
        })
        .collect();
    let along_segments: Vec<(u32, [Rgb; N])> = gather
        .media_segments
        .par_iter()
        .enumerate()
        .map(|(i, seg)| {
            let mut s = stream(1, i);
            let mut c = [Rgb::ZERO; N];
            c[Component::Direct as usize] = direct::direct_in_medium(ts, seg, &mut s);
            c[Component::Lms as usize] = lights
                .vpls
                .iter()
                .map(|v| vpl::vpl_to_media(ts, seg, v, settings.clamp, &mut s))
                .sum::<Rgb>()
                / m;
            c[Component::Lmm as usize] = lights
                .vrls
                .iter()
                .map(|v| vrl::vrl_to_media(ts, seg, v, settings.clamp, &mut s))
                .sum::<Rgb>()
                / m;
            (seg.pixel, c)
        })
        .collect();
    for (pixel, c) in at_points.into_iter().chain(along_segments) {
        for (k, v) in c.into_iter().enumerate() {
            out[k][pixel as usize] += v;
        }
    }
}
