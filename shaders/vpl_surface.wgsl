//! use lib/media.wgsl
//! use lib/surface_record.wgsl
//! use lib/gather_entry.wgsl
// Lss with virtual point lights: every VPL against one shading point, the twin of
// `beamlight_trace::vpl::vpl_to_surface` (clamped when params.clamp > 0).

fn vpl_to_surface(sp: ShadingPoint, f_sp: Bsdf, vpl: SurfaceVertex, f_vpl: Bsdf, s: ptr<function, Sampler>) -> vec3<f32> {
    let to = vpl.pos - sp.pos;
    let d2 = dot(to, to);
    if !(d2 > 0.0) {
        return vec3<f32>(0.0);
    }
    let dist = sqrt(d2);
    let w = to / dist;
    let sp_frame = frame_from_normal(sp.normal);
    let vpl_frame = frame_from_normal(vpl.normal);
    let wo_sp = to_local(sp_frame, sp.wo);
    let wi_sp = to_local(sp_frame, w);
    let wi_vpl = to_local(vpl_frame, vpl.wi);
    let wo_vpl = to_local(vpl_frame, -w);
    let f = bsdf_eval(f_sp, wo_sp, wi_sp) * abs(wi_sp.z) * bsdf_eval(f_vpl, wo_vpl, wi_vpl) * abs(wo_vpl.z);
    if is_black(f) {
        return vec3<f32>(0.0);
    }
    let origin = spawn_from_triangle(sp.tri, sp.pos, w);
    let target_point = spawn_from_triangle(vpl.tri, vpl.pos, -w);
    let tr = shadow_transmittance(origin, target_point, sp.medium, s);
    return sp.throughput * vpl.power * f * tr * falloff(d2);
}

// The hooks of the shared entry point (lib/gather_entry.wgsl) that lib/surface_record.wgsl
// leaves to the kernel.
const GATHER_KIND: u32 = KIND_VPL_TO_SURFACE;

// Virtual ray and point lights are gathered without light selection: no tree, so the entry
// point never asks for a receiver.
fn light_tree_of(r: GatherRecord) -> vec2<u32> {
    return vec2<u32>(0u, 0u);
}

fn light_contribution(r: GatherRecord, light: u32, s: ptr<function, Sampler>) -> vec3<f32> {
    return vpl_to_surface(r.sp, r.f_sp, vpls[light], vpl_bsdfs[light], s);
}
