//! use lib/vbl.wgsl
//! use lib/angular.wgsl
//! use lib/media_record.wgsl
//! use lib/gather_entry.wgsl
// Lms with virtual spherical lights: every VPL, inflated to radius R, against one camera
// media segment, the twin of `beamlight_trace::vbl::vsl_to_media` (paper §3.3): the camera
// point by a piecewise-linear PDF in the angle about the VPL, then the VSL's cone integrated
// numerically.

fn vsl_to_media(seg: MediaSegment, vpl: SurfaceVertex, f_vpl: Bsdf, walls: Walls, s: ptr<function, Sampler>) -> vec3<f32> {
    let m = media[seg.medium];
    if !gathers_in_medium(m.g) {
        return vec3<f32>(0.0);
    }
    let r2 = clean_r2(params.radius2);
    let o = seg.origin;
    let d = seg.dir;
    let q = vpl.pos;
    if degenerate_length(seg.length) {
        return degenerate_estimate(seg.length);
    }
    if f_vpl.kind == BSDF_NONE {
        return vec3<f32>(0.0);
    }
    let light = surface_lobe(f_vpl, vpl.normal, vpl.wi, -1.0);
    let phase = phase_lobe(m.g, -d, 1.0);
    let line = line_angles(o, d, 0.0, seg.length, q, sqrt(r2));
    let lobe = sharper(light, phase);
    let u_angle = next_1d(s);
    let sample = sample_angular(line, AngularIntegrand(o, d, q, r2, light, phase, seg.medium), 0.0, seg.length, lobe.scale, u_angle);
    let t = sample.x;
    let pdf = sample.y;
    let rnd = cone_random(s);
    if !(pdf > 0.0) {
        return failed_estimate();
    }
    let x = o + d * t;
    let cone = vsl_sheet_cone(x, q, r2, -light.n);
    if !cone.valid {
        return vec3<f32>(0.0);
    }
    let sigma_s = m.sigma_s * medium_density(seg.medium, x);
    let rate = MEDIA_PAIR_TRACKING_RATE;
    let t_cam = transmittance_at_rate(seg.medium, o, d, t, rate, s);
    let dist = length_glam(q - x);
    // The VSL centre just off its surface, on the side its light arrived from.
    let target_point = spawn_from_triangle(vpl.tri, q, vpl.wi);
    let tr = connect(x, target_point, dist, seg.medium, rate, s);
    if is_black(tr) {
        return vec3<f32>(0.0);
    }
    centre_walls = walls;
    let col = Collection(x, false, q, true, vec3<f32>(0.0), sqrt(r2), light.n, tr, NO_MEDIUM);
    let l_vsl = integrate_cone(cone, params.directions, lobe, light, phase, col, rnd);
    return seg.throughput * sigma_s * t_cam * vpl.power * l_vsl / pdf;
}

// The hooks of lib/angular.wgsl: the camera point's angular density about the VPL q.
struct AngularIntegrand {
    o: vec3<f32>,
    d: vec3<f32>,
    q: vec3<f32>,
    r2: f32,
    light: Lobe,
    phase: Lobe,
    medium: u32,
}

// The VPL's BSDF (mean over colours) times the phase function at the camera point o + t·d,
// in the direction towards q (the VRL paper's vertex rule) or the one in the VSL's cone where
// the BSDF peaks, times σ_s(x)'s density; and the extinction at x.
fn angular_value(f: AngularIntegrand, t: f32) -> vec2<f32> {
    let x = f.o + f.d * t;
    // σ_s(x)'s grid density: no camera point where the medium is empty; and the light fades
    // on its way to the camera.
    let density = medium_density_near(f.medium, x);
    return vec2<f32>(surface_vertex_value(f.light, f.phase, x, f.q, f.r2, -f.d) * density, shaping_sigma_t(f.medium) * density);
}

// The hooks of the shared entry point (lib/gather_entry.wgsl) that lib/media_record.wgsl
// leaves to the kernel.
const GATHER_KIND: u32 = KIND_VPL_TO_MEDIA;

// The VSL tree: the first nodes of the pass's tree array.
fn light_tree_of(r: GatherRecord) -> vec2<u32> {
    return vec2<u32>(0u, params.vsl_tree_nodes);
}

fn light_contribution(r: GatherRecord, light: u32, s: ptr<function, Sampler>) -> vec3<f32> {
    return vsl_to_media(r.seg, vpls[light], vpl_bsdfs[light], vpl_walls[light], s);
}
