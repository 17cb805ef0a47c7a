//! use lib/media.wgsl
//! use lib/media_record.wgsl
//! use lib/gather_entry.wgsl
// Lms with virtual point lights: every VPL against one camera media segment, the twin of
// `beamlight_trace::vpl::vpl_to_media` (the point on the segment sampled equiangularly).

fn vpl_to_media(seg: MediaSegment, vpl: SurfaceVertex, f_vpl: Bsdf, s: ptr<function, Sampler>) -> vec3<f32> {
    let m = media[seg.medium];
    if !gathers_in_medium(m.g) {
        return vec3<f32>(0.0);
    }
    if degenerate_length(seg.length) {
        return degenerate_estimate(seg.length);
    }
    let sample = equiangular(seg.origin, seg.dir, 0.0, seg.length, vpl.pos, next_1d(s));
    let t = sample.x;
    let pdf = sample.y;
    if !(pdf > 0.0) {
        return failed_estimate();
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

// The hooks of the shared entry point (lib/gather_entry.wgsl) that lib/media_record.wgsl
// leaves to the kernel.
const GATHER_KIND: u32 = KIND_VPL_TO_MEDIA;

// Virtual ray and point lights are gathered without light selection: no tree, so the entry
// point never asks for a receiver.
fn light_tree_of(r: GatherRecord) -> vec2<u32> {
    return vec2<u32>(0u, 0u);
}

fn light_contribution(r: GatherRecord, light: u32, s: ptr<function, Sampler>) -> vec3<f32> {
    return vpl_to_media(r.seg, vpls[light], vpl_bsdfs[light], s);
}
