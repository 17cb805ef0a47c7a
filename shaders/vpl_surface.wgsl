//! use lib/gather.wgsl
//! use lib/media.wgsl
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

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = record_index(gid);
    if i >= params.records {
        return;
    }
    let sp = shading_points[i];
    let f_sp = point_bsdfs[i];
    var sum = vec3<f32>(0.0);
    var discarded = 0u;
    for (var j = 0u; j < params.lights; j++) {
        var s = pair_sampler(KIND_VPL_TO_SURFACE, i, j);
        sum += admit(vpl_to_surface(sp, f_sp, vpls[j], vpl_bsdfs[j], &s), &discarded);
    }
    let total = admit(injected(sum * params.scale, i), &discarded);
    gathered[i] = vec4<f32>(total, f32(discarded));
}
