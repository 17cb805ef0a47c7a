//! use lib/rng.wgsl
//! use lib/shading.wgsl
// The gathers' inputs and outputs (bind group 1 of every gather kernel): one pass's camera
// gather records and light records, mirrored from `beamlight_trace::{camera_paths,
// light_paths}`, with each record's BSDF resolved (texture applied) on the CPU.

// `camera_paths::ShadingPoint`.
struct ShadingPoint {
    pos: vec3<f32>,
    material: u32,
    normal: vec3<f32>,
    tri: u32,
    wo: vec3<f32>,
    pixel: u32,
    throughput: vec3<f32>,
    medium: u32,
    uv: vec2<f32>,
    _pad2: vec2<u32>,
}

// `camera_paths::MediaSegment`.
struct MediaSegment {
    origin: vec3<f32>,
    length: f32,
    dir: vec3<f32>,
    medium: u32,
    throughput: vec3<f32>,
    pixel: u32,
}

// `light_paths::SurfaceVertex`: a VPL.
struct SurfaceVertex {
    pos: vec3<f32>,
    material: u32,
    normal: vec3<f32>,
    tri: u32,
    wi: vec3<f32>,
    u: f32,
    power: vec3<f32>,
    v: f32,
}

// `light_paths::LightSegment`: a VRL.
struct LightSegment {
    origin: vec3<f32>,
    length: f32,
    dir: vec3<f32>,
    medium: u32,
    power: vec3<f32>,
    flags: u32,
}

// `GatherParams` in crates/gpu/src/layout.rs.
struct GatherParams {
    // Base seed of the per-pair streams (`beamlight_trace::streams::pair_seed`).
    pair_seed: u32,
    pass_index: u32,
    // Gather records (shading points or media segments) and light records (VPLs or VRLs).
    records: u32,
    lights: u32,
    // Invocations per row of the 2-D dispatch.
    row: u32,
    // Minimum distance of the 1/d² falloff (0: unclamped).
    clamp: f32,
    // 1 / light paths traced: a set's sum times this is the per-pass estimate.
    scale: f32,
    // The `vbl` kernels' settings: the pass's squared radius R², and `VblSettings`.
    radius2: f32,
    directions: u32,
    pdf_vertices: u32,
    uniform_share: f32,
    // ANGULAR_PDF_VBL or ANGULAR_PDF_VRL.
    angular_pdf: u32,
    // Index of this dispatch's first record in the pass: the bound arrays start there.
    record_offset: u32,
    // Lights a record draws per kernel from the light tree (0: every light, all pairs), and
    // the sizes of the VSL and VBL trees in `light_tree` (`lib/light_tree.wgsl`).
    light_samples: u32,
    vsl_tree_nodes: u32,
    vbl_tree_nodes: u32,
    // Fault injection for the discard counters' tests: 0, or a NaN's bits.
    poison: u32,
    // How `Lmm`'s records draw their VBLs: 0 down the tree, 1 flat (`light_tree::Drawing`).
    media_drawing: u32,
    // An all-pairs gather goes over its lights in chunks, one dispatch each (lavapipe caps the
    // loop iterations of an invocation, `lib/gather_entry.wgsl`): this dispatch gathers lights
    // first_light .. first_light + light_chunk, and a chunk after the first adds to what the
    // earlier ones wrote.
    first_light: u32,
    light_chunk: u32,
}

// `components::SHARP_PHASE_G`: HG media at least this anisotropic are sharp, and a camera
// point in one connects to no virtual light (the camera path's walk carries that light).
const SHARP_PHASE_G: f32 = 0.95;

fn gathers_in_medium(camera_g: f32) -> bool {
    return abs(camera_g) < SHARP_PHASE_G;
}

const ANGULAR_PDF_VBL: u32 = 0u;
const ANGULAR_PDF_VRL: u32 = 1u;

@group(1) @binding(0) var<uniform> params: GatherParams;
@group(1) @binding(1) var<storage, read> shading_points: array<ShadingPoint>;
@group(1) @binding(2) var<storage, read> point_bsdfs: array<Bsdf>;
@group(1) @binding(3) var<storage, read> media_segments: array<MediaSegment>;
@group(1) @binding(4) var<storage, read> vpls: array<SurfaceVertex>;
@group(1) @binding(5) var<storage, read> vpl_bsdfs: array<Bsdf>;
@group(1) @binding(6) var<storage, read> vrls: array<LightSegment>;
@group(1) @binding(7) var<storage, read_write> gathered: array<vec4<f32>>;

// The streams' `kind` words (`beamlight_trace::streams::GatherKind`).
const KIND_VPL_TO_SURFACE: u32 = 0u;
const KIND_VRL_TO_SURFACE: u32 = 1u;
const KIND_VPL_TO_MEDIA: u32 = 2u;
const KIND_VRL_TO_MEDIA: u32 = 3u;

// The random stream of one (gather record, light) pair: `streams::pair_sampler`.
fn pair_sampler(kind: u32, record: u32, light: u32) -> Sampler {
    return sampler_new(params.pair_seed + light, params.pass_index, (params.record_offset + record) * 4u + kind);
}

// `vpl::falloff`: 1 / max(d², clamp²).
fn falloff(d2: f32) -> f32 {
    return 1.0 / max(d2, params.clamp * params.clamp);
}

// `many_lights::admit`: what may enter an accumulator. `v` when it is finite and non-negative;
// otherwise it counts in `discarded` (returned to the CPU in the record's w) and only its finite
// non-negative part passes.
fn admit(v: vec3<f32>, discarded: ptr<function, u32>) -> vec3<f32> {
    if finite_vec3(v) && min(v.x, min(v.y, v.z)) >= 0.0 {
        return v;
    }
    *discarded += 1u;
    if finite_vec3(v) {
        return max(v, vec3<f32>(0.0));
    }
    return vec3<f32>(0.0);
}

// `failed::FAILED_ESTIMATE`: a light's estimate when it cannot be made (a density that came out
// zero or not finite, a segment of negative, infinite or NaN length): NaN, which `admit` counts.
fn failed_estimate() -> vec3<f32> {
    return vec3<f32>(bitcast<f32>(0x7fc00000u));
}

// `failed::degenerate_length`: whether a segment of this length ends a pair's estimate before
// sampling, and `degenerate_estimate` what with: zero for no length, the failed estimate for a
// negative, infinite or NaN one.
fn degenerate_length(len: f32) -> bool {
    return !(len > 0.0 && finite_f32(len));
}

fn degenerate_estimate(len: f32) -> vec3<f32> {
    if len == 0.0 {
        return vec3<f32>(0.0);
    }
    return failed_estimate();
}

// `record_gathers::injected`: the record's estimate, or the injected NaN for the pass's first record
// (`GatherParams::poison`).
fn injected(v: vec3<f32>, record: u32) -> vec3<f32> {
    if params.poison != 0u && params.record_offset + record == 0u && params.first_light == 0u {
        return vec3<f32>(bitcast<f32>(params.poison));
    }
    return v;
}

fn is_black(c: vec3<f32>) -> bool {
    return all(c == vec3<f32>(0.0));
}

// The record index of this invocation, or a value ≥ params.records past the end.
fn record_index(gid: vec3<u32>) -> u32 {
    return gid.x + gid.y * params.row;
}
