//! use lib/sampling.wgsl
// Test kernel: `equiangular` of lib/sampling.wgsl on a batch of queries, to compare with
// `beamlight_scene::sampling::equiangular`, which it twins (`crates/gpu/tests/sampling.rs`).

struct EquiangularQuery {
    o: vec3<f32>,
    t0: f32,
    d: vec3<f32>,
    t1: f32,
    c: vec3<f32>,
    u: f32,
}

struct Batch {
    count: u32,
    // Invocations per row of the 2-D dispatch.
    row: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> batch: Batch;
@group(0) @binding(1) var<storage, read> queries: array<EquiangularQuery>;
// (t, pdf) of each query.
@group(0) @binding(2) var<storage, read_write> results: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * batch.row;
    if i >= batch.count {
        return;
    }
    let q = queries[i];
    results[i] = equiangular(q.o, q.d, q.t0, q.t1, q.c, q.u);
}
