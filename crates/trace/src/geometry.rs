//! Ray–triangle intersection and robust ray offsetting.
use glam::{IVec3, Vec3};

/// Watertight ray–triangle intersection (Woop, Benthin & Wald, JCGT 2013): a ray through a
/// shared edge or vertex of a closed mesh hits at least one of the triangles, so rays cannot
/// slip through the seams of a medium boundary. Returns `(t, b1, b2)` with `t` in `(tmin, tmax)`
/// and (b1, b2) the barycentric weights of vertices 1 and 2, or `None`.
#[inline]
pub fn intersect_triangle(o: Vec3, d: Vec3, p: &[Vec3; 3], tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
    // Permute axes so that z is the ray direction's largest component (keeping handedness).
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
    // Shear so the ray points along +z; then the test is 2-D in x, y.
    let sx = d[kx] / d[kz];
    let sy = d[ky] / d[kz];
    let sz = 1.0 / d[kz];
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
    let t_scaled = sz * (u * a[kz] + v * b[kz] + w * c[kz]);
    let inv = 1.0 / det;
    let t = t_scaled * inv;
    (t > tmin && t < tmax).then_some((t, v * inv, w * inv))
}

/// Moves `p` off a surface along `n` (the geometric normal, flipped to the side the new ray
/// leaves from) by a few ULPs of `p`'s own magnitude, so the offset scales with the distance
/// from the origin instead of being a fixed epsilon.
/// (Wächter & Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems, ch. 6.)
#[inline]
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let of_i = IVec3::new(
        (INT_SCALE * n.x) as i32,
        (INT_SCALE * n.y) as i32,
        (INT_SCALE * n.z) as i32,
    );
    let step = |p: f32, o: i32, n: f32| -> f32 {
        if p.abs() < ORIGIN {
            p + FLOAT_SCALE * n
        } else {
            let o = if p < 0.0 { -o } else { o };
            f32::from_bits((p.to_bits() as i32).wrapping_add(o) as u32)
        }
    };
    Vec3::new(step(p.x, of_i.x, n.x), step(p.y, of_i.y, n.y), step(p.z, of_i.z, n.z))
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
        for scale in [1e-3f32, 1.0, 1e3, 1e5] {
            let tri = [
                Vec3::new(0.3, 0.1, 0.7) * scale,
                Vec3::new(1.1, 0.2, 0.9) * scale,
                Vec3::new(0.4, 1.3, 0.2) * scale,
            ];
            let ng = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
            let p = tri[0] * 0.3 + tri[1] * 0.3 + tri[2] * 0.4;
            let o = offset_ray_origin(p, ng);
            // Leaving along the normal's side must not hit the triangle itself.
            let d = (ng + Vec3::new(0.3, -0.2, 0.1)).normalize();
            let d = face_towards(d, ng);
            assert!(
                intersect_triangle(o, d, &tri, 0.0, f32::INFINITY).is_none(),
                "scale {scale}"
            );
            // Going back must hit it, very close.
            let back = offset_ray_origin(p, -ng);
            assert!((back - p).length() <= 1e-4 * scale.max(1.0));
            assert!(intersect_triangle(o, -d, &tri, 0.0, f32::INFINITY).is_some());
        }
    }
}
