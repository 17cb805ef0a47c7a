//! use lib/media.wgsl
// Test kernel: evaluates lib/media.wgsl on a batch of queries, each with its own sampler keys,
// to compare with the CPU functions it twins (`crates/gpu/tests/media.rs`).

const QUERY_SHADOW: u32 = 0u;
const QUERY_TRANSMITTANCE: u32 = 1u;
const QUERY_DENSITY: u32 = 2u;

struct MediaQuery {
    o: vec3<f32>,
    // Medium the query starts in (NO_MEDIUM: vacuum); the medium sampled for QUERY_DENSITY.
    medium: u32,
    // QUERY_SHADOW: the target point. QUERY_TRANSMITTANCE: the unit direction. Unused for
    // QUERY_DENSITY (which samples at `o`).
    v: vec3<f32>,
    kind: u32,
    // Segment length for QUERY_TRANSMITTANCE.
    tmax: f32,
    seed: u32,
    pass_index: u32,
    index: u32,
}

struct MediaBatch {
    count: u32,
    // Invocations per row of the 2-D dispatch.
    row: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(1) @binding(0) var<uniform> batch: MediaBatch;
@group(1) @binding(1) var<storage, read> queries: array<MediaQuery>;
// rgb: the result; w: random numbers drawn (to tell a porting bug from a rounding flip).
@group(1) @binding(2) var<storage, read_write> results: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * batch.row;
    if i >= batch.count {
        return;
    }
    let q = queries[i];
    var s = sampler_new(q.seed, q.pass_index, q.index);
    var r = vec3<f32>(0.0);
    if q.kind == QUERY_SHADOW {
        r = shadow_transmittance(q.o, q.v, q.medium, &s);
    } else if q.kind == QUERY_TRANSMITTANCE {
        r = medium_transmittance(q.medium, q.o, q.v, q.tmax, &s);
    } else {
        r = vec3<f32>(medium_density(q.medium, q.o));
    }
    results[i] = vec4<f32>(r, f32(s.dim));
}
