//! Ray–triangle intersection and robust ray offsetting.
use glam::{IVec3, Vec3};

/// Möller–Trumbore intersection. Returns `(t, b1, b2)` with `t` in `(tmin, tmax)` and
/// (b1, b2) the barycentric weights of vertices 1 and 2, or `None`.
#[inline]
pub fn intersect_triangle(o: Vec3, d: Vec3, p: &[Vec3; 3], tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
    let e1 = p[1] - p[0];
    let e2 = p[2] - p[0];
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let tv = o - p[0];
    let b1 = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&b1) {
        return None;
    }
    let qv = tv.cross(e1);
    let b2 = d.dot(qv) * inv;
    if b2 < 0.0 || b1 + b2 > 1.0 {
        return None;
    }
    let t = e2.dot(qv) * inv;
    (t > tmin && t < tmax).then_some((t, b1, b2))
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
