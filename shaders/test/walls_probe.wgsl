//! use lib/walls.wgsl
// Test kernel: `walls_around` for a batch of VSL centres, to compare with the CPU's
// `Walls::around` (`crates/gpu/tests/walls.rs`).

struct WallsQuery {
    centre: vec3<f32>,
    r: f32,
}

struct WallsBatch {
    count: u32,
    // Invocations per row of the 2-D dispatch.
    row: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(1) @binding(0) var<uniform> batch: WallsBatch;
@group(1) @binding(1) var<storage, read> queries: array<WallsQuery>;
@group(1) @binding(2) var<storage, read_write> results: array<Walls>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * batch.row;
    if i >= batch.count {
        return;
    }
    let q = queries[i];
    results[i] = walls_around(q.centre, q.r);
}
