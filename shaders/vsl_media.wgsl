//! use lib/vbl.wgsl
//! use lib/light_tree.wgsl
// Lms with virtual spherical lights: every VPL, inflated to radius R, against one camera
// media segment, the twin of `beamlight_trace::vbl::vsl_to_media` (paper §3.3): the camera
// point by a piecewise-linear PDF in the angle about the VPL, then the VSL's cone integrated
// numerically.

fn vsl_to_media(seg: MediaSegment, vpl: SurfaceVertex, f_vpl: Bsdf, s: ptr<function, Sampler>) -> vec3<f32> {
    let m = media[seg.medium];
    if !gathers_in_medium(m.g) {
        return vec3<f32>(0.0);
    }
    let r2 = clean_r2(params.radius2);
    let o = seg.origin;
    let d = seg.dir;
    let q = vpl.pos;
    if !(seg.length > 0.0) || f_vpl.kind == BSDF_NONE {
        return vec3<f32>(0.0);
    }
    let light = surface_lobe(f_vpl, vpl.normal, vpl.wi, -1.0);
    let phase = phase_lobe(m.g, -d, 1.0);
    let line = line_angles(o, d, 0.0, seg.length, q, sqrt(r2));
    let lobe = sharper(light, phase);
    let u_angle = next_1d(s);
    let k = vertex_count(line.theta1 - line.theta0, lobe.scale);
    var values: array<f32, 64>;
    for (var i = 0u; i < k; i++) {
        let x = o + d * vertex_t(line, i, k, 0.0, seg.length);
        var value = 0.0;
        if params.angular_pdf == ANGULAR_PDF_VRL {
            let w = normalize_or_zero(q - x);
            value = luminance_mean(lobe_eval(light, w)) * lobe_eval(phase, w).x;
        } else {
            let cone = vsl_cone(x, q, r2, -d);
            if cone.valid {
                let w = surface_max_dir(light, cone);
                value = luminance_mean(lobe_eval(light, w)) * lobe_eval(phase, w).x;
            }
        }
        values[i] = value;
    }
    let sample = sample_angular(line, &values, k, 0.0, seg.length, u_angle);
    let t = sample.x;
    let pdf = sample.y;
    let rnd = cone_random(s);
    if !(pdf > 0.0) {
        return vec3<f32>(0.0);
    }
    let x = o + d * t;
    let cone = vsl_cone(x, q, r2, -d);
    if !cone.valid {
        return vec3<f32>(0.0);
    }
    let sigma_s = m.sigma_s * medium_density(seg.medium, x);
    let t_cam = transmittance(seg.medium, o, d, t, s);
    let dist = length_glam(q - x);
    // The VSL centre just off its surface, on the side its light arrived from.
    let target_point = spawn_from_triangle(vpl.tri, q, vpl.wi);
    let tr = connect(x, target_point, dist, seg.medium, s);
    if is_black(tr) {
        return vec3<f32>(0.0);
    }
    let col = Collection(x, false, q, true, vec3<f32>(0.0), sqrt(r2), light.n, tr, false, vec3<f32>(0.0), vec3<f32>(0.0));
    let l_vsl = integrate_cone(cone, params.directions, lobe, light, phase, col, rnd);
    return seg.throughput * sigma_s * t_cam * vpl.power * l_vsl / pdf;
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
    if params.light_samples == 0u {
        for (var j = 0u; j < params.lights; j++) {
            var s = pair_sampler(KIND_VPL_TO_MEDIA, i, j);
            sum += admit(vsl_to_media(seg, vpls[j], vpl_bsdfs[j], &s), &discarded);
        }
    } else if params.vsl_tree_nodes > 0u {
        // Light selection: `light_samples` lights drawn from the pass's tree, each over its
        // probability (`many_lights::timed_drawn`).
        let receiver = segment_receiver(seg.origin, seg.dir, seg.length, media[seg.medium].g);
        let xi = selection_number(KIND_VPL_TO_MEDIA, i);
        for (var k = 0u; k < params.light_samples; k++) {
            let pick = tree_sample_slot(0u, receiver, KIND_VPL_TO_MEDIA, i, k, xi);
            if pick.found {
                var s = drawn_pair_sampler(KIND_VPL_TO_MEDIA, i, k);
                sum += admit(vsl_to_media(seg, vpls[pick.light], vpl_bsdfs[pick.light], &s), &discarded) / pick.pmf;
            }
        }
        sum = sum / f32(params.light_samples);
    }
    let total = admit(injected(sum * params.scale, i), &discarded);
    gathered[i] = vec4<f32>(total, f32(discarded));
}
