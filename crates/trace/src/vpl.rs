//! Virtual point lights: the light a recorded light-path vertex sends to a camera shading point
//! (`Lss`, surface → surface) or scatters into a camera media segment (`Lms`, surface → media),
//! unclamped. Later estimators (clamped VPLs, virtual spherical lights) build on the same
//! geometry.
use crate::{
    TraceScene,
    camera_paths::{MediaSegment, ShadingPoint},
    failed::{FAILED_ESTIMATE, degenerate_length},
    light_paths::SurfaceVertex,
    lights::LightSample,
    media,
};
use beamlight_scene::{Rgb, frame::Frame, phase::HenyeyGreenstein, rng::Sampler, sampling};
use glam::{Vec2, Vec3};

/// The inverse-square falloff between a virtual light and a gather point, `1 / max(d², c²)`:
/// with `clamp` c = 0 exact (unclamped, unbiased but singular as d → 0); with c > 0 the
/// clamped variant the VRL paper compares against, which bounds every contribution and loses
/// the energy of all pairs closer than c.
#[inline]
pub fn falloff(d2: f32, clamp: f32) -> f32 {
    1.0 / d2.max(clamp * clamp)
}

/// Radiance a VPL sends to the pixel of `sp`, per light path traced (divide the sum over a
/// light set by its path count): Φ · f_vpl(wi → ω) |cos| · f_sp(ω → wo) |cos| / d² · T · V.
/// The shadow ray starts in the shading point's medium.
pub fn vpl_to_surface(ts: &TraceScene, sp: &ShadingPoint, vpl: &SurfaceVertex, clamp: f32, s: &mut Sampler) -> Rgb {
    let scene = &ts.scene;
    let (p, q) = (Vec3::from(sp.pos), Vec3::from(vpl.pos));
    let to = q - p;
    let d2 = to.length_squared();
    if !(d2 > 0.0) {
        return Rgb::ZERO;
    }
    let dist = d2.sqrt();
    let w = to / dist; // from the shading point towards the VPL
    let (Some(f_sp), Some(f_vpl)) = (
        scene.bsdf_at(sp.material, Some(Vec2::from(sp.uv))),
        scene.bsdf_at(vpl.material, Some(Vec2::new(vpl.u, vpl.v))),
    ) else {
        return Rgb::ZERO;
    };
    let sp_frame = Frame::from_normal(Vec3::from(sp.normal));
    let vpl_frame = Frame::from_normal(Vec3::from(vpl.normal));
    let (wo_sp, wi_sp) = (sp_frame.to_local(Vec3::from(sp.wo)), sp_frame.to_local(w));
    let (wi_vpl, wo_vpl) = (vpl_frame.to_local(Vec3::from(vpl.wi)), vpl_frame.to_local(-w));
    let f = f_sp.eval(wo_sp, wi_sp) * wi_sp.z.abs() * f_vpl.eval(wo_vpl, wi_vpl) * wo_vpl.z.abs();
    if f == Rgb::ZERO {
        return Rgb::ZERO;
    }
    let origin = ts.spawn_from_triangle(sp.tri, p, w);
    let shadow = shadow_to_vpl(ts, vpl, w, dist);
    let tr = ts.shadow_transmittance(origin, &shadow, sp.medium(), s);
    Rgb::from(sp.throughput) * Rgb::from(vpl.power) * f * tr * falloff(d2, clamp)
}

/// A shadow ray's end at a VPL seen along `w` from `dist` away: just off the VPL's surface on
/// the viewer's side.
fn shadow_to_vpl(ts: &TraceScene, vpl: &SurfaceVertex, w: Vec3, dist: f32) -> LightSample {
    let q = Vec3::from(vpl.pos);
    let target = ts.spawn_from_triangle(vpl.tri, q, -w);
    let n = ts.scene.triangles[vpl.tri as usize].cross().normalize();
    LightSample {
        p: q,
        n: Some(n),
        wi: w,
        dist,
        target,
        contribution: Rgb::ONE,
        pdf: 0.0,
    }
}

/// Radiance a VPL scatters into the pixel of a camera media segment (`Lms`, surface → media),
/// per light path traced. The point on the segment is sampled equiangularly towards the VPL
/// (density ∝ 1/distance², which cancels the VPL's own falloff).
pub fn vpl_to_media(ts: &TraceScene, seg: &MediaSegment, vpl: &SurfaceVertex, clamp: f32, s: &mut Sampler) -> Rgb {
    let scene = &ts.scene;
    let m = &scene.media[seg.medium as usize];
    if !crate::components::gathers_in_medium(m.g) {
        // A sharp phase function: the camera path's walk carries this light (`components`).
        return Rgb::ZERO;
    }
    let (o, d) = (Vec3::from(seg.origin), Vec3::from(seg.dir));
    let q = Vec3::from(vpl.pos);
    if let Some(v) = degenerate_length(seg.length) {
        return v;
    }
    let (t, pdf) = sampling::equiangular(o, d, 0.0, seg.length, q, s.next_1d());
    if !(pdf > 0.0) {
        return FAILED_ESTIMATE;
    }
    let x = o + d * t;
    let to = q - x;
    let d2 = to.length_squared();
    if !(d2 > 0.0) {
        return Rgb::ZERO;
    }
    let dist = d2.sqrt();
    let w = to / dist;
    let Some(f_vpl) = scene.bsdf_at(vpl.material, Some(Vec2::new(vpl.u, vpl.v))) else {
        return Rgb::ZERO;
    };
    let vpl_frame = Frame::from_normal(Vec3::from(vpl.normal));
    let (wi_vpl, wo_vpl) = (vpl_frame.to_local(Vec3::from(vpl.wi)), vpl_frame.to_local(-w));
    let phase = HenyeyGreenstein { g: m.g }.eval(-d, w);
    let f = f_vpl.eval(wo_vpl, wi_vpl) * wo_vpl.z.abs() * phase;
    if f == Rgb::ZERO {
        return Rgb::ZERO;
    }
    let sigma_s = m.sigma_s * m.density_at(x);
    let t_cam = media::transmittance(m, o, d, t, s);
    let shadow = shadow_to_vpl(ts, vpl, w, dist);
    let tr = ts.shadow_transmittance(x, &shadow, Some(seg.medium), s);
    Rgb::from(seg.throughput) * sigma_s * t_cam * Rgb::from(vpl.power) * f * tr * falloff(d2, clamp) / pdf
}
