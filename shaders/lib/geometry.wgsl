//! use lib/scene.wgsl
// Ray–triangle intersection and ray origins off surfaces: twins of `beamlight_trace::geometry`.

const F32_MACHINE_EPS: f32 = 5.9604645e-8; // 2^-24, half of f32::EPSILON

// γ(n) = n·u / (1 − n·u): the relative error bound of n chained f32 operations.
fn gamma(n: f32) -> f32 {
    let e = n * F32_MACHINE_EPS;
    return e / (1.0 - e);
}

// A ray prepared for watertight intersection (Woop et al. 2013): axes permuted so that z is
// the direction's largest component, then sheared so the ray points along +z.
struct TriangleRay {
    o: vec3<f32>,
    kx: u32,
    ky: u32,
    kz: u32,
    shear: vec3<f32>,
}

fn triangle_ray(o: vec3<f32>, d: vec3<f32>) -> TriangleRay {
    let ad = abs(d);
    var kz = 2u;
    if ad.x > ad.y && ad.x > ad.z {
        kz = 0u;
    } else if ad.y > ad.z {
        kz = 1u;
    }
    var kx = (kz + 1u) % 3u;
    var ky = (kz + 2u) % 3u;
    if d[kz] < 0.0 {
        let k = kx;
        kx = ky;
        ky = k;
    }
    return TriangleRay(o, kx, ky, kz, vec3<f32>(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]));
}

// (t, b1, b2) of a hit with t in (tmin, tmax), or t < 0 for a miss. Unlike the CPU, points
// exactly on an edge in f32 are not re-decided in f64 (WGSL has no f64); both sides of the
// edge then see edge functions of 0 and count the hit, so watertightness is kept.
fn intersect_triangle(r: TriangleRay, p0: vec3<f32>, p1: vec3<f32>, p2: vec3<f32>, tmin: f32, tmax: f32) -> vec3<f32> {
    let miss = vec3<f32>(-1.0, 0.0, 0.0);
    let a = p0 - r.o;
    let b = p1 - r.o;
    let c = p2 - r.o;
    let ax = a[r.kx] - r.shear.x * a[r.kz];
    let ay = a[r.ky] - r.shear.y * a[r.kz];
    let bx = b[r.kx] - r.shear.x * b[r.kz];
    let by = b[r.ky] - r.shear.y * b[r.kz];
    let cx = c[r.kx] - r.shear.x * c[r.kz];
    let cy = c[r.ky] - r.shear.y * c[r.kz];
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return miss;
    }
    let det = u + v + w;
    if det == 0.0 || !is_finite(det) {
        return miss;
    }
    let az = r.shear.z * a[r.kz];
    let bz = r.shear.z * b[r.kz];
    let cz = r.shear.z * c[r.kz];
    let inv = 1.0 / det;
    let t = (u * az + v * bz + w * cz) * inv;
    if !(t > tmin && t < tmax) {
        return miss;
    }
    // Reject hits closer than the rounding error of t itself (pbrt-v4 §6.8.6).
    let max_z = max(abs(az), max(abs(bz), abs(cz)));
    let max_x = max(abs(ax), max(abs(bx), abs(cx)));
    let max_y = max(abs(ay), max(abs(by), abs(cy)));
    let delta_z = gamma(3.0) * max_z;
    let delta_x = gamma(5.0) * (max_x + max_z);
    let delta_y = gamma(5.0) * (max_y + max_z);
    let delta_e = 2.0 * (gamma(2.0) * max_x * max_y + delta_y * max_x + delta_x * max_y);
    let max_e = max(abs(u), max(abs(v), abs(w)));
    let delta_t = 3.0 * (gamma(3.0) * max_e * max_z + delta_e * max_z + delta_z * max_e) * abs(inv);
    if !(t > delta_t) {
        return miss;
    }
    return vec3<f32>(t, v * inv, w * inv);
}

fn is_finite(x: f32) -> bool {
    return abs(x) <= 3.4028235e38;
}

// The next float towards +∞ (o > 0) or −∞ (o < 0); x itself for o = 0.
fn step_away(x: f32, o: f32) -> f32 {
    if o == 0.0 || !is_finite(x) {
        return x;
    }
    if x == 0.0 {
        return select(-1.0e-45, 1.0e-45, o > 0.0);
    }
    let bits = bitcast<u32>(x);
    let up = (x > 0.0) == (o > 0.0);
    return bitcast<f32>(select(bits - 1u, bits + 1u, up));
}

// Relative rounding error allowed for a point interpolated from triangle vertices
// (`INTERPOLATION_ERROR` on the CPU).
const INTERPOLATION_ERROR: f32 = 1.9073486e-6; // 32 · 2^-24

// Moves `p` (per-axis error bound `p_error`) along `n`, the normal on the side the new ray
// leaves from, far enough that rounding cannot put it back, then one ulp further per axis.
fn offset_ray_origin(p: vec3<f32>, p_error: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let offset = n * dot(abs(n), p_error);
    let po = p + offset;
    return vec3<f32>(step_away(po.x, offset.x), step_away(po.y, offset.y), step_away(po.z, offset.z));
}

fn face_towards(ng: vec3<f32>, w: vec3<f32>) -> vec3<f32> {
    return select(ng, -ng, dot(ng, w) < 0.0);
}

// The triangle of scene index `id`.
fn scene_triangle(id: u32) -> Triangle {
    return leaf_triangle(triangle_info[id].leaf_slot);
}

fn triangle_normal(t: Triangle) -> vec3<f32> {
    return normalize(cross(t.p1 - t.p0, t.p2 - t.p0));
}

// An error bound valid anywhere on the triangle, never zero along an axis
// (`geometry::triangle_error_bound`, which says why the extent term is there).
fn triangle_error_bound(t: Triangle) -> vec3<f32> {
    let lo = min(t.p0, min(t.p1, t.p2));
    let hi = max(t.p0, max(t.p1, t.p2));
    let e = hi - lo;
    let extent = max(e.x, max(e.y, e.z));
    return (max(abs(t.p0), max(abs(t.p1), abs(t.p2))) + vec3<f32>(extent)) * INTERPOLATION_ERROR;
}

// Origin for a ray leaving point `p` of scene triangle `id` towards `w` (or the end of a
// shadow ray arriving there from −w): `TraceScene::spawn_from_triangle`.
fn spawn_from_triangle(id: u32, p: vec3<f32>, w: vec3<f32>) -> vec3<f32> {
    let t = scene_triangle(id);
    return offset_ray_origin(p, triangle_error_bound(t), face_towards(triangle_normal(t), w));
}

// The point with barycentrics (b1, b2) of `t`, summed in the CPU's order (`TraceScene::surface`)
// so that both sides spawn the next ray from the same float.
fn triangle_point(t: Triangle, b1: f32, b2: f32) -> vec3<f32> {
    return t.p0 * (1.0 - b1 - b2) + t.p1 * b1 + t.p2 * b2;
}

// Per-axis error bound of `triangle_point(t, b1, b2)` (`geometry::interpolation_error`): tighter
// than the whole-triangle bound of `spawn_from_triangle`, and what `SurfaceHit::spawn` uses.
fn interpolation_error(t: Triangle, b1: f32, b2: f32) -> vec3<f32> {
    return (abs(t.p0 * (1.0 - b1 - b2)) + abs(t.p1 * b1) + abs(t.p2 * b2)) * INTERPOLATION_ERROR;
}
