//! The scene on the GPU (bind group 0 of every tracing kernel, `lib/scene.wgsl`): a BVH2
//! flattened from obvhs, triangles in leaf order, per-triangle medium interfaces, and the
//! media with their density and majorant grids.
//!
//! Why a BVH2 rather than the CPU's CWBVH: a binary node is 32 bytes with plain f32 bounds and
//! needs no quantised-box decoding, and laid out in depth-first preorder with a skip index per
//! inner node it is traversed without a stack (`lib/bvh.wgsl`), one node and one box test per
//! step, whatever the tree's depth. On a SIMD CPU adapter like lavapipe each invocation is one
//! lane, so a wide node's advantage (fewer, fatter node fetches) mostly disappears anyway.
use crate::{
    Gpu, GpuError,
    compute::{self, Slot},
    layout::{
        self, BvhNode, NO_MEDIUM, PatchEdge, SceneInfo, TRI_NULL_INTERFACE, TRI_PATCH_FLIPPED, TRI_PLATE_BACK,
        TRI_PLATE_FRONT, TriangleInfo,
    },
};
use beamlight_scene::Scene;
use beamlight_trace::patches::{BACK, FRONT, Patches};
use obvhs::{BvhBuildParams, bvh2::Bvh2};

/// The flattened BVH2 and leaf-ordered triangles, before upload. `nodes` are in depth-first
/// preorder: an inner node's first child follows it, and its `first` is the index just past
/// its subtree (where traversal goes when its box is missed).
pub struct FlatBvh {
    pub nodes: Vec<BvhNode>,
    pub triangles: Vec<layout::Triangle>,
    /// `leaf_slot[i]`: where scene triangle `i` sits in `triangles`.
    pub leaf_slot: Vec<u32>,
}

impl FlatBvh {
    pub fn build(positions: &[[glam::Vec3; 3]]) -> FlatBvh {
        if positions.is_empty() {
            return FlatBvh {
                nodes: Vec::new(),
                triangles: Vec::new(),
                leaf_slot: Vec::new(),
            };
        }
        let prims = beamlight_trace::bvh::obvhs_triangles(positions);
        let mut build_time = std::time::Duration::ZERO;
        let bvh: Bvh2 =
            obvhs::bvh2::builder::build_bvh2_from_tris(&prims, BvhBuildParams::medium_build(), &mut build_time);
        let triangles: Vec<layout::Triangle> = bvh
            .primitive_indices
            .iter()
            .map(|&i| {
                let p = positions[i as usize];
                layout::Triangle {
                    p0: p[0].into(),
                    id: i,
                    p1: p[1].into(),
                    p2: p[2].into(),
                    ..Default::default()
                }
            })
            .collect();
        let mut leaf_slot = vec![0u32; positions.len()];
        for (slot, t) in triangles.iter().enumerate() {
            leaf_slot[t.id as usize] = slot as u32;
        }
        let nodes = preorder(&bvh);
        FlatBvh {
            nodes,
            triangles,
            leaf_slot,
        }
    }
}

/// obvhs's nodes (children at `first_index` and `first_index + 1`) rewritten in depth-first
/// preorder with skip indices.
fn preorder(bvh: &Bvh2) -> Vec<BvhNode> {
    enum Step {
        Visit(usize),
        /// The subtree of the node at this output index is complete: set its skip index.
        Close(usize),
    }
    let mut out: Vec<BvhNode> = Vec::with_capacity(bvh.nodes.len());
    let mut todo = vec![Step::Visit(0)];
    while let Some(step) = todo.pop() {
        match step {
            Step::Visit(i) => {
                let n = &bvh.nodes[i];
                let at = out.len();
                out.push(BvhNode {
                    lo: n.aabb().min.into(),
                    count: n.prim_count,
                    hi: n.aabb().max.into(),
                    first: n.first_index,
                });
                if n.prim_count == 0 {
                    let left = n.first_index as usize;
                    todo.push(Step::Close(at));
                    todo.push(Step::Visit(left + 1));
                    todo.push(Step::Visit(left));
                }
            }
            Step::Close(at) => out[at].first = out.len() as u32,
        }
    }
    out
}

/// What bind group 0 holds besides the BVH and the triangles.
struct Parts<'a> {
    info: &'a [TriangleInfo],
    has_null_interfaces: bool,
    media: &'a [layout::Medium],
    grid: &'a [f32],
    patch_edges: &'a [PatchEdge],
}

/// The scene's buffers and bind group (group 0 of the tracing kernels).
pub struct GpuScene {
    pub layout: wgpu::BindGroupLayout,
    pub bind_group: wgpu::BindGroup,
}

/// The slots of bind group 0, in binding order (see `lib/scene.wgsl`): the scene info, then
/// seven read-only storage buffers.
pub const SCENE_SLOTS: [Slot; 8] = {
    let mut slots = [Slot::Read; 8];
    slots[0] = Slot::Uniform;
    slots
};

pub fn scene_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    compute::bind_group_layout(gpu, "scene", &SCENE_SLOTS)
}

fn medium_index(m: Option<u32>) -> u32 {
    m.unwrap_or(NO_MEDIUM)
}

impl GpuScene {
    pub fn upload(gpu: &Gpu, scene: &Scene) -> Result<GpuScene, GpuError> {
        Self::upload_with(gpu, scene, &Patches::build(scene))
    }

    /// [`GpuScene::upload`] with the scene's planar patches already built (a `TraceScene`'s).
    pub fn upload_with(gpu: &Gpu, scene: &Scene, patches: &Patches) -> Result<GpuScene, GpuError> {
        let positions: Vec<[glam::Vec3; 3]> = scene.triangles.iter().map(|t| t.p).collect();
        let bvh = FlatBvh::build(&positions);
        let mut has_null_interfaces = false;
        let info: Vec<TriangleInfo> = scene
            .triangles
            .iter()
            .zip(&bvh.leaf_slot)
            .enumerate()
            .map(|(i, (t, &leaf_slot))| {
                let [patch_start, patch_count] = patches.spans[i];
                let plate = patches.plate[i];
                let null = scene.materials[t.material as usize].bsdf.is_none();
                has_null_interfaces |= null;
                let (inside, outside) = t.interface.map_or((NO_MEDIUM, NO_MEDIUM), |i| {
                    (medium_index(i.inside), medium_index(i.outside))
                });
                TriangleInfo {
                    leaf_slot,
                    flags: if null { TRI_NULL_INTERFACE } else { 0 }
                        | if plate & FRONT != 0 { TRI_PLATE_FRONT } else { 0 }
                        | if plate & BACK != 0 { TRI_PLATE_BACK } else { 0 }
                        | if patches.flipped[i] { TRI_PATCH_FLIPPED } else { 0 },
                    inside,
                    outside,
                    patch_start,
                    patch_count,
                }
            })
            .collect();
        let mut grid = Vec::new();
        let media: Vec<layout::Medium> = scene
            .media
            .iter()
            .map(|m| {
                let mut g = layout::Medium {
                    sigma_s: m.sigma_s.into(),
                    g: m.g,
                    sigma_a: m.sigma_a.into(),
                    ..Default::default()
                };
                if let Some(d) = &m.density {
                    g.grid_offset = grid.len() as u32;
                    grid.extend_from_slice(&d.values);
                    g.majorant_offset = grid.len() as u32;
                    grid.extend_from_slice(&d.majorants);
                    g.grid_lo = d.lo.into();
                    g.grid_hi = d.hi.into();
                    g.grid_res = d.res.into();
                    g.majorant_res = d.majorant_res.into();
                }
                g
            })
            .collect();
        let edges: Vec<PatchEdge> = patches
            .edges
            .iter()
            .map(|e| PatchEdge {
                a: e.ends[0].into(),
                sides: e.sides as u32,
                b: e.ends[1].into(),
                ..Default::default()
            })
            .collect();
        let parts = Parts {
            info: &info,
            has_null_interfaces,
            media: &media,
            grid: &grid,
            patch_edges: &edges,
        };
        Self::from_parts(gpu, &bvh, &parts, usize::MAX)
    }

    /// Bare geometry: opaque triangles, no media (ray-query tests and benchmarks).
    pub fn geometry_only(gpu: &Gpu, positions: &[[glam::Vec3; 3]]) -> Result<GpuScene, GpuError> {
        Self::geometry_split(gpu, positions, usize::MAX)
    }

    /// [`GpuScene::geometry_only`] with at most `per_binding` triangles in each of the two
    /// triangle bindings (tests exercise the split without uploading gigabytes).
    pub fn geometry_split(gpu: &Gpu, positions: &[[glam::Vec3; 3]], per_binding: usize) -> Result<GpuScene, GpuError> {
        let bvh = FlatBvh::build(positions);
        let info: Vec<TriangleInfo> = bvh
            .leaf_slot
            .iter()
            .map(|&leaf_slot| TriangleInfo {
                leaf_slot,
                flags: 0,
                inside: NO_MEDIUM,
                outside: NO_MEDIUM,
                patch_start: 0,
                patch_count: 0,
            })
            .collect();
        let parts = Parts {
            info: &info,
            has_null_interfaces: false,
            media: &[],
            grid: &[],
            patch_edges: &[],
        };
        Self::from_parts(gpu, &bvh, &parts, per_binding)
    }

    fn from_parts(gpu: &Gpu, bvh: &FlatBvh, parts: &Parts, per_binding: usize) -> Result<GpuScene, GpuError> {
        let Parts {
            info,
            has_null_interfaces,
            media,
            grid,
            patch_edges,
        } = *parts;
        // The triangles may need two bindings: split at the most one binding may hold.
        let fits = (compute::max_binding(gpu) / size_of::<layout::Triangle>() as u64) as usize;
        let split = bvh.triangles.len().min(per_binding).min(fits);
        let scene_info = SceneInfo {
            node_count: bvh.nodes.len() as u32,
            has_null_interfaces: has_null_interfaces as u32,
            medium_count: media.len() as u32,
            triangle_split: split as u32,
        };
        let buffers = [
            compute::uniform(gpu, "scene info", &scene_info),
            compute::storage(gpu, "BVH nodes", &bvh.nodes)?,
            compute::storage(gpu, "triangles", &bvh.triangles[..split])?,
            compute::storage(gpu, "triangle info", info)?,
            compute::storage(gpu, "media", media)?,
            compute::storage(gpu, "density grids", grid)?,
            compute::storage(gpu, "triangles beyond the first binding", &bvh.triangles[split..])?,
            compute::storage(gpu, "planar patches' open edges", patch_edges)?,
        ];
        let layout = scene_layout(gpu);
        let refs: Vec<&wgpu::Buffer> = buffers.iter().collect();
        let bind_group = compute::bind_group(gpu, "scene", &layout, &refs);
        Ok(GpuScene { layout, bind_group })
    }
}
