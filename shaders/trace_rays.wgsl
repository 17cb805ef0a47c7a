//! use lib/bvh.wgsl
// Ray queries in bulk: closest hit, or occlusion, for each ray of a batch. Used to check the
// traversal against the CPU BVH and to measure rays per second.

struct Ray {
    o: vec3<f32>,
    tmax: f32,
    d: vec3<f32>,
    // 0: closest hit; 1: any hit (occlusion only).
    any_hit: u32,
}

struct RayBatch {
    count: u32,
    // Invocations per row of the 2-D dispatch (workgroups in x times the workgroup size).
    row: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(1) @binding(0) var<uniform> batch: RayBatch;
@group(1) @binding(1) var<storage, read> rays: array<Ray>;
@group(1) @binding(2) var<storage, read_write> hits: array<Hit>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * batch.row;
    if i >= batch.count {
        return;
    }
    let ray = rays[i];
    if ray.any_hit != 0u {
        let blocked = occluded(ray.o, ray.d, ray.tmax);
        hits[i] = Hit(select(-1.0, 0.0, blocked), 0u, 0.0, 0.0);
    } else {
        hits[i] = closest_hit(ray.o, ray.d, ray.tmax);
    }
}
