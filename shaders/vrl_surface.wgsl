//! use lib/media.wgsl
//! use lib/surface_record.wgsl
//! use lib/gather_entry.wgsl
// Lsm with virtual ray lights: every VRL against one shading point, the twin of
// `beamlight_trace::vrl::vrl_to_surface` (the point on the VRL sampled equiangularly).

fn vrl_to_surface(sp: ShadingPoint, f_sp: Bsdf, vrl: LightSegment, s: ptr<function, Sampler>) -> vec3<f32> {
    let m = media[vrl.medium];
    if degenerate_length(vrl.length) {
        return degenerate_estimate(vrl.length);
    }
    let sample = equiangular(vrl.origin, vrl.dir, 0.0, vrl.length, sp.pos, next_1d(s));
    let u = sample.x;
    let pdf = sample.y;
    if !(pdf > 0.0) {
        return failed_estimate();
    }
    let y = vrl.origin + vrl.dir * u;
    let v = y - sp.pos;
    let dist = length(v);
    if !(dist > 0.0) {
        return vec3<f32>(0.0);
    }
    let w = v / dist;
    let frame = frame_from_normal(sp.normal);
    let wo_l = to_local(frame, sp.wo);
    let wi_l = to_local(frame, w);
    // At y the light travels along dir and leaves towards the shading point (−w).
    let phase = hg_eval(m.g, -w, -vrl.dir);
    let f = bsdf_eval(f_sp, wo_l, wi_l) * abs(wi_l.z) * phase;
    if is_black(f) {
        return vec3<f32>(0.0);
    }
    let sigma_s = m.sigma_s * medium_density(vrl.medium, y);
    let t_vrl = transmittance(vrl.medium, vrl.origin, vrl.dir, u, s);
    let origin = spawn_from_triangle(sp.tri, sp.pos, w);
    let tr = shadow_transmittance(origin, y, sp.medium, s);
    return sp.throughput * vrl.power * sigma_s * t_vrl * f * tr * falloff(dist * dist) / pdf;
}

// The hooks of the shared entry point (lib/gather_entry.wgsl) that lib/surface_record.wgsl
// leaves to the kernel.
const GATHER_KIND: u32 = KIND_VRL_TO_SURFACE;

// Virtual ray and point lights are gathered without light selection: no tree, so the entry
// point never asks for a receiver.
fn light_tree_of(r: GatherRecord) -> vec2<u32> {
    return vec2<u32>(0u, 0u);
}

fn light_contribution(r: GatherRecord, light: u32, s: ptr<function, Sampler>) -> vec3<f32> {
    return vrl_to_surface(r.sp, r.f_sp, vrls[light], s);
}
