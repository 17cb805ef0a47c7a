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
    let (u, pdf) = sampling::equiangular(ov, dv, 0.0, vrl.length, p, s.next_1d());
    if !(pdf > 0.0) {
        return Rgb::ZERO;
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

/// Light a VRL scatters into a camera media segment (`Lmm`).
pub fn vrl_to_media(ts: &TraceScene, seg: &MediaSegment, vrl: &LightSegment, clamp: f32, s: &mut Sampler) -> Rgb {
    let scene = &ts.scene;
    let (mv, mc) = (&scene.media[vrl.medium as usize], &scene.media[seg.medium as usize]);
    let (ov, dv) = (Vec3::from(vrl.origin), Vec3::from(vrl.dir));
    let (oc, dc) = (Vec3::from(seg.origin), Vec3::from(seg.dir));
    // Stage 1: u on the VRL with density ∝ 1 / dist(y(u), camera line)². That squared distance
    // is |A + uB|² = |B|² ((u − u0)² + h²): an equiangular density in the parameter u.
    let a = (ov - oc) - dc * (ov - oc).dot(dc);
    let b = dv - dc * dv.dot(dc);
    let bb = b.length_squared();
    let (u, pdf_u) = if bb > 1e-12 {
        let u0 = -a.dot(b) / bb;
        let h = ((a.length_squared() - a.dot(b) * a.dot(b) / bb).max(0.0) / bb).sqrt();
        sampling::equiangular(Vec3::ZERO, Vec3::X, 0.0, vrl.length, Vec3::new(u0, h, 0.0), s.next_1d())
    } else {
        // Parallel lines: every point is equally far; sample uniformly.
        (s.next_1d() * vrl.length, 1.0 / vrl.length)
    };
    if !(pdf_u > 0.0) || !pdf_u.is_finite() {
        return Rgb::ZERO;
    }
    let y = ov + dv * u;
    // Stage 2: t on the camera segment equiangularly towards y.
    let (t, pdf_t) = sampling::equiangular(oc, dc, 0.0, seg.length, y, s.next_1d());
    if !(pdf_t > 0.0) {
        return Rgb::ZERO;
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
