//! use lib/scene.wgsl
//! use lib/geometry.wgsl
// BVH2 traversal (closest hit and any hit), stackless: the nodes are in depth-first preorder,
// so an entered node continues at the next node (its first child, or for a leaf the next
// subtree), and a missed inner node jumps past its subtree (`BvhNode::first` holds that
// index). Every step is one node fetch and one box test, with no per-invocation stack: on a
// SIMD adapter such as lavapipe this measured faster than a near-first stack traversal, and
// no tree is too deep for it.

struct Hit {
    // Distance along the unit direction; negative for a miss.
    t: f32,
    // Scene index of the triangle.
    tri: u32,
    b1: f32,
    b2: f32,
}

const NO_ENTRY: f32 = 3.0e38;

// Entry distance of the ray into a box, or NO_ENTRY when it misses or enters beyond `tmax`.
// The far distance is widened by 2γ(3) so that rounding never culls a box the ray grazes
// (pbrt-v4).
fn box_entry(lo: vec3<f32>, hi: vec3<f32>, o: vec3<f32>, inv_d: vec3<f32>, tmax: f32) -> f32 {
    let ta = (lo - o) * inv_d;
    let tb = (hi - o) * inv_d;
    let tnear = min(ta, tb);
    let tfar = max(ta, tb) * (1.0 + 2.0 * gamma(3.0));
    let t0 = max(max(tnear.x, tnear.y), max(tnear.z, 0.0));
    let t1 = min(min(tfar.x, tfar.y), min(tfar.z, tmax));
    return select(NO_ENTRY, t0, t0 <= t1);
}

// 1/d with zero components replaced by a huge finite value of the same sign, so slab
// distances stay ordered and never NaN.
fn safe_inverse(d: vec3<f32>) -> vec3<f32> {
    let tiny = 1.0e-30;
    let s = select(vec3<f32>(-tiny), vec3<f32>(tiny), d >= vec3<f32>(0.0));
    return 1.0 / select(d, s, abs(d) < vec3<f32>(tiny));
}

// The node after node `i` (entered or not) in the threaded traversal.
fn next_node(i: u32, node: BvhNode, entered: bool) -> u32 {
    return select(i + 1u, node.first, node.count == 0u && !entered);
}

// Closest hit with t in (0, tmax) along o + t·d (d unit length).
fn closest_hit(o: vec3<f32>, d: vec3<f32>, tmax_in: f32) -> Hit {
    var hit = Hit(-1.0, 0u, 0.0, 0.0);
    let inv_d = safe_inverse(d);
    let r = triangle_ray(o, d);
    var tmax = tmax_in;
    var i = 0u;
    while i < scene_info.node_count {
        let node = nodes[i];
        let entered = box_entry(node.lo, node.hi, o, inv_d, tmax) < NO_ENTRY;
        if entered && node.count > 0u {
            for (var k = node.first; k < node.first + node.count; k++) {
                let tri = leaf_triangle(k);
                let h = intersect_triangle(r, tri.p0, tri.p1, tri.p2, 0.0, tmax);
                if h.x >= 0.0 {
                    tmax = h.x;
                    hit = Hit(h.x, tri.id, h.y, h.z);
                }
            }
        }
        i = next_node(i, node, entered);
    }
    return hit;
}

// Whether anything lies on o + t·d for t in (0, tmax).
fn occluded(o: vec3<f32>, d: vec3<f32>, tmax: f32) -> bool {
    let inv_d = safe_inverse(d);
    let r = triangle_ray(o, d);
    var blocked = false;
    var i = 0u;
    while i < scene_info.node_count && !blocked {
        let node = nodes[i];
        let entered = box_entry(node.lo, node.hi, o, inv_d, tmax) < NO_ENTRY;
        if entered && node.count > 0u {
            for (var k = node.first; k < node.first + node.count; k++) {
                let tri = leaf_triangle(k);
                if intersect_triangle(r, tri.p0, tri.p1, tri.p2, 0.0, tmax).x >= 0.0 {
                    blocked = true;
                    break;
                }
            }
        }
        i = next_node(i, node, entered);
    }
    return blocked;
}
