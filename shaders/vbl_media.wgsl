//! use lib/vbl.wgsl
//! use lib/angular.wgsl
//! use lib/media_record.wgsl
//! use lib/gather_entry.wgsl
// Lmm with virtual beam lights: every VRL, its points inflated to radius R, against one
// camera media segment, the twin of `beamlight_trace::vbl::vbl_to_media` (paper eq. 10): the
// VSL centre on the VRL ∝ 1/(distance to the camera line)², floored at R, then the camera
// point by a piecewise-linear PDF in the angle about that centre, then the VSL's cone
// integrated numerically.

// `vrl::near_line_apex`: in the VRL's frame (the VRL from the origin along x), the point
// whose equiangular density along the VRL is ∝ 1/max(dist(y(u), camera line), min_dist)²;
// w = 0 for parallel lines.
fn near_line_apex(ov: vec3<f32>, dv: vec3<f32>, oc: vec3<f32>, dc: vec3<f32>, min_dist: f32) -> vec4<f32> {
    let a = (ov - oc) - dc * dot(ov - oc, dc);
    let b = dv - dc * dot(dv, dc);
    let bb = dot(b, b);
    if !(bb > 1e-12) {
        return vec4<f32>(0.0);
    }
    let ab = dot(a, b);
    let u0 = -ab / bb;
    let h = sqrt(max(dot(a, a) - ab * ab / bb, 0.0) / bb);
    return vec4<f32>(u0, max(h, min_dist / sqrt(bb)), 0.0, 1.0);
}

// `vrl::sample_near_line` with the distance floored at `min_dist`: (u, pdf).
fn near_line_sample(ov: vec3<f32>, dv: vec3<f32>, len: f32, oc: vec3<f32>, dc: vec3<f32>, min_dist: f32, xi: f32) -> vec2<f32> {
    let apex = near_line_apex(ov, dv, oc, dc, min_dist);
    if apex.w == 0.0 {
        return vec2<f32>(xi * len, 1.0 / len);
    }
    return equiangular(vec3<f32>(0.0), vec3<f32>(1.0, 0.0, 0.0), 0.0, len, apex.xyz, xi);
}

// `vbl::hg_peak_gather`: the gather direction where hg(−ω', −travel) peaks, w = 0 when
// isotropic.
fn hg_peak_gather(g: f32, travel: vec3<f32>) -> vec4<f32> {
    if g > 0.0 {
        return vec4<f32>(-travel, 1.0);
    }
    if g < 0.0 {
        return vec4<f32>(travel, 1.0);
    }
    return vec4<f32>(0.0);
}

fn vbl_to_media(seg: MediaSegment, vrl: LightSegment, s: ptr<function, Sampler>) -> vec3<f32> {
    let mv = media[vrl.medium];
    let mc = media[seg.medium];
    if !gathers_in_medium(mc.g) {
        return vec3<f32>(0.0);
    }
    let r2 = clean_r2(params.radius2);
    let r = sqrt(r2);
    let ov = vrl.origin;
    let dv = vrl.dir;
    let oc = seg.origin;
    let dc = seg.dir;
    if degenerate_length(vrl.length) {
        return degenerate_estimate(vrl.length);
    }
    if degenerate_length(seg.length) {
        return degenerate_estimate(seg.length);
    }
    // Stage 1: the VSL centre ∝ 1/dist(y(u), camera line)², the distance floored at R; in a
    // medium with a density grid, times σ_s(y)'s density, by a piecewise-linear density in
    // the angle about the apex.
    let apex = near_line_apex(ov, dv, oc, dc, r);
    let along = line_angles(vec3<f32>(0.0), vec3<f32>(1.0, 0.0, 0.0), 0.0, vrl.length, apex.xyz, 0.0);
    var stage1: vec2<f32>;
    if mv.grid_res.x != 0u && apex.w != 0.0 && !subtends_no_angle(along.theta0, along.theta1) {
        let density = AngularIntegrand(ov, dv, vec3<f32>(0.0), 0.0, vec4<f32>(0.0), phase_lobe(0.0, dv, 1.0), phase_lobe(0.0, dv, 1.0), vrl.medium, 1u);
        stage1 = sample_angular(along, density, 0.0, vrl.length, 0.0, next_1d(s));
    } else {
        stage1 = near_line_sample(ov, dv, vrl.length, oc, dc, r, next_1d(s));
    }
    let u = stage1.x;
    let pdf_u = stage1.y;
    if !(pdf_u > 0.0 && finite_f32(pdf_u)) {
        return failed_estimate();
    }
    let y = ov + dv * u;
    // ω' is the gather direction at the camera point (towards the VSL centre).
    let phase_y = phase_lobe(mv.g, -dv, -1.0);
    let phase_x = phase_lobe(mc.g, -dc, 1.0);
    // ω'_max: the VSL centre's HG peak, else the camera point's, else the cone axis.
    var peak = hg_peak_gather(mv.g, dv);
    if peak.w == 0.0 {
        peak = hg_peak_gather(mc.g, -dc);
    }
    // Stage 2: the camera point by a piecewise-linear PDF in the angle about y.
    let line = line_angles(oc, dc, 0.0, seg.length, y, r);
    let lobe = sharper(phase_y, phase_x);
    let u_angle = next_1d(s);
    let integrand = AngularIntegrand(oc, dc, y, r2, peak, phase_x, phase_y, seg.medium, 0u);
    let stage2 = sample_angular(line, integrand, 0.0, seg.length, lobe.scale, u_angle);
    let t = stage2.x;
    let pdf_t = stage2.y;
    let rnd = cone_random(s);
    if !(pdf_t > 0.0) {
        return failed_estimate();
    }
    let x = oc + dc * t;
    let cone = vsl_cone(x, y, r2, -dc);
    if !cone.valid {
        return vec3<f32>(0.0);
    }
    // The grid's density at y enters at each collection point (`collection_weight`).
    let sigma_y = mv.sigma_s;
    let sigma_x = mc.sigma_s * medium_density(seg.medium, x);
    let rate = MEDIA_PAIR_TRACKING_RATE;
    let t_vrl = transmittance_at_rate(vrl.medium, ov, dv, u, rate, s);
    let t_cam = transmittance_at_rate(seg.medium, oc, dc, t, rate, s);
    let dist = length_glam(y - x);
    let tr = connect(x, y, dist, seg.medium, rate, s);
    if is_black(tr) {
        return vec3<f32>(0.0);
    }
    centre_walls = walls_around(y, r);
    let col = Collection(x, false, y, false, vec3<f32>(0.0), r, vec3<f32>(0.0), tr, grid_medium(mv, vrl.medium));
    let l_vsl = integrate_cone(cone, params.directions, lobe, phase_x, phase_y, col, rnd);
    return seg.throughput * vrl.power * sigma_y * t_vrl * sigma_x * t_cam * l_vsl / (pdf_u * pdf_t);
}

// The hooks of lib/angular.wgsl: the camera point's angular density about the VSL centre y,
// or stage 1's along the VRL.
struct AngularIntegrand {
    oc: vec3<f32>,
    dc: vec3<f32>,
    y: vec3<f32>,
    r2: f32,
    peak: vec4<f32>,
    phase_x: Lobe,
    phase_y: Lobe,
    medium: u32,
    // 1: stage 1's density along the VRL oc + t·dc (`oc`, `dc` then the VRL's origin and
    // direction, `medium` its medium; the other fields unused).
    along_vrl: u32,
}

// Both phase functions at the camera point x = o_c + t·d_c, in the direction towards y (the
// VRL paper's vertex rule) or the one in the VSL's cone closest to ω'_max, times σ_s(x)'s
// density; and the extinction at x (stage 1: the density along the VRL and the extinction
// there).
fn angular_value(f: AngularIntegrand, t: f32) -> vec2<f32> {
    let sigma_t = shaping_sigma_t(f.medium);
    if f.along_vrl != 0u {
        let density = medium_density_near(f.medium, f.oc + f.dc * t);
        return vec2<f32>(density, sigma_t * density);
    }
    let x = f.oc + f.dc * t;
    // σ_s(x)'s grid density: no camera point where the medium is empty; and the light fades
    // on its way to the camera.
    let density = medium_density_near(f.medium, x);
    var w = normalize_or_zero(f.y - x);
    if params.angular_pdf != ANGULAR_PDF_VRL {
        let cone = vsl_cone(x, f.y, f.r2, -f.dc);
        if !cone.valid {
            return vec2<f32>(0.0, sigma_t * density);
        }
        w = cone.axis;
        if f.peak.w != 0.0 {
            w = closest_in_cone(cone, f.peak.xyz);
        }
    }
    return vec2<f32>(lobe_eval(f.phase_x, w).x * lobe_eval(f.phase_y, w).x * density, sigma_t * density);
}

// The hooks of the shared entry point (lib/gather_entry.wgsl) that lib/media_record.wgsl
// leaves to the kernel.
const GATHER_KIND: u32 = KIND_VRL_TO_MEDIA;

// The VBL tree: after the VSL tree's nodes in the pass's tree array.
fn light_tree_of(r: GatherRecord) -> vec2<u32> {
    return vec2<u32>(params.vsl_tree_nodes, params.vbl_tree_nodes);
}

fn light_contribution(r: GatherRecord, light: u32, s: ptr<function, Sampler>) -> vec3<f32> {
    return vbl_to_media(r.seg, vrls[light], s);
}
