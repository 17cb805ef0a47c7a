//! use lib/vbl.wgsl
//! use lib/angular.wgsl
//! use lib/surface_record.wgsl
//! use lib/gather_entry.wgsl
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
    if degenerate_length(len) {
        return degenerate_estimate(len);
    }
    let line = line_angles(ov, dv, 0.0, len, p, sqrt(r2));
    let lobe = sharper(rx, phase);
    let u_angle = next_1d(s);
    let sample = sample_angular(line, AngularIntegrand(ov, dv, p, r2, rx, phase, vrl.medium), 0.0, len, lobe.scale, u_angle);
    let u = sample.x;
    let pdf = sample.y;
    let rnd = cone_random(s);
    if !(pdf > 0.0) {
        return failed_estimate();
    }
    let y = ov + dv * u;
    let cone = vsl_cone(p, y, r2, rx.n);
    if !cone.valid {
        return vec3<f32>(0.0);
    }
    // The grid's density enters at each collection point (`collection_weight`).
    let sigma_s = m.sigma_s;
    let t_vrl = transmittance(vrl.medium, ov, dv, u, s);
    let dist = length_glam(y - p);
    // The shadow ray leaves on the viewer's side: a centre behind the surface is occluded.
    let origin = spawn_from_triangle(sp.tri, p, sp.wo);
    let tr = connect(origin, y, dist, sp.medium, 1.0, s);
    if is_black(tr) {
        return vec3<f32>(0.0);
    }
    centre_walls = walls_around(y, sqrt(r2));
    let col = Collection(p, true, y, false, rx.n, sqrt(r2), vec3<f32>(0.0), tr, grid_medium(m, vrl.medium));
    let l_vsl = integrate_cone(cone, params.directions, lobe, rx, phase, col, rnd);
    return sp.throughput * vrl.power * sigma_s * t_vrl * l_vsl / pdf;
}

// The hooks of lib/angular.wgsl: the VSL centre's angular density about the shading point p.
struct AngularIntegrand {
    ov: vec3<f32>,
    dv: vec3<f32>,
    p: vec3<f32>,
    r2: f32,
    rx: Lobe,
    phase: Lobe,
    medium: u32,
}

// The receiver's BSDF (mean over colours) times the phase function at the VRL point
// o_v + u·d_v, in the direction towards it (the VRL paper's vertex rule) or the one in the
// VSL's cone where the BSDF peaks, times the largest of σ_s's density there and R away
// (the light scatters at collection points up to R from y); and the extinction at y.
fn angular_value(f: AngularIntegrand, u: f32) -> vec2<f32> {
    let y = f.ov + f.dv * u;
    // No VSL centre whose sphere holds no medium; the VBL's light fades along it.
    let value = surface_vertex_value(f.rx, f.phase, f.p, y, f.r2, f.rx.n) * medium_density_within(f.medium, y, sqrt(f.r2));
    return vec2<f32>(value, shaping_sigma_t(f.medium) * medium_density_near(f.medium, y));
}

// The hooks of the shared entry point (lib/gather_entry.wgsl) that lib/surface_record.wgsl
// leaves to the kernel.
const GATHER_KIND: u32 = KIND_VRL_TO_SURFACE;

// The VBL tree: after the VSL tree's nodes in the pass's tree array.
fn light_tree_of(r: GatherRecord) -> vec2<u32> {
    return vec2<u32>(params.vsl_tree_nodes, params.vbl_tree_nodes);
}

fn light_contribution(r: GatherRecord, light: u32, s: ptr<function, Sampler>) -> vec3<f32> {
    return vbl_to_surface(r.sp, r.rx, vrls[light], s);
}
