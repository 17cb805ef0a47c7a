//! use lib/gather.wgsl
//! use lib/sampling.wgsl
// Light selection: the twin of `beamlight_trace::light_tree` (the same operations in the same
// order, so a record draws the same lights as on the CPU up to rounding ties). Both of a
// pass's trees share one array: the VSL tree's nodes first, then the VBL tree's.

// `light_tree::LightTreeNode`.
struct LightTreeNode {
    lo: vec3<f32>,
    weight: f32,
    hi: vec3<f32>,
    // Interior: index of the left child (the right one follows); leaf: LIGHT_LEAF | the
    // segment's diagonal (bits 28–30) | light.
    child: u32,
    // A segment leaf's extinction: its light fades like exp(−σt t) along it.
    sigma_t: f32,
    // A segment leaf's Henyey–Greenstein g.
    g: f32,
    // `light_tree::Emission`: the glossy lobes of its VSLs (all 0: none).
    lobe_share: f32,
    lobe_cos: f32,
    lobe_axis: vec3<f32>,
    lobe_exponent: f32,
    // The cone of its VSLs' normals (0: segment lights).
    normal: vec3<f32>,
    normal_cos: f32,
    lobe_peak: f32,
    lobe_base: f32,
    _pad: array<u32, 2>,
}

const LIGHT_LEAF: u32 = 0x80000000u;
const LIGHT_MASK: u32 = 0x0fffffffu;
// The largest f32 below 1.
const ONE_BELOW: f32 = 0.99999994;

@group(1) @binding(8) var<storage, read> light_tree: array<LightTreeNode>;
// The flat draw's masses (`LightTree::group_masses`, weighed on the CPU: `flat_masses` in
// crates/gpu/src/gather.rs): row g the pmfs of the leaves, in node order, for the dispatch's
// g-th group of `FLAT_GROUP` records, each row `flat_stride(tree.y)` long.
@group(1) @binding(9) var<storage, read> flat_masses: array<f32>;

// `light_tree::Receiver`: a shading point (a = p, b = n, and its `Gloss`) or a media segment
// (a = o, b = d).
struct Receiver {
    a: vec3<f32>,
    is_segment: bool,
    b: vec3<f32>,
    len: f32,
    mirror: vec3<f32>,
    exponent: f32,
    diffuse: f32,
    specular: f32,
    // A media segment's phase function g.
    g: f32,
}

// `Receiver::at_point` with `Gloss::of` the record's BSDF.
fn point_receiver(p: vec3<f32>, n: vec3<f32>, wo: vec3<f32>, f: Bsdf) -> Receiver {
    var rx = Receiver(p, false, n, 0.0, vec3<f32>(0.0, 0.0, 1.0), 0.0, 0.0, 0.0, 0.0);
    if f.kind == BSDF_PHONG {
        rx.mirror = n * (2.0 * dot_glam(n, wo)) - wo;
        rx.exponent = f.exponent;
        rx.diffuse = luminance_mean(max(f.diffuse, vec3<f32>(0.0)));
        rx.specular = luminance_mean(max(f.specular, vec3<f32>(0.0)));
    } else if f.kind == BSDF_LAMBERT {
        rx.diffuse = luminance_mean(max(f.diffuse, vec3<f32>(0.0)));
    }
    return rx;
}

fn segment_receiver(o: vec3<f32>, d: vec3<f32>, len: f32, g: f32) -> Receiver {
    return Receiver(o, true, d, len, vec3<f32>(0.0, 0.0, 1.0), 0.0, 0.0, 0.0, g);
}

// `light_tree::phase_ratio`.
fn phase_ratio(g: f32, cos_t: f32) -> f32 {
    let q = max(1.0 + g * g - 2.0 * g * cos_t, 1e-12);
    return (1.0 - g * g) / (q * sqrt(q));
}

// `light_tree::asinh`: stable near 0, where the builtin may cancel.
fn asinh_stable(x: f32) -> f32 {
    let v = log_1p(exp_asinh_m1(abs(x)));
    return select(v, -v, x < 0.0);
}

// `light_tree::phase_towards`.
fn phase_towards(g: f32, travel: vec3<f32>, to: vec3<f32>) -> f32 {
    let len = length_glam(travel) * length_glam(to);
    if len > 0.0 {
        return phase_ratio(g, clamp(dot_glam(travel, to) / len, -1.0, 1.0));
    }
    return 1.0;
}

// The point of the camera segment closest to y (`nearest` in `light_tree::importance`).
fn segment_nearest(rx: Receiver, y: vec3<f32>) -> vec3<f32> {
    return rx.a + rx.b * clamp(dot_glam(y - rx.a, rx.b), 0.0, rx.len);
}

// `Gloss::in_cone`.
fn gloss_in_cone(rx: Receiver, axis: vec3<f32>, cos_a: f32, sin_a: f32, inside: bool, sphere: bool) -> f32 {
    let peak = rx.specular * (rx.exponent + 2.0) * 0.5;
    if peak == 0.0 {
        return rx.diffuse;
    }
    var lobe = 1.0;
    if !inside {
        let cos_t = clamp(dot_glam(rx.mirror, axis), -1.0, 1.0);
        let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
        var c = 1.0;
        if cos_t < cos_a {
            c = cos_t * cos_a + sin_t * sin_a;
        }
        lobe = pow(max(c, 0.0), rx.exponent);
    }
    var lobed = peak * lobe;
    if sphere {
        var one_minus_cos = 1.0;
        if !inside {
            one_minus_cos = sin_a * sin_a / (1.0 + cos_a);
        }
        lobed = min(lobed, peak / ((rx.exponent + 1.0) * max(one_minus_cos, 1e-12)));
    }
    return max(rx.diffuse + lobed, 1e-4 * (rx.diffuse + peak));
}

// `Emission::towards`.
fn emission_towards(node: LightTreeNode, towards: vec3<f32>, cos_a: f32, sin_a: f32, everywhere: bool) -> f32 {
    if node.lobe_share == 0.0 {
        return 1.0;
    }
    let c = largest_cos(node.lobe_axis, node.lobe_cos, towards, cos_a, sin_a, everywhere);
    var lobe = 1.0;
    if c < 1.0 {
        lobe = pow(max(c, 0.0), node.lobe_exponent);
    }
    var one_minus_cos = 1.0;
    if !everywhere {
        one_minus_cos = sin_a * sin_a / (1.0 + cos_a);
    }
    let mean = node.lobe_peak / ((node.lobe_exponent + 1.0) * max(one_minus_cos, 1e-12));
    let lobed = max(node.lobe_base + min(node.lobe_peak * lobe, mean), 1e-4 * (node.lobe_base + node.lobe_peak));
    return 1.0 - node.lobe_share + node.lobe_share * lobed;
}

// `light_tree::largest_cos`.
fn largest_cos(axis: vec3<f32>, cos_s: f32, towards: vec3<f32>, cos_a: f32, sin_a: f32, everywhere: bool) -> f32 {
    let sin_s = sqrt(max(1.0 - cos_s * cos_s, 0.0));
    let cos_w = cos_a * cos_s - sin_a * sin_s;
    let sin_w = sin_a * cos_s + cos_a * sin_s;
    if everywhere || sin_w < 0.0 {
        return 1.0;
    }
    let cos_t = clamp(dot_glam(axis, towards), -1.0, 1.0);
    if cos_t >= cos_w {
        return 1.0;
    }
    let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
    return cos_t * cos_w + sin_t * sin_w;
}

// `light_tree::facing`.
fn facing(axis: vec3<f32>, cos_s: f32, towards: vec3<f32>, cos_a: f32, sin_a: f32, everywhere: bool) -> f32 {
    return max(largest_cos(axis, cos_s, towards, cos_a, sin_a, everywhere), 1e-3);
}

fn dot_glam(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// `light_tree::fade_length`.
fn fade_length(sigma_t: f32, len: f32) -> f32 {
    if sigma_t * len > 1e-4 {
        return -(exp(-sigma_t * len) - 1.0) / sigma_t;
    }
    return len;
}

// `light_tree::fade_density`.
fn fade_density(sigma_t: f32, len: f32, t: f32) -> f32 {
    return exp(-sigma_t * t) / fade_length(sigma_t, len);
}

// `light_tree::free_path`.
fn free_path(sigma_t: f32, len: f32) -> f32 {
    if sigma_t * len > 1.0 {
        return 1.0 / sigma_t;
    }
    return len;
}

// The `prim` of `light_tree::importance`: ∫ (α + β s) / (h² + s²)^(3/2) ds up to s.
fn cosine_prim(alpha: f32, beta: f32, h: f32, s: f32) -> f32 {
    let q = sqrt(h * h + s * s);
    return alpha * s / (h * h * q) - beta / q;
}

// The `cosine_line` of `light_tree::importance` over [t_a, t_b] within [lo_t, hi_t].
fn cosine_line(alpha: f32, beta: f32, h: f32, t0: f32, lo_t: f32, hi_t: f32, t_a_in: f32, t_b_in: f32) -> f32 {
    let t_a = max(t_a_in, lo_t);
    let t_b = min(t_b_in, hi_t);
    if t_b > t_a {
        return max(cosine_prim(alpha, beta, h, t_b - t0) - cosine_prim(alpha, beta, h, t_a - t0), 0.0);
    }
    return 0.0;
}

// `LightTreeNode::segment`: a leaf's segment along its box's diagonal.
fn leaf_segment_start(node: LightTreeNode) -> vec3<f32> {
    let bits = node.child >> 28u;
    return select(node.lo, node.hi, vec3<bool>((bits & 1u) != 0u, (bits & 2u) != 0u, (bits & 4u) != 0u));
}

fn leaf_segment_end(node: LightTreeNode) -> vec3<f32> {
    let bits = node.child >> 28u;
    return select(node.hi, node.lo, vec3<bool>((bits & 1u) != 0u, (bits & 2u) != 0u, (bits & 4u) != 0u));
}

// The angle a camera segment subtends at y and y's distance to its line, floored at `floor`
// and r (`seen_from` in `light_tree::importance`).
fn seen_from(rx: Receiver, y: vec3<f32>, floor: f32, r: f32) -> vec2<f32> {
    let v = y - rx.a;
    let tc = dot_glam(v, rx.b);
    let h = max(max(sqrt(max(dot_glam(v, v) - tc * tc, 0.0)), floor), r);
    // `precise_atan2` (lib/sampling.wgsl): the builtin atan may be off by thousands of ulps.
    return vec2<f32>(max(precise_atan2(rx.len - tc, h) + precise_atan2(tc, h), 0.0), h);
}

// `importance::FRAC_1_SQRT_3`: the two-point Gauss–Legendre nodes.
const FRAC_1_SQRT_3: f32 = 0.57735026;

// `light_tree::exp_asinh_m1`: e^(asinh x) − 1 for x ≥ 0.
fn exp_asinh_m1(x: f32) -> f32 {
    return x + x * x / (1.0 + sqrt(1.0 + x * x));
}

// `importance::Closest`: a segment light seen from the camera line.
struct Closest {
    l: f32,
    dir: vec3<f32>,
    u0: f32,
    sin2: f32,
}

fn closest_on_light(a: vec3<f32>, b: vec3<f32>, rx: Receiver) -> Closest {
    let l = length_glam(b - a);
    let dir = (b - a) / l;
    let w = a - rx.a;
    let d = rx.b;
    let cos = dot_glam(dir, d);
    let sin2 = max(1.0 - cos * cos, 0.0);
    var u0: f32;
    if sin2 > 1e-6 {
        u0 = (cos * dot_glam(d, w) - dot_glam(dir, w)) / sin2;
    } else {
        u0 = dot_glam(rx.a + d * (0.5 * rx.len) - a, dir);
    }
    return Closest(l, dir, clamp(u0, 0.0, l), sin2);
}

// `light_tree::importance`.
fn light_importance(node: LightTreeNode, rx: Receiver, r_in: f32) -> f32 {
    let c = 0.5 * (node.lo + node.hi);
    let half = 0.5 * (node.hi - node.lo);
    let rb = length_glam(half);
    let r = max(r_in, 1e-12);
    let is_segment = (node.child & LIGHT_LEAF) != 0u && any(node.lo != node.hi);
    let a = leaf_segment_start(node);
    let b = leaf_segment_end(node);
    if !rx.is_segment {
        let p = rx.a;
        let n = rx.b;
        let top = dot_glam(n, c - p) + dot_glam(abs(n), half) + r;
        if top < 0.0 && node.sigma_t == 0.0 {
            return 0.0;
        }
        let to = c - p;
        let dc = length_glam(to);
        let reach = rb + r;
        let inside = dc <= reach;
        var axis = n;
        var sin_a = 1.0;
        if !inside {
            axis = to / dc;
            sin_a = reach / dc;
        }
        let cos_a = sqrt(max(1.0 - sin_a * sin_a, 0.0));
        var cos_bound = 1.0;
        if !inside {
            let cos_t = clamp(dot_glam(n, axis), -1.0, 1.0);
            let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
            if cos_t < cos_a {
                cos_bound = cos_t * cos_a + sin_t * sin_a;
            }
        }
        let sphere = (node.child & LIGHT_LEAF) != 0u && !is_segment;
        var f = gloss_in_cone(rx, axis, cos_a, sin_a, inside, sphere) * emission_towards(node, -axis, cos_a, sin_a, inside);
        if any(node.normal != vec3<f32>(0.0)) {
            if (node.child & LIGHT_LEAF) != 0u {
                let h = dot_glam(node.normal, p - c);
                f *= clamp(h / max(max(h, dc - r), 1e-12), 1e-3, 1.0);
            } else {
                f *= facing(node.normal, node.normal_cos, -axis, cos_a, sin_a, inside);
            }
        }
        if is_segment {
            let len = length_glam(b - a);
            let dir = (b - a) / len;
            let v = p - a;
            let t0 = dot_glam(v, dir);
            let d2 = dot_glam(v, v);
            let h = max(sqrt(max(d2 - t0 * t0, 0.0)), r);
            let e0 = dot_glam(n, a - p) + r;
            let beta = dot_glam(n, dir);
            var lo_t = 0.0;
            var hi_t = len;
            if beta > 0.0 {
                lo_t = max(lo_t, -e0 / beta);
            } else if beta < 0.0 {
                hi_t = min(hi_t, -e0 / beta);
            } else if e0 < 0.0 {
                hi_t = lo_t;
            }
            let alpha = e0 + beta * t0;
            let closest = fade_density(node.sigma_t, len, clamp(t0, 0.0, len)) * cosine_line(alpha, beta, h, t0, lo_t, hi_t, 0.0, len);
            let first = free_path(node.sigma_t, len);
            let start = fade_density(node.sigma_t, len, first) * cosine_line(alpha, beta, h, t0, lo_t, hi_t, 0.0, first);
            let floor = 1e-3 / max(d2, r * r);
            return node.weight * f * max(max(closest, start), floor);
        }
        let cp = c - p;
        // Points: floored at rb²; segment lights (σt > 0) at rb·R (see the CPU twin).
        let floor2 = select(rb * rb, rb * r, node.sigma_t > 0.0);
        let falloff = 1.0 / max(max(dot_glam(cp, cp), floor2), r * r);
        return node.weight * f * max(cos_bound, 1e-3) * falloff;
    }
    if is_segment {
        let near = closest_on_light(a, b, rx);
        let l = near.l;
        let dir = near.dir;
        let u0 = near.u0;
        let sin2 = near.sin2;
        let d = rx.b;
        let seen = seen_from(rx, a + dir * u0, 0.0, r);
        let s = max(sqrt(sin2), 1e-3);
        let along = (asinh_stable((l - u0) * s / seen.y) + asinh_stable(u0 * s / seen.y)) / s;
        let closest = fade_density(node.sigma_t, l, u0) * seen.x * along;
        let first = free_path(node.sigma_t, l);
        let seen_a = seen_from(rx, a, 0.0, r);
        let start = fade_density(node.sigma_t, l, first) * seen_a.x * asinh_stable(first * s / seen_a.y) / s;
        let y = a + dir * u0;
        let to = segment_nearest(rx, y) - y;
        let phase = phase_towards(node.g, dir, to) * phase_towards(rx.g, to, -d);
        return node.weight * phase * max(closest, start);
    }
    let seen = seen_from(rx, c, rb, r);
    var phase = 1.0;
    if (node.child & LIGHT_LEAF) != 0u {
        phase = phase_towards(rx.g, segment_nearest(rx, c) - c, -rx.b);
    }
    return node.weight * phase * seen.x / seen.y;
}

// `light_tree::DEFENSIVE_SHARE`.
const DEFENSIVE_SHARE: f32 = 0.1;

// `light_tree::left_probability`.
fn left_probability(a: f32, b: f32, left: LightTreeNode, right: LightTreeNode) -> f32 {
    let p = a / (a + b);
    if a > 0.0 && b > 0.0 {
        return (1.0 - DEFENSIVE_SHARE) * p + DEFENSIVE_SHARE * (left.weight / (left.weight + right.weight));
    }
    return p;
}

// A drawn light: its index and probability (`found` false when no light can reach).
struct Pick {
    light: u32,
    pmf: f32,
    found: bool,
}

// `LightTree::sample` on the tree whose root is at `base` in `light_tree`: the root's choice
// by `u_in`, deeper ones by fresh numbers from `s`.
fn tree_sample(base: u32, rx: Receiver, r: f32, u_in: f32, s: ptr<function, Sampler>) -> Pick {
    var at = 0u;
    var pmf = 1.0;
    var u = u_in;
    // A median-split tree is at most 32 levels deep (fewer than 2³¹ lights).
    for (var level = 0u; level < 64u; level++) {
        let node = light_tree[base + at];
        if (node.child & LIGHT_LEAF) != 0u {
            return Pick(node.child & LIGHT_MASK, pmf, true);
        }
        let c = node.child;
        let a = light_importance(light_tree[base + c], rx, r);
        let b = light_importance(light_tree[base + c + 1u], rx, r);
        if !(a + b > 0.0) {
            return Pick(0u, 0.0, false);
        }
        let p_left = left_probability(a, b, light_tree[base + c], light_tree[base + c + 1u]);
        if u < p_left {
            pmf *= p_left;
            at = c;
        } else {
            pmf *= 1.0 - p_left;
            at = c + 1u;
        }
        u = next_1d(s);
    }
    return Pick(0u, 0.0, false);
}

// Slot `slot` of record `record`'s draws for kernel `kind` (`LightTree::sample_k`): the root
// choice by the stratified number (slot + ξ)/K, the rest from the slot's descent stream.
fn tree_sample_slot(base: u32, rx: Receiver, kind: u32, record: u32, slot: u32, xi: f32) -> Pick {
    let u = min((f32(slot) + xi) / f32(params.light_samples), ONE_BELOW);
    var s = selection_sampler(kind, record, slot);
    return tree_sample(base, rx, sqrt(max(params.radius2, 0.0)), u, &s);
}

// `light_tree::FLAT_GROUP`: consecutive records that share one flat draw's masses.
const FLAT_GROUP: u32 = 16u;

// The group of record `i` (`LightTree::group_masses` on the CPU), in this dispatch's
// numbering: a dispatch starts at a multiple of 16 records, so its groups are whole.
fn flat_group(i: u32) -> u32 {
    return i / FLAT_GROUP;
}

// The length of a row of `flat_masses` for a tree of `nodes` nodes: its (nodes + 1) / 2
// leaves, padded to a multiple of 64 (256 bytes, so that a dispatch binds whole rows).
fn flat_stride(nodes: u32) -> u32 {
    return max((nodes + 1u) / 2u + 63u, 64u) / 64u * 64u;
}

// `streams::selection_sampler`.
fn selection_sampler(kind: u32, record: u32, slot: u32) -> Sampler {
    return sampler_new(pcg_hash(params.pair_seed ^ 0x27d4eb2fu) + slot, params.pass_index, (params.record_offset + record) * 4u + kind);
}

// `streams::selection_number`.
fn selection_number(kind: u32, record: u32) -> f32 {
    var s = sampler_new(pcg_hash(params.pair_seed ^ 0xb5297a4du), params.pass_index, (params.record_offset + record) * 4u + kind);
    return next_1d(&s);
}

// `streams::drawn_pair_sampler`.
fn drawn_pair_sampler(kind: u32, record: u32, slot: u32) -> Sampler {
    return sampler_new(pcg_hash(params.pair_seed ^ 0x68e31da4u) + slot, params.pass_index, (params.record_offset + record) * 4u + kind);
}
