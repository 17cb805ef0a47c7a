//! use lib/media.wgsl
//! use lib/media_record.wgsl
//! use lib/gather_entry.wgsl
// Lmm with virtual ray lights: every VRL against one camera media segment, the twin of
// `beamlight_trace::vrl::vrl_to_media` with the VRL paper's two-stage sampling.

// `vrl::sample_near_line` without a distance floor: u on the VRL ∝ 1 / (distance to the
// camera line)², uniform for parallel lines. Returns (u, pdf).
fn sample_near_line(ov: vec3<f32>, dv: vec3<f32>, len: f32, oc: vec3<f32>, dc: vec3<f32>, xi: f32) -> vec2<f32> {
    let a = (ov - oc) - dc * dot(ov - oc, dc);
    let b = dv - dc * dot(dv, dc);
    let bb = dot(b, b);
    if !(bb > 1e-12) {
        return vec2<f32>(xi * len, 1.0 / len);
    }
    let ab = dot(a, b);
    let u0 = -ab / bb;
    let h = sqrt(max(dot(a, a) - ab * ab / bb, 0.0) / bb);
    return equiangular(vec3<f32>(0.0), vec3<f32>(1.0, 0.0, 0.0), 0.0, len, vec3<f32>(u0, h, 0.0), xi);
}

fn vrl_to_media(seg: MediaSegment, vrl: LightSegment, s: ptr<function, Sampler>) -> vec3<f32> {
    let mv = media[vrl.medium];
    let mc = media[seg.medium];
    if !gathers_in_medium(mc.g) {
        return vec3<f32>(0.0);
    }
    if degenerate_length(vrl.length) {
        return degenerate_estimate(vrl.length);
    }
    if degenerate_length(seg.length) {
        return degenerate_estimate(seg.length);
    }
    let stage1 = sample_near_line(vrl.origin, vrl.dir, vrl.length, seg.origin, seg.dir, next_1d(s));
    let u = stage1.x;
    let pdf_u = stage1.y;
    if !(pdf_u > 0.0) || !is_finite(pdf_u) {
        return failed_estimate();
    }
    let y = vrl.origin + vrl.dir * u;
    let stage2 = equiangular(seg.origin, seg.dir, 0.0, seg.length, y, next_1d(s));
    let t = stage2.x;
    let pdf_t = stage2.y;
    if !(pdf_t > 0.0) {
        return failed_estimate();
    }
    let x = seg.origin + seg.dir * t;
    let v = y - x;
    let dist = length(v);
    if !(dist > 0.0) {
        return vec3<f32>(0.0);
    }
    let w = v / dist;
    let phase_y = hg_eval(mv.g, -w, -vrl.dir);
    let phase_x = hg_eval(mc.g, -seg.dir, w);
    let sigma_y = mv.sigma_s * medium_density(vrl.medium, y);
    let sigma_x = mc.sigma_s * medium_density(seg.medium, x);
    let t_vrl = transmittance(vrl.medium, vrl.origin, vrl.dir, u, s);
    let t_cam = transmittance(seg.medium, seg.origin, seg.dir, t, s);
    let tr = shadow_transmittance(x, y, seg.medium, s);
    return seg.throughput * vrl.power * sigma_y * t_vrl * sigma_x * t_cam * tr * (phase_x * phase_y)
        * falloff(dist * dist) / (pdf_u * pdf_t);
}

// The hooks of the shared entry point (lib/gather_entry.wgsl) that lib/media_record.wgsl
// leaves to the kernel.
const GATHER_KIND: u32 = KIND_VRL_TO_MEDIA;

// Virtual ray and point lights are gathered without light selection: no tree, so the entry
// point never asks for a receiver.
fn light_tree_of(r: GatherRecord) -> vec2<u32> {
    return vec2<u32>(0u, 0u);
}

fn light_contribution(r: GatherRecord, light: u32, s: ptr<function, Sampler>) -> vec3<f32> {
    return vrl_to_media(r.seg, vrls[light], s);
}
