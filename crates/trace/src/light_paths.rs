//! Light tracing: photon random walks from the emitters, recorded as the light sets the
//! many-light estimators gather from (VRLs, VPLs, caustic photons, photon beams).
//!
//! Flux bookkeeping: a path starts with the flux of its [`EmissionSample`] (so the mean over
//! paths is the scene's emitted power) and is multiplied by each interaction's weight. Every
//! record stores the flux *arriving* at it: a segment's flux is the flux entering it (before
//! any attenuation along it), a vertex's the flux incident on it. Segments run from where the
//! path entered the medium to the next surface, whether or not the walk scattered on the way:
//! the flux scattered out of a segment at distance u is Φ σs(u) T(u). Averaging a set's records
//! over the number of paths traced (`LightSet::paths`) gives unbiased flux estimates.
//!
//! The records are plain `#[repr(C)]` data in flat arrays, laid out for the GPU (each 3-vector
//! is followed by a 4-byte scalar, which is how WGSL packs `vec3<f32>` + `f32`).
use crate::{
    TraceScene,
    context::MAX_CROSSINGS,
    geometry::{offset_ray_origin, triangle_error_bound},
    lights::EmissionSample,
    media::{self, MediumEvent},
};
use beamlight_scene::{Rgb, bsdf::TransportMode, frame::Frame, phase::HenyeyGreenstein, rng::Sampler, scene::MediumId};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use rayon::prelude::*;

/// A straight piece of a light path inside one medium: a virtual ray light, or a photon beam.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct LightSegment {
    pub origin: [f32; 3],
    pub length: f32,
    pub dir: [f32; 3],
    /// Index into `Scene::media`.
    pub medium: u32,
    /// Flux entering the segment (before transmittance along it).
    pub power: [f32; 3],
    /// How the path reached the segment: [`FROM_LIGHT`] or [`AFTER_SPECULAR`] (or neither).
    pub flags: u32,
}

/// `LightSegment::flags`: the segment starts at the light (no scattering before it).
pub const FROM_LIGHT: u32 = 1;
/// `LightSegment::flags`: the last scattering before the segment was a specular bounce.
pub const AFTER_SPECULAR: u32 = 2;

/// A light-path vertex on a diffuse or glossy surface (a VPL; the centre of a VSL), or a
/// caustic photon.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct SurfaceVertex {
    pub pos: [f32; 3],
    /// Index into `Scene::materials`.
    pub material: u32,
    /// Shading normal, on the side the light arrived from.
    pub normal: [f32; 3],
    /// Index into `Scene::triangles` (for texture lookups and offsets).
    pub tri: u32,
    /// Unit direction towards where the light came from.
    pub wi: [f32; 3],
    pub u: f32,
    /// Flux arriving at the vertex.
    pub power: [f32; 3],
    pub v: f32,
}

/// Everything one pass's light paths produced.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    /// Number of light paths traced (the M of the estimators), including ones that left nothing.
    pub paths: u32,
    /// Every path segment through a medium (virtual ray lights).
    pub vrls: Vec<LightSegment>,
    /// Every diffuse or glossy surface vertex (virtual point lights / VSL centres).
    pub vpls: Vec<SurfaceVertex>,
    /// Diffuse/glossy vertices whose light arrived through a specular bounce (L … S+ D, any
    /// prefix): the light a camera shading point cannot gather from a VPL, since no straight
    /// connection passes through the specular chain in between.
    pub caustic_photons: Vec<SurfaceVertex>,
    /// Medium segments that start at the light or right after a specular bounce (flags say
    /// which): single scattering and volume caustics.
    pub photon_beams: Vec<LightSegment>,
    /// Paths ended early because their power turned NaN or infinite (at emission, after a
    /// scattering, or through a shading-normal correction of a direction in the surface's
    /// plane): their light is lost, so the count is reported (`Discards::light_paths` in the
    /// render crate) instead of the path ending unseen. Zero in a sane scene.
    pub nonfinite_paths: u32,
}

#[derive(Clone, Copy, Debug)]
pub struct LightTracerSettings {
    /// Scattering events after which Russian roulette starts.
    pub rr_depth: u32,
    /// Maximum number of scattering events per path (`None`: unbounded).
    pub max_depth: Option<u32>,
    /// The records kept; the others are not stored (the walk is the same).
    pub keep: Keep,
    /// Fault injection for the counters' tests (`ManyLightSettings::inject_nan` in the render
    /// crate): path 0 leaves its light with a NaN power, so it must be counted.
    pub inject_nan: bool,
}

impl Default for LightTracerSettings {
    fn default() -> Self {
        Self {
            rr_depth: 3,
            max_depth: None,
            keep: Keep::ALL,
            inject_nan: false,
        }
    }
}

/// Which of a [`LightSet`]'s record kinds a trace stores. The caustic sets of a pass need only
/// their photons or their beams, and they come in hundreds of thousands of paths: keeping every
/// VRL and VPL of theirs would cost about a kilobyte a path for records nobody reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Keep {
    pub vrls: bool,
    pub vpls: bool,
    pub caustic_photons: bool,
    pub photon_beams: bool,
}

impl Keep {
    pub const ALL: Keep = Keep {
        vrls: true,
        vpls: true,
        caustic_photons: true,
        photon_beams: true,
    };
    pub const CAUSTIC_PHOTONS: Keep = Keep {
        vrls: false,
        vpls: false,
        caustic_photons: true,
        photon_beams: false,
    };
    pub const PHOTON_BEAMS: Keep = Keep {
        vrls: false,
        vpls: false,
        caustic_photons: false,
        photon_beams: true,
    };
}

/// Traces `paths` light paths for pass `pass`; path `k` uses the random stream
/// `(seed, pass, k)`, so a pass is reproducible and can be split across threads or machines.
pub fn trace_light_paths(
    ts: &TraceScene,
    settings: &LightTracerSettings,
    paths: u32,
    seed: u32,
    pass: u32,
) -> LightSet {
    // Chunks of paths in parallel, joined in path order: the records' order (which keys the
    // gathers' random streams) is the same on any number of threads.
    const CHUNK: u32 = 64;
    let chunks: Vec<LightSet> = (0..paths.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut part = LightSet::default();
            for k in c * CHUNK..((c + 1) * CHUNK).min(paths) {
                let mut s = Sampler::new(seed ^ 0x9e37_79b9, pass, k);
                if let Some(mut e) = ts.lights.sample_emission(&ts.scene, &mut s) {
                    if settings.inject_nan && k == 0 {
                        e.power = Rgb::splat(f32::NAN);
                    }
                    if !trace_one(ts, settings, e, &mut s, &mut part) {
                        part.nonfinite_paths += 1;
                    }
                }
            }
            part
        })
        .collect();
    let mut set = LightSet {
        paths,
        ..Default::default()
    };
    for part in chunks {
        set.vrls.extend(part.vrls);
        set.vpls.extend(part.vpls);
        set.caustic_photons.extend(part.caustic_photons);
        set.photon_beams.extend(part.photon_beams);
        set.nonfinite_paths += part.nonfinite_paths;
    }
    set
}

fn segment(origin: Vec3, dir: Vec3, length: f32, medium: u32, power: Rgb, flags: u32) -> LightSegment {
    LightSegment {
        origin: origin.into(),
        length,
        dir: dir.into(),
        medium,
        power: power.into(),
        flags,
    }
}

/// Traces one light path into `set`; false when it ended because its power turned NaN or
/// infinite (counted by the caller), true when it ended as paths do.
fn trace_one(
    ts: &TraceScene,
    settings: &LightTracerSettings,
    e: EmissionSample,
    s: &mut Sampler,
    set: &mut LightSet,
) -> bool {
    let scene = &ts.scene;
    let max_depth = settings.max_depth.unwrap_or(u32::MAX);
    let mut power = e.power;
    if !power.is_finite() {
        return false;
    }
    let mut d = e.dir;
    let (mut o, mut medium): (Vec3, MediumId) = match e.surface {
        Some((tri, n)) => {
            let t = &scene.triangles[tri as usize];
            let err = triangle_error_bound(&t.p);
            let o = offset_ray_origin(e.p, err, n);
            (o, ts.medium_at(o))
        }
        None => (e.p, ts.medium_at(e.p)),
    };
    // What the path did last: nothing yet (still leaving the light), a specular bounce, or a
    // diffuse/glossy/medium scattering. Beams and caustic photons are defined by it.
    let mut flags = FROM_LIGHT;
    let mut depth = 0u32;
    let mut crossings = 0u32;
    loop {
        // Surface data is built only if the ray gets there (not when it scatters in a medium).
        let hit = ts.bvh.closest_hit(o, d, f32::INFINITY);
        let tmax = hit.map_or(f32::INFINITY, |h| h.t);
        if let Some(mi) = medium {
            let m = &scene.media[mi as usize];
            let event = media::sample_distance(m, o, d, tmax, power, s);
            // The whole stretch to the next surface ("long" VRLs and beams, Jarosz et al. 2011):
            // gathers weight it by transmittance, independently of where this path scatters.
            // (A segment cut at the sampled collision would need the collision's survival
            // probability instead, which spectral tracking does not have in closed form.)
            let length = media::extent(m, o, tmax);
            // Finite and positive wherever something can scatter (`media::extent`, tested); a
            // medium that scatters nothing (clear glass's inside) keeps no record.
            if m.scatters() && length.is_finite() && length > 0.0 {
                let seg = segment(o, d, length, mi, power, flags);
                if settings.keep.vrls {
                    set.vrls.push(seg);
                }
                if flags != 0 && settings.keep.photon_beams {
                    set.photon_beams.push(seg);
                }
            }
            match event {
                MediumEvent::Scatter { t, weight } => {
                    power *= weight;
                    depth += 1;
                    if depth > max_depth || power == Rgb::ZERO {
                        return power.is_finite();
                    }
                    let p = o + d * t;
                    // HG is symmetric, so the same sampling serves light paths: `wo` points back
                    // towards where the light came from.
                    let ps = HenyeyGreenstein { g: m.g }.sample(-d, s.next_2d());
                    power *= ps.weight;
                    flags = 0;
                    o = p;
                    d = ps.wi;
                    if !roulette(&mut power, e.power, depth, settings.rr_depth, s) {
                        return power.is_finite();
                    }
                    continue;
                }
                MediumEvent::Pass { weight } => {
                    power *= weight;
                    if power == Rgb::ZERO {
                        return true;
                    }
                    if !power.is_finite() {
                        return false;
                    }
                }
            }
        }
        let Some(h) = hit else { return true };
        let sh = ts.surface(&h);
        let Some(bsdf) = scene.bsdf_at(sh.material, sh.uv) else {
            medium = ts.medium_beyond(&sh, d, medium);
            crossings += 1;
            if crossings > MAX_CROSSINGS {
                return true;
            }
            o = sh.spawn(d);
            continue;
        };
        let wo = -d;
        // Shading normal on the side the light arrives from.
        let ns = if sh.ns.dot(wo) < 0.0 { -sh.ns } else { sh.ns };
        if !bsdf.is_delta() {
            let uv = sh.uv.unwrap_or_default();
            let vertex = SurfaceVertex {
                pos: sh.p.into(),
                material: sh.material,
                normal: ns.into(),
                tri: sh.tri,
                wi: wo.into(),
                u: uv.x,
                power: power.into(),
                v: uv.y,
            };
            if settings.keep.vpls {
                set.vpls.push(vertex);
            }
            if flags & AFTER_SPECULAR != 0 && settings.keep.caustic_photons {
                set.caustic_photons.push(vertex);
            }
        }
        depth += 1;
        if depth > max_depth {
            return true;
        }
        let frame = Frame::from_normal(sh.ns);
        let Some(bs) = bsdf.sample_mode(frame.to_local(wo), s.next_2d(), s.next_1d(), TransportMode::Importance) else {
            return true;
        };
        if bs.weight == Rgb::ZERO {
            return true;
        }
        let wi = frame.to_world(bs.wi);
        let transmissive = matches!(bsdf, beamlight_scene::bsdf::Bsdf::Glass { .. });
        if !transmissive && sh.ng.dot(wi) * sh.ng.dot(wo) <= 0.0 {
            return true;
        }
        // Adjoint BSDFs with shading normals need Veach's correction |wo·ns||wi·ng| / (|wo·ng||wi·ns|);
        // a direction in the plane of either normal makes it infinite or NaN, and the path
        // ends at the roulette below, counted.
        let correction = (wo.dot(sh.ns) * wi.dot(sh.ng)).abs() / (wo.dot(sh.ng) * wi.dot(sh.ns)).abs();
        power *= bs.weight * correction;
        flags = if bs.is_delta { AFTER_SPECULAR } else { 0 };
        medium = ts.medium_beyond(&sh, wi, medium);
        o = sh.spawn(wi);
        d = wi;
        if !roulette(&mut power, e.power, depth, settings.rr_depth, s) {
            return power.is_finite();
        }
    }
}

/// Russian roulette for light paths: survival in proportion to the largest channel of the flux
/// relative to its value at emission (the path's throughput), capped at 0.95 so that every
/// path ends, as in the path tracer.
fn roulette(power: &mut Rgb, emitted: Rgb, depth: u32, rr_depth: u32, s: &mut Sampler) -> bool {
    if !power.is_finite() || *power == Rgb::ZERO {
        return false;
    }
    if depth < rr_depth {
        return true;
    }
    let q = (power.max_element() / emitted.max_element()).min(0.95);
    if s.next_1d() >= q {
        return false;
    }
    *power /= q;
    true
}
