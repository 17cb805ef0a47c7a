//! Direct light (the `Direct` component) for camera gather data: light arriving at a shading
//! point or scattered along a camera media segment straight from an emitter. Emitters seen
//! directly are already in `GatherSet::emitted`.
use crate::{
    TraceScene,
    camera_paths::{MediaSegment, ShadingPoint},
    context::MAX_CROSSINGS,
    failed::{FAILED_ESTIMATE, degenerate_length},
    media,
};
use beamlight_scene::{Rgb, frame::Frame, phase::HenyeyGreenstein, rng::Sampler, sampling};
use glam::{Vec2, Vec3};

/// Direct light at a shading point: one light sample and one BSDF sample, combined with the
/// power heuristic (as the path tracer does at its first vertex).
pub fn direct_at_surface(ts: &TraceScene, sp: &ShadingPoint, s: &mut Sampler) -> Rgb {
    let scene = &ts.scene;
    let Some(bsdf) = scene.bsdf_at(sp.material, Some(Vec2::from(sp.uv))) else {
        return Rgb::ZERO;
    };
    let p = Vec3::from(sp.pos);
    let ng = scene.triangles[sp.tri as usize].cross().normalize();
    let frame = Frame::from_normal(Vec3::from(sp.normal));
    let wo = Vec3::from(sp.wo);
    let wo_l = frame.to_local(wo);
    let mut l = Rgb::ZERO;
    // Light sampling.
    if let Some(ls) = ts.lights.sample(scene, p, s) {
        let wi_l = frame.to_local(ls.wi);
        let f = bsdf.eval(wo_l, wi_l) * wi_l.z.abs();
        if ng.dot(ls.wi) * ng.dot(wo) > 0.0 && f != Rgb::ZERO {
            let origin = ts.spawn_from_triangle(sp.tri, p, ls.wi);
            let tr = ts.shadow_transmittance(origin, &ls, sp.medium(), s);
            let w = if ls.pdf > 0.0 {
                sampling::power_heuristic(ls.pdf, bsdf.pdf(wo_l, wi_l))
            } else {
                1.0
            };
            l += f * tr * ls.contribution * w;
        }
    }
    // BSDF sampling: the emitter the sampled ray reaches, if any, with the MIS weight.
    if let Some(bs) = bsdf.sample(wo_l, s.next_2d(), s.next_1d()) {
        let wi = frame.to_world(bs.wi);
        if !bs.is_delta && ng.dot(wi) * ng.dot(wo) > 0.0 {
            let o = ts.spawn_from_triangle(sp.tri, p, wi);
            if let Some((le, light_pdf)) = emitter_along(ts, p, o, wi, sp.medium(), s) {
                l += bs.weight * le * sampling::power_heuristic(bs.pdf, light_pdf);
            }
        }
    }
    Rgb::from(sp.throughput) * l
}

/// Single scattering of direct light along a camera media segment: a point on a light, then
/// a point x on the segment sampled equiangularly towards it (Kulla & Fajardo 2012); at x, the
/// light point and a direction drawn from the phase function, combined with the power
/// heuristic (as the path tracer does). The phase-sampled ray is what finds the light of a
/// forward-scattering medium: with |g| near 1 the lobe is narrower than any emitter, and a
/// light point falls in it almost never. (x's density depends on the light point, but
/// averaged over light points the 1/p(t | light point) factor integrates out, so the
/// phase-sampled term stays unbiased.)
pub fn direct_in_medium(ts: &TraceScene, seg: &MediaSegment, s: &mut Sampler) -> Rgb {
    let scene = &ts.scene;
    let m = &scene.media[seg.medium as usize];
    let (o, d) = (Vec3::from(seg.origin), Vec3::from(seg.dir));
    if let Some(v) = degenerate_length(seg.length) {
        return v;
    }
    let Some(lp) = ts.lights.sample_point(scene, s) else {
        return Rgb::ZERO;
    };
    let directional = ts.lights.connect(scene, &lp, o).is_some_and(|ls| !ls.dist.is_finite());
    let (t, pdf_t) = if directional {
        // No point to aim at: sample the segment uniformly.
        (s.next_1d() * seg.length, 1.0 / seg.length)
    } else {
        sampling::equiangular(o, d, 0.0, seg.length, lp.p, s.next_1d())
    };
    let u_phase = s.next_2d();
    if !(pdf_t > 0.0) || !pdf_t.is_finite() {
        return FAILED_ESTIMATE;
    }
    let x = o + d * t;
    let hg = HenyeyGreenstein { g: m.g };
    let mut l = Rgb::ZERO;
    if let Some(ls) = ts.lights.connect(scene, &lp, x) {
        let phase = hg.eval(-d, ls.wi);
        let tr = ts.shadow_transmittance(x, &ls, Some(seg.medium), s);
        let w = if ls.pdf > 0.0 {
            sampling::power_heuristic(ls.pdf, hg.pdf(-d, ls.wi))
        } else {
            1.0
        };
        l += tr * ls.contribution * phase * w;
    }
    let ps = hg.sample(-d, u_phase);
    if let Some((le, light_pdf)) = emitter_along(ts, x, x, ps.wi, Some(seg.medium), s) {
        l += le * ps.weight * sampling::power_heuristic(ps.pdf, light_pdf);
    }
    let sigma_s = m.sigma_s * m.density_at(x);
    let t_cam = media::transmittance(m, o, d, t, s);
    Rgb::from(seg.throughput) * sigma_s * t_cam * l / pdf_t
}

/// The emitter a ray from `o` (already off its surface, if any) in direction `wi` reaches
/// through invisible medium boundaries: its radiance times the transmittance on the way, and
/// the density with which light sampling from `p` would have drawn that point (solid angle).
fn emitter_along(
    ts: &TraceScene,
    p: Vec3,
    mut o: Vec3,
    wi: Vec3,
    mut medium: Option<u32>,
    s: &mut Sampler,
) -> Option<(Rgb, f32)> {
    let mut tr = Rgb::ONE;
    for _ in 0..MAX_CROSSINGS {
        let (h, hit) = ts.intersect(o, wi, f32::INFINITY)?;
        tr *= ts.medium_transmittance(medium, o, wi, h.t, s);
        let m = ts.material(&hit);
        if m.bsdf.is_none() {
            medium = ts.medium_beyond(&hit, wi, medium);
            o = hit.spawn(wi);
            continue;
        }
        if m.is_emissive() && (m.double_sided || hit.ng.dot(wi) < 0.0) {
            return Some((tr * m.emission, ts.lights.pdf_hit(&ts.scene, p, hit.tri, hit.p)));
        }
        return None;
    }
    None
}
