//! The planar patches of a scene's surfaces, for the blur of virtual spherical lights: a
//! surface next to a VSL centre cuts its discs as a plane only where its patch covers that
//! plane (`vbl::Walls`).
use beamlight_scene::Scene;
use glam::Vec3;
use rayon::prelude::*;

/// The planar patches of a scene's surfaces: triangles joined across shared edges (the same
/// vertex positions, bit for bit) where both lie in one plane facing the same way. What ends a
/// patch's plane as a model of the surface are its *open* edges: those where the surface folds
/// away from the free side (a convex edge, such as a box's) or simply ends. An edge where
/// another surface rises on the free side (a room's corner) ends nothing: the space beyond it
/// is not free, and that surface is a wall of its own. Medium boundaries without a BSDF are
/// never walls and get no patch.
#[derive(Clone, Debug, Default)]
pub struct Patches {
    /// Per scene triangle: for a patch of several triangles, the span of its open edges in
    /// `edges` (start, count > 0); for a triangle that is a patch alone, (mask, 0), bit k of
    /// the mask set when its edge from vertex k to vertex k + 1 is open. A patch of several
    /// triangles without open edges has the span (0, u32::MAX): it covers everything.
    pub spans: Vec<[u32; 2]>,
    /// The open edges of the patches of several triangles.
    pub edges: Vec<[Vec3; 2]>,
    /// Per scene triangle: whether its patch is a plate, a surface whose open edges all end it
    /// (no other surface meets them): a lamp's quad, a sheet of paper. A probe that meets a
    /// plate too small to be a wall goes on past it; past a solid's face it would enter the
    /// solid.
    pub plate: Vec<bool>,
}

/// How far (relative to the triangle's longest edge) a vertex may lie off a neighbour's plane,
/// and how nearly parallel their normals must be, for the two to be one patch: rounding of
/// coordinates written as floats, no more.
const COPLANAR_OFFSET: f32 = 1e-5;
const COPLANAR_NORMALS: f32 = 1.0 - 1e-6;
/// An edge of a triangle: its end points' bits (in order), the triangle and which edge.
type Side = (([u32; 3], [u32; 3]), u32, u8);

/// [`Patches::spans`]' count for a patch with no open edge.
const CLOSED: u32 = u32::MAX;

impl Patches {
    pub fn build(scene: &Scene) -> Self {
        let tris = &scene.triangles;
        let n = tris.len();
        let wall: Vec<bool> = tris
            .iter()
            .map(|t| scene.materials[t.material as usize].bsdf.is_some() && t.cross().length_squared() > 0.0)
            .collect();
        let normal: Vec<Vec3> = tris.iter().map(|t| t.cross().normalize_or_zero()).collect();
        let size: Vec<f32> = tris
            .iter()
            .map(|t| (0..3).map(|k| t.p[k].distance(t.p[(k + 1) % 3])).fold(0.0, f32::max))
            .collect();
        // The vertex of `b` (sharing an edge with `a`) farthest off `a`'s plane, signed, in
        // `a`'s size.
        let height = |a: usize, b: usize| {
            let h = tris[b].p.iter().map(|&p| (p - tris[a].p[0]).dot(normal[a]));
            let (lo, hi) = h.fold((0.0f32, 0.0f32), |(lo, hi), x| (lo.min(x), hi.max(x)));
            (if hi > -lo { hi } else { lo }) / size[a]
        };
        let coplanar =
            |a: usize, b: usize| normal[a].dot(normal[b]) >= COPLANAR_NORMALS && height(a, b).abs() <= COPLANAR_OFFSET;
        // Every edge of every wall triangle, keyed by its end points' bits, sorted so that the
        // triangles sharing an edge are neighbours: (key, triangle, edge).
        let key = |p: Vec3| p.to_array().map(f32::to_bits);
        let mut sides: Vec<Side> = Vec::with_capacity(3 * n);
        for (t, tri) in tris.iter().enumerate().filter(|(t, _)| wall[*t]) {
            for k in 0..3 {
                let (a, b) = (key(tri.p[k]), key(tri.p[(k + 1) % 3]));
                sides.push((if a <= b { (a, b) } else { (b, a) }, t as u32, k as u8));
            }
        }
        sides.par_sort_unstable();
        let shared: Vec<&[Side]> = sides.chunk_by(|x, y| x.0 == y.0).collect();
        // Union–find over the triangles joined across coplanar shared edges.
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn root(parent: &mut [u32], mut i: u32) -> u32 {
            while parent[i as usize] != i {
                parent[i as usize] = parent[parent[i as usize] as usize];
                i = parent[i as usize];
            }
            i
        }
        for edge in &shared {
            for (i, &(_, a, _)) in edge.iter().enumerate() {
                for &(_, b, _) in &edge[i + 1..] {
                    if coplanar(a as usize, b as usize) {
                        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
                        parent[ra as usize] = rb;
                    }
                }
            }
        }
        let roots: Vec<u32> = (0..n as u32).map(|i| root(&mut parent, i)).collect();
        // Per triangle, bit k: its edge k is open, i.e. no triangle of its own patch shares
        // it and no other surface rises from it on its free side (a concave fold); bit 3 + k:
        // that open edge is a rim, met by no other surface at all.
        let mut edge_bits = vec![0u8; n];
        for edge in &shared {
            for &(_, t, k) in edge.iter() {
                let (t, r) = (t as usize, roots[t as usize]);
                let closed = edge.iter().any(|&(_, o, _)| {
                    let o = o as usize;
                    o != t && (roots[o] == r || height(t, o) > COPLANAR_OFFSET)
                });
                if !closed {
                    edge_bits[t] |= 1 << k | (((edge.len() == 1) as u8) << (3 + k));
                }
            }
        }
        let mut patches = Patches {
            spans: vec![[0, 0]; n],
            edges: Vec::new(),
            plate: vec![false; n],
        };
        // The patches, each a run of triangles sorted by root (then index: deterministic).
        let mut order: Vec<(u32, u32)> = (0..n as u32)
            .filter(|&t| wall[t as usize])
            .map(|t| (roots[t as usize], t))
            .collect();
        order.sort_unstable();
        for group in order.chunk_by(|x, y| x.0 == y.0) {
            let opens: u32 = group
                .iter()
                .map(|&(_, t)| (edge_bits[t as usize] & 7).count_ones())
                .sum();
            let rims: u32 = group
                .iter()
                .map(|&(_, t)| (edge_bits[t as usize] >> 3).count_ones())
                .sum();
            for &(_, t) in group {
                patches.plate[t as usize] = opens > 0 && rims == opens;
            }
            if let [(_, t)] = group {
                patches.spans[*t as usize] = [(edge_bits[*t as usize] & 7) as u32, 0];
                continue;
            }
            let start = patches.edges.len();
            for &(_, t) in group {
                let p = tris[t as usize].p;
                let bits = edge_bits[t as usize];
                patches
                    .edges
                    .extend((0..3).filter(|&k| bits & (1 << k) != 0).map(|k| [p[k], p[(k + 1) % 3]]));
            }
            let count = patches.edges.len() - start;
            let span = if count == 0 {
                [0, CLOSED]
            } else {
                [start as u32, count as u32]
            };
            for &(_, t) in group {
                patches.spans[t as usize] = span;
            }
        }
        patches
    }

    /// Whether the patch of triangle `tri` covers the disc of radius `need` around `p`, a point
    /// of it: no open edge of the patch comes closer.
    pub fn covers(&self, scene: &Scene, tri: u32, p: Vec3, need: f32) -> bool {
        let [start, count] = self.spans.get(tri as usize).copied().unwrap_or([0, 0]);
        let clear = |[a, b]: [Vec3; 2]| segment_distance(p, a, b) >= need;
        match count {
            CLOSED => true,
            0 => {
                let t = scene.triangles[tri as usize].p;
                (0..3).all(|k| (start & (1 << k)) == 0 || clear([t[k], t[(k + 1) % 3]]))
            }
            _ => self.edges[start as usize..(start + count) as usize]
                .iter()
                .all(|&e| clear(e)),
        }
    }
}

/// The distance from `p` to the segment from `a` to `b`.
pub fn segment_distance(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let s = if len2 > 0.0 {
        ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + ab * s)
}
