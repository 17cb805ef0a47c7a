//! The scene on the GPU (bind group 0 of every tracing kernel, `lib/scene.wgsl`): a BVH2
//! flattened from obvhs, triangles in leaf order, per-triangle medium interfaces, and the
//! media with their density and majorant grids.
//!
//! Why a BVH2 rather than the CPU's CWBVH: a binary node is 32 bytes with plain f32 bounds,
//! traversal needs no quantised-box decoding or child-ordering bit tricks, and a stack of 64
//! entries covers every tree obvhs builds for scenes of millions of triangles (checked here
//! against the real depth). On a SIMD CPU adapter like lavapipe the wide node's advantage
//! (fewer, fatter node fetches) mostly disappears, because each invocation is one SIMD lane.
use crate::{
    Gpu, GpuError,
    compute::{self, Slot},
    layout::{self, BvhNode, NO_MEDIUM, SceneInfo, TRI_NULL_INTERFACE, TriangleInfo},
};
use beamlight_scene::Scene;
use obvhs::{BvhBuildParams, bvh2::Bvh2, triangle::Triangle as ObvhsTriangle};

/// Traversal stack entries in `lib/bvh.wgsl` (`STACK_SIZE`).
pub const STACK_SIZE: u32 = 64;

/// The flattened BVH2 and leaf-ordered triangles, before upload.
pub struct FlatBvh {
    pub nodes: Vec<BvhNode>,
    pub triangles: Vec<layout::Triangle>,
    /// `leaf_slot[i]`: where scene triangle `i` sits in `triangles`.
    pub leaf_slot: Vec<u32>,
    /// Longest root-to-leaf path (edges).
    pub depth: u32,
}

impl FlatBvh {
    pub fn build(positions: &[[glam::Vec3; 3]]) -> FlatBvh {
        if positions.is_empty() {
            return FlatBvh {
                nodes: Vec::new(),
                triangles: Vec::new(),
                leaf_slot: Vec::new(),
                depth: 0,
            };
        }
        let prims: Vec<ObvhsTriangle> = positions
            .iter()
            .map(|p| ObvhsTriangle {
                v0: p[0].into(),
                v1: p[1].into(),
                v2: p[2].into(),
            })
            .collect();
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
        let nodes: Vec<BvhNode> = bvh
            .nodes
            .iter()
            .map(|n| BvhNode {
                lo: n.aabb().min.into(),
                count: n.prim_count,
                hi: n.aabb().max.into(),
                first: n.first_index,
            })
            .collect();
        let depth = depth(&nodes);
        FlatBvh {
            nodes,
            triangles,
            leaf_slot,
            depth,
        }
    }
}

fn depth(nodes: &[BvhNode]) -> u32 {
    let mut deepest = 0;
    let mut stack = vec![(0usize, 0u32)];
    while let Some((i, d)) = stack.pop() {
        deepest = deepest.max(d);
        let n = nodes[i];
        if n.count == 0 {
            stack.push((n.first as usize, d + 1));
            stack.push((n.first as usize + 1, d + 1));
        }
    }
    deepest
}

/// The scene's buffers and bind group (group 0 of the tracing kernels).
pub struct GpuScene {
    pub info: SceneInfo,
    pub layout: wgpu::BindGroupLayout,
    pub bind_group: wgpu::BindGroup,
    /// Bytes uploaded.
    pub bytes: u64,
}

/// The slots of bind group 0, in binding order (see `lib/scene.wgsl`).
pub const SCENE_SLOTS: [Slot; 6] = [
    Slot::Uniform,
    Slot::Read,
    Slot::Read,
    Slot::Read,
    Slot::Read,
    Slot::Read,
];

pub fn scene_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    compute::bind_group_layout(gpu, "scene", &SCENE_SLOTS)
}

fn medium_index(m: Option<u32>) -> u32 {
    m.unwrap_or(NO_MEDIUM)
}

impl GpuScene {
    pub fn upload(gpu: &Gpu, scene: &Scene) -> Result<GpuScene, GpuError> {
        let positions: Vec<[glam::Vec3; 3]> = scene.triangles.iter().map(|t| t.p).collect();
        let bvh = FlatBvh::build(&positions);
        check_depth(&bvh)?;
        let mut has_null_interfaces = false;
        let info: Vec<TriangleInfo> = scene
            .triangles
            .iter()
            .zip(&bvh.leaf_slot)
            .map(|(t, &leaf_slot)| {
                let null = scene.materials[t.material as usize].bsdf.is_none();
                has_null_interfaces |= null;
                let (inside, outside) = t.interface.map_or((NO_MEDIUM, NO_MEDIUM), |i| {
                    (medium_index(i.inside), medium_index(i.outside))
                });
                TriangleInfo {
                    leaf_slot,
                    flags: if null { TRI_NULL_INTERFACE } else { 0 },
                    inside,
                    outside,
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
        Self::from_parts(gpu, &bvh, &info, has_null_interfaces, &media, &grid)
    }

    /// Bare geometry: opaque triangles, no media (ray-query tests and benchmarks).
    pub fn geometry_only(gpu: &Gpu, positions: &[[glam::Vec3; 3]]) -> Result<GpuScene, GpuError> {
        let bvh = FlatBvh::build(positions);
        check_depth(&bvh)?;
        let info: Vec<TriangleInfo> = bvh
            .leaf_slot
            .iter()
            .map(|&leaf_slot| TriangleInfo {
                leaf_slot,
                flags: 0,
                inside: NO_MEDIUM,
                outside: NO_MEDIUM,
            })
            .collect();
        Self::from_parts(gpu, &bvh, &info, false, &[], &[])
    }

    fn from_parts(
        gpu: &Gpu,
        bvh: &FlatBvh,
        info: &[TriangleInfo],
        has_null_interfaces: bool,
        media: &[layout::Medium],
        grid: &[f32],
    ) -> Result<GpuScene, GpuError> {
        let scene_info = SceneInfo {
            node_count: bvh.nodes.len() as u32,
            has_null_interfaces: has_null_interfaces as u32,
            medium_count: media.len() as u32,
            _pad: 0,
        };
        let buffers = [
            compute::uniform(gpu, "scene info", &scene_info),
            compute::storage(gpu, "BVH nodes", &bvh.nodes)?,
            compute::storage(gpu, "triangles", &bvh.triangles)?,
            compute::storage(gpu, "triangle info", info)?,
            compute::storage(gpu, "media", media)?,
            compute::storage(gpu, "density grids", grid)?,
        ];
        let bytes = buffers.iter().map(|b| b.size()).sum();
        let layout = scene_layout(gpu);
        let refs: Vec<&wgpu::Buffer> = buffers.iter().collect();
        let bind_group = compute::bind_group(gpu, "scene", &layout, &refs);
        Ok(GpuScene {
            info: scene_info,
            layout,
            bind_group,
            bytes,
        })
    }
}

fn check_depth(bvh: &FlatBvh) -> Result<(), GpuError> {
    if bvh.depth >= STACK_SIZE {
        return Err(GpuError::Limit {
            what: "the BVH's depth (traversal stack entries)",
            needed: bvh.depth as u64 + 1,
            allowed: STACK_SIZE as u64,
        });
    }
    Ok(())
}
