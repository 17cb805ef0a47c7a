//! The planar patches of a scene's surfaces, for the blur of virtual spherical lights: a
//! surface next to a VSL centre cuts its discs as a plane only where its patch covers that
//! plane (`vbl::Walls`).
use beamlight_scene::Scene;
use glam::Vec3;
use rayon::prelude::*;

/// The planar patches of a scene's surfaces: triangles joined across shared edges (the same
/// vertex positions, bit for bit) where both lie in one plane, whichever way each is wound.
/// What ends a patch's plane as a model of the surface are its *open* edges, and which edges
/// those are depends on the side it is seen from: an edge where another surface rises on the
/// side of the viewer (a room's corner, seen from inside) ends nothing, for the space beyond
/// it is not free and that surface is a wall of its own; an edge where the surface folds away
/// from the viewer (a box's edge, seen from outside) or simply ends (a rim) is open. So no
/// winding convention is assumed: a room whose normals face out has the same walls inside it
/// as one whose normals face in. Medium boundaries without a BSDF are never walls and get no
/// patch.
#[derive(Clone, Debug, Default)]
pub struct Patches {
    /// Per scene triangle: for a patch of several triangles, the span of its open edges in
    /// `edges` (start, count > 0); for a triangle that is a patch alone, (mask, 0), bit k of
    /// the mask set when its edge from vertex k to vertex k + 1 is open from its front, bit
    /// 3 + k when from its back. A patch of several triangles without open edges has the span
    /// (0, u32::MAX): it covers everything.
    pub spans: Vec<[u32; 2]>,
    /// The open edges of the patches of several triangles.
    pub edges: Vec<OpenEdge>,
    /// Per scene triangle: whether its front is its patch's back (the patch's sides are those
    /// of its first triangle, and [`OpenEdge::sides`] are the patch's).
    pub flipped: Vec<bool>,
    /// Per scene triangle: the sides ([`FRONT`], [`BACK`], its own) from which its patch is a
    /// plate, a surface whose edges open from that side all end it (no other surface meets
    /// them): a lamp's quad, a sheet of paper. A probe that meets a plate too small to be a
    /// wall goes on past it; past a solid's face it would enter the solid.
    pub plate: Vec<u8>,
}

/// A triangle's side: its front (the side its winding's normal points to) and its back.
pub const FRONT: u8 = 1;
pub const BACK: u8 = 2;

/// An open edge of a patch of several triangles, and the sides of the patch ([`FRONT`] |
/// [`BACK`]) from which it is open.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpenEdge {
    pub ends: [Vec3; 2],
    pub sides: u8,
}

/// How far (relative to the triangle's longest edge) a vertex may lie off a neighbour's plane,
/// and how nearly parallel (or opposite) their normals must be, for the two to be one patch:
/// rounding of coordinates written as floats, no more.
const COPLANAR_OFFSET: f32 = 1e-5;
const COPLANAR_NORMALS: f32 = 1.0 - 1e-6;
/// An edge of a triangle: its end points' bits (in order), the triangle and which edge.
type Side = (([u32; 3], [u32; 3]), u32, u8);

/// [`Patches::spans`]' count for a patch with no open edge.
const CLOSED: u32 = u32::MAX;

/// The other side.
fn opposite(side: u8) -> u8 {
    side ^ (FRONT | BACK)
}

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
        // The vertex of `b` (sharing an edge with `a`) farthest off `a`'s plane, signed (on
        // `a`'s front positive), in `a`'s size.
        let height = |a: usize, b: usize| {
            let h = tris[b].p.iter().map(|&p| (p - tris[a].p[0]).dot(normal[a]));
            let (lo, hi) = h.fold((0.0f32, 0.0f32), |(lo, hi), x| (lo.min(x), hi.max(x)));
            (if hi > -lo { hi } else { lo }) / size[a]
        };
        // Wound either way: a mesh whose triangles disagree is still one surface.
        let coplanar = |a: usize, b: usize| {
            normal[a].dot(normal[b]).abs() >= COPLANAR_NORMALS && height(a, b).abs() <= COPLANAR_OFFSET
        };
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
        // Per triangle, bit k: its edge k is open from its front, i.e. no triangle of its own
        // patch shares it and no other surface rises from it on its front (a concave fold
        // there); bit 3 + k: the same from its back. And bit k of `rim`: that edge is met by
        // no other surface at all (open from both sides).
        let mut open = vec![0u8; n];
        let mut rim = vec![0u8; n];
        for edge in &shared {
            for &(_, t, k) in edge.iter() {
                let (t, r) = (t as usize, roots[t as usize]);
                let others = || edge.iter().map(|&(_, o, _)| o as usize).filter(|&o| o != t);
                if others().any(|o| roots[o] == r) {
                    continue;
                }
                if !others().any(|o| height(t, o) > COPLANAR_OFFSET) {
                    open[t] |= 1 << k;
                }
                if !others().any(|o| height(t, o) < -COPLANAR_OFFSET) {
                    open[t] |= 1 << (3 + k);
                }
                if edge.len() == 1 {
                    rim[t] |= 1 << k;
                }
            }
        }
        let mut patches = Patches {
            spans: vec![[0, 0]; n],
            edges: Vec::new(),
            flipped: vec![false; n],
            plate: vec![0; n],
        };
        // The patches, each a run of triangles sorted by root (then index: deterministic).
        let mut order: Vec<(u32, u32)> = (0..n as u32)
            .filter(|&t| wall[t as usize])
            .map(|t| (roots[t as usize], t))
            .collect();
        order.sort_unstable();
        for group in order.chunk_by(|x, y| x.0 == y.0) {
            let first = group[0].1 as usize;
            // A triangle's open edges from the patch's front and back (its first triangle's).
            let flipped = |t: usize| normal[t].dot(normal[first]) < 0.0;
            let from = |t: usize, side: u8| {
                let own = if flipped(t) { opposite(side) } else { side };
                if own == FRONT { open[t] & 7 } else { open[t] >> 3 }
            };
            let count = |side: u8| -> u32 { group.iter().map(|&(_, t)| from(t as usize, side).count_ones()).sum() };
            let rims: u32 = group.iter().map(|&(_, t)| rim[t as usize].count_ones()).sum();
            // A plate from a side: edges open from there, every one a rim.
            let plate = |side: u8| {
                if count(side) > 0 && count(side) == rims {
                    side
                } else {
                    0
                }
            };
            let plate_sides = plate(FRONT) | plate(BACK);
            for &(_, t) in group {
                let t = t as usize;
                patches.flipped[t] = flipped(t);
                patches.plate[t] = if flipped(t) {
                    (plate_sides & FRONT) << 1 | (plate_sides & BACK) >> 1
                } else {
                    plate_sides
                };
            }
            if let [(_, t)] = group {
                patches.spans[*t as usize] = [open[*t as usize] as u32, 0];
                continue;
            }
            let start = patches.edges.len();
            for &(_, t) in group {
                let t = t as usize;
                let p = tris[t].p;
                let (front, back) = (from(t, FRONT), from(t, BACK));
                patches
                    .edges
                    .extend((0..3).filter(|&k| (front | back) & (1 << k) != 0).map(|k| OpenEdge {
                        ends: [p[k], p[(k + 1) % 3]],
                        sides: if front & (1 << k) != 0 { FRONT } else { 0 }
                            | if back & (1 << k) != 0 { BACK } else { 0 },
                    }));
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

    /// Whether the patch of triangle `tri`, seen from its `side` ([`FRONT`] or [`BACK`]),
    /// covers the disc of radius `need` around `p`, a point of it: no edge of the patch open
    /// from that side comes closer.
    pub fn covers(&self, scene: &Scene, tri: u32, side: u8, p: Vec3, need: f32) -> bool {
        self.open_edges(scene, tri, side)
            .all(|[a, b]| segment_distance(p, a, b) >= need)
    }

    /// The edges of triangle `tri`'s patch that are open from its `side`.
    pub fn open_edges<'a>(&'a self, scene: &Scene, tri: u32, side: u8) -> impl Iterator<Item = [Vec3; 2]> + 'a {
        let (mut alone, mut several) = (None, None);
        match self.spans.get(tri as usize).copied().unwrap_or([0, 0]) {
            [_, CLOSED] => {}
            [mask, 0] => {
                let t = scene.triangles[tri as usize].p;
                let mask = if side == FRONT { mask } else { mask >> 3 };
                alone = Some(
                    (0..3)
                        .filter(move |k| mask & (1 << k) != 0)
                        .map(move |k| [t[k], t[(k + 1) % 3]]),
                );
            }
            [start, count] => {
                // The edges' sides are the patch's.
                let side = if self.flipped[tri as usize] {
                    opposite(side)
                } else {
                    side
                };
                let edges = &self.edges[start as usize..(start + count) as usize];
                several = Some(edges.iter().filter(move |e| e.sides & side != 0).map(|e| e.ends));
            }
        }
        alone.into_iter().flatten().chain(several.into_iter().flatten())
    }

    /// Whether triangle `tri`'s patch, seen from its `side`, is a plate.
    pub fn is_plate(&self, tri: u32, side: u8) -> bool {
        self.plate.get(tri as usize).is_some_and(|&p| p & side != 0)
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
