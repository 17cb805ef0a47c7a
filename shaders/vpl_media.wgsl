//! use lib/gather.wgsl
//! use lib/media.wgsl
// Lms with virtual point lights: every VPL against one camera media segment, the twin of
// `beamlight_trace::vpl::vpl_to_media` (the point on the segment sampled equiangularly).

fn vpl_to_media(seg: MediaSegment, vpl: SurfaceVertex, f_vpl: Bsdf, s: ptr<function, Sampler>) -> vec3<f32> {
    let m = media[seg.medium];
    if !gathers_in_medium(m.g) {
        return vec3<f32>(0.0);
    }
    let sample = equiangular(seg.origin, seg.dir, 0.0, seg.length, vpl.pos, next_1d(s));
    let t = sample.x;
    let pdf = sample.y;
    if !(pdf > 0.0) {
        return vec3<f32>(0.0);
    }
    let x = seg.origin + seg.dir * t;
    let to = vpl.pos - x;
    let d2 = dot(to, to);
    if !(d2 > 0.0) {
        return vec3<f32>(0.0);
    }
    let dist = sqrt(d2);
    let w = to / dist;
    let vpl_frame = frame_from_normal(vpl.normal);
    let wi_vpl = to_local(vpl_frame, vpl.wi);
    let wo_vpl = to_local(vpl_frame, -w);
    let phase = hg_eval(m.g, -seg.dir, w);
    let f = bsdf_eval(f_vpl, wo_vpl, wi_vpl) * abs(wo_vpl.z) * phase;
    if is_black(f) {
        return vec3<f32>(0.0);
    }
    let sigma_s = m.sigma_s * medium_density(seg.medium, x);
    let t_cam = transmittance(seg.medium, seg.origin, seg.dir, t, s);
    let target_point = spawn_from_triangle(vpl.tri, vpl.pos, -w);
    let tr = shadow_transmittance(x, target_point, seg.medium, s);
    return seg.throughput * sigma_s * t_cam * vpl.power * f * tr * falloff(d2) / pdf;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = record_index(gid);
    if i >= params.records {
        return;
    }
    let seg = media_segments[i];
    var sum = vec3<f32>(0.0);
    var discarded = 0u;
    for (var j = 0u; j < params.lights; j++) {
        var s = pair_sampler(KIND_VPL_TO_MEDIA, i, j);
        sum += admit(vpl_to_media(seg, vpls[j], vpl_bsdfs[j], &s), &discarded);
    }
    let total = admit(injected(sum * params.scale, i), &discarded);
    gathered[i] = vec4<f32>(total, f32(discarded));
}
