//! use lib/gather.wgsl
//! use lib/media.wgsl
//! use lib/sampling.wgsl
//! use lib/walls.wgsl
// What the VBL/VSL kernels share: twins of the helpers in `beamlight_trace::vbl` (the VSL's
// cone of gather directions, the scattering functions as factors of the cone integrand and as
// lobes to draw directions from, the cone integral, the angular PDFs' vertices). WGSL has no
// closures: the CPU's integrand `g(ω')` is always a product of two factors (a surface's f·cos
// or an HG lobe), so it is passed as the two factors, and each kernel computes the vertex
// values of its angular PDF in its own loop.

// `vbl::clean_r2`: NaN or negative → 0, ∞ → the largest finite value.
fn clean_r2(r2: f32) -> f32 {
    return select(0.0, min(r2, 3.4028235e38), r2 > 0.0);
}

// `vbl::Cone`: the gather directions from a receiver whose rays pass within R of a VSL centre.
struct Cone {
    axis: vec3<f32>,
    // cos θmax and sin θmax.
    cos_max: f32,
    sin_max: f32,
    // 1 − cos θmax, formed without cancellation.
    one_minus_cos: f32,
    // Ω / (πR²).
    weight: f32,
    // false where the CPU's `vsl_cone` returns `None`.
    valid: bool,
}

// `vbl::vsl_cone`: the VSL of squared radius r2 at `centre`, seen from `at`.
fn vsl_cone(at: vec3<f32>, centre: vec3<f32>, r2: f32, fallback: vec3<f32>) -> Cone {
    let to = centre - at;
    let d2 = dot(to, to);
    let d = sqrt(d2);
    var axis = fallback;
    if d > 0.0 && finite_vec3(to / d) {
        axis = to / d;
    }
    var c = Cone(axis, 0.0, 1.0, 1.0, 2.0 / r2, false);
    if d2 > r2 {
        let sin2 = r2 / d2;
        let cos_max = sqrt(max((d2 - r2) / d2, 0.0));
        c = Cone(axis, cos_max, sqrt(sin2), sin2 / (1.0 + cos_max), 2.0 / (d2 * (1.0 + cos_max)), false);
    }
    c.valid = finite_f32(c.weight) && c.weight > 0.0 && finite_vec3(axis);
    return c;
}

// `vbl::vsl_sheet_cone`: a surface photon's cone; inside the sphere the hemisphere about
// `inside`, the side its surface's disc lies on.
fn vsl_sheet_cone(at: vec3<f32>, centre: vec3<f32>, r2: f32, inside: vec3<f32>) -> Cone {
    var c = vsl_cone(at, centre, r2, inside);
    let to = centre - at;
    if dot(to, to) <= r2 {
        c.axis = inside;
    }
    return c;
}

// `vbl::closest_in_cone`: the direction within the cone closest to the unit direction a.
fn closest_in_cone(cone: Cone, a: vec3<f32>) -> vec3<f32> {
    let ca = dot(a, cone.axis);
    if ca >= cone.cos_max {
        return a;
    }
    var perp = a - cone.axis * ca;
    let len = length_glam(perp);
    if len > 1e-6 {
        perp = perp / len;
    } else {
        perp = frame_from_normal(cone.axis)[0];
    }
    return normalize_glam(cone.axis * cone.cos_max + perp * cone.sin_max);
}

// A factor of the cone integrand and a distribution over gather directions ω' in one
// (`vbl::Lobe` with `vbl::Surface`): a surface's f·cos, f(fixed, sign·ω')·|cos| (sign +1 at a
// camera shading point, −1 at a VPL), or an HG lobe hg(a, sign·ω').
const LOBE_SURFACE: u32 = 0u;
const LOBE_PHASE: u32 = 1u;

struct Lobe {
    kind: u32,
    // Surface: the BSDF, its frame, the fixed direction (local), the normal.
    bsdf: Bsdf,
    frame: mat3x3<f32>,
    fixed: vec3<f32>,
    n: vec3<f32>,
    // The gather direction where f·cos peaks (`Surface::peak`).
    peak: vec3<f32>,
    // Phase: g and the fixed direction a.
    g: f32,
    a: vec3<f32>,
    sign: f32,
    // Angular scale (`bsdf_scale`, `hg_scale`).
    scale: f32,
}

// `vbl::Surface::new` for a BSDF that is not BSDF_NONE: normal n, fixed direction `fixed`
// (world), sign +1 (receiver) or −1 (VPL).
fn surface_lobe(b: Bsdf, n: vec3<f32>, fixed: vec3<f32>, sign: f32) -> Lobe {
    let frame = frame_from_normal(n);
    let glossy = b.kind == BSDF_PHONG && max_component(b.specular) > 0.0;
    // `surface_peak`: the mirror direction of `fixed` for Phong, else the normal.
    var peak = n;
    var scale = 1.0;
    if glossy {
        let r = n * (2.0 * dot(n, fixed)) - fixed;
        let rcp = 1.0 / length_glam(r);
        if finite_f32(rcp) && rcp > 0.0 {
            peak = r * rcp;
        }
        scale = 1.0 / sqrt(b.exponent + 1.0);
    }
    return Lobe(LOBE_SURFACE, b, frame, to_local(frame, fixed), n, peak * sign, 0.0, vec3<f32>(0.0), sign, scale);
}

// `vbl::phase_lobe`: hg(a, sign·ω') with its angular scale `hg_scale`.
fn phase_lobe(g: f32, a: vec3<f32>, sign: f32) -> Lobe {
    let zero = vec3<f32>(0.0);
    let b = Bsdf(zero, 0.0, zero, BSDF_NONE);
    return Lobe(LOBE_PHASE, b, mat3x3<f32>(zero, zero, zero), zero, zero, zero, g, a, sign, max(1.0 - abs(g), 1e-4));
}

// `vbl::sharper`: of two lobes, the one with the smaller scale (the first on a tie).
fn sharper(a: Lobe, b: Lobe) -> Lobe {
    if b.scale < a.scale {
        return b;
    }
    return a;
}

// The factor's value at ω': `Surface::f_cos`, or the HG density (splat).
fn lobe_eval(l: Lobe, w: vec3<f32>) -> vec3<f32> {
    if l.kind == LOBE_PHASE {
        return vec3<f32>(hg_eval(l.g, l.a, w * l.sign));
    }
    let x = to_local(l.frame, w * l.sign);
    return bsdf_eval(l.bsdf, l.fixed, x) * abs(x.z);
}

// `Lobe::pdf`.
fn lobe_pdf(l: Lobe, w: vec3<f32>) -> f32 {
    if l.kind == LOBE_PHASE {
        return hg_eval(l.g, l.a, w * l.sign);
    }
    return bsdf_pdf(l.bsdf, l.fixed, to_local(l.frame, w * l.sign));
}

// `Lobe::sample`: (ω', 1), or w = 0 for `None`.
fn lobe_sample(l: Lobe, u: vec2<f32>, u_pick: f32) -> vec4<f32> {
    if l.kind == LOBE_PHASE {
        return vec4<f32>(hg_sample_dir(l.g, l.a, u) * l.sign, 1.0);
    }
    let bs = bsdf_sample_dir(l.bsdf, l.fixed, u, u_pick);
    if bs.w == 0.0 {
        return bs;
    }
    return vec4<f32>(to_world(l.frame, bs.xyz) * l.sign, 1.0);
}

// `Surface::max_dir` (`surface_max_dir`): the cone direction closest to the lobe's peak, or to
// the normal if that one is below the horizon.
fn surface_max_dir(l: Lobe, cone: Cone) -> vec3<f32> {
    let w = closest_in_cone(cone, l.peak);
    if dot(w, l.n * l.sign) > 0.0 {
        return w;
    }
    return closest_in_cone(cone, l.n * l.sign);
}

// `vbl::ConeRandom`: the uniform and lobe lattice shifts and the lobe-pick offset, five draws.
struct ConeRandom {
    uniform: vec2<f32>,
    lobe: vec2<f32>,
    pick: f32,
}

fn cone_random(s: ptr<function, Sampler>) -> ConeRandom {
    let u0 = next_1d(s);
    let u1 = next_1d(s);
    let l0 = next_1d(s);
    let l1 = next_1d(s);
    let pick = next_1d(s);
    return ConeRandom(vec2<f32>(u0, u1), vec2<f32>(l0, l1), pick);
}

// `vbl::cone_directions`.
fn cone_directions(cone: Cone, max_dirs: u32, scale: f32) -> u32 {
    let ratio = 2.0 * cone.one_minus_cos / (scale * scale);
    let n = ceil(f32(max_dirs) * ratio);
    if n >= f32(max_dirs) {
        return max(max_dirs, 1u);
    }
    if !(n >= 1.0) {
        return 1u;
    }
    return u32(n);
}

// `vbl::Collection`: where along a gather ray a VSL's light is collected (its sheet: the VPL's
// surface, or for a VBL point the plane perpendicular to ω'), and the plane through the
// receiver that cuts the blur (a surface receiver's tangent plane, or the plane perpendicular to
// ω' for a receiver in a medium).
struct Collection {
    origin: vec3<f32>,
    has_plane: bool,
    centre: vec3<f32>,
    has_sheet: bool,
    plane: vec3<f32>,
    r: f32,
    sheet: vec3<f32>,
    // Transmittance × visibility from origin to centre (the shadow ray's).
    transmittance: vec3<f32>,
    // `Collection::medium`: a VBL point's medium when it has a density grid, whose density at
    // the collection point scales the light (`grid_medium`); NO_MEDIUM otherwise.
    medium: u32,
}

// `mi` when medium `m` has a density grid, else NO_MEDIUM: what `Collection.medium` takes, so
// that homogeneous media skip the per-direction lookup (as `Collection::medium` on the CPU).
fn grid_medium(m: Medium, mi: u32) -> u32 {
    return select(NO_MEDIUM, mi, m.grid_res.x != 0u);
}

// The walls next to each VPL of the pass, found on the CPU (`vbl::vpl_walls_all`).
@group(1) @binding(10) var<storage, read> vpl_walls: array<Walls>;

// `Collection::walls`: the surfaces next to the VSL centre being integrated, where its photons'
// density ends (set by the kernel before `integrate_cone`; a private variable rather than a
// field of `Collection`, which is passed by value for every direction).
var<private> centre_walls: Walls;

// `vbl::Cuts`: the chords cutting one collection disc, the receiver's and at most one per wall;
// each the vector `across` the chord towards its kept side (its length the disc's reach across
// it) and the centre's height above the chord.
const MAX_CUTS: u32 = 7u;
struct Cuts {
    across: array<vec3<f32>, 7>,
    height: array<f32, 7>,
    count: u32,
}

// `Cuts::push`: adds a chord if it meets the disc (a negative height is taken as 0).
fn cuts_push(cuts: ptr<function, Cuts>, height: f32, across: vec3<f32>) {
    let reach2 = dot(across, across);
    if !(reach2 > 0.0) || (height * height >= reach2 && height >= 0.0) || (*cuts).count == MAX_CUTS {
        return;
    }
    (*cuts).across[(*cuts).count] = across;
    (*cuts).height[(*cuts).count] = max(height, 0.0);
    (*cuts).count += 1u;
}

// `Cuts::push_wall`: a wall's chord of a disc of radius r (height: the collection point's
// height over the wall; across: the disc's reach across it). False where the point lies
// beyond the wall; a disc the wall misses, or one parallel to it, is not cut.
fn cuts_push_wall(cuts: ptr<function, Cuts>, height: f32, across: vec3<f32>, r: f32) -> bool {
    let reach2 = dot(across, across);
    let parallel = 1e-4 * r;
    if (height >= 0.0 && height * height >= reach2) || !(reach2 > parallel * parallel) {
        return true;
    }
    if height < 0.0 {
        return false;
    }
    cuts_push(cuts, height, across);
    return true;
}

// `Cuts::weight`: 1 / (the fraction of the disc with normal `normal` that every chord leaves).
fn cuts_weight(cuts: Cuts, normal: vec3<f32>) -> f32 {
    if cuts.count == 0u {
        return 1.0;
    }
    if cuts.count == 1u {
        let a = cuts.height[0] / length_glam(cuts.across[0]);
        let c = sqrt(1.0 - a * a);
        // asin(a) as atan2(a, √(1 − a²)), with the twin of the CPU's accurate atan2.
        let fraction = 0.5 + (a * c + precise_atan2(a, c)) * FRAC_1_PI;
        return 1.0 / fraction;
    }
    let e1 = normalize_glam(cuts.across[0]);
    let e2 = cross(normal, e1);
    var half_planes: array<vec3<f32>, 7>;
    for (var i = 0u; i < cuts.count; i++) {
        let v = cuts.across[i];
        let reach = length_glam(v);
        half_planes[i] = vec3<f32>(vec2<f32>(dot(v, e1), dot(v, e2)) / reach, cuts.height[i] / reach);
    }
    return 1.0 / kept_fraction(half_planes, cuts.count);
}

// `vbl::kept_fraction`: the fraction of the unit disc in the half-planes {v : v·u ≥ −a}, each
// given as (u, a): the square around the disc clipped by each, then the disc's area within the
// polygon as a sum of signed wedges over its edges.
fn kept_fraction(half_planes: array<vec3<f32>, 7>, count: u32) -> f32 {
    var polygon: array<vec2<f32>, 11>;
    polygon[0] = vec2<f32>(-1.0, -1.0);
    polygon[1] = vec2<f32>(1.0, -1.0);
    polygon[2] = vec2<f32>(1.0, 1.0);
    polygon[3] = vec2<f32>(-1.0, 1.0);
    var corners = 4u;
    for (var k = 0u; k < count; k++) {
        let u = half_planes[k].xy;
        let a = half_planes[k].z;
        var clipped: array<vec2<f32>, 11>;
        var kept = 0u;
        for (var i = 0u; i < corners; i++) {
            let p = polygon[i];
            let q = polygon[(i + 1u) % corners];
            let dp = dot(p, u) + a;
            let dq = dot(q, u) + a;
            if dp >= 0.0 {
                clipped[kept] = p;
                kept += 1u;
            }
            if (dp >= 0.0) != (dq >= 0.0) {
                clipped[kept] = p + (q - p) * (dp / (dp - dq));
                kept += 1u;
            }
        }
        polygon = clipped;
        corners = kept;
    }
    var area = 0.0;
    for (var i = 0u; i < corners; i++) {
        area += disc_wedge(polygon[i], polygon[(i + 1u) % corners]);
    }
    return area * FRAC_1_PI;
}

fn perp_dot(p: vec2<f32>, q: vec2<f32>) -> f32 {
    return p.x * q.y - p.y * q.x;
}

fn disc_sector(p: vec2<f32>, q: vec2<f32>) -> f32 {
    return 0.5 * precise_atan2(perp_dot(p, q), dot(p, q));
}

// `vbl::disc_wedge`: the signed area of the unit disc within the triangle (0, a, b).
fn disc_wedge(a: vec2<f32>, b: vec2<f32>) -> f32 {
    let d = b - a;
    let dd = dot(d, d);
    let ad = dot(a, d);
    let disc = ad * ad - dd * (dot(a, a) - 1.0);
    if !(dd > 0.0 && disc > 0.0) {
        return disc_sector(a, b);
    }
    let root = sqrt(disc);
    let p1 = a + d * clamp((-ad - root) / dd, 0.0, 1.0);
    let p2 = a + d * clamp((-ad + root) / dd, 0.0, 1.0);
    return disc_sector(a, p1) + 0.5 * perp_dot(p1, p2) + disc_sector(p2, b);
}

// `vbl::transmittance_share`: T^share per channel (0 stays 0; a NaN or negative T stays NaN,
// for `admit` to count).
fn transmittance_share(tr: vec3<f32>, share: f32) -> vec3<f32> {
    return select(exp(log(tr) * share), vec3<f32>(0.0), tr == vec3<f32>(0.0));
}

// `Collection::weight`: the transmittance to the collection point over the uncut fraction of the
// disc, along ω' = w, times the density there for a VBL point in a density grid (a surface
// photon: `collection_on_surface`).
fn collection_weight(col: Collection, w: vec3<f32>) -> vec3<f32> {
    if col.has_sheet {
        return collection_on_surface(col, w);
    }
    let to = col.centre - col.origin;
    let t = dot(to, w);
    let d = length_glam(to);
    var share = 1.0;
    if d > 0.0 {
        share = max(t, 0.0) / d;
    }
    var cuts: Cuts;
    cuts.count = 0u;
    if col.has_plane {
        let wn = dot(w, col.plane);
        cuts_push(&cuts, t * wn, col.r * (col.plane - w * wn));
    }
    for (var i = 0u; i < centre_walls.count; i++) {
        let wall = centre_walls.planes[i];
        let above = dot(col.origin - wall.point, wall.normal);
        let own = col.has_plane && dot(col.plane, wall.normal) > 0.999 && abs(above) <= 1e-3 * col.r;
        if own || above < -1e-3 * col.r {
            continue;
        }
        let wall_n = dot(w, wall.normal);
        if !cuts_push_wall(&cuts, above + t * wall_n, col.r * (wall.normal - w * wall_n), col.r) {
            return vec3<f32>(0.0);
        }
    }
    let weight = cuts_weight(cuts, w);
    // Clamped into the grid's box, as on the CPU.
    var density = 1.0;
    if col.medium != NO_MEDIUM {
        density = medium_density_near(col.medium, col.origin + w * max(t, 0.0));
    }
    return transmittance_share(col.transmittance, share) * (weight * density);
}

// `Collection::on_surface`: a surface photon on the sheet with normal m, collected where the ray
// crosses its surface within R of it, by the disc in the surface (f, not f·cos: 1/|ω'·m|).
fn collection_on_surface(col: Collection, w: vec3<f32>) -> vec3<f32> {
    if col.r == 0.0 {
        return col.transmittance;
    }
    let m = col.sheet;
    let to = col.centre - col.origin;
    let wm = dot(w, m);
    let t = dot(to, m) / wm;
    let off = w * t - to;
    if !(t > 0.0) || !(dot(off, off) < col.r * col.r) {
        return vec3<f32>(0.0);
    }
    var cuts: Cuts;
    cuts.count = 0u;
    for (var i = 0u; i < centre_walls.count; i++) {
        let wall = centre_walls.planes[i];
        let above = dot(col.origin - wall.point, wall.normal);
        if above < -1e-3 * col.r {
            continue;
        }
        let height = above + t * dot(w, wall.normal);
        if !cuts_push_wall(&cuts, height, col.r * (wall.normal - m * dot(wall.normal, m)), col.r) {
            return vec3<f32>(0.0);
        }
    }
    let d = length_glam(to);
    return transmittance_share(col.transmittance, t / d) * (cuts_weight(cuts, m) / abs(wm));
}

// `vbl::integrate_cone` with g(ω') = eval(fa, ω') · eval(fb, ω') · collection_weight(col, ω') and
// `lobe` the sharper factor; a surface photon seen from beyond 2R draws its directions on its
// disc (`integrate_disc`).
fn integrate_cone(cone: Cone, max_dirs: u32, lobe: Lobe, fa: Lobe, fb: Lobe, col: Collection, rnd: ConeRandom) -> vec3<f32> {
    let omega = TAU * cone.one_minus_cos;
    let wide = 2.0 * cone.one_minus_cos >= lobe.scale * lobe.scale && omega > 0.0 && max_dirs >= 2u;
    if collection_has_disc(col) {
        return integrate_disc(cone, max_dirs, lobe, fa, fb, col, rnd, wide);
    }
    // The cone's own directions, from here on.
    let frame = frame_from_normal(cone.axis);
    var sum = vec3<f32>(0.0);
    if !wide {
        let n = cone_directions(cone, max_dirs, lobe.scale);
        for (var k = 0u; k < n; k++) {
            let local = uniform_cone_1mc(shifted_lattice(k, n, rnd.uniform), cone.one_minus_cos);
            let w = normalize_glam(to_world(frame, local));
            sum += lobe_eval(fa, w) * lobe_eval(fb, w) * collection_weight(col, w);
        }
        return sum * (cone.weight / f32(n));
    }
    let na = max_dirs - max_dirs / 2u;
    let nb = max_dirs / 2u;
    // Balance heuristic over all na + nb directions.
    let p_uniform = 1.0 / omega;
    for (var k = 0u; k < na; k++) {
        let local = uniform_cone_1mc(shifted_lattice(k, na, rnd.uniform), cone.one_minus_cos);
        let w = normalize_glam(to_world(frame, local));
        let denominator = f32(na) * p_uniform + f32(nb) * lobe_pdf(lobe, w);
        sum += lobe_eval(fa, w) * lobe_eval(fb, w) * collection_weight(col, w) / denominator;
    }
    for (var k = 0u; k < nb; k++) {
        let ls = lobe_direction(lobe, k, nb, rnd);
        let w = ls.xyz;
        if ls.w != 0.0 && dot(w, cone.axis) >= cone.cos_max {
            let denominator = f32(na) * p_uniform + f32(nb) * lobe_pdf(lobe, w);
            sum += lobe_eval(fa, w) * lobe_eval(fb, w) * collection_weight(col, w) / denominator;
        }
    }
    return sum * (cone.weight / omega);
}

// `vbl::lobe_direction`: the k-th of n directions drawn from `lobe` (w = 0: none).
fn lobe_direction(lobe: Lobe, k: u32, n: u32, rnd: ConeRandom) -> vec4<f32> {
    let pick = fract_trunc((f32(k) + 0.5) / f32(n) + rnd.pick);
    return lobe_sample(lobe, shifted_lattice(k, n, rnd.lobe), pick);
}

// `Collection::disc`: a surface photon seen from beyond 2R.
fn collection_has_disc(col: Collection) -> bool {
    let to = col.centre - col.origin;
    return col.has_sheet && col.r > 0.0 && dot(to, to) > 4.0 * col.r * col.r;
}

// `SurfaceDisc::direction`: towards the disc point of u (concentric map), `frame` the sheet's.
fn disc_direction(col: Collection, frame: mat3x3<f32>, u: vec2<f32>) -> vec3<f32> {
    let p = concentric_disk(u) * col.r;
    let y = col.centre + frame[0] * p.x + frame[1] * p.y;
    return normalize_glam(y - col.origin);
}

// `SurfaceDisc::scaled_pdf`: πR² times the density in solid angle of `disc_direction`,
// dist²/|ω'·m| where the ray crosses the disc, 0 where it misses it.
fn disc_scaled_pdf(col: Collection, w: vec3<f32>) -> f32 {
    let to = col.centre - col.origin;
    let wm = dot(w, col.sheet);
    let t = dot(to, col.sheet) / wm;
    let off = w * t - to;
    if !(t > 0.0) || !(dot(off, off) < col.r * col.r) {
        return 0.0;
    }
    return t * t / abs(wm);
}

// One direction's term of `integrate_disc`: g / (na πR² p_disc + nb πR² p_lobe), 0 off the disc.
fn disc_term(w: vec3<f32>, na: u32, nb: u32, area: f32, wide: bool, lobe: Lobe, fa: Lobe, fb: Lobe, col: Collection) -> vec3<f32> {
    let q = disc_scaled_pdf(col, w);
    var lobe_share = 0.0;
    if wide {
        lobe_share = f32(nb) * area * lobe_pdf(lobe, w);
    }
    if q > 0.0 {
        return lobe_eval(fa, w) * lobe_eval(fb, w) * collection_weight(col, w) / (f32(na) * q + lobe_share);
    }
    return vec3<f32>(0.0);
}

// `vbl::integrate_disc`: the cone's count of directions towards uniform points of a surface
// photon's disc (half of them from the lobe when the cone is wide), by the balance heuristic.
fn integrate_disc(cone: Cone, max_dirs: u32, lobe: Lobe, fa: Lobe, fb: Lobe, col: Collection, rnd: ConeRandom, wide: bool) -> vec3<f32> {
    var na = cone_directions(cone, max_dirs, lobe.scale);
    var nb = 0u;
    if wide {
        na = max_dirs - max_dirs / 2u;
        nb = max_dirs / 2u;
    }
    let frame = frame_from_normal(col.sheet);
    let area = PI * col.r * col.r;
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < na; k++) {
        let w = disc_direction(col, frame, shifted_lattice(k, na, rnd.uniform));
        sum += disc_term(w, na, nb, area, wide, lobe, fa, fb, col);
    }
    for (var k = 0u; k < nb; k++) {
        let ls = lobe_direction(lobe, k, nb, rnd);
        if ls.w != 0.0 {
            sum += disc_term(ls.xyz, na, nb, area, wide, lobe, fa, fb, col);
        }
    }
    return sum;
}

// `vbl::surface_vertex_value`: an angular density's vertex value between a surface's lobe
// (mean over colours) and a phase function, seen from `at`: both at the direction towards
// `centre` (the VRL paper's rule) or at the direction in the VSL's cone (squared radius r2,
// `fallback` when `at` is inside it) where the surface's lobe peaks; 0 without a cone.
fn surface_vertex_value(surface: Lobe, phase: Lobe, at: vec3<f32>, centre: vec3<f32>, r2: f32, fallback: vec3<f32>) -> f32 {
    var w = normalize_or_zero(centre - at);
    if params.angular_pdf != ANGULAR_PDF_VRL {
        let cone = vsl_cone(at, centre, r2, fallback);
        if !cone.valid {
            return 0.0;
        }
        w = surface_max_dir(surface, cone);
    }
    return luminance_mean(lobe_eval(surface, w)) * lobe_eval(phase, w).x;
}

// `vbl::MEDIA_PAIR_TRACKING_RATE`: ratio tracking's rate (times the majorant) for the
// transmittances of a pair gathered into a camera media segment (`Lmm`, `Lms`).
const MEDIA_PAIR_TRACKING_RATE: f32 = 4.0;

// A shadow ray from `origin` to `target_point` starting in `medium`, ratio tracking at `rate`
// times the majorant (`vbl::connect`): 1 when the receiver is at the VSL centre (`dist` = 0).
fn connect(origin: vec3<f32>, target_point: vec3<f32>, dist: f32, medium: u32, rate: f32, s: ptr<function, Sampler>) -> vec3<f32> {
    if !(dist > 0.0) {
        return vec3<f32>(1.0);
    }
    return shadow_transmittance_at_rate(origin, target_point, medium, rate, s);
}
