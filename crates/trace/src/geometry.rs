//! Ray–triangle intersection and robust ray offsetting.
use glam::Vec3;

/// Watertight ray–triangle intersection (Woop, Benthin & Wald, JCGT 2013): a ray through a
/// shared edge or vertex of a closed mesh hits at least one of the triangles, so rays cannot
/// slip through the seams of a medium boundary. Returns `(t, b1, b2)` with `t` in `(tmin, tmax)`
/// and (b1, b2) the barycentric weights of vertices 1 and 2, or `None`.
#[inline]
pub fn intersect_triangle(o: Vec3, d: Vec3, p: &[Vec3; 3], tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
    TriangleRay::new(o, d).intersect(p, tmin, tmax)
}

/// A ray prepared for [`intersect_triangle`]: the per-ray axis permutation and shear are
/// computed once and reused for every triangle the traversal visits.
#[derive(Clone, Copy, Debug)]
pub struct TriangleRay {
    o: Vec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

impl TriangleRay {
    #[inline]
    pub fn new(o: Vec3, d: Vec3) -> Self {
        // Permute axes so that z is the direction's largest component (keeping handedness),
        // then shear so the ray points along +z and the test becomes 2-D in x, y.
        let ad = d.abs();
        let kz = if ad.x > ad.y && ad.x > ad.z {
            0
        } else if ad.y > ad.z {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Self {
            o,
            kx,
            ky,
            kz,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }

    #[inline]
    pub fn intersect(&self, p: &[Vec3; 3], tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
        let Self {
            o,
            kx,
            ky,
            kz,
            sx,
            sy,
            sz,
        } = *self;
        let (a, b, c) = (p[0] - o, p[1] - o, p[2] - o);
        let (ax, ay) = (a[kx] - sx * a[kz], a[ky] - sy * a[kz]);
        let (bx, by) = (b[kx] - sx * b[kz], b[ky] - sy * b[kz]);
        let (cx, cy) = (c[kx] - sx * c[kz], c[ky] - sy * c[kz]);
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        // Exactly on an edge in f32: decide in f64 so neighbouring triangles agree.
        if u == 0.0 || v == 0.0 || w == 0.0 {
            let e = |px: f32, py: f32, qx: f32, qy: f32| (px as f64 * qy as f64 - py as f64 * qx as f64) as f32;
            u = e(cx, cy, bx, by);
            v = e(ax, ay, cx, cy);
            w = e(bx, by, ax, ay);
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let (az, bz, cz) = (sz * a[kz], sz * b[kz], sz * c[kz]);
        let inv = 1.0 / det;
        let t = (u * az + v * bz + w * cz) * inv;
        if !(t > tmin && t < tmax) {
            return None;
        }
        // Reject hits closer than the rounding error of t itself (pbrt-v4 §6.8.6): a ray that
        // starts on this very triangle must not find it again at a tiny positive distance.
        let max_z = az.abs().max(bz.abs()).max(cz.abs());
        let max_x = ax.abs().max(bx.abs()).max(cx.abs());
        let max_y = ay.abs().max(by.abs()).max(cy.abs());
        let delta_z = gamma(3) * max_z;
        let delta_x = gamma(5) * (max_x + max_z);
        let delta_y = gamma(5) * (max_y + max_z);
        let delta_e = 2.0 * (gamma(2) * max_x * max_y + delta_y * max_x + delta_x * max_y);
        let max_e = u.abs().max(v.abs()).max(w.abs());
        let delta_t = 3.0 * (gamma(3) * max_e * max_z + delta_e * max_z + delta_z * max_e) * inv.abs();
        (t > delta_t).then_some((t, v * inv, w * inv))
    }
}

/// γ(n) = n·u / (1 − n·u), u = 2⁻²⁴: the relative error bound of n chained f32 operations.
#[inline]
const fn gamma(n: u32) -> f32 {
    let e = n as f32 * (f32::EPSILON * 0.5);
    e / (1.0 - e)
}

/// Relative rounding error allowed for a point interpolated from triangle vertices. The exact
/// bound for b0·p0 + b1·p1 + b2·p2 is γ₇ ≈ 7·2⁻²⁴ of Σ|bᵢ pᵢ| (pbrt-v4 §6.8); intersection and
/// the subtraction o − p in the next ray test add a few more ulps, so we keep a 5× margin.
const INTERPOLATION_ERROR: f32 = 32.0 * f32::EPSILON * 0.5;

/// Per-axis bound on the floating-point error of the point with barycentrics (b1, b2) on `tri`.
/// It scales with the vertices' magnitudes, so it is right for scenes of any size and position.
#[inline]
pub fn interpolation_error(tri: &[Vec3; 3], b1: f32, b2: f32) -> Vec3 {
    ((tri[0] * (1.0 - b1 - b2)).abs() + (tri[1] * b1).abs() + (tri[2] * b2).abs()) * INTERPOLATION_ERROR
}

/// An error bound valid for any point of the triangle, for points known only by position
/// (recorded gather points and light vertices, which were computed by ray intersection or
/// sampling, not by the exact interpolation of [`interpolation_error`]): Σ|bᵢ pᵢ| ≤ maxᵢ |pᵢ|
/// per axis, plus the triangle's extent on every axis. The extent term keeps the bound away
/// from zero on an axis where all vertices sit at coordinate 0 (an axis-aligned wall through
/// the origin): without it such a point is not moved at all, and a shadow ray ending there
/// hits its own triangle at t = tmax up to rounding, so whether it counts as blocked depends
/// on the last bit (and differs between the CPU and the GPU, which fuses multiply-adds).
pub fn triangle_error_bound(tri: &[Vec3; 3]) -> Vec3 {
    let lo = tri[0].min(tri[1]).min(tri[2]);
    let hi = tri[0].max(tri[1]).max(tri[2]);
    let extent = (hi - lo).max_element();
    (tri[0].abs().max(tri[1].abs()).max(tri[2].abs()) + Vec3::splat(extent)) * INTERPOLATION_ERROR
}

/// Moves the surface point `p` (with per-axis error bound `p_error`) along `n` — the geometric
/// normal already flipped to the side the new ray leaves from — just far enough that the
/// rounding error cannot put it back on the other side, then one ulp further per axis.
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let offset = n * d;
    let po = p + offset;
    let away = |x: f32, o: f32| {
        if o > 0.0 {
            x.next_up()
        } else if o < 0.0 {
            x.next_down()
        } else {
            x
        }
    };
    Vec3::new(away(po.x, offset.x), away(po.y, offset.y), away(po.z, offset.z))
}

/// Geometric normal `ng` flipped to the side of direction `w`.
#[inline]
pub fn face_towards(ng: Vec3, w: Vec3) -> Vec3 {
    if ng.dot(w) < 0.0 { -ng } else { ng }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_and_barycentrics() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let (t, b1, b2) = intersect_triangle(Vec3::new(0.25, 0.5, 1.0), -Vec3::Z, &tri, 0.0, f32::INFINITY).unwrap();
        assert!((t - 1.0).abs() < 1e-6 && (b1 - 0.25).abs() < 1e-6 && (b2 - 0.5).abs() < 1e-6);
        assert!(intersect_triangle(Vec3::new(0.75, 0.5, 1.0), -Vec3::Z, &tri, 0.0, f32::INFINITY).is_none());
        assert!(intersect_triangle(Vec3::new(0.25, 0.5, 1.0), Vec3::X, &tri, 0.0, f32::INFINITY).is_none());
        assert!(intersect_triangle(Vec3::new(0.25, 0.5, 1.0), -Vec3::Z, &tri, 0.0, 0.5).is_none());
    }

    /// Rays aimed exactly at the shared edge and the shared vertex of a fan of triangles must
    /// hit one of them (the property that keeps closed medium boundaries closed).
    #[test]
    fn shared_edges_and_vertices_are_watertight() {
        let c = Vec3::new(0.3, 0.2, 0.0);
        let ring: Vec<Vec3> = (0..7)
            .map(|i| {
                let a = i as f32 / 7.0 * std::f32::consts::TAU;
                c + Vec3::new(a.cos(), a.sin(), 0.0) * 0.77
            })
            .collect();
        let tris: Vec<[Vec3; 3]> = (0..7).map(|i| [c, ring[i], ring[(i + 1) % 7]]).collect();
        let mut s = beamlight_scene::rng::Sampler::new(5, 0, 0);
        for k in 0..2000 {
            // Target: the centre vertex, or a point on one of the shared edges.
            let target = if k % 5 == 0 {
                c
            } else {
                c + (ring[k % 7] - c) * s.next_1d()
            };
            let o = Vec3::new(s.next_1d() - 0.5, s.next_1d() - 0.5, 1.0 + s.next_1d()) * 3.0;
            let d = (target - o).normalize();
            let hits = tris
                .iter()
                .filter(|t| intersect_triangle(o, d, t, 0.0, f32::INFINITY).is_some())
                .count();
            assert!(hits >= 1, "ray {k} towards {target} slipped through");
        }
    }

    #[test]
    fn offset_leaves_the_surface_at_any_scale() {
        for scale in [1e-6f32, 1e-3, 1.0, 1e3, 1e5] {
            let tri = [
                Vec3::new(0.3, 0.1, 0.7) * scale,
                Vec3::new(1.1, 0.2, 0.9) * scale,
                Vec3::new(0.4, 1.3, 0.2) * scale,
            ];
            let ng = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
            let p = tri[0] * 0.3 + tri[1] * 0.3 + tri[2] * 0.4;
            let err = interpolation_error(&tri, 0.3, 0.4);
            let o = offset_ray_origin(p, err, ng);
            // Leaving along the normal's side must not hit the triangle itself.
            let d = (ng + Vec3::new(0.3, -0.2, 0.1)).normalize();
            let d = face_towards(d, ng);
            assert!(
                intersect_triangle(o, d, &tri, 0.0, f32::INFINITY).is_none(),
                "scale {scale}"
            );
            // Going back must hit it, very close.
            // The offset is tiny compared with the scene.
            assert!((o - p).length() <= 1e-5 * scale);
            assert!(intersect_triangle(o, -d, &tri, 0.0, f32::INFINITY).is_some());
        }
    }
}
