//! The scene's BVH (an obvhs compressed wide BVH8) and ray queries against it.
use crate::geometry::TriangleRay;
use beamlight_scene::Scene;
use glam::{Vec3, Vec3A};
use obvhs::{BvhBuildParams, cwbvh::CwBvh, ray::Ray, triangle::Triangle as ObvhsTriangle};

/// A closest hit: distance along the (unit) ray direction, triangle index and barycentrics.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    /// Index into `Scene::triangles`.
    pub tri: u32,
    pub b1: f32,
    pub b2: f32,
}

/// BVH over all scene triangles, with vertex positions stored in leaf order for locality.
pub struct Bvh {
    bvh: Option<CwBvh>,
    /// Positions in BVH leaf order: `positions[k]` is triangle `bvh.primitive_indices[k]`.
    positions: Vec<[Vec3; 3]>,
}

impl Bvh {
    pub fn build(scene: &Scene) -> Self {
        Self::from_positions(scene.triangles.iter().map(|t| t.p).collect())
    }

    /// Builds over raw triangles (index = position in `tris`).
    pub fn from_positions(tris: Vec<[Vec3; 3]>) -> Self {
        if tris.is_empty() {
            return Self {
                bvh: None,
                positions: Vec::new(),
            };
        }
        let prims = obvhs_triangles(&tris);
        let mut build_time = std::time::Duration::ZERO;
        let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(&prims, BvhBuildParams::medium_build(), &mut build_time);
        let positions = bvh.primitive_indices.iter().map(|&i| tris[i as usize]).collect();
        Self {
            bvh: Some(bvh),
            positions,
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.positions.len()
    }

    /// Closest hit with `t` in `(0, tmax)` along `o + t·d` (`d` unit length).
    pub fn closest_hit(&self, o: Vec3, d: Vec3, tmax: f32) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let (ray, shift) = traversal_ray(o, d, tmax);
        let tri_ray = TriangleRay::new(o, d);
        let mut hit = obvhs::ray::RayHit::none();
        let mut best = (0.0f32, 0.0f32, 0.0f32);
        let found = bvh.ray_traverse(ray, &mut hit, |r, k| {
            // Intersect in our own (unshifted) frame; report obvhs's parameter, t + shift.
            match tri_ray.intersect(&self.positions[k], 0.0, r.tmax - shift) {
                // obvhs keeps the hit only if its parameter beats the current one; record the
                // barycentrics under the same condition so they stay with the reported triangle.
                Some(h) if h.0 + shift < r.tmax => {
                    best = h;
                    h.0 + shift
                }
                _ => f32::INFINITY,
            }
        });
        found.then(|| Hit {
            t: best.0,
            tri: bvh.primitive_indices[hit.primitive_id as usize],
            b1: best.1,
            b2: best.2,
        })
    }

    /// True when anything lies on `o + t·d` for `t` in `(0, tmax)`.
    pub fn occluded(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        let Some(bvh) = self.bvh.as_ref() else { return false };
        let (ray, shift) = traversal_ray(o, d, tmax);
        let tri_ray = TriangleRay::new(o, d);
        !bvh.ray_traverse_miss(ray, |_, k| {
            tri_ray
                .intersect(&self.positions[k], 0.0, tmax)
                .map_or(f32::INFINITY, |h| h.0 + shift)
        })
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

/// obvhs's wide-node test ignores boxes the ray leaves before t = 1e-4 (an absolute epsilon),
/// which loses nearby hits in small scenes. Starting the traversal ray a little behind the real
/// origin moves every relevant box beyond that cut-off; the triangle tests still use the real
/// origin, and parameters are shifted back. Returns the ray and the shift actually applied.
fn traversal_ray(o: Vec3, d: Vec3, tmax: f32) -> (Ray, f32) {
    const BACK: f32 = 4e-4;
    let o_back = o - d * BACK;
    // Rounding may make the real shift differ from BACK (or vanish for huge coordinates).
    let shift = (o - o_back).dot(d).max(0.0);
    (Ray::new(Vec3A::from(o_back), Vec3A::from(d), 0.0, tmax + shift), shift)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::intersect_triangle;
    use beamlight_scene::rng::Sampler;

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
        let bvh = Bvh::from_positions(tris.clone());
        for _ in 0..2000 {
            let o = rnd() * 12.0 - Vec3::splat(scale);
            let d = (rnd() / scale - 0.5).normalize();
            let tmax = if rnd().x < 0.5 * scale {
                f32::INFINITY
            } else {
                5.0 * scale
            };
            let brute = tris
                .iter()
                .enumerate()
                .filter_map(|(i, p)| intersect_triangle(o, d, p, 0.0, tmax).map(|h| (h.0, i)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let hit = bvh.closest_hit(o, d, tmax);
            assert_eq!(hit.map(|h| h.tri as usize), brute.map(|b| b.1));
            if let (Some(h), Some(b)) = (hit, brute) {
                assert_eq!(h.t, b.0);
                let p = tris[h.tri as usize];
                let q = p[0] * (1.0 - h.b1 - h.b2) + p[1] * h.b1 + p[2] * h.b2;
                assert!((q - (o + d * h.t)).length() < 1e-3 * scale);
            }
            assert_eq!(bvh.occluded(o, d, tmax), brute.is_some());
        }
    }

    #[test]
    fn empty_scene_misses() {
        let bvh = Bvh::from_positions(Vec::new());
        assert!(bvh.closest_hit(Vec3::ZERO, Vec3::X, f32::INFINITY).is_none());
        assert!(!bvh.occluded(Vec3::ZERO, Vec3::X, f32::INFINITY));
    }
}
