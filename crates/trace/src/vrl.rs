//! Virtual ray lights (Novák et al. 2012): light scattered out of a recorded light-path segment
//! in a medium, gathered at camera shading points (`Lsm`, media → surface) and along camera
//! media segments (`Lmm`, media → media), unclamped, with the VRL paper's importance sampling:
//! * `Lsm`: the point on the VRL equiangularly (∝ 1/distance²) as seen from the shading point;
//! * `Lmm`: two stages — the point on the VRL ∝ 1/(distance to the infinite camera line)², then
//!   the point on the camera segment equiangularly towards it.
//!
//! Each function returns the radiance per light path traced (divide a set's sum by its paths);
//! `clamp` is the minimum distance of [`falloff`] (0: unclamped).
use crate::{
    TraceScene,
    camera_paths::{MediaSegment, ShadingPoint},
    failed::{FAILED_ESTIMATE, degenerate_length},
    light_paths::LightSegment,
    lights::LightSample,
    media,
    vpl::falloff,
};
use beamlight_scene::{Rgb, frame::Frame, phase::HenyeyGreenstein, rng::Sampler, sampling};
use glam::{Vec2, Vec3};

/// A shadow ray's end at a point inside a medium (no surface to step off).
fn medium_target(from: Vec3, to: Vec3) -> Option<LightSample> {
    let v = to - from;
    let dist = v.length();
    (dist > 0.0).then(|| LightSample {
        p: to,
        n: None,
        wi: v / dist,
        dist,
        target: to,
        contribution: Rgb::ONE,
        pdf: 0.0,
    })
}

/// Light a VRL scatters towards a camera shading point (`Lsm`).
pub fn vrl_to_surface(ts: &TraceScene, sp: &ShadingPoint, vrl: &LightSegment, clamp: f32, s: &mut Sampler) -> Rgb {
    let scene = &ts.scene;
    let m = &scene.media[vrl.medium as usize];
    let (ov, dv) = (Vec3::from(vrl.origin), Vec3::from(vrl.dir));
    let p = Vec3::from(sp.pos);
    if let Some(v) = degenerate_length(vrl.length) {
        return v;
    }
    let (u, pdf) = sampling::equiangular(ov, dv, 0.0, vrl.length, p, s.next_1d());
    if !(pdf > 0.0) {
        return FAILED_ESTIMATE;
    }
    let y = ov + dv * u;
    let Some(shadow) = medium_target(p, y) else {
        return Rgb::ZERO;
    };
    let w = shadow.wi; // from the shading point towards the VRL point
    let Some(f_sp) = scene.bsdf_at(sp.material, Some(Vec2::from(sp.uv))) else {
        return Rgb::ZERO;
    };
    let frame = Frame::from_normal(Vec3::from(sp.normal));
    let (wo_l, wi_l) = (frame.to_local(Vec3::from(sp.wo)), frame.to_local(w));
    // At y the light travels along dv and leaves towards the shading point (−w).
    let phase = HenyeyGreenstein { g: m.g }.eval(-w, -dv);
    let f = f_sp.eval(wo_l, wi_l) * wi_l.z.abs() * phase;
    if f == Rgb::ZERO {
        return Rgb::ZERO;
    }
    let sigma_s = m.sigma_s * m.density_at(y);
    let t_vrl = media::transmittance(m, ov, dv, u, s);
    let origin = ts.spawn_from_triangle(sp.tri, p, w);
    let tr = ts.shadow_transmittance(origin, &shadow, sp.medium(), s);
    let d2 = shadow.dist * shadow.dist;
    Rgb::from(sp.throughput) * Rgb::from(vrl.power) * sigma_s * t_vrl * f * tr * falloff(d2, clamp) / pdf
}

/// The point of closest approach and its distance, in the VRL's parameter u, for the squared
/// distance from y(u) = ov + u·dv to the infinite line (oc, dc): that distance² is
/// |A + uB|² = |B|² ((u − u0)² + h²) (A, B the parts of ov − oc and dv perpendicular to dc),
/// so a density ∝ 1/distance² is the equiangular density about the point (u0, h) of the
/// (u, ·) plane. `None` when the lines are parallel (the distance does not vary).
pub(crate) fn near_line_apex(ov: Vec3, dv: Vec3, oc: Vec3, dc: Vec3, min_dist: f32) -> Option<Vec3> {
    let a = (ov - oc) - dc * (ov - oc).dot(dc);
    let b = dv - dc * dv.dot(dc);
    let bb = b.length_squared();
    (bb > 1e-12).then(|| {
        let u0 = -a.dot(b) / bb;
        let h = ((a.length_squared() - a.dot(b) * a.dot(b) / bb).max(0.0) / bb).sqrt();
        // A floor on the distance itself is a floor of min_dist / |B| on h.
        Vec3::new(u0, h.max(min_dist / bb.sqrt()), 0.0)
    })
}

/// Stage 1 of the two-stage `Lmm` sampling (VRL paper): u ∈ [0, len] on the VRL with density
/// ∝ 1 / max(dist(y(u), camera line), `min_dist`)² — uniform for parallel lines. Returns
/// (u, pdf).
pub fn sample_near_line(ov: Vec3, dv: Vec3, len: f32, oc: Vec3, dc: Vec3, min_dist: f32, xi: f32) -> (f32, f32) {
    match near_line_apex(ov, dv, oc, dc, min_dist) {
        Some(c) => sampling::equiangular(Vec3::ZERO, Vec3::X, 0.0, len, c, xi),
        None => (xi * len, 1.0 / len),
    }
}

/// The density of [`sample_near_line`] at u.
pub fn near_line_pdf(ov: Vec3, dv: Vec3, len: f32, oc: Vec3, dc: Vec3, min_dist: f32, u: f32) -> f32 {
    if !(0.0..=len).contains(&u) {
        return 0.0;
    }
    match near_line_apex(ov, dv, oc, dc, min_dist) {
        Some(c) => sampling::equiangular_pdf(Vec3::ZERO, Vec3::X, 0.0, len, c, u),
        None => 1.0 / len,
    }
}

/// Light a VRL scatters into a camera media segment (`Lmm`).
pub fn vrl_to_media(ts: &TraceScene, seg: &MediaSegment, vrl: &LightSegment, clamp: f32, s: &mut Sampler) -> Rgb {
    let scene = &ts.scene;
    let (mv, mc) = (&scene.media[vrl.medium as usize], &scene.media[seg.medium as usize]);
    if !crate::components::gathers_in_medium(mc.g) {
        // A sharp phase function: the camera path's walk carries this light (`components`).
        return Rgb::ZERO;
    }
    let (ov, dv) = (Vec3::from(vrl.origin), Vec3::from(vrl.dir));
    let (oc, dc) = (Vec3::from(seg.origin), Vec3::from(seg.dir));
    if let Some(v) = degenerate_length(vrl.length).or(degenerate_length(seg.length)) {
        return v;
    }
    // Stage 1: u on the VRL ∝ 1 / dist(y(u), camera line)².
    let (u, pdf_u) = sample_near_line(ov, dv, vrl.length, oc, dc, 0.0, s.next_1d());
    if !(pdf_u > 0.0) || !pdf_u.is_finite() {
        return FAILED_ESTIMATE;
    }
    let y = ov + dv * u;
    // Stage 2: t on the camera segment equiangularly towards y.
    let (t, pdf_t) = sampling::equiangular(oc, dc, 0.0, seg.length, y, s.next_1d());
    if !(pdf_t > 0.0) {
        return FAILED_ESTIMATE;
    }
    let x = oc + dc * t;
    let Some(shadow) = medium_target(x, y) else {
        return Rgb::ZERO;
    };
    let w = shadow.wi; // from x towards y
    let phase_y = HenyeyGreenstein { g: mv.g }.eval(-w, -dv);
    let phase_x = HenyeyGreenstein { g: mc.g }.eval(-dc, w);
    let sigma_y = mv.sigma_s * mv.density_at(y);
    let sigma_x = mc.sigma_s * mc.density_at(x);
    let t_vrl = media::transmittance(mv, ov, dv, u, s);
    let t_cam = media::transmittance(mc, oc, dc, t, s);
    let tr = ts.shadow_transmittance(x, &shadow, Some(seg.medium), s);
    let d2 = shadow.dist * shadow.dist;
    Rgb::from(seg.throughput)
        * Rgb::from(vrl.power)
        * sigma_y
        * t_vrl
        * sigma_x
        * t_cam
        * tr
        * (phase_x * phase_y)
        * falloff(d2, clamp)
        / (pdf_u * pdf_t)
}
