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
    // Interior: index of the left child (the right one follows); leaf: LIGHT_LEAF | light.
    child: u32,
}

const LIGHT_LEAF: u32 = 0x80000000u;
// The largest f32 below 1.
const ONE_BELOW: f32 = 0.99999994;

@group(1) @binding(8) var<storage, read> light_tree: array<LightTreeNode>;

// `light_tree::Receiver`: a shading point (a = p, b = n) or a media segment (a = o, b = d).
struct Receiver {
    a: vec3<f32>,
    is_segment: bool,
    b: vec3<f32>,
    len: f32,
}

fn point_receiver(p: vec3<f32>, n: vec3<f32>) -> Receiver {
    return Receiver(p, false, n, 0.0);
}

fn segment_receiver(o: vec3<f32>, d: vec3<f32>, len: f32) -> Receiver {
    return Receiver(o, true, d, len);
}

fn dot_glam(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// `light_tree::importance`.
fn light_importance(node: LightTreeNode, rx: Receiver, r_in: f32) -> f32 {
    let c = 0.5 * (node.lo + node.hi);
    let half = 0.5 * (node.hi - node.lo);
    let rb = length_glam(half);
    let r = max(r_in, 1e-12);
    if !rx.is_segment {
        let p = rx.a;
        let n = rx.b;
        let top = dot_glam(n, c - p) + dot_glam(abs(n), half) + r;
        if top < 0.0 {
            return 0.0;
        }
        let q = clamp(p, node.lo, node.hi);
        let qp = q - p;
        let d2 = max(dot_glam(qp, qp), r * r);
        let to = c - p;
        let dc = length_glam(to);
        let reach = rb + r;
        var cos_bound = 1.0;
        if dc > reach {
            let cos_t = clamp(dot_glam(n, to) / dc, -1.0, 1.0);
            let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
            let sin_a = reach / dc;
            let cos_a = sqrt(max(1.0 - sin_a * sin_a, 0.0));
            if cos_t < cos_a {
                cos_bound = cos_t * cos_a + sin_t * sin_a;
            }
        }
        return node.weight * max(cos_bound, 1e-3) / d2;
    }
    let v = c - rx.a;
    let tc = dot_glam(v, rx.b);
    let h2 = max(dot_glam(v, v) - tc * tc, 0.0);
    let h = max(sqrt(h2) - rb, r);
    let angle = atan((rx.len - tc) / h) + atan(tc / h);
    return node.weight * max(angle, 0.0) / h;
}

// A drawn light: its index and probability (`found` false when no light can reach).
struct Pick {
    light: u32,
    pmf: f32,
    found: bool,
}

// `LightTree::sample` on the tree whose root is at `base` in `light_tree`.
fn tree_sample(base: u32, rx: Receiver, r: f32, u_in: f32) -> Pick {
    var at = 0u;
    var pmf = 1.0;
    var u = u_in;
    // A median-split tree is at most 32 levels deep (fewer than 2³¹ lights).
    for (var level = 0u; level < 64u; level++) {
        let node = light_tree[base + at];
        if (node.child & LIGHT_LEAF) != 0u {
            return Pick(node.child & ~LIGHT_LEAF, pmf, true);
        }
        let c = node.child;
        let a = light_importance(light_tree[base + c], rx, r);
        let b = light_importance(light_tree[base + c + 1u], rx, r);
        let total = a + b;
        if !(total > 0.0) {
            return Pick(0u, 0.0, false);
        }
        let p_left = a / total;
        if u < p_left {
            u = min(u / p_left, ONE_BELOW);
            pmf *= p_left;
            at = c;
        } else {
            let p_right = 1.0 - p_left;
            u = min((u - p_left) / p_right, ONE_BELOW);
            pmf *= p_right;
            at = c + 1u;
        }
    }
    return Pick(0u, 0.0, false);
}

// Slot `slot` of a record's stratified draws: `LightTree::sample_k`.
fn tree_sample_slot(base: u32, rx: Receiver, slot: u32, xi: f32) -> Pick {
    let u = min((f32(slot) + xi) / f32(params.light_samples), ONE_BELOW);
    return tree_sample(base, rx, sqrt(max(params.radius2, 0.0)), u);
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
