//! Ray–triangle intersection and robust ray offsetting.
use glam::{Vec3, Vec4, Vec4Swizzles};

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
    /// The origin's coordinates in permuted order: `o[kx]`, `o[ky]`, `o[kz]`.
    o: [f32; 3],
    /// Where the permuted x, y and z rows start in [`TriangleRows`]: `3·kx`, `3·ky`, `3·kz`.
    rows: [usize; 3],
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
        let (o, d) = (o.to_array(), d.to_array());
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Self {
            o: [o[kx], o[ky], o[kz]],
            rows: [3 * kx, 3 * ky, 3 * kz],
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }

    #[inline]
    pub fn intersect(&self, p: &[Vec3; 3], tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
        self.intersect_rows(&vertices_to_rows(p), tmin, tmax)
    }

    /// [`Self::intersect`] on a triangle stored by rows.
    #[inline]
    pub fn intersect_rows(&self, r: &TriangleRows, tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
        let Self { o, rows, sx, sy, sz } = *self;
        // SAFETY: `rows` holds 0, 3 and 6, so each row is inside the nine floats.
        let row = |k: usize| unsafe { r.as_ptr().add(rows[k]).cast::<[f32; 3]>().read() };
        let (px, py, pz) = (row(0), row(1), row(2));
        // The vertices a = p[0] − o, b = p[1] − o, c = p[2] − o in permuted coordinates.
        let (a_kx, a_ky, a_kz) = (px[0] - o[0], py[0] - o[1], pz[0] - o[2]);
        let (b_kx, b_ky, b_kz) = (px[1] - o[0], py[1] - o[1], pz[1] - o[2]);
        let (c_kx, c_ky, c_kz) = (px[2] - o[0], py[2] - o[1], pz[2] - o[2]);
        let (ax, ay) = (a_kx - sx * a_kz, a_ky - sy * a_kz);
        let (bx, by) = (b_kx - sx * b_kz, b_ky - sy * b_kz);
        let (cx, cy) = (c_kx - sx * c_kz, c_ky - sy * c_kz);
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        Self::finish(
            sz,
            [ax, bx, cx],
            [ay, by, cy],
            [a_kz, b_kz, c_kz],
            [u, v, w],
            tmin,
            tmax,
        )
    }

    /// The rest of [`Self::intersect_rows`] from the sheared vertices `x`, `y` (a, b, c), their
    /// unsheared permuted z, and the edge functions `e` = (u, v, w): shared with [`EdgeTest`],
    /// so that both give the same hits bit for bit.
    #[inline(always)]
    fn finish(
        sz: f32,
        [ax, bx, cx]: [f32; 3],
        [ay, by, cy]: [f32; 3],
        [a_kz, b_kz, c_kz]: [f32; 3],
        [mut u, mut v, mut w]: [f32; 3],
        tmin: f32,
        tmax: f32,
    ) -> Option<(f32, f32, f32)> {
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
        let (az, bz, cz) = (sz * a_kz, sz * b_kz, sz * c_kz);
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

/// A triangle stored by coordinate rows, `[x0, x1, x2, y0, y1, y2, z0, z1, z2]`, so that one
/// 4-wide load fetches one coordinate of all three vertices (the fourth lane is ignored).
pub type TriangleRows = [f32; 9];

/// The rows of a triangle (see [`TriangleRows`]).
#[inline(always)]
pub fn vertices_to_rows(p: &[Vec3; 3]) -> TriangleRows {
    [p[0].x, p[1].x, p[2].x, p[0].y, p[1].y, p[2].y, p[0].z, p[1].z, p[2].z]
}

/// [`TriangleRay::intersect_rows`] with its first half four lanes wide: the three vertices' sheared
/// coordinates and the three edge functions `(u, v, w)` come out of the same IEEE operations in
/// the same order as there, one vertex or edge per lane, and most triangles a ray misses are
/// rejected right there (a strict sign disagreement with no zero, which `intersect_rows` rejects
/// too). The rest goes through the same scalar code as `intersect_rows`, so the hits are its
/// hits, bit for bit.
#[derive(Clone, Copy, Debug)]
pub struct EdgeTest {
    /// Offsets (in floats) of the permuted x, y and z rows.
    offsets: [usize; 3],
    o: [Vec4; 3],
    sx: Vec4,
    sy: Vec4,
    sz: f32,
}

impl EdgeTest {
    #[inline]
    pub fn new(ray: &TriangleRay) -> Self {
        let o = ray.o;
        Self {
            offsets: ray.rows,
            o: [Vec4::splat(o[0]), Vec4::splat(o[1]), Vec4::splat(o[2])],
            sx: Vec4::splat(ray.sx),
            sy: Vec4::splat(ray.sy),
            sz: ray.sz,
        }
    }

    /// The hit of the triangle whose rows are the first nine floats of `rows`, exactly as
    /// [`TriangleRay::intersect_rows`] gives it. The tenth float only pads the last 4-wide load.
    #[inline(always)]
    pub fn intersect(&self, rows: &[f32; 10], tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
        let rows = rows.as_ptr();
        // SAFETY: offsets are 0, 3 or 6, so each load reads floats inside the ten.
        let load = |k: usize| Vec4::from_array(unsafe { rows.add(k).cast::<[f32; 4]>().read_unaligned() });
        // Lanes 0, 1, 2 are vertices a, b, c (p[0], p[1], p[2]) as seen from the origin.
        let x = load(self.offsets[0]) - self.o[0];
        let y = load(self.offsets[1]) - self.o[1];
        let z = load(self.offsets[2]) - self.o[2];
        // (ax, bx, cx) and (ay, by, cy) of `intersect_rows`: p[kx] − sx·p[kz], p[ky] − sy·p[kz].
        let xs = x - self.sx * z;
        let ys = y - self.sy * z;
        // (u, v, w) = (cx·by − cy·bx, ax·cy − ay·cx, bx·ay − by·ax).
        let e = xs.zxyw() * ys.yzxw() - ys.zxyw() * xs.yzxw();
        let neg = e.cmplt(Vec4::ZERO).bitmask() & 7;
        let pos = e.cmpgt(Vec4::ZERO).bitmask() & 7;
        let zero = e.cmpeq(Vec4::ZERO).bitmask() & 7;
        if zero == 0 && neg != 0 && pos != 0 {
            return None;
        }
        let lanes = |v: Vec4| [v.x, v.y, v.z];
        TriangleRay::finish(self.sz, lanes(xs), lanes(ys), lanes(z), lanes(e), tmin, tmax)
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

    away3(po, offset)
}

/// [`away`] on all three axes at once (SSE2 on x86-64: the per-axis selects cost 3 % of a path
/// tracer's time, this a third of that).
#[inline(always)]
fn away3(x: Vec3, o: Vec3) -> Vec3 {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of x86-64.
    unsafe {
        use std::arch::x86_64::*;
        let (xv, ov) = (_mm_setr_ps(x.x, x.y, x.z, 0.0), _mm_setr_ps(o.x, o.y, o.z, 0.0));
        let (xi, oi) = (_mm_castps_si128(xv), _mm_castps_si128(ov));
        let (one, sign, exponent) = (_mm_set1_epi32(1), _mm_set1_epi32(i32::MIN), _mm_set1_epi32(0x7f80_0000));
        // One step of the bit pattern: up in magnitude where x and o share a sign, down where not.
        let stepped = _mm_add_epi32(xi, _mm_or_si128(_mm_srai_epi32::<31>(_mm_xor_si128(xi, oi)), one));
        // ±0 becomes the least subnormal of the offset's sign.
        let zero = _mm_castps_si128(_mm_cmpeq_ps(xv, _mm_setzero_ps()));
        let from_zero = _mm_or_si128(_mm_and_si128(oi, sign), one);
        let stepped = _mm_or_si128(_mm_and_si128(zero, from_zero), _mm_andnot_si128(zero, stepped));
        // No offset, or x not finite: x itself.
        let keep = _mm_or_si128(
            _mm_castps_si128(_mm_cmpeq_ps(ov, _mm_setzero_ps())),
            _mm_cmpeq_epi32(_mm_and_si128(xi, exponent), exponent),
        );
        let mut r = [0f32; 4];
        _mm_storeu_ps(
            r.as_mut_ptr(),
            _mm_castsi128_ps(_mm_or_si128(_mm_and_si128(keep, xi), _mm_andnot_si128(keep, stepped))),
        );
        Vec3::new(r[0], r[1], r[2])
    }
    #[cfg(not(target_arch = "x86_64"))]
    Vec3::new(away(x.x, o.x), away(x.y, o.y), away(x.z, o.z))
}

/// `x.next_up()` where the offset `o` is positive, `x.next_down()` where it is negative, `x`
/// where it is 0 (the same results for finite `x`), written as one step of the bit pattern so
/// that it compiles to selects instead of branches, which the signs of the coordinates make
/// unpredictable (4 % of a path tracer's time with `next_up`/`next_down`).
/// On x86-64 it is only the reference that [`away3`] is tested against.
#[inline(always)]
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
fn away(x: f32, o: f32) -> f32 {
    let stepped = if x == 0.0 {
        if o > 0.0 { f32::from_bits(1) } else { -f32::from_bits(1) }
    } else if (x > 0.0) == (o > 0.0) {
        f32::from_bits(x.to_bits().wrapping_add(1))
    } else {
        f32::from_bits(x.to_bits().wrapping_sub(1))
    };
    if o == 0.0 || !x.is_finite() { x } else { stepped }
}

/// Geometric normal `ng` flipped to the side of direction `w`.
#[inline]
pub fn face_towards(ng: Vec3, w: Vec3) -> Vec3 {
    if ng.dot(w) < 0.0 { -ng } else { ng }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bit-stepping of `offset_ray_origin` must agree with `next_up`/`next_down`
    /// (fails if a sign case or zero is stepped the wrong way).
    #[test]
    fn away_steps_like_next_up_and_next_down() {
        let xs = [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            1e-40,
            -1e-40,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MAX,
            3.5e7,
            -2.25,
        ];
        for x in xs {
            for (o, expected) in [(0.5f32, x.next_up()), (-0.5, x.next_down()), (0.0, x)] {
                assert_eq!(away(x, o).to_bits(), expected.to_bits(), "x = {x:e}, o = {o}");
                // The three-axis form, with x and o in every lane position.
                for lane in 0..3 {
                    let mut xs3 = Vec3::splat(1.5);
                    let mut os3 = Vec3::ZERO;
                    xs3[lane] = x;
                    os3[lane] = o;
                    let got = away3(xs3, os3);
                    assert_eq!(
                        got[lane].to_bits(),
                        expected.to_bits(),
                        "away3: x = {x:e}, o = {o}, lane {lane}"
                    );
                    for other in (0..3).filter(|&k| k != lane) {
                        assert_eq!(got[other], 1.5, "away3 must keep axes without an offset");
                    }
                }
            }
        }
        // A coordinate that is not finite stays as it is, in both forms.
        for x in [f32::INFINITY, f32::NEG_INFINITY, f32::NAN] {
            for o in [0.5f32, -0.5, 0.0] {
                assert_eq!(away(x, o).to_bits(), x.to_bits());
                assert_eq!(away3(Vec3::splat(x), Vec3::splat(o)).x.to_bits(), x.to_bits());
            }
        }
    }

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

    /// `EdgeTest` (the BVH's fast path) gives exactly `intersect`'s hits, bit for bit: random
    /// triangles (some degenerate) at several scales and offsets, and rays through their
    /// vertices, their edges, and points inside and outside them.
    #[test]
    fn edge_test_gives_intersects_hits() {
        let mut s = beamlight_scene::rng::Sampler::new(7, 0, 0);
        let (mut hits, mut misses) = (0, 0);
        for (scale, offset) in [(1.0f32, 0.0f32), (1e-4, 0.0), (1e4, 0.0), (1.0, 1e3)] {
            let mut rnd = || Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5;
            for k in 0..20000 {
                let mut p = [rnd(), rnd(), rnd()].map(|v| v * scale + Vec3::splat(offset));
                match k % 10 {
                    0 => p[2] = p[1],                       // two vertices equal
                    1 => p[2] = p[0] + (p[1] - p[0]) * 0.5, // collinear
                    _ => {}
                }
                let (b1, b2) = match k % 4 {
                    0 => ([0.0, 1.0, 0.0][k % 3], [0.0, 0.0, 1.0][k % 3]), // a vertex
                    1 => {
                        let t = rnd().x + 0.5;
                        [(t, 0.0), (0.0, t), (t, 1.0 - t)][k % 3] // an edge
                    }
                    _ => (rnd().x * 1.4 + 0.5, rnd().y * 1.4 + 0.5), // inside or outside
                };
                let target = p[0] * (1.0 - b1 - b2) + p[1] * b1 + p[2] * b2;
                let o = target + rnd().normalize() * scale * (0.1 + rnd().x + 0.5);
                let d = (target - o).normalize();
                let ray = TriangleRay::new(o, d);
                let rows = vertices_to_rows(&p);
                let padded: [f32; 10] = std::array::from_fn(|i| rows.get(i).copied().unwrap_or(f32::NAN));
                let tmax = [f32::INFINITY, scale][k % 2];
                let exact = ray.intersect(&p, 0.0, tmax);
                let bits = |h: Option<(f32, f32, f32)>| h.map(|(t, b1, b2)| [t, b1, b2].map(f32::to_bits));
                assert_eq!(
                    bits(EdgeTest::new(&ray).intersect(&padded, 0.0, tmax)),
                    bits(exact),
                    "{p:?}, ray {o} → {d}, tmax {tmax}"
                );
                if exact.is_some() {
                    hits += 1;
                } else {
                    misses += 1;
                }
            }
        }
        assert!(hits > 20000 && misses > 10000, "{hits} hits, {misses} misses");
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
