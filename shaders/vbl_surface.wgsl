//! use lib/vbl.wgsl
//! use lib/light_tree.wgsl
// Lsm with virtual beam lights: every VRL, its points inflated to radius R, against one
// shading point, the twin of `beamlight_trace::vbl::vbl_to_surface` (paper eqs. 8–9): the VSL
// centre on the VRL by a piecewise-linear PDF in the angle about the shading point, then the
// VSL's cone integrated numerically.

fn vbl_to_surface(sp: ShadingPoint, rx: Lobe, vrl: LightSegment, s: ptr<function, Sampler>) -> vec3<f32> {
    let m = media[vrl.medium];
    let r2 = clean_r2(params.radius2);
    let ov = vrl.origin;
    let dv = vrl.dir;
    let p = sp.pos;
    // At the VSL centre the light travels along dv and leaves towards the receiver (−ω').
    let phase = phase_lobe(m.g, -dv, -1.0);
    let len = vrl.length;
    if !(len > 0.0) {
        return vec3<f32>(0.0);
    }
    let line = line_angles(ov, dv, 0.0, len, p, sqrt(r2));
    let lobe = sharper(rx, phase);
    let u_angle = next_1d(s);
    let k = vertex_count(line.theta1 - line.theta0, lobe.scale);
    var values: array<f32, 64>;
    for (var i = 0u; i < k; i++) {
        let y = ov + dv * vertex_t(line, i, k, 0.0, len);
        var value = 0.0;
        if params.angular_pdf == ANGULAR_PDF_VRL {
            let w = normalize_or_zero(y - p);
            value = luminance_mean(lobe_eval(rx, w)) * lobe_eval(phase, w).x;
        } else {
            let cone = vsl_cone(p, y, r2, rx.n);
            if cone.valid {
                let w = surface_max_dir(rx, cone);
                value = luminance_mean(lobe_eval(rx, w)) * lobe_eval(phase, w).x;
            }
        }
        values[i] = value;
    }
    let sample = sample_angular(line, &values, k, 0.0, len, u_angle);
    let u = sample.x;
    let pdf = sample.y;
    let rnd = cone_random(s);
    if !(pdf > 0.0) {
        return vec3<f32>(0.0);
    }
    let y = ov + dv * u;
    let cone = vsl_cone(p, y, r2, rx.n);
    if !cone.valid {
        return vec3<f32>(0.0);
    }
    let sigma_s = m.sigma_s * medium_density(vrl.medium, y);
    let t_vrl = transmittance(vrl.medium, ov, dv, u, s);
    let dist = length_glam(y - p);
    // The shadow ray leaves on the viewer's side: a centre behind the surface is occluded.
    let origin = spawn_from_triangle(sp.tri, p, sp.wo);
    let tr = connect(origin, y, dist, sp.medium, s);
    if is_black(tr) {
        return vec3<f32>(0.0);
    }
    let col = Collection(p, true, y, false, rx.n, sqrt(r2), vec3<f32>(0.0), tr, false, vec3<f32>(0.0), vec3<f32>(0.0));
    let l_vsl = integrate_cone(cone, params.directions, lobe, rx, phase, col, rnd);
    return sp.throughput * vrl.power * sigma_s * t_vrl * l_vsl / pdf;
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
    // `Surface::receiver` is None for a delta or missing BSDF: nothing to gather.
    if f_sp.kind != BSDF_NONE {
        let rx = surface_lobe(f_sp, sp.normal, sp.wo, 1.0);
        if params.light_samples == 0u {
            for (var j = 0u; j < params.lights; j++) {
                var s = pair_sampler(KIND_VRL_TO_SURFACE, i, j);
                sum += admit(vbl_to_surface(sp, rx, vrls[j], &s), &discarded);
            }
        } else if params.vbl_tree_nodes > 0u {
            // Light selection: `light_samples` lights drawn from the pass's tree, each over its
            // probability (`many_lights::timed_drawn`).
            let receiver = point_receiver(sp.pos, sp.normal, sp.wo, f_sp);
            let xi = selection_number(KIND_VRL_TO_SURFACE, i);
            for (var k = 0u; k < params.light_samples; k++) {
                let pick = tree_sample_slot(params.vsl_tree_nodes, receiver, KIND_VRL_TO_SURFACE, i, k, xi);
                if pick.found {
                    var s = drawn_pair_sampler(KIND_VRL_TO_SURFACE, i, k);
                    sum += admit(vbl_to_surface(sp, rx, vrls[pick.light], &s), &discarded) / pick.pmf;
                }
            }
            sum = sum / f32(params.light_samples);
        }
    }
    let total = admit(injected(sum * params.scale, i), &discarded);
    gathered[i] = vec4<f32>(total, f32(discarded));
}
