// The scene as the kernels see it: bind group 0, shared by every kernel that traces rays.
// Each struct mirrors a `#[repr(C)]` type in `crates/gpu/src/layout.rs` (checked by
// `crates/gpu/tests/layout.rs`).

// A node of the flattened BVH2. Inner nodes (count = 0): children at `first` and `first + 1`.
// Leaves: triangles `first .. first + count` of `triangles`.
struct BvhNode {
    lo: vec3<f32>,
    count: u32,
    hi: vec3<f32>,
    first: u32,
}

// A triangle in BVH leaf order; `id` is its index in the scene.
struct Triangle {
    p0: vec3<f32>,
    id: u32,
    p1: vec3<f32>,
    _pad1: u32,
    p2: vec3<f32>,
    _pad2: u32,
}

// Per scene triangle (scene order).
struct TriangleInfo {
    // Position of the triangle in `triangles`.
    leaf_slot: u32,
    // TRI_NULL_INTERFACE when shadow rays pass through it (a medium boundary without a BSDF);
    // TRI_PLATE_FRONT / TRI_PLATE_BACK when its planar patch is a plate seen from its front /
    // back; TRI_PATCH_FLIPPED when its front is its patch's back.
    flags: u32,
    // Media on the two sides, NO_MEDIUM for vacuum (meaningful only for interfaces).
    inside: u32,
    outside: u32,
    // Its planar patch (`patches::Patches::spans`): the span of the patch's open edges in
    // `patch_edges` (start, count); for a patch of one, the masks of its edges open from its
    // front (bits 0-2) and back (bits 3-5) (mask, 0); (0, PATCH_CLOSED) for a patch with none.
    patch_start: u32,
    patch_count: u32,
}

// An open edge of a planar patch: where the surface folds away or ends, seen from `sides` of
// the patch (SIDE_FRONT | SIDE_BACK).
struct PatchEdge {
    a: vec3<f32>,
    sides: u32,
    b: vec3<f32>,
    _pad1: u32,
}

const PATCH_CLOSED: u32 = 0xffffffffu;

const TRI_NULL_INTERFACE: u32 = 1u;
// Its planar patch is a plate seen from its front / back: a surface whose edges open from that
// side all end it (`patches::Patches::plate`); its front is its patch's back (`flipped`).
const TRI_PLATE_FRONT: u32 = 2u;
const TRI_PLATE_BACK: u32 = 4u;
const TRI_PATCH_FLIPPED: u32 = 8u;
// A triangle's sides (`patches::FRONT`, `BACK`).
const SIDE_FRONT: u32 = 1u;
const SIDE_BACK: u32 = 2u;
const NO_MEDIUM: u32 = 0xffffffffu;

// A medium. Homogeneous when `grid_res.x` = 0; otherwise a density grid of `grid_res` cells
// over [grid_lo, grid_hi] starting at `grid[grid_offset]` (x fastest), followed by its
// majorant grid of `majorant_res` cells.
struct Medium {
    sigma_s: vec3<f32>,
    g: f32,
    sigma_a: vec3<f32>,
    grid_offset: u32,
    grid_lo: vec3<f32>,
    majorant_offset: u32,
    grid_hi: vec3<f32>,
    _pad: u32,
    grid_res: vec3<u32>,
    _pad2: u32,
    majorant_res: vec3<u32>,
    _pad3: u32,
}

// Scene-wide facts.
struct SceneInfo {
    // Number of BVH nodes (0 for an empty scene).
    node_count: u32,
    // 1 when any triangle is a null interface: shadow rays must then walk hits.
    has_null_interfaces: u32,
    medium_count: u32,
    // Triangles in `triangles`; the rest are in `triangles_more` (a buffer may not exceed the
    // adapter's storage-binding limit, 128 MiB on lavapipe: 2.8 M triangles).
    triangle_split: u32,
}

@group(0) @binding(0) var<uniform> scene_info: SceneInfo;
@group(0) @binding(1) var<storage, read> nodes: array<BvhNode>;
@group(0) @binding(2) var<storage, read> triangles: array<Triangle>;
@group(0) @binding(3) var<storage, read> triangle_info: array<TriangleInfo>;
@group(0) @binding(4) var<storage, read> media: array<Medium>;
@group(0) @binding(5) var<storage, read> grid: array<f32>;
@group(0) @binding(6) var<storage, read> triangles_more: array<Triangle>;
@group(0) @binding(7) var<storage, read> patch_edges: array<PatchEdge>;

// Triangle `k` in leaf order, from whichever binding holds it.
fn leaf_triangle(k: u32) -> Triangle {
    if k < scene_info.triangle_split {
        return triangles[k];
    }
    return triangles_more[k - scene_info.triangle_split];
}
