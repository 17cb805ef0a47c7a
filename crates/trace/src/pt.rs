//! The reference volumetric path tracer: unbiased, next-event estimation through media with
//! MIS (power heuristic) between light sampling and BSDF/phase sampling, Russian roulette.
//! It is the ground truth every other estimator is measured against.
use crate::components::Component;
use crate::{
    context::{MAX_CROSSINGS, TraceScene},
    media::{self, MediumEvent},
};
use beamlight_scene::{
    Rgb, frame::Frame, phase::HenyeyGreenstein, rng::Sampler, sampling::power_heuristic, scene::MediumId,
};
use glam::{Vec2, Vec3};

#[derive(Clone, Copy, Debug)]
pub struct PathTracerSettings {
    /// Maximum number of scattering events (surface or medium) on a path; `None` = unbounded.
    /// 1 gives direct lighting / single scattering only.
    pub max_depth: Option<u32>,
    /// Scattering events before Russian roulette starts.
    pub rr_depth: u32,
    /// The components estimated, by [`Component::ALL`] index (all by default). With some left
    /// out, a path ends as soon as its class ([`Component`]'s decomposition) can no longer
    /// reach a wanted one, light found for an unwanted one is not looked for, and in a
    /// homogeneous medium a segment whose far surface could only feed unwanted components
    /// collides for sure ([`media::forced_collision`]): e.g. for `Lmm` alone, every camera
    /// ray scatters in the medium and so does the next segment. `--only` sets it; `--method
    /// auto` restricts its path tracer to the components it serves, and at times to one.
    pub components: [bool; N],
}

const N: usize = Component::ALL.len();

/// A component's bit in a set of components.
const fn bit(c: Component) -> u8 {
    1 << c as u8
}

impl Default for PathTracerSettings {
    fn default() -> Self {
        Self {
            max_depth: None,
            rr_depth: 3,
            components: [true; N],
        }
    }
}

/// One radiance sample for pixel `(x, y)` of a `width × height` image: a jittered camera ray
/// (box filter) traced with the pass's own random stream.
pub fn sample_pixel(
    ts: &TraceScene,
    settings: &PathTracerSettings,
    x: u32,
    y: u32,
    width: u32,
    height: u32,
    s: &mut Sampler,
) -> Rgb {
    let mut l = Rgb::ZERO;
    sample_pixel_split(ts, settings, x, y, width, height, s, &mut |_, c| l += c);
    l
}

/// [`sample_pixel`] split by transport component, in [`Component::ALL`]'s order.
///
/// Not generic, so it is compiled here, where the path tracer's callees (`TraceScene::surface`,
/// `LightSampler::sample`) can be inlined into it as they are into [`sample_pixel`]; a generic
/// sink instantiated in another crate could not inline them, and the split path tracer ran
/// 7–10 % slower than the plain one (cornell, 96², 1000 spp).
pub fn sample_pixel_components(
    ts: &TraceScene,
    settings: &PathTracerSettings,
    x: u32,
    y: u32,
    width: u32,
    height: u32,
    s: &mut Sampler,
) -> [Rgb; N] {
    let mut l = [Rgb::ZERO; N];
    sample_pixel_split(ts, settings, x, y, width, height, s, &mut |k, c| l[k as usize] += c);
    l
}

/// [`sample_pixel`] with every contribution handed to `sink` with its transport component.
fn sample_pixel_split(
    ts: &TraceScene,
    settings: &PathTracerSettings,
    x: u32,
    y: u32,
    width: u32,
    height: u32,
    s: &mut Sampler,
    sink: &mut impl FnMut(Component, Rgb),
) {
    let jitter = s.next_2d();
    let film = Vec2::new(
        (x as f32 + jitter.x) / width as f32,
        (y as f32 + jitter.y) / height as f32,
    );
    let cam = &ts.scene.camera;
    let d = cam.direction(film, width as f32 / height as f32);
    radiance_split(ts, settings, cam.position(), d, ts.camera_medium, s, sink)
}

/// Radiance arriving at `o` from direction `-d`, for a ray starting in `medium`.
pub fn radiance(
    ts: &TraceScene,
    settings: &PathTracerSettings,
    o: Vec3,
    d: Vec3,
    medium: MediumId,
    s: &mut Sampler,
) -> Rgb {
    let mut l = Rgb::ZERO;
    radiance_split(ts, settings, o, d, medium, s, &mut |_, c| l += c);
    l
}

/// Whether a scattering vertex is on a surface or in a medium.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Vertex {
    Surface,
    Medium,
}

/// Which component a contribution belongs to, from the camera path's first two non-specular
/// vertices v1, v2 (see [`Component`] for the decomposition).
#[derive(Clone, Copy, Debug, Default)]
struct PathClass {
    v1: Option<Vertex>,
    v2: Option<Vertex>,
    /// A specular bounce happened after v1 (and before v2 or the light).
    specular_after_v1: bool,
}

impl PathClass {
    fn scatter(&mut self, v: Vertex) {
        if self.v1.is_none() {
            self.v1 = Some(v);
        } else if self.v2.is_none() {
            self.v2 = Some(v);
        }
    }

    fn specular_bounce(&mut self) {
        if self.v1.is_some() && self.v2.is_none() {
            self.specular_after_v1 = true;
        }
    }

    /// The components that light found from now on may belong to, as a [`bit`] set.
    fn reachable(&self) -> u8 {
        use Component::*;
        match (self.v1, self.v2) {
            (None, _) => u8::MAX,
            (Some(Vertex::Surface), _) if self.specular_after_v1 => bit(CausticSurface),
            (Some(Vertex::Medium), _) if self.specular_after_v1 => bit(CausticVolume),
            (Some(Vertex::Surface), None) => bit(Direct) | bit(CausticSurface) | bit(Lss) | bit(Lsm),
            (Some(Vertex::Medium), None) => bit(Direct) | bit(CausticVolume) | bit(Lms) | bit(Lmm),
            (Some(_), Some(_)) => bit(self.component()),
        }
    }

    /// Whether light found from now on can belong to a component in `wanted` (a [`bit`] set).
    fn can_reach(&self, wanted: u8) -> bool {
        self.reachable() & wanted != 0
    }

    /// Whether a path scattering at a (non-specular) surface next could still reach `wanted`.
    fn surface_can_reach(&self, wanted: u8) -> bool {
        let mut next = *self;
        next.scatter(Vertex::Surface);
        next.can_reach(wanted)
    }

    /// The component that light found now (by next-event estimation at the current vertex or
    /// by hitting an emitter) belongs to.
    fn component(&self) -> Component {
        match (self.v1, self.v2, self.specular_after_v1) {
            (None, _, _) => Component::Direct,
            (Some(Vertex::Surface), _, true) => Component::CausticSurface,
            (Some(Vertex::Medium), _, true) => Component::CausticVolume,
            (Some(_), None, false) => Component::Direct,
            (Some(Vertex::Surface), Some(Vertex::Surface), false) => Component::Lss,
            (Some(Vertex::Surface), Some(Vertex::Medium), false) => Component::Lsm,
            (Some(Vertex::Medium), Some(Vertex::Surface), false) => Component::Lms,
            (Some(Vertex::Medium), Some(Vertex::Medium), false) => Component::Lmm,
        }
    }
}

/// [`radiance`], with every contribution handed to `sink` together with the transport
/// component it belongs to, so the path tracer can serve as the reference for each component
/// of the many-light methods.
pub fn radiance_split(
    ts: &TraceScene,
    settings: &PathTracerSettings,
    mut o: Vec3,
    mut d: Vec3,
    mut medium: MediumId,
    s: &mut Sampler,
    sink: &mut impl FnMut(Component, Rgb),
) {
    let scene = &ts.scene;
    let max_depth = settings.max_depth.unwrap_or(u32::MAX);
    let mut class = PathClass::default();
    let mut beta = Rgb::ONE;
    let mut depth = 0u32;
    // The last scattering vertex and the solid-angle pdf of the direction sampled there, for
    // MIS weights when the ray hits an emitter; `specular` when that pdf was a delta.
    let mut prev_p = o;
    let mut prev_pdf = 0.0f32;
    let mut specular = true;
    let mut crossings = 0u32;
    let wanted = settings
        .components
        .iter()
        .zip(Component::ALL)
        .filter(|(w, _)| **w)
        .fold(0u8, |m, (_, c)| m | bit(c));
    let restricted = settings.components.iter().any(|&w| !w);

    loop {
        let m = medium.map(|mi| &scene.media[mi as usize]);
        // A restricted path tracer forces the collision in a homogeneous medium when a surface
        // scattering next could reach no wanted component: the ray is traced to its surface
        // first, to see whether that surface (an emitter, a specular or invisible one) keeps
        // the path alive after all.
        let force = restricted && m.is_some_and(|m| m.density.is_none()) && !class.surface_can_reach(wanted);
        // Otherwise, in a homogeneous medium the collision distance is drawn first and the ray
        // cut there: a surface beyond the collision never needs to be found. Surface data is
        // built only if the ray gets there.
        let flight = if force {
            None
        } else {
            m.and_then(|m| media::Flight::sample(m, beta, s))
        };
        let hit = ts.bvh.closest_hit(o, d, flight.map_or(f32::INFINITY, |f| f.t));
        let tmax = hit.map_or(f32::INFINITY, |h| h.t);

        if let Some(m) = m {
            let forced = match hit {
                Some(h) if force && ends_path(ts, &h, d, &class, wanted) => media::forced_collision(m, tmax, beta, s),
                _ => None,
            };
            let event = match (forced, flight) {
                (Some(e), _) => e,
                (None, Some(f)) => f.event(m, tmax),
                (None, None) => media::sample_distance(m, o, d, tmax, beta, s),
            };
            match event {
                MediumEvent::Scatter { t, weight } => {
                    beta *= weight;
                    depth += 1;
                    if depth > max_depth || beta == Rgb::ZERO {
                        break;
                    }
                    class.scatter(Vertex::Medium);
                    if restricted && !class.can_reach(wanted) {
                        break;
                    }
                    let p = o + d * t;
                    let wo = -d;
                    let phase = HenyeyGreenstein { g: m.g };
                    if wanted & bit(class.component()) != 0
                        && let Some(ls) = ts.lights.sample(scene, p, s)
                    {
                        let f = phase.eval(wo, ls.wi);
                        if f > 0.0 {
                            let tr = ts.shadow_transmittance(p, &ls, medium, s);
                            let w = if ls.pdf > 0.0 {
                                power_heuristic(ls.pdf, phase.pdf(wo, ls.wi))
                            } else {
                                1.0
                            };
                            sink(class.component(), beta * tr * ls.contribution * (f * w));
                        }
                    }
                    let ps = phase.sample(wo, s.next_2d());
                    beta *= ps.weight;
                    prev_p = p;
                    prev_pdf = ps.pdf;
                    specular = false;
                    o = p;
                    d = ps.wi;
                    if !russian_roulette(&mut beta, depth, settings.rr_depth, s) {
                        break;
                    }
                    continue;
                }
                MediumEvent::Pass { weight } => {
                    beta *= weight;
                    if beta == Rgb::ZERO {
                        break;
                    }
                }
            }
        }

        let Some(h) = hit else { break };
        let sh = ts.surface(&h);
        let mat = ts.material(&sh);

        if mat.is_emissive() && (mat.double_sided || sh.ng.dot(d) < 0.0) && wanted & bit(class.component()) != 0 {
            let w = if specular {
                1.0
            } else {
                power_heuristic(prev_pdf, ts.lights.pdf_hit(scene, prev_p, sh.tri, sh.p))
            };
            sink(class.component(), beta * mat.emission * w);
        }

        let Some(bsdf) = scene.bsdf_at(sh.material, sh.uv) else {
            // Invisible medium boundary: switch media and carry on in the same direction.
            medium = ts.medium_beyond(&sh, d, medium);
            crossings += 1;
            if crossings > MAX_CROSSINGS {
                break;
            }
            o = sh.spawn(d);
            continue;
        };

        depth += 1;
        if depth > max_depth {
            break;
        }
        if !bsdf.is_delta() {
            class.scatter(Vertex::Surface);
            if restricted && !class.can_reach(wanted) {
                break;
            }
        }
        let frame = Frame::from_normal(sh.ns);
        let wo = -d;
        let wo_local = frame.to_local(wo);
        // Opaque surfaces reflect on the side the ray came from; a shading normal must not let
        // light leak through (both directions must agree with the geometric normal's side).
        let transmissive = matches!(bsdf, beamlight_scene::bsdf::Bsdf::Glass { .. });

        if !bsdf.is_delta()
            && wanted & bit(class.component()) != 0
            && let Some(ls) = ts.lights.sample(scene, sh.p, s)
        {
            let same_side = sh.ng.dot(ls.wi) * sh.ng.dot(wo) > 0.0;
            let wi_local = frame.to_local(ls.wi);
            let f = bsdf.eval(wo_local, wi_local) * wi_local.z.abs();
            if (same_side || transmissive) && f != Rgb::ZERO {
                let tr = ts.shadow_transmittance(sh.spawn(ls.wi), &ls, medium, s);
                let w = if ls.pdf > 0.0 {
                    power_heuristic(ls.pdf, bsdf.pdf(wo_local, wi_local))
                } else {
                    1.0
                };
                sink(class.component(), beta * f * tr * ls.contribution * w);
            }
        }

        let u = s.next_2d();
        let u_lobe = s.next_1d();
        let Some(bs) = bsdf.sample(wo_local, u, u_lobe) else {
            break;
        };
        let wi = frame.to_world(bs.wi);
        if !transmissive && sh.ng.dot(wi) * sh.ng.dot(wo) <= 0.0 {
            break;
        }
        beta *= bs.weight;
        prev_p = sh.p;
        prev_pdf = bs.pdf;
        specular = bs.is_delta;
        if bs.is_delta {
            class.specular_bounce();
            if restricted && !class.can_reach(wanted) {
                break;
            }
        }
        medium = ts.medium_beyond(&sh, wi, medium);
        o = sh.spawn(wi);
        d = wi;
        if !russian_roulette(&mut beta, depth, settings.rr_depth, s) {
            break;
        }
    }
    // A throughput gone NaN or infinite (a weight or pdf bug upstream) has ended the path;
    // handed on as a non-finite sample it is counted by the film (`Film::rejected`, reported
    // and required to be 0 by the tests) instead of leaving the pixel a little dark unseen.
    if !beta.is_finite() {
        sink(class.component(), Rgb::splat(f32::NAN));
    }
}

/// Whether the path ends at surface hit `h` for a path tracer restricted to `wanted`: the
/// surface scatters (neither specular nor an invisible boundary, which keep the path's class),
/// scattering there reaches no wanted component, and its emission, if seen, is not wanted.
fn ends_path(ts: &TraceScene, h: &crate::bvh::Hit, d: Vec3, class: &PathClass, wanted: u8) -> bool {
    let sh = ts.surface(h);
    let mat = ts.material(&sh);
    let seen_emitter = mat.is_emissive() && (mat.double_sided || sh.ng.dot(d) < 0.0);
    if seen_emitter && wanted & bit(class.component()) != 0 {
        return false;
    }
    match ts.scene.bsdf_at(sh.material, sh.uv) {
        Some(bsdf) => !bsdf.is_delta() && !class.surface_can_reach(wanted),
        None => false,
    }
}

/// Highest survival probability Russian roulette grants once it has started. Capping it below 1
/// (as Mitsuba 3 does) keeps the estimator unbiased and guarantees that every path ends, even
/// one wandering through an unbounded, non-absorbing medium where the throughput never drops.
const MAX_SURVIVAL: f32 = 0.95;

/// Russian roulette on the largest throughput channel; returns false when the path ends.
fn russian_roulette(beta: &mut Rgb, depth: u32, rr_depth: u32, s: &mut Sampler) -> bool {
    if !beta.is_finite() || *beta == Rgb::ZERO {
        return false;
    }
    if depth < rr_depth {
        return true;
    }
    let q = beta.max_element().min(MAX_SURVIVAL);
    if s.next_1d() >= q {
        return false;
    }
    *beta /= q;
    true
}
