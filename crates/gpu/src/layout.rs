//! Every struct that crosses the CPU–GPU boundary: `#[repr(C)]` + `Pod` here, mirrored by a
//! WGSL struct of the same name in `shaders/` (`tests/layout.rs` checks size, alignment and
//! each member's offset with naga). A `vec3<f32>` has 16-byte alignment in WGSL, so each
//! 3-vector is followed by a 4-byte scalar.
use bytemuck::{Pod, Zeroable};

/// A node of the flattened BVH2 (`BvhNode` in `lib/scene.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    pub lo: [f32; 3],
    /// Triangles in the leaf; 0 for an inner node.
    pub count: u32,
    pub hi: [f32; 3],
    /// Inner node: index of the left child (the right one follows it). Leaf: first triangle.
    pub first: u32,
}

/// A triangle in BVH leaf order (`Triangle` in `lib/scene.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Triangle {
    pub p0: [f32; 3],
    /// Index in `Scene::triangles`.
    pub id: u32,
    pub p1: [f32; 3],
    pub _pad1: u32,
    pub p2: [f32; 3],
    pub _pad2: u32,
}

/// Per scene triangle, in scene order (`TriangleInfo` in `lib/scene.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TriangleInfo {
    /// Position of the triangle in the leaf-ordered triangle array.
    pub leaf_slot: u32,
    /// [`TRI_NULL_INTERFACE`] or 0.
    pub flags: u32,
    /// Media on the back and front side ([`NO_MEDIUM`] for vacuum).
    pub inside: u32,
    pub outside: u32,
    /// The triangle's planar patch, `patches::Patches::spans`: its open edges in the scene's
    /// `patch_edges` (start, count), or for a patch of one the masks of its edges open from
    /// its front (bits 0–2) and back (bits 3–5) (mask, 0).
    pub patch_start: u32,
    pub patch_count: u32,
}

/// An open edge of a planar patch (`PatchEdge` in `lib/scene.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PatchEdge {
    pub a: [f32; 3],
    /// The sides of the patch it is open from (`patches::OpenEdge::sides`: 1 front, 2 back).
    pub sides: u32,
    pub b: [f32; 3],
    pub _pad1: u32,
}

/// `TriangleInfo::flags`: a medium boundary without a BSDF, which shadow rays pass through.
pub const TRI_NULL_INTERFACE: u32 = 1;
/// `TriangleInfo::flags`: its planar patch is a plate seen from its front, from its back
/// (`patches::Patches::plate`), and its front is its patch's back (`Patches::flipped`).
pub const TRI_PLATE_FRONT: u32 = 2;
pub const TRI_PLATE_BACK: u32 = 4;
pub const TRI_PATCH_FLIPPED: u32 = 8;
/// A medium index meaning vacuum (the CPU's `camera_paths::NO_MEDIUM`).
pub const NO_MEDIUM: u32 = u32::MAX;

/// A medium (`Medium` in `lib/scene.wgsl`). Homogeneous when `grid_res[0]` is 0.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Medium {
    pub sigma_s: [f32; 3],
    pub g: f32,
    pub sigma_a: [f32; 3],
    /// First density value in the shared grid buffer.
    pub grid_offset: u32,
    pub grid_lo: [f32; 3],
    /// First majorant in the shared grid buffer.
    pub majorant_offset: u32,
    pub grid_hi: [f32; 3],
    pub _pad: u32,
    pub grid_res: [u32; 3],
    pub _pad2: u32,
    pub majorant_res: [u32; 3],
    pub _pad3: u32,
}

/// Scene-wide facts (`SceneInfo` in `lib/scene.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SceneInfo {
    pub node_count: u32,
    pub has_null_interfaces: u32,
    pub medium_count: u32,
    /// Leaf-order triangles in the first triangle binding; the rest are in the second.
    pub triangle_split: u32,
}

/// A ray query (`Ray` in `trace_rays.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Ray {
    pub o: [f32; 3],
    pub tmax: f32,
    pub d: [f32; 3],
    /// 0: closest hit; 1: occlusion only.
    pub any_hit: u32,
}

/// A ray query's answer (`Hit` in `lib/bvh.wgsl`): `t < 0` for a miss (for an occlusion
/// query, `t = 0` means blocked).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Hit {
    pub t: f32,
    pub tri: u32,
    pub b1: f32,
    pub b2: f32,
}

/// The size of a batch and the row length of its 2-D dispatch (`RayBatch` in
/// `trace_rays.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RayBatch {
    pub count: u32,
    pub row: u32,
    pub _pad0: u32,
    pub _pad1: u32,
}

/// A BSDF with its texture applied (`Bsdf` in `lib/shading.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Bsdf {
    /// Lambert albedo or Phong diffuse colour.
    pub diffuse: [f32; 3],
    pub exponent: f32,
    pub specular: [f32; 3],
    /// [`BSDF_NONE`], [`BSDF_LAMBERT`] or [`BSDF_PHONG`].
    pub kind: u32,
}

/// No BSDF, or a delta one (mirror, glass): nothing to evaluate.
pub const BSDF_NONE: u32 = 0;
pub const BSDF_LAMBERT: u32 = 1;
pub const BSDF_PHONG: u32 = 2;

/// The parameters of one gather dispatch (`GatherParams` in `lib/gather.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GatherParams {
    /// `beamlight_trace::streams::pair_seed` of the render seed.
    pub pair_seed: u32,
    pub pass_index: u32,
    /// Gather records (shading points or media segments).
    pub records: u32,
    /// Light records (VPLs or VRLs).
    pub lights: u32,
    /// Invocations per row of the 2-D dispatch.
    pub row: u32,
    /// Minimum distance of the 1/d² falloff (0: unclamped).
    pub clamp: f32,
    /// 1 / light paths traced.
    pub scale: f32,
    /// The pass's squared VBL/VSL radius R² (the `vbl` kernels only).
    pub radius2: f32,
    /// `VblSettings::directions`.
    pub directions: u32,
    /// `VblSettings::pdf_vertices`.
    pub pdf_vertices: u32,
    /// `VblSettings::uniform_share`.
    pub uniform_share: f32,
    /// `VblSettings::pdf`: [`ANGULAR_PDF_VBL`] or [`ANGULAR_PDF_VRL`].
    pub angular_pdf: u32,
    /// Index of this dispatch's first record in the pass (dispatches bind chunks of records).
    pub record_offset: u32,
    /// Lights a record draws from the light tree (0: every light, the all-pairs gather).
    pub light_samples: u32,
    /// Nodes of the VSL tree, first in the tree binding, and of the VBL tree after it.
    pub vsl_tree_nodes: u32,
    pub vbl_tree_nodes: u32,
    /// Fault injection (`GatherInputs::inject_nan`): 0, or the bits of the NaN that the pass's
    /// first record estimates instead of its gather (a NaN from the CPU, not a WGSL constant,
    /// which the shader compiler may fold or reject).
    pub poison: u32,
    /// How `Lmm`'s records draw their VBLs: 0 down the tree, 1 flat (`Drawing`).
    pub media_drawing: u32,
    /// This dispatch's lights of an all-pairs gather, `first_light .. first_light +
    /// light_chunk` (`gather::LIGHTS_PER_DISPATCH`); chunks after the first add to the output.
    pub first_light: u32,
    pub light_chunk: u32,
}

/// `GatherParams::angular_pdf`: the paper's vertex values (at ω'_max).
pub const ANGULAR_PDF_VBL: u32 = 0;
/// `GatherParams::angular_pdf`: the VRL paper's vertex values (at the cone's axis).
pub const ANGULAR_PDF_VRL: u32 = 1;

/// A wall's plane next to a VSL centre (`Plane` in `lib/vbl.wgsl`; `beamlight_trace::vbl::Plane`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Plane {
    pub point: [f32; 3],
    pub _pad0: u32,
    pub normal: [f32; 3],
    pub _pad1: u32,
}

/// The walls next to a VPL (`Walls` in `lib/vbl.wgsl`; `beamlight_trace::vbl::Walls`): the
/// first `count` planes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Walls {
    pub planes: [Plane; beamlight_trace::vbl::MAX_WALLS],
    pub count: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

impl From<&beamlight_trace::vbl::Walls> for Walls {
    fn from(w: &beamlight_trace::vbl::Walls) -> Self {
        let mut out = Walls::default();
        for (i, p) in w.planes().iter().enumerate() {
            out.planes[i] = Plane {
                point: p.point.into(),
                normal: p.normal.into(),
                ..Default::default()
            };
        }
        out.count = w.planes().len() as u32;
        out
    }
}
