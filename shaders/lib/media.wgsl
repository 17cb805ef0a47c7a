//! use lib/rng.wgsl
//! use lib/bvh.wgsl
//! use lib/sampling.wgsl
// Transmittance through the scene's media: the twin of `beamlight_trace::media::transmittance`
// and of `TraceScene::{medium_transmittance, shadow_transmittance}`. Each `next_1d` is drawn at
// the same point of the same loop as on the CPU, so a kernel and its CPU oracle agree sample for
// sample; the loops therefore keep the CPU's structure even where a GPU would prefer another.

// Null-interface crossings after which a shadow ray is given up on (`context::MAX_CROSSINGS`).
const MAX_CROSSINGS: u32 = 256u;
// Voxels per majorant cell along each axis (`medium::MAJORANT_BLOCK`).
const MAJORANT_BLOCK: f32 = 8.0;
// The CPU's +∞ for DDA axes the ray never crosses: WGSL has no infinity literal (and may assume
// none occurs), and the largest finite float orders the same against every finite distance.
const MEDIA_FAR: f32 = 3.4028235e38;

fn rgb_max(v: vec3<f32>) -> f32 {
    return max(v.x, max(v.y, v.z));
}

fn grid_voxel(m: Medium, x: u32, y: u32, z: u32) -> f32 {
    return grid[m.grid_offset + x + m.grid_res.x * (y + m.grid_res.y * z)];
}

// Majorant of majorant cell `c` (`DensityGrid::majorant`).
fn grid_majorant(m: Medium, c: vec3<u32>) -> f32 {
    return grid[m.majorant_offset + c.x + m.majorant_res.x * (c.y + m.majorant_res.y * c.z)];
}

// Twin of `DensityGrid::density`: trilinear between voxel centres, zero outside the box. The
// lerps are spelled out rather than `mix`, which may be evaluated in another order.
fn grid_density(m: Medium, p: vec3<f32>) -> f32 {
    if any(p < m.grid_lo) || any(p > m.grid_hi) {
        return 0.0;
    }
    let resf = vec3<f32>(m.grid_res);
    let u = clamp((p - m.grid_lo) / (m.grid_hi - m.grid_lo) * resf - vec3<f32>(0.5), vec3<f32>(0.0), resf - vec3<f32>(1.0));
    let i0 = vec3<u32>(floor(u));
    let f = u - vec3<f32>(i0);
    let i1 = min(i0 + vec3<u32>(1u), m.grid_res - vec3<u32>(1u));
    let a00 = grid_voxel(m, i0.x, i0.y, i0.z);
    let c00 = a00 + (grid_voxel(m, i1.x, i0.y, i0.z) - a00) * f.x;
    let a10 = grid_voxel(m, i0.x, i1.y, i0.z);
    let c10 = a10 + (grid_voxel(m, i1.x, i1.y, i0.z) - a10) * f.x;
    let a01 = grid_voxel(m, i0.x, i0.y, i1.z);
    let c01 = a01 + (grid_voxel(m, i1.x, i0.y, i1.z) - a01) * f.x;
    let a11 = grid_voxel(m, i0.x, i1.y, i1.z);
    let c11 = a11 + (grid_voxel(m, i1.x, i1.y, i1.z) - a11) * f.x;
    let c0 = c00 + (c10 - c00) * f.y;
    let c1 = c01 + (c11 - c01) * f.y;
    return c0 + (c1 - c0) * f.z;
}

// `vbl::shaping_sigma_t`: the extinction per unit of density that shapes the angular PDFs'
// transmittance, the least σt over the channels.
fn shaping_sigma_t(mi: u32) -> f32 {
    let st = media[mi].sigma_s + media[mi].sigma_a;
    return max(min(min(st.x, st.y), st.z), 0.0);
}

// `Medium::density_near`: the density with `p` clamped into the grid's box (continuous, for
// shaping sampling densities alike on both sides of a rounding error at the box's faces).
fn medium_density_near(mi: u32, p: vec3<f32>) -> f32 {
    let m = media[mi];
    if m.grid_res.x == 0u {
        return 1.0;
    }
    return grid_density(m, clamp(p, m.grid_lo, m.grid_hi));
}

// `Medium::density_within`: the largest of the density near p and near the six points r away
// along the axes.
fn medium_density_within(mi: u32, p: vec3<f32>, r: f32) -> f32 {
    let m = media[mi];
    if m.grid_res.x == 0u {
        return 1.0;
    }
    var best = grid_density(m, clamp(p, m.grid_lo, m.grid_hi));
    for (var axis = 0u; axis < 3u; axis++) {
        var offset = vec3<f32>(0.0);
        offset[axis] = r;
        best = max(max(best, grid_density(m, clamp(p + offset, m.grid_lo, m.grid_hi))), grid_density(m, clamp(p - offset, m.grid_lo, m.grid_hi)));
    }
    return best;
}

// Density of medium `mi` at `p` (`Medium::density_at`): 1 in homogeneous media.
fn medium_density(mi: u32, p: vec3<f32>) -> f32 {
    let m = media[mi];
    if m.grid_res.x == 0u {
        return 1.0;
    }
    return grid_density(m, p);
}

// exp(−σ·t) per channel (`media::homogeneous_transmittance`). A channel without extinction
// transmits fully even for t = ∞, where exp would see 0·∞.
fn homogeneous_transmittance(sigma_t: vec3<f32>, t: f32) -> vec3<f32> {
    return select(exp(-sigma_t * t), vec3<f32>(1.0), sigma_t == vec3<f32>(0.0));
}

// `media::MAJORANT_SLACK` and `media::null_fraction`, per channel: a ratio-tracking factor is
// ≥ 0 under a true majorant; rounding below 0 becomes 0, anything further below (a majorant too
// small) NaN, and a NaN stays NaN, for the gathers' `admit` to count.
const MAJORANT_SLACK: f32 = 1e-4;
fn null_fraction(v: vec3<f32>) -> vec3<f32> {
    // A quiet NaN built from the input's bits at run time: a NaN constant is what a shader
    // compiler may fold away or refuse.
    let nan = bitcast<vec3<f32>>((bitcast<vec3<u32>>(v) & vec3<u32>(0u)) | vec3<u32>(0x7fc00000u));
    let rounded = select(v, vec3<f32>(0.0), v < vec3<f32>(0.0));
    return select(rounded, nan, v < vec3<f32>(-MAJORANT_SLACK));
}

// Ratio tracking through a density grid for one group of channels (`mask`, extinction
// `sigma_g` = σt · mask, majorant scale `sigma_max`; `media::transmittance_counted`'s loop
// body): `walk_majorant_cells` with the body of `tentative_collisions` and of the walk's
// closure written inline (WGSL has no closures), in the same order, so the same draws land on
// the same collisions. Channels outside the group keep a factor of exactly 1.
fn ratio_tracking(m: Medium, o: vec3<f32>, d: vec3<f32>, tmax: f32, sigma_g: vec3<f32>, sigma_max: f32, mask: vec3<f32>, s: ptr<function, Sampler>) -> vec3<f32> {
    let sigma_t = sigma_g;
    let rest = vec3<f32>(1.0) - mask;
    var tr = vec3<f32>(1.0);
    // Slab test against the grid box. On the CPU, 1/0 = ±∞ and the NaN of 0·∞ (dropped by
    // f32::min/max) settle axis-parallel rays; WGSL may assume neither exists, so such an axis is
    // decided explicitly with the CPU's outcome: no limit strictly inside the slab, an empty
    // interval otherwise (on its planes included).
    var t_enter = 0.0;
    var t_exit = tmax;
    var inv = vec3<f32>(0.0);
    for (var a = 0u; a < 3u; a++) {
        if d[a] == 0.0 {
            if !(o[a] > m.grid_lo[a] && o[a] < m.grid_hi[a]) {
                return tr;
            }
        } else {
            inv[a] = 1.0 / d[a];
            let ta = (m.grid_lo[a] - o[a]) * inv[a];
            let tb = (m.grid_hi[a] - o[a]) * inv[a];
            t_enter = max(t_enter, min(ta, tb));
            t_exit = min(t_exit, max(ta, tb));
        }
    }
    if !(t_enter < t_exit) {
        return tr;
    }
    // 3-D DDA over the majorant cells (Amanatides & Woo), as the CPU sets it up.
    let res = m.majorant_res;
    let cell = (m.grid_hi - m.grid_lo) / vec3<f32>(m.grid_res) * MAJORANT_BLOCK;
    let p = o + d * t_enter;
    // Clamped before the conversion: out-of-range float → u32 is undefined in WGSL, while the
    // CPU's saturating `as_uvec3` followed by `min` gives the same cell.
    var c = vec3<u32>(min(max(floor((p - m.grid_lo) / cell), vec3<f32>(0.0)), vec3<f32>(res - vec3<u32>(1u))));
    var t_next = vec3<f32>(MEDIA_FAR);
    var t_delta = vec3<f32>(MEDIA_FAR);
    for (var a = 0u; a < 3u; a++) {
        if d[a] != 0.0 {
            let boundary = m.grid_lo[a] + (f32(c[a]) + select(0.0, 1.0, d[a] > 0.0)) * cell[a];
            t_next[a] = (boundary - o[a]) * inv[a];
            t_delta[a] = cell[a] * abs(inv[a]);
        }
    }
    var t = t_enter;
    loop {
        // An axis the ray does not move along is never chosen: its t_next is MEDIA_FAR.
        var axis = 2u;
        if t_next.x < t_next.y && t_next.x < t_next.z {
            axis = 0u;
        } else if t_next.y < t_next.z {
            axis = 1u;
        }
        let t_end = min(t_next[axis], t_exit);
        if t_end > t {
            // `tentative_collisions`: exponential steps against the cell's μ, restarted at its
            // border (the exponential is memoryless); empty cells draw nothing.
            let mu = grid_majorant(m, c) * sigma_max;
            if mu > 0.0 {
                var tc = t;
                loop {
                    tc = tc - log(1.0 - next_1d(s)) / mu;
                    if tc >= t_end {
                        break;
                    }
                    let density = grid_density(m, o + d * tc);
                    tr = tr * null_fraction(vec3<f32>(1.0) - sigma_t * (density / mu));
                    if !finite_vec3(tr) {
                        return tr; // a broken grid: the NaN goes to the counters
                    }
                    let mx = rgb_max(tr * mask);
                    if mx < 0.1 {
                        // Russian roulette keeps the expected value and bounds the work.
                        if next_1d(s) >= mx {
                            return rest;
                        }
                        tr = tr * mask / mx + rest;
                    }
                }
            }
        }
        if t_next[axis] >= t_exit {
            break;
        }
        t = t_end;
        let next = i32(c[axis]) + select(-1, 1, d[axis] > 0.0);
        if next < 0 || next >= i32(res[axis]) {
            break;
        }
        c[axis] = u32(next);
        t_next[axis] += t_delta[axis];
    }
    return tr;
}

// `media::GROUP_RATIO`: channels within this factor of their group's densest share a walk.
const GROUP_RATIO: f32 = 4.0;

// Transmittance of medium `mi` along o + t·d, t ∈ (0, tmax) (`media::transmittance`): closed
// form when homogeneous, ratio tracking in a density grid.
fn transmittance(mi: u32, o: vec3<f32>, d: vec3<f32>, tmax: f32, s: ptr<function, Sampler>) -> vec3<f32> {
    return transmittance_at_rate(mi, o, d, tmax, 1.0, s);
}

// `media::transmittance_at_rate`: ratio tracking stepping at `rate` times the majorant.
fn transmittance_at_rate(mi: u32, o: vec3<f32>, d: vec3<f32>, tmax: f32, rate: f32, s: ptr<function, Sampler>) -> vec3<f32> {
    let m = media[mi];
    let sigma_t = m.sigma_s + m.sigma_a;
    if m.grid_res.x == 0u {
        return homogeneous_transmittance(sigma_t, tmax);
    }
    // `media::extinction_groups`, densest first, one walk each.
    var left = sigma_t > vec3<f32>(0.0);
    var tr = vec3<f32>(1.0);
    for (var k = 0u; k < 3u; k++) {
        var lead = 0.0;
        for (var c = 0u; c < 3u; c++) {
            if left[c] {
                lead = max(lead, sigma_t[c]);
            }
        }
        if !(lead > 0.0) {
            break;
        }
        var mask = vec3<f32>(0.0);
        for (var c = 0u; c < 3u; c++) {
            if left[c] && sigma_t[c] * GROUP_RATIO >= lead {
                mask[c] = 1.0;
                left[c] = false;
            }
        }
        tr = tr * ratio_tracking(m, o, d, tmax, sigma_t * mask, lead * rate, mask, s);
    }
    // Negative rounding cut to 0; a NaN stays NaN (for the record's discard count), which
    // WGSL's max does not promise.
    return select(tr, vec3<f32>(0.0), tr < vec3<f32>(0.0));
}

// `TraceScene::medium_transmittance`: NO_MEDIUM is vacuum.
fn medium_transmittance(medium: u32, o: vec3<f32>, d: vec3<f32>, len: f32, s: ptr<function, Sampler>) -> vec3<f32> {
    return medium_transmittance_at_rate(medium, o, d, len, 1.0, s);
}

fn medium_transmittance_at_rate(medium: u32, o: vec3<f32>, d: vec3<f32>, len: f32, rate: f32, s: ptr<function, Sampler>) -> vec3<f32> {
    if medium == NO_MEDIUM {
        return vec3<f32>(1.0);
    }
    return transmittance_at_rate(medium, o, d, len, rate, s);
}

// The medium beyond scene triangle `tri` for a ray along `dir` (`TraceScene::medium_beyond`,
// `MediumInterface::entered`). TriangleInfo cannot tell "no interface" (the CPU keeps `current`)
// from "vacuum on both sides"; the loader never makes the latter (a region's inside is its own
// medium), so both-vacuum is read as no interface.
fn medium_beyond(tri: u32, ng: vec3<f32>, dir: vec3<f32>, current: u32) -> u32 {
    let info = triangle_info[tri];
    if info.inside == NO_MEDIUM && info.outside == NO_MEDIUM {
        return current;
    }
    return select(info.outside, info.inside, dot(dir, ng) < 0.0);
}

// Transmittance along a shadow ray from `o` (already offset off its surface) to the finite
// point `target_point`, starting in `medium` (`TraceScene::shadow_transmittance` for a light sample
// at finite distance). Zero behind an opaque surface; null interfaces are crossed and switch
// the medium.
fn shadow_transmittance(o_start: vec3<f32>, target_point: vec3<f32>, medium_start: u32, s: ptr<function, Sampler>) -> vec3<f32> {
    return shadow_transmittance_at_rate(o_start, target_point, medium_start, 1.0, s);
}

// `TraceScene::shadow_transmittance_at_rate`: ratio tracking at `rate` times the majorant.
fn shadow_transmittance_at_rate(o_start: vec3<f32>, target_point: vec3<f32>, medium_start: u32, rate: f32, s: ptr<function, Sampler>) -> vec3<f32> {
    let v = target_point - o_start;
    // sqrt(dot) as glam's `length` computes it.
    let len = sqrt(dot(v, v));
    if !(len > 0.0) {
        return vec3<f32>(0.0);
    }
    let d = v / len;
    var o = o_start;
    var medium = medium_start;
    var remaining = len;
    var tr = vec3<f32>(1.0);
    for (var crossing = 0u; crossing < MAX_CROSSINGS; crossing++) {
        // Without null interfaces any hit blocks: an any-hit query is enough.
        if scene_info.has_null_interfaces == 0u {
            if occluded(o, d, remaining) {
                return vec3<f32>(0.0);
            }
            return tr * medium_transmittance_at_rate(medium, o, d, remaining, rate, s);
        }
        let h = closest_hit(o, d, remaining);
        if h.t < 0.0 {
            return tr * medium_transmittance_at_rate(medium, o, d, remaining, rate, s);
        }
        if (triangle_info[h.tri].flags & TRI_NULL_INTERFACE) == 0u {
            return vec3<f32>(0.0);
        }
        tr = tr * medium_transmittance_at_rate(medium, o, d, h.t, rate, s);
        if all(tr == vec3<f32>(0.0)) {
            return tr;
        }
        let t = scene_triangle(h.tri);
        let ng = triangle_normal(t);
        medium = medium_beyond(h.tri, ng, d, medium);
        // `SurfaceHit::spawn` from the interpolated hit point, with the per-point error bound.
        let next = offset_ray_origin(
            triangle_point(t, h.b1, h.b2),
            interpolation_error(t, h.b1, h.b2),
            face_towards(ng, d),
        );
        remaining -= dot(next - o, d);
        o = next;
        if !(remaining > 0.0) {
            return tr;
        }
    }
    return vec3<f32>(0.0);
}
