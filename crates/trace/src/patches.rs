//! The planar patches of a scene's surfaces, for the blur of virtual spherical lights: a
//! surface next to a VSL centre cuts its discs as a plane only where its patch covers that
//! plane (`vbl::Walls`).
use beamlight_scene::Scene;
use glam::Vec3;
use std::collections::HashMap;

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
/// [`Patches::spans`]' count for a patch with no open edge.
const CLOSED: u32 = u32::MAX;

impl Patches {
    pub fn build(scene: &Scene) -> Self {
        let tris = &scene.triangles;
        let n = tris.len();
        let key = |p: Vec3| p.to_array().map(f32::to_bits);
        let edge_key = |a: Vec3, b: Vec3| {
            let (ka, kb) = (key(a), key(b));
            if ka <= kb { (ka, kb) } else { (kb, ka) }
        };
        let is_wall = |t: usize| {
            scene.materials[tris[t].material as usize].bsdf.is_some() && tris[t].cross().length_squared() > 0.0
        };
        let normal = |t: usize| tris[t].cross().normalize();
        let size = |t: usize| {
            (0..3)
                .map(|k| tris[t].p[k].distance(tris[t].p[(k + 1) % 3]))
                .fold(0.0, f32::max)
        };
        // The third vertex of `b` (sharing an edge with `a`) over `a`'s plane, in `a`'s size.
        let height = |a: usize, b: usize| {
            let h = tris[b].p.iter().map(|&p| (p - tris[a].p[0]).dot(normal(a)));
            let (lo, hi) = h.fold((0.0f32, 0.0f32), |(lo, hi), x| (lo.min(x), hi.max(x)));
            (if hi > -lo { hi } else { lo }) / size(a)
        };
        let coplanar =
            |a: usize, b: usize| normal(a).dot(normal(b)) >= COPLANAR_NORMALS && height(a, b).abs() <= COPLANAR_OFFSET;
        let mut by_edge: HashMap<_, Vec<u32>> = HashMap::new();
        for i in (0..n).filter(|&i| is_wall(i)) {
            for k in 0..3 {
                by_edge
                    .entry(edge_key(tris[i].p[k], tris[i].p[(k + 1) % 3]))
                    .or_default()
                    .push(i as u32);
            }
        }
        // Union–find over the triangles joined across coplanar shared edges.
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn root(parent: &mut [u32], mut i: u32) -> u32 {
            while parent[i as usize] != i {
                parent[i as usize] = parent[parent[i as usize] as usize];
                i = parent[i as usize];
            }
            i
        }
        for sharing in by_edge.values() {
            for (i, &a) in sharing.iter().enumerate() {
                for &b in &sharing[i + 1..] {
                    if coplanar(a as usize, b as usize) {
                        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
                        parent[ra as usize] = rb;
                    }
                }
            }
        }
        let roots: Vec<u32> = (0..n as u32).map(|i| root(&mut parent, i)).collect();
        // An edge of triangle t is open unless a triangle of another patch shares it and rises
        // on t's free side (a concave fold); an open edge is a rim when no other surface
        // meets it at all.
        let sharing = |t: usize, k: usize| &by_edge[&edge_key(tris[t].p[k], tris[t].p[(k + 1) % 3])];
        let open = |t: usize, k: usize| {
            let sharing = sharing(t, k);
            let inner = sharing
                .iter()
                .any(|&o| o as usize != t && roots[o as usize] == roots[t]);
            !inner
                && !sharing
                    .iter()
                    .any(|&o| roots[o as usize] != roots[t] && height(t, o as usize) > COPLANAR_OFFSET)
        };
        let rim = |t: usize, k: usize| sharing(t, k).len() == 1;
        let mut members: HashMap<u32, Vec<u32>> = HashMap::new();
        for i in (0..n).filter(|&i| is_wall(i)) {
            members.entry(roots[i]).or_default().push(i as u32);
        }
        let mut patches = Patches {
            spans: vec![[0, 0]; n],
            edges: Vec::new(),
            plate: vec![false; n],
        };
        let mut groups: Vec<Vec<u32>> = members.into_values().collect();
        groups.sort_unstable();
        for group in groups {
            let (mut opens, mut rims) = (0, 0);
            for &t in &group {
                for k in 0..3 {
                    if open(t as usize, k) {
                        opens += 1;
                        rims += rim(t as usize, k) as u32;
                    }
                }
            }
            for &t in &group {
                patches.plate[t as usize] = opens > 0 && rims == opens;
            }
            if let [t] = group[..] {
                let mask = (0..3).filter(|&k| open(t as usize, k)).fold(0, |m, k| m | 1 << k);
                patches.spans[t as usize] = [mask, 0];
                continue;
            }
            let start = patches.edges.len();
            for &t in &group {
                let p = tris[t as usize].p;
                patches
                    .edges
                    .extend((0..3).filter(|&k| open(t as usize, k)).map(|k| [p[k], p[(k + 1) % 3]]));
            }
            let count = patches.edges.len() - start;
            let span = if count == 0 {
                [0, CLOSED]
            } else {
                [start as u32, count as u32]
            };
            for &t in &group {
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
