//! use lib/rng.wgsl
// Test kernel: the hash of counter k, for k = first .. first + count, to compare bit for bit
// with the CPU (`tests/rng.rs`).

struct Params {
    seed: u32,
    pass_index: u32,
    first: u32,
    count: u32,
    // Invocations per row of the 2-D dispatch.
    row: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> bits: array<u32>;
@group(0) @binding(2) var<storage, read_write> floats: array<f32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x + gid.y * params.row;
    if k >= params.count {
        return;
    }
    let counter = params.first + k;
    // Spread the counter over the index and dimension words as the renderer does.
    bits[k] = hash4(params.seed, params.pass_index, counter >> 4u, counter & 15u);
    var s = sampler_new(params.seed, params.pass_index, counter);
    floats[k] = next_1d(&s);
}
