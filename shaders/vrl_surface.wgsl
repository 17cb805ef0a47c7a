//! use lib/gather.wgsl
//! use lib/media.wgsl
// Lsm with virtual ray lights: every VRL against one shading point, the twin of
// `beamlight_trace::vrl::vrl_to_surface` (the point on the VRL sampled equiangularly).

fn vrl_to_surface(sp: ShadingPoint, f_sp: Bsdf, vrl: LightSegment, s: ptr<function, Sampler>) -> vec3<f32> {
    let m = media[vrl.medium];
    let sample = equiangular(vrl.origin, vrl.dir, 0.0, vrl.length, sp.pos, next_1d(s));
    let u = sample.x;
    let pdf = sample.y;
    if !(pdf > 0.0) {
        return vec3<f32>(0.0);
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
        var s = pair_sampler(KIND_VRL_TO_SURFACE, i, j);
        sum += admit(vrl_to_surface(sp, f_sp, vrls[j], &s), &discarded);
    }
    let total = admit(injected(sum * params.scale, i), &discarded);
    gathered[i] = vec4<f32>(total, f32(discarded));
}
