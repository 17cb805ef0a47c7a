//! use lib/vbl.wgsl
//! use lib/surface_record.wgsl
//! use lib/gather_entry.wgsl
// Lss with virtual spherical lights: every VPL, inflated to radius R, against one shading
// point, the twin of `beamlight_trace::vbl::vsl_to_surface` (Hašan et al.'s VSLs).

fn vsl_to_surface(sp: ShadingPoint, rx: Lobe, vpl: SurfaceVertex, f_vpl: Bsdf, walls: Walls, s: ptr<function, Sampler>) -> vec3<f32> {
    if f_vpl.kind == BSDF_NONE {
        return vec3<f32>(0.0);
    }
    let r2 = clean_r2(params.radius2);
    let light = surface_lobe(f_vpl, vpl.normal, vpl.wi, -1.0);
    let rnd = cone_random(s);
    let cone = vsl_sheet_cone(sp.pos, vpl.pos, r2, sp.normal);
    if !cone.valid {
        return vec3<f32>(0.0);
    }
    let lobe = sharper(rx, light);
    let origin = spawn_from_triangle(sp.tri, sp.pos, sp.wo);
    let dist = length_glam(vpl.pos - sp.pos);
    // The VSL centre just off its surface, on the side its light arrived from.
    let target_point = spawn_from_triangle(vpl.tri, vpl.pos, vpl.wi);
    let tr = connect(origin, target_point, dist, sp.medium, 1.0, s);
    if is_black(tr) {
        return vec3<f32>(0.0);
    }
    centre_walls = walls;
    let col = Collection(sp.pos, true, vpl.pos, true, rx.n, sqrt(r2), light.n, tr, NO_MEDIUM);
    let l_vsl = integrate_cone(cone, params.directions, lobe, rx, light, col, rnd);
    return sp.throughput * vpl.power * l_vsl;
}

// The hooks of the shared entry point (lib/gather_entry.wgsl) that lib/surface_record.wgsl
// leaves to the kernel.
const GATHER_KIND: u32 = KIND_VPL_TO_SURFACE;

// The VSL tree: the first nodes of the pass's tree array.
fn light_tree_of(r: GatherRecord) -> vec2<u32> {
    return vec2<u32>(0u, params.vsl_tree_nodes);
}

fn light_contribution(r: GatherRecord, light: u32, s: ptr<function, Sampler>) -> vec3<f32> {
    return vsl_to_surface(r.sp, r.rx, vpls[light], vpl_bsdfs[light], vpl_walls[light], s);
}
