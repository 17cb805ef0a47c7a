//! use lib/vbl.wgsl
//! use lib/light_tree.wgsl
// Lss with virtual spherical lights: every VPL, inflated to radius R, against one shading
// point, the twin of `beamlight_trace::vbl::vsl_to_surface` (Hašan et al.'s VSLs).

fn vsl_to_surface(sp: ShadingPoint, rx: Lobe, vpl: SurfaceVertex, f_vpl: Bsdf, s: ptr<function, Sampler>) -> vec3<f32> {
    if f_vpl.kind == BSDF_NONE {
        return vec3<f32>(0.0);
    }
    let r2 = clean_r2(params.radius2);
    let light = surface_lobe(f_vpl, vpl.normal, vpl.wi, -1.0);
    let rnd = cone_random(s);
    let cone = vsl_cone(sp.pos, vpl.pos, r2, sp.normal);
    if !cone.valid {
        return vec3<f32>(0.0);
    }
    let lobe = sharper(rx, light);
    let origin = spawn_from_triangle(sp.tri, sp.pos, sp.wo);
    let dist = length_glam(vpl.pos - sp.pos);
    // The VSL centre just off its surface, on the side its light arrived from.
    let target_point = spawn_from_triangle(vpl.tri, vpl.pos, vpl.wi);
    let tr = connect(origin, target_point, dist, sp.medium, s);
    if is_black(tr) {
        return vec3<f32>(0.0);
    }
    let col = Collection(sp.pos, true, vpl.pos, true, rx.n, sqrt(r2), light.n, tr, false, vec3<f32>(0.0), vec3<f32>(0.0));
    let l_vsl = integrate_cone(cone, params.directions, lobe, rx, light, col, rnd);
    return sp.throughput * vpl.power * l_vsl;
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
                var s = pair_sampler(KIND_VPL_TO_SURFACE, i, j);
                sum += admit(vsl_to_surface(sp, rx, vpls[j], vpl_bsdfs[j], &s), &discarded);
            }
        } else if params.vsl_tree_nodes > 0u {
            // Light selection: `light_samples` lights drawn from the pass's tree, each over its
            // probability (`many_lights::timed_drawn`).
            let receiver = point_receiver(sp.pos, sp.normal, sp.wo, f_sp);
            let xi = selection_number(KIND_VPL_TO_SURFACE, i);
            for (var k = 0u; k < params.light_samples; k++) {
                let pick = tree_sample_slot(0u, receiver, KIND_VPL_TO_SURFACE, i, k, xi);
                if pick.found {
                    var s = drawn_pair_sampler(KIND_VPL_TO_SURFACE, i, k);
                    sum += admit(vsl_to_surface(sp, rx, vpls[pick.light], vpl_bsdfs[pick.light], &s), &discarded) / pick.pmf;
                }
            }
            sum = sum / f32(params.light_samples);
        }
    }
    let total = admit(injected(sum * params.scale, i), &discarded);
    gathered[i] = vec4<f32>(total, f32(discarded));
}
