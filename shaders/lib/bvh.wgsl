//! use lib/scene.wgsl
//! use lib/geometry.wgsl
// BVH2 traversal (closest hit and any hit) with a per-invocation stack.

const STACK_SIZE: u32 = 64u;

struct Hit {
    // Distance along the unit direction; negative for a miss.
    t: f32,
    // Scene index of the triangle.
    tri: u32,
    b1: f32,
    b2: f32,
}

// Entry distance of the ray into a box, or +∞ when it misses or enters beyond `tmax`. The far
// distance is widened by 2γ(3) so that rounding never culls a box the ray grazes (pbrt-v4).
fn box_entry(lo: vec3<f32>, hi: vec3<f32>, o: vec3<f32>, inv_d: vec3<f32>, tmax: f32) -> f32 {
    let ta = (lo - o) * inv_d;
    let tb = (hi - o) * inv_d;
    let tnear = min(ta, tb);
    let tfar = max(ta, tb) * (1.0 + 2.0 * gamma(3.0));
    let t0 = max(max(tnear.x, tnear.y), max(tnear.z, 0.0));
    let t1 = min(min(tfar.x, tfar.y), min(tfar.z, tmax));
    return select(3.0e38, t0, t0 <= t1);
}

// 1/d with zero components replaced by a huge finite value of the same sign, so slab
// distances stay ordered and never NaN.
fn safe_inverse(d: vec3<f32>) -> vec3<f32> {
    let tiny = 1.0e-30;
    let s = select(vec3<f32>(-tiny), vec3<f32>(tiny), d >= vec3<f32>(0.0));
    return 1.0 / select(d, s, abs(d) < vec3<f32>(tiny));
}

// Closest hit with t in (0, tmax) along o + t·d (d unit length).
fn closest_hit(o: vec3<f32>, d: vec3<f32>, tmax_in: f32) -> Hit {
    var hit = Hit(-1.0, 0u, 0.0, 0.0);
    if scene_info.node_count == 0u {
        return hit;
    }
    let inv_d = safe_inverse(d);
    let r = triangle_ray(o, d);
    var tmax = tmax_in;
    var stack: array<u32, STACK_SIZE>;
    var top = 0u;
    var node_index = 0u;
    loop {
        let node = nodes[node_index];
        if node.count > 0u {
            for (var k = node.first; k < node.first + node.count; k++) {
                let tri = triangles[k];
                let h = intersect_triangle(r, tri.p0, tri.p1, tri.p2, 0.0, tmax);
                if h.x >= 0.0 {
                    tmax = h.x;
                    hit = Hit(h.x, tri.id, h.y, h.z);
                }
            }
        } else {
            let left = nodes[node.first];
            let right = nodes[node.first + 1u];
            let tl = box_entry(left.lo, left.hi, o, inv_d, tmax);
            let tr = box_entry(right.lo, right.hi, o, inv_d, tmax);
            let hit_l = tl < 3.0e38;
            let hit_r = tr < 3.0e38;
            if hit_l && hit_r {
                // Visit the nearer child first; the other waits on the stack.
                let near_first = select(node.first + 1u, node.first, tl <= tr);
                let far = select(node.first, node.first + 1u, tl <= tr);
                if top < STACK_SIZE {
                    stack[top] = far;
                    top++;
                }
                node_index = near_first;
                continue;
            } else if hit_l {
                node_index = node.first;
                continue;
            } else if hit_r {
                node_index = node.first + 1u;
                continue;
            }
        }
        if top == 0u {
            break;
        }
        top--;
        node_index = stack[top];
        // Entries pushed before tmax shrank may now be too far: box_entry rejects them next.
    }
    return hit;
}

// Whether anything lies on o + t·d for t in (0, tmax).
fn occluded(o: vec3<f32>, d: vec3<f32>, tmax: f32) -> bool {
    if scene_info.node_count == 0u {
        return false;
    }
    let inv_d = safe_inverse(d);
    let r = triangle_ray(o, d);
    var stack: array<u32, STACK_SIZE>;
    var top = 0u;
    var node_index = 0u;
    // The root's own box: a ray that misses the scene's bounds needs no further work.
    if box_entry(nodes[0].lo, nodes[0].hi, o, inv_d, tmax) >= 3.0e38 {
        return false;
    }
    loop {
        let node = nodes[node_index];
        if node.count > 0u {
            for (var k = node.first; k < node.first + node.count; k++) {
                let tri = triangles[k];
                if intersect_triangle(r, tri.p0, tri.p1, tri.p2, 0.0, tmax).x >= 0.0 {
                    return true;
                }
            }
        } else {
            let left = nodes[node.first];
            let right = nodes[node.first + 1u];
            let hit_l = box_entry(left.lo, left.hi, o, inv_d, tmax) < 3.0e38;
            let hit_r = box_entry(right.lo, right.hi, o, inv_d, tmax) < 3.0e38;
            if hit_l && hit_r {
                if top < STACK_SIZE {
                    stack[top] = node.first + 1u;
                    top++;
                }
                node_index = node.first;
                continue;
            } else if hit_l {
                node_index = node.first;
                continue;
            } else if hit_r {
                node_index = node.first + 1u;
                continue;
            }
        }
        if top == 0u {
            break;
        }
        top--;
        node_index = stack[top];
    }
    return false;
}
