//! The scene's BVH (an obvhs compressed wide BVH8) and ray queries against it.
//!
//! obvhs builds the tree; the traversal is ours (obvhs's `traverse!` loop with a node test and
//! triangle test of our own), because on this kind of data the time goes into three things that
//! obvhs's closure-per-primitive traversal cannot change:
//! * the node test: obvhs converts the 48 quantized plane bytes to floats one at a time; ours
//!   widens eight at a time (SSE2), or tests all eight children in one AVX2 register, and turns
//!   the hits into obvhs's hit mask without a loop;
//! * the triangle test: the watertight test's axis permutation is resolved once per ray, and the
//!   triangles are stored by coordinate rows, so that the test's first half (the sheared
//!   vertices and the three edge functions) takes three 4-wide loads and a dozen vector
//!   operations ([`EdgeTest`]). Most triangles a ray misses end there; the rest continue in the
//!   scalar code of [`TriangleRay::intersect`] itself, so the hits are its hits, bit for bit;
//! * memory: on large meshes most node and triangle reads miss every cache, and each costs about
//!   150 ns on the CI machine, as much as testing a few nodes. Each triangle's input index sits
//!   in the same record as its rows (no lookup after a hit). Every child node the ray enters is
//!   prefetched as soon as its parent is tested, together with what it points to: its triangles
//!   and, for the nearest, its children ([`Ahead`]), so the traversal mostly waits for one miss
//!   per two levels, not per level. On meshes that fit in the caches nothing is prefetched.
//!
//! Box tests are conservative by a bound on their rounding error ([`SLAB_ERROR`]) and the
//! triangle test is exactly [`crate::geometry::intersect_triangle`]: the hits are that function's,
//! bit for bit, for the triangle with the least t (the tests compare with brute force).
use crate::geometry::{EdgeTest, TriangleRay, TriangleRows, vertices_to_rows};
use beamlight_scene::Scene;
use bytemuck::{Pod, Zeroable};
use glam::{UVec2, Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    cwbvh::{CwBvh, node::CwBvhNode},
    triangle::Triangle as ObvhsTriangle,
};

/// A closest hit: distance along the (unit) ray direction, triangle index and barycentrics.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    /// Index into `Scene::triangles`.
    pub tri: u32,
    pub b1: f32,
    pub b2: f32,
}

/// BVH over all scene triangles, with the triangles stored in leaf order for locality.
pub struct Bvh {
    bvh: Option<CwBvh>,
    /// Triangles in BVH leaf order: `leaves[k]` is triangle `bvh.primitive_indices[k]`.
    leaves: Vec<LeafTriangle>,
    /// Per node, what its parent prefetches (see [`Ahead`]); empty, and nothing prefetched,
    /// when the nodes and triangles fit in the caches ([`PREFETCH_BYTES`]).
    ahead: Vec<Ahead>,
    /// Whether the CPU runs the AVX2 traversal, detected once here: the detection's atomic
    /// loads on every query cost about 1 % of a path tracer's time.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    avx2: bool,
}

/// Where a node's own triangles (those of its leaf children) and its inner children lie, so
/// that its parent can prefetch them together with the node itself: the node's two dependent
/// misses (the node, then what it points to) become one. The parent also prefetches these
/// entries of the node's children, which the node will read. Packed as `first << 5 | count` and
/// `first << 4 | count`; a count of 0 prefetches nothing (also where `first` would not fit).
#[derive(Clone, Copy, Default)]
struct Ahead {
    tris: u32,
    children: u32,
}

impl Ahead {
    /// The node's own triangles: first leaf-order index and count.
    #[inline(always)]
    fn triangles(self) -> (usize, usize) {
        ((self.tris >> 5) as usize, (self.tris & 31) as usize)
    }

    /// The node's inner children: first node index and count.
    #[inline(always)]
    fn children(self) -> (usize, usize) {
        ((self.children >> 4) as usize, (self.children & 15) as usize)
    }

    fn new(node: &CwBvhNode) -> Self {
        let tris: u32 = (0..8)
            .filter(|&i| node.is_leaf(i))
            .map(|i| node.child_primitives(i).1)
            .sum();
        let children = node.imask.count_ones();
        Self {
            tris: if node.primitive_base_idx < 1 << 27 {
                node.primitive_base_idx << 5 | tris
            } else {
                0
            },
            children: if node.child_base_idx < 1 << 28 {
                node.child_base_idx << 4 | children
            } else {
                0
            },
        }
    }
}

/// Below this many bytes of nodes and triangles nothing is prefetched: they mostly stay in the
/// caches, and prefetching only costs instructions. On the 2-core CI machine (bumpy spheres,
/// random rays, closest-hit / any-hit rates with prefetching against without, one process
/// alternating): 4 k triangles (0.2 MiB) 2 % / 6 % slower, 16 k (0.8 MiB) 5 % faster / 3 %
/// slower, 32 k (1.5 MiB) 11 % / 6 % faster, 65 k (3.1 MiB) 27 % / 14 %, 131 k (6 MiB)
/// 65 % / 69 %, 1 M (50 MiB) 55 % / 62 %.
const PREFETCH_BYTES: usize = 1 << 20;

/// A triangle as the traversal reads it: its coordinate rows for [`EdgeTest::intersect`] and
/// its index in the input, in one 40-byte record.
#[derive(Clone, Copy, Pod, Zeroable)]
#[repr(C)]
struct LeafTriangle {
    rows: TriangleRows,
    index: u32,
}

impl LeafTriangle {
    /// The rows and then the index's bits, for [`EdgeTest::intersect`]'s 4-wide loads.
    #[inline(always)]
    fn floats(&self) -> &[f32; 10] {
        bytemuck::cast_ref(self)
    }
}

impl Bvh {
    pub fn build(scene: &Scene) -> Self {
        Self::from_positions(scene.triangles.iter().map(|t| t.p).collect())
    }

    /// Builds over raw triangles (index = position in `tris`).
    pub fn from_positions(tris: Vec<[Vec3; 3]>) -> Self {
        Self::from_positions_prefetching(tris, None)
    }

    /// [`Self::from_positions`], prefetching or not as `prefetch` says (by size when `None`).
    fn from_positions_prefetching(tris: Vec<[Vec3; 3]>, prefetch: Option<bool>) -> Self {
        if tris.is_empty() {
            return Self {
                bvh: None,
                leaves: Vec::new(),
                ahead: Vec::new(),
                avx2: avx2(),
            };
        }
        let prims = obvhs_triangles(&tris);
        let mut build_time = std::time::Duration::ZERO;
        let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(&prims, BvhBuildParams::medium_build(), &mut build_time);
        let leaves: Vec<LeafTriangle> = bvh
            .primitive_indices
            .iter()
            .map(|&i| LeafTriangle {
                rows: vertices_to_rows(&tris[i as usize]),
                index: i,
            })
            .collect();
        let bytes = bvh.nodes.len() * size_of::<CwBvhNode>() + leaves.len() * size_of::<LeafTriangle>();
        let ahead = if prefetch.unwrap_or(bytes > PREFETCH_BYTES) {
            bvh.nodes.iter().map(Ahead::new).collect()
        } else {
            Vec::new()
        };
        Self {
            bvh: Some(bvh),
            leaves,
            ahead,
            avx2: avx2(),
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.leaves.len()
    }

    /// Closest hit with `t` in `(0, tmax)` along `o + t·d` (`d` unit length).
    pub fn closest_hit(&self, o: Vec3, d: Vec3, tmax: f32) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has the features `closest_hit_avx2` is compiled for.
            return unsafe { self.closest_hit_avx2(o, d, tmax) };
        }
        self.closest_hit_with::<false>(o, d, 0.0, tmax)
    }

    /// Closest hit with `t` in `(tmin, tmax)`: the next surface along a ray that met one at
    /// `tmin`.
    pub fn closest_hit_beyond(&self, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        self.closest_hit_with::<false>(o, d, tmin, tmax)
    }

    /// True when anything lies on `o + t·d` for `t` in `(0, tmax)`.
    pub fn occluded(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has the features `occluded_avx2` is compiled for.
            return unsafe { self.occluded_avx2(o, d, tmax) };
        }
        self.occluded_with::<false>(o, d, tmax)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn closest_hit_avx2(&self, o: Vec3, d: Vec3, tmax: f32) -> Option<Hit> {
        self.closest_hit_with::<true>(o, d, 0.0, tmax)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn occluded_avx2(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        self.occluded_with::<true>(o, d, tmax)
    }

    #[inline(always)]
    fn closest_hit_with<const AVX2: bool>(&self, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let edges = EdgeTest::new(&TriangleRay::new(o, d));
        let mut best: Option<(f32, f32, f32, u32)> = None;
        let mut t_best = tmax;
        traverse::<_, AVX2>(bvh, &self.leaves, &self.ahead, NodeRay::new(o, d, tmax), |k, cull| {
            let tri = &self.leaves[k];
            if let Some(h) = edges.intersect(tri.floats(), tmin, t_best) {
                t_best = h.0;
                *cull = cull_beyond(t_best);
                best = Some((h.0, h.1, h.2, tri.index));
            }
            false
        });
        best.map(|(t, b1, b2, tri)| Hit { t, tri, b1, b2 })
    }

    #[inline(always)]
    fn occluded_with<const AVX2: bool>(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        let Some(bvh) = self.bvh.as_ref() else { return false };
        let edges = EdgeTest::new(&TriangleRay::new(o, d));
        let mut blocked = false;
        // Stop at the first triangle that blocks: no closest-hit bookkeeping.
        traverse::<_, AVX2>(bvh, &self.leaves, &self.ahead, NodeRay::new(o, d, tmax), |k, _| {
            let tri = &self.leaves[k];
            blocked = edges.intersect(tri.floats(), 0.0, tmax).is_some();
            blocked
        });
        blocked
    }
}

/// Triangles in obvhs's form, for its BVH builders (the CPU's CWBVH, the GPU's BVH2).
pub fn obvhs_triangles(tris: &[[Vec3; 3]]) -> Vec<ObvhsTriangle> {
    tris.iter()
        .map(|p| ObvhsTriangle {
            v0: p[0].into(),
            v1: p[1].into(),
            v2: p[2].into(),
        })
        .collect()
}

/// Whether the CPU has what the eight-wide node test is compiled for (any x86-64 since 2013).
#[inline(always)]
fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("bmi1")
            && std::arch::is_x86_feature_detected!("bmi2")
            && std::arch::is_x86_feature_detected!("lzcnt")
            && std::arch::is_x86_feature_detected!("popcnt")
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// Prefetches the first and last byte of the `T` at `p` (all its lines when it spans at most
/// two, as nodes, triangles and eight side-table entries do).
#[inline(always)]
fn prefetch_one<T>(p: *const T) {
    prefetch(p);
    prefetch(p.cast::<u8>().wrapping_add(size_of::<T>() - 1));
}

/// Prefetches `LINES` lines from `start`, unrolled: a loop over the exact count mispredicts its
/// exit once per call, which cost more than the extra lines (6-16 % on the 1 M-triangle sphere).
#[inline(always)]
fn prefetch_lines<const LINES: usize, T>(start: *const T) {
    let start = start.cast::<u8>();
    for i in 0..LINES {
        prefetch(start.wrapping_add(64 * i));
    }
}

#[inline(always)]
#[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))]
fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: prefetching is a hint and never faults, whatever the address.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.cast())
    }
}

/// Relative bound on the rounding error of a slab distance `q · scale + start` (a quantized
/// plane `q`; `scale` and `start` come from the node's corner and exponent, the ray's origin
/// and reciprocal direction through a few roundings each, and obvhs rounds `q` from a rounded
/// difference): a few units of 2⁻²⁴ of `255 |scale| + |start|`, taken four times over. Near
/// planes are moved closer and far planes farther by this much, so that a ray aimed exactly
/// at a vertex or an edge on a box's boundary cannot find the box's entry after its exit and
/// skip it (and with it a triangle the exact test hits). Too loose only costs a visit.
const SLAB_ERROR: f32 = 1.0 / (1 << 20) as f32;

/// A query's end as the node test uses it: a triangle's t has rounding error too, and the
/// exact test must see every triangle whose computed t could beat the current one.
#[inline(always)]
fn cull_beyond(t: f32) -> f32 {
    t * (1.0 + 1.0 / (1 << 16) as f32)
}

/// Byte offsets of a node's quantized planes: `[child_min_*, child_max_*]` for x, y and z.
const PLANES: [[usize; 2]; 3] = {
    use std::mem::offset_of;
    [
        [offset_of!(CwBvhNode, child_min_x), offset_of!(CwBvhNode, child_max_x)],
        [offset_of!(CwBvhNode, child_min_y), offset_of!(CwBvhNode, child_max_y)],
        [offset_of!(CwBvhNode, child_min_z), offset_of!(CwBvhNode, child_max_z)],
    ]
};

/// Bytes from an axis's `child_min_*` to its `child_max_*` in a `CwBvhNode`.
const PLANE_STEP: usize = 8;
const _: () = assert!(
    PLANES[0][1] == PLANES[0][0] + PLANE_STEP
        && PLANES[1][1] == PLANES[1][0] + PLANE_STEP
        && PLANES[2][1] == PLANES[2][0] + PLANE_STEP
);

/// A ray prepared for the node test: origin, clamped reciprocal direction, which quantized
/// plane of each axis is the near one, and the query's end `hi`.
struct NodeRay {
    o: Vec3A,
    inv: Vec3A,
    /// Byte offsets in a `CwBvhNode` of the near and far planes' `child_min_*`/`child_max_*`.
    near: [usize; 3],
    far: [usize; 3],
    hi: f32,
    oct_inv4: u32,
}

impl NodeRay {
    fn new(o: Vec3, d: Vec3, tmax: f32) -> Self {
        // A zero component becomes a tiny one of the same sign: slabs stay finite (no 0 · ∞).
        let inv = |c: f32| 1.0 / if c.abs() < 1e-20 { 1e-20f32.copysign(c) } else { c };
        // The near plane is the min plane where the direction is positive, the max one where not.
        // Each axis's max plane follows its min plane by `PLANE_STEP` bytes (checked below), so
        // the choice is arithmetic, not a table lookup per axis.
        let neg = [d.x < 0.0, d.y < 0.0, d.z < 0.0].map(|n| n as usize * PLANE_STEP);
        let near: [usize; 3] = std::array::from_fn(|i| PLANES[i][0] + neg[i]);
        let far: [usize; 3] = std::array::from_fn(|i| PLANES[i][1] - neg[i]);
        Self {
            o: o.into(),
            inv: Vec3A::new(inv(d.x), inv(d.y), inv(d.z)),
            near,
            far,
            hi: cull_beyond(tmax),
            // The inverted ray octant in every byte, as obvhs's `ray_get_octant_inv4`.
            oct_inv4: (if d.x < 0.0 { 0 } else { 0x04040404 })
                | (if d.y < 0.0 { 0 } else { 0x02020202 })
                | (if d.z < 0.0 { 0 } else { 0x01010101 }),
        }
    }

    /// A node's slab distances are `q · scale + near` for near planes and `q · scale + far` for
    /// far ones, on each axis, with [`SLAB_ERROR`] folded into `near` and `far`.
    #[inline(always)]
    fn slabs(&self, node: &CwBvhNode) -> (Vec3A, Vec3A, Vec3A) {
        let scale = node.compute_extent() * self.inv;
        let start = (Vec3A::from(node.p) - self.o) * self.inv;
        let error = (scale.abs() * 255.0 + start.abs()) * SLAB_ERROR;
        (scale, start - error, start + error)
    }

    /// obvhs's node hit mask (see `CwBvhNode::intersect_ray`): for every child box the ray meets
    /// before `hi`, an inner child's bit (24 + its octant-ordered slot) or a leaf's
    /// primitive bits.
    #[inline(always)]
    fn hitmask(&self, node: &CwBvhNode, hi: f32) -> u32 {
        let mut slots = self.slots(node, hi);
        let (child_bits8, bit_index8) = node.get_child_and_index_bits(self.oct_inv4);
        let mut hitmask = 0u32;
        while slots != 0 {
            let i = slots.trailing_zeros();
            slots &= slots - 1;
            let child_bits = (child_bits8 >> (8 * i)) as u32 & 0xff;
            let bit_index = (bit_index8 >> (8 * i)) as u32 & 0xff;
            hitmask |= child_bits << bit_index;
        }
        hitmask
    }

    /// [`Self::hitmask`] eight lanes wide.
    ///
    /// # Safety
    /// The CPU must have AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn hitmask_avx2(&self, node: &CwBvhNode, hi: f32) -> u32 {
        use std::arch::x86_64::*;
        let (scale, near, far) = self.slabs(node);
        let base = (node as *const CwBvhNode).cast::<u8>();
        // SAFETY: every load reads 8 bytes inside `node`.
        let bytes = |offset: usize| _mm256_cvtepu8_epi32(unsafe { _mm_loadl_epi64(base.add(offset).cast()) });
        let t = |offset: usize, s: f32, b: f32| {
            _mm256_fmadd_ps(_mm256_cvtepi32_ps(bytes(offset)), _mm256_set1_ps(s), _mm256_set1_ps(b))
        };
        let tmin = _mm256_max_ps(
            _mm256_max_ps(t(self.near[0], scale.x, near.x), t(self.near[1], scale.y, near.y)),
            _mm256_max_ps(t(self.near[2], scale.z, near.z), _mm256_setzero_ps()),
        );
        let tmax = _mm256_min_ps(
            _mm256_min_ps(t(self.far[0], scale.x, far.x), t(self.far[1], scale.y, far.y)),
            _mm256_min_ps(t(self.far[2], scale.z, far.z), _mm256_set1_ps(hi)),
        );
        let hit = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LE_OQ>(tmin, tmax));
        // obvhs's `get_child_and_index_bits`, one child per lane: an inner child (meta 24..32)
        // sets bit 24 + (slot ^ octant); a leaf sets its unary primitive count (meta >> 5) at
        // its first primitive's offset (meta & 31).
        let meta = bytes(std::mem::offset_of!(CwBvhNode, child_meta));
        let inner = _mm256_cmpeq_epi32(_mm256_and_si256(meta, _mm256_set1_epi32(0x18)), _mm256_set1_epi32(0x18));
        let octant = _mm256_and_si256(inner, _mm256_set1_epi32((self.oct_inv4 & 0xff) as i32));
        let index = _mm256_and_si256(_mm256_xor_si256(meta, octant), _mm256_set1_epi32(0x1f));
        let count = _mm256_srli_epi32::<5>(meta);
        let bits = _mm256_and_si256(_mm256_sllv_epi32(count, index), hit);
        let half = _mm_or_si128(_mm256_castsi256_si128(bits), _mm256_extracti128_si256::<1>(bits));
        let pair = _mm_or_si128(half, _mm_unpackhi_epi64(half, half));
        _mm_cvtsi128_si32(_mm_or_si128(pair, _mm_srli_epi64::<32>(pair))) as u32
    }

    /// Bit `i` set when the ray meets child slot `i`'s box before `hi` (empty slots may be
    /// set too; the caller masks them out).
    #[inline(always)]
    fn slots(&self, node: &CwBvhNode, hi: f32) -> u32 {
        let (scale, near, far) = self.slabs(node);
        #[cfg(target_arch = "x86_64")]
        // SAFETY: SSE2 is part of x86_64; every load reads 8 bytes inside `node`.
        unsafe {
            use std::arch::x86_64::*;
            let base = (node as *const CwBvhNode).cast::<u8>();
            let zero = _mm_setzero_si128();
            let q = |offset: usize| {
                let b = _mm_unpacklo_epi8(_mm_loadl_epi64(base.add(offset).cast()), zero);
                (
                    _mm_cvtepi32_ps(_mm_unpacklo_epi16(b, zero)),
                    _mm_cvtepi32_ps(_mm_unpackhi_epi16(b, zero)),
                )
            };
            let t = |offset: usize, s: f32, b: f32| {
                let (q0, q1) = q(offset);
                let (s, b) = (_mm_set1_ps(s), _mm_set1_ps(b));
                (_mm_add_ps(_mm_mul_ps(q0, s), b), _mm_add_ps(_mm_mul_ps(q1, s), b))
            };
            let (nx0, nx1) = t(self.near[0], scale.x, near.x);
            let (ny0, ny1) = t(self.near[1], scale.y, near.y);
            let (nz0, nz1) = t(self.near[2], scale.z, near.z);
            let (fx0, fx1) = t(self.far[0], scale.x, far.x);
            let (fy0, fy1) = t(self.far[1], scale.y, far.y);
            let (fz0, fz1) = t(self.far[2], scale.z, far.z);
            let (zero, hi) = (_mm_setzero_ps(), _mm_set1_ps(hi));
            let tmin0 = _mm_max_ps(_mm_max_ps(nx0, ny0), _mm_max_ps(nz0, zero));
            let tmin1 = _mm_max_ps(_mm_max_ps(nx1, ny1), _mm_max_ps(nz1, zero));
            let tmax0 = _mm_min_ps(_mm_min_ps(fx0, fy0), _mm_min_ps(fz0, hi));
            let tmax1 = _mm_min_ps(_mm_min_ps(fx1, fy1), _mm_min_ps(fz1, hi));
            (_mm_movemask_ps(_mm_cmple_ps(tmin0, tmax0)) | _mm_movemask_ps(_mm_cmple_ps(tmin1, tmax1)) << 4) as u32
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let bytes = bytemuck::bytes_of(node);
            let mut mask = 0;
            for i in 0..8 {
                let t = |axis: usize, planes: &[usize; 3], start: Vec3A| {
                    bytes[planes[axis] + i] as f32 * scale[axis] + start[axis]
                };
                let tmin = t(0, &self.near, near)
                    .max(t(1, &self.near, near))
                    .max(t(2, &self.near, near).max(0.0));
                let tmax = t(0, &self.far, far)
                    .min(t(1, &self.far, far))
                    .min(t(2, &self.far, far).min(hi));
                mask |= ((tmin <= tmax) as u32) << i;
            }
            mask
        }
    }
}

/// Front-to-back traversal of the CWBVH (obvhs's `traverse!` loop with our own node test and
/// prefetching): calls `visit(k, &mut hi)` for every leaf-order primitive `k` whose leaf box the
/// ray meets before `hi`; `visit` may lower `hi` and returns true to stop.
#[inline(always)]
fn traverse<F: FnMut(usize, &mut f32) -> bool, const AVX2: bool>(
    bvh: &CwBvh,
    prims: &[LeafTriangle],
    ahead: &[Ahead],
    ray: NodeRay,
    mut visit: F,
) {
    let oct_inv4 = ray.oct_inv4;
    let mut hi = ray.hi;
    // Node groups still to visit (obvhs's stack; a CWBVH over 2³² triangles is far shallower).
    let mut stack = [std::mem::MaybeUninit::<UVec2>::uninit(); 64];
    let mut depth = 0usize;
    let mut current_group = UVec2::new(0, 0x80000000);
    loop {
        if current_group.y & 0xff000000 != 0 {
            let hits_imask = current_group.y;
            let child_index_offset = 31 - hits_imask.leading_zeros();
            let child_index_base = current_group.x;
            current_group.y &= !(1u32 << child_index_offset);
            if current_group.y & 0xff000000 != 0 {
                stack[depth].write(current_group);
                depth = (depth + 1).min(stack.len() - 1);
            }
            let slot_index = (child_index_offset - 24) ^ (oct_inv4 & 0xff);
            let relative_index = (hits_imask & !(0xffffffffu32 << slot_index)).count_ones();
            let node = &bvh.nodes[(child_index_base + relative_index) as usize];
            let hitmask = if AVX2 {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: only instantiated behind `avx2()`.
                unsafe {
                    ray.hitmask_avx2(node, hi)
                }
                #[cfg(not(target_arch = "x86_64"))]
                unreachable!()
            } else {
                ray.hitmask(node, hi)
            };
            if !ahead.is_empty() {
                // Prefetch the child nodes the ray enters, nearest first, so that their cache
                // misses overlap instead of being paid one after another as the traversal
                // reaches them, and what they point to: their triangles (so a node's triangles
                // are on their way before it is even tested), the side-table entries they will
                // read, and the nearest one's children (everyone's children costs more in memory
                // traffic than it saves in waiting: 10 % slower on the 1 M-triangle sphere).
                let mut inner = hitmask >> 24;
                let mut nearest = true;
                while inner != 0 {
                    let bit = 31 - inner.leading_zeros();
                    inner &= !(1 << bit);
                    let slot = bit ^ (oct_inv4 & 0xff);
                    let child =
                        (node.child_base_idx + (node.imask as u32 & !(0xffffffffu32 << slot)).count_ones()) as usize;
                    prefetch_one(bvh.nodes.as_ptr().wrapping_add(child));
                    let a = ahead[child];
                    // A node's triangles (at most 24 of 40 bytes) span at most 16 lines.
                    let (first, count) = a.triangles();
                    if count > 0 {
                        prefetch_lines::<16, _>(prims.as_ptr().wrapping_add(first));
                    }
                    // Its children (at most 8 of 80 bytes) span at most 11.
                    let (first, count) = a.children();
                    if nearest && count > 0 {
                        prefetch_lines::<11, _>(bvh.nodes.as_ptr().wrapping_add(first));
                    }
                    // The entries the child will read here for its own children.
                    prefetch_one(ahead.as_ptr().wrapping_add(first).cast::<[Ahead; 8]>());
                    nearest = false;
                }
            }
            current_group = UVec2::new(node.child_base_idx, (hitmask & 0xff000000) | (node.imask as u32));
            // The node's triangles, in obvhs's order.
            let mut tris = hitmask & 0x00ffffff;
            while tris != 0 {
                let local = 31 - tris.leading_zeros();
                tris &= !(1u32 << local);
                if visit((node.primitive_base_idx + local) as usize, &mut hi) {
                    return;
                }
            }
        } else {
            if depth == 0 {
                return;
            }
            depth -= 1;
            // SAFETY: entries below `depth` were written by the push above.
            current_group = unsafe { stack[depth].assume_init() };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::intersect_triangle;
    use beamlight_scene::rng::Sampler;

    /// Closest hit and occlusion by every traversal this machine can run: the SSE2 node test,
    /// and the AVX2 one where the CPU has it.
    fn queries(bvh: &Bvh, o: Vec3, d: Vec3, tmax: f32) -> Vec<(Option<Hit>, bool)> {
        let mut out = vec![(
            bvh.closest_hit_with::<false>(o, d, 0.0, tmax),
            bvh.occluded_with::<false>(o, d, tmax),
        )];
        #[cfg(target_arch = "x86_64")]
        if avx2() {
            // SAFETY: the CPU has the features these are compiled for.
            out.push(unsafe { (bvh.closest_hit_avx2(o, d, tmax), bvh.occluded_avx2(o, d, tmax)) });
        }
        out
    }

    /// The closest of `intersect_triangle`'s hits in (tmin, tmax) over all triangles: (t, b1,
    /// b2, index).
    fn brute_force(tris: &[[Vec3; 3]], o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<(f32, f32, f32, usize)> {
        tris.iter()
            .enumerate()
            .filter_map(|(i, p)| intersect_triangle(o, d, p, tmin, tmax).map(|h| (h.0, h.1, h.2, i)))
            .min_by(|a, b| a.0.total_cmp(&b.0))
    }

    /// The BVH over `tris` as built, and with prefetching forced the other way (the test scenes
    /// are small enough not to prefetch).
    fn both_ways(tris: &[[Vec3; 3]]) -> [Bvh; 2] {
        let bvh = Bvh::from_positions(tris.to_vec());
        let other = Bvh::from_positions_prefetching(tris.to_vec(), Some(bvh.ahead.is_empty()));
        [bvh, other]
    }

    /// The BVH's hit is a closest one of brute force (the same t; on a tie, as where a ray meets
    /// a shared vertex, any of the triangles at that t), and its t and barycentrics are exactly
    /// what `intersect_triangle` reports for that triangle; and so is the next hit beyond it
    /// (`closest_hit_beyond`).
    fn assert_agrees(bvhs: &[Bvh], tris: &[[Vec3; 3]], o: Vec3, d: Vec3, tmax: f32) -> bool {
        let brute = brute_force(tris, o, d, 0.0, tmax);
        if let Some((t, ..)) = brute {
            let next = brute_force(tris, o, d, t, tmax);
            for bvh in bvhs {
                let hit = bvh.closest_hit_beyond(o, d, t, tmax);
                assert_eq!(
                    hit.map(|h| h.t),
                    next.map(|b| b.0),
                    "ray {o} → {d} beyond {t}: bvh {hit:?}, brute {next:?}"
                );
            }
        }
        for (hit, blocked) in bvhs.iter().flat_map(|bvh| queries(bvh, o, d, tmax)) {
            let context = || format!("ray {o} → {d}, tmax {tmax}: bvh {hit:?}, brute force {brute:?}");
            assert_eq!(hit.map(|h| h.t), brute.map(|b| b.0), "{}", context());
            if let Some(h) = hit {
                let exact = intersect_triangle(o, d, &tris[h.tri as usize], 0.0, tmax);
                assert_eq!(Some((h.t, h.b1, h.b2)), exact, "{}", context());
            }
            assert_eq!(blocked, brute.is_some(), "{}", context());
        }
        brute.is_some()
    }

    /// The BVH must agree with brute force on random rays through a random triangle soup.
    #[test]
    fn agrees_with_brute_force() {
        for scale in [1e-4f32, 1.0, 1e4] {
            agrees_with_brute_force_at(scale);
        }
    }

    fn agrees_with_brute_force_at(scale: f32) {
        let mut s = Sampler::new(1, 0, 0);
        let mut rnd = || Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * scale;
        let tris: Vec<[Vec3; 3]> = (0..2000)
            .map(|_| {
                let c = rnd() * 10.0;
                let h = Vec3::splat(0.5 * scale);
                [c + rnd() - h, c + rnd() - h, c + rnd() - h]
            })
            .collect();
        let bvhs = both_ways(&tris);
        let mut hits = 0;
        for _ in 0..2000 {
            let o = rnd() * 12.0 - Vec3::splat(scale);
            let d = (rnd() / scale - 0.5).normalize();
            let tmax = if rnd().x < 0.5 * scale {
                f32::INFINITY
            } else {
                5.0 * scale
            };
            hits += assert_agrees(&bvhs, &tris, o, d, tmax) as u32;
        }
        assert!(hits > 200, "only {hits} hits at scale {scale}");
    }

    /// A closed, bumpy sphere at several scales and offsets, and rays aimed exactly at its
    /// vertices and at points of its shared edges: every ray hits (no leaks between
    /// neighbours), and the BVH agrees with brute force on which triangle and where.
    #[test]
    fn closed_mesh_is_watertight_and_agrees_with_brute_force() {
        let (rings, segments) = (24u32, 48u32);
        for (scale, offset) in [(1.0f32, 0.0f32), (1e-3, 0.0), (1e3, 0.0), (1.0, 1e3)] {
            // Closed exactly: the seam's vertices are shared (j wraps) and the poles are points.
            let point = |i: u32, j: u32| {
                let theta = std::f32::consts::PI * i as f32 / rings as f32;
                let phi = std::f32::consts::TAU * (j % segments) as f32 / segments as f32;
                let r = 1.0 + 0.05 * (7.0 * theta).sin() * (11.0 * phi).cos();
                let (sin_theta, cos_theta) = match i {
                    0 => (0.0, 1.0),
                    i if i == rings => (0.0, -1.0),
                    _ => theta.sin_cos(),
                };
                Vec3::new(sin_theta * phi.cos(), cos_theta, sin_theta * phi.sin()) * r * scale + Vec3::splat(offset)
            };
            let mut tris = Vec::new();
            for i in 0..rings {
                for j in 0..segments {
                    let (a, b, c, d) = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1));
                    tris.push([a, b, c]);
                    tris.push([a, c, d]);
                }
            }
            let bvhs = both_ways(&tris);
            let mut s = Sampler::new(3, 0, 0);
            let mut crossings = 0;
            for k in 0..3000 {
                let tri = tris[(s.next_1d() * tris.len() as f32) as usize % tris.len()];
                // A vertex, or a point of an edge (its ends are the vertices `shared`).
                let (target, shared) = match k % 3 {
                    0 => (tri[k % 9 / 3], vec![tri[k % 9 / 3]]),
                    _ => (
                        tri[k % 3] + (tri[(k + 1) % 3] - tri[k % 3]) * s.next_1d(),
                        vec![tri[k % 3], tri[(k + 1) % 3]],
                    ),
                };
                let o = (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5) * 6.0 * scale + Vec3::splat(offset);
                let d = (target - o).normalize();
                let hit = assert_agrees(&bvhs, &tris, o, d, f32::INFINITY);
                // Where the ray crosses the surface (every triangle around the vertex or edge
                // faces the same way along it, not a silhouette it only grazes), it must hit.
                let facing: Vec<f32> = tris
                    .iter()
                    .filter(|t| shared.iter().all(|v| t.contains(v)))
                    .map(|t| (t[1] - t[0]).cross(t[2] - t[0]).normalize().dot(d))
                    .collect();
                if facing.iter().all(|&c| c > 1e-3) || facing.iter().all(|&c| c < -1e-3) {
                    assert!(hit, "ray {k} from {o} towards {target} slipped through (scale {scale})");
                    crossings += 1;
                }
            }
            assert!(crossings > 2000, "only {crossings} crossings");
        }
    }

    #[test]
    fn empty_scene_misses() {
        let bvh = Bvh::from_positions(Vec::new());
        assert!(bvh.closest_hit(Vec3::ZERO, Vec3::X, f32::INFINITY).is_none());
        assert!(!bvh.occluded(Vec3::ZERO, Vec3::X, f32::INFINITY));
    }
}
