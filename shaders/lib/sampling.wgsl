// Sampling warps and densities: twins of `beamlight_scene::sampling` (concentric_disk,
// cosine_hemisphere, uniform_cone_1mc, shifted_lattice, PiecewiseLinear, LineAngles) and of
// `Frame::from_normal`/`to_world` as the VBL/VSL kernels need them. Every function keeps the
// CPU's order of operations, so the twins agree to rounding.

const TAU: f32 = 6.2831855;
const FRAC_PI_2: f32 = 1.5707964;
const FRAC_PI_4: f32 = 0.7853982;
// The largest f32 below 1 (`sampling::ONE_MINUS_EPSILON`).
const ONE_MINUS_EPSILON: f32 = 0.99999994;
// `f32::MIN_POSITIVE`.
const F32_MIN_POSITIVE: f32 = 1.1754944e-38;

// Neither NaN nor ±∞ (`f32::is_finite`).
fn finite_f32(x: f32) -> bool {
    return abs(x) <= 3.4028235e38;
}

fn finite_vec3(v: vec3<f32>) -> bool {
    return finite_f32(v.x) && finite_f32(v.y) && finite_f32(v.z);
}

// glam's `length`: sqrt of the dot product.
fn length_glam(v: vec3<f32>) -> f32 {
    return sqrt(dot(v, v));
}

// glam's `normalize`: v · (1 / |v|).
fn normalize_glam(v: vec3<f32>) -> vec3<f32> {
    return v * (1.0 / length_glam(v));
}

// glam's `normalize_or_zero`.
fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let rcp = 1.0 / length_glam(v);
    if finite_f32(rcp) && rcp > 0.0 {
        return v * rcp;
    }
    return vec3<f32>(0.0);
}

// An orthonormal frame (s, t, n) around a unit normal (Duff et al. 2017), `Frame::from_normal`:
// the sign comes from the sign bit of n.z as `f32::copysign` does, so n.z = −0 gives the CPU's
// frame too (which matters where the tangents do: sampling).
fn frame_from_normal(n: vec3<f32>) -> mat3x3<f32> {
    let sign = select(1.0, -1.0, (bitcast<u32>(n.z) & 0x80000000u) != 0u);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let s = vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let t = vec3<f32>(b, sign + n.y * n.y * a, -n.y);
    return mat3x3<f32>(s, t, n);
}

// `Frame::to_local`.
fn to_local(f: mat3x3<f32>, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(v, f[0]), dot(v, f[1]), dot(v, f[2]));
}

// `Frame::to_world`: s·x + t·y + n·z, summed in that order.
fn to_world(f: mat3x3<f32>, v: vec3<f32>) -> vec3<f32> {
    return f[0] * v.x + f[1] * v.y + f[2] * v.z;
}

// atan and tan to a few ulps (Cephes' atanf and tanf). The adapter's own may be much coarser
// (Vulkan allows atan 4096 ulps; lavapipe's measured ≈ 1e-6 absolute), and the angular PDFs
// map angles back to distances with t = δ + h·tan θ, which amplifies such errors; with these
// the sampled points stay within a few ulps of the CPU's (libm's), so the rare discrete
// decisions that hang on them (a shadow ray grazing an edge, a lobe direction on the rim of a
// VSL's cone) flip as rarely as rounding allows.
fn precise_atan(x_in: f32) -> f32 {
    var x = abs(x_in);
    var y = 0.0;
    if x > 2.4142135 {
        y = FRAC_PI_2;
        x = -1.0 / x;
    } else if x > 0.41421357 {
        y = FRAC_PI_4;
        x = (x - 1.0) / (x + 1.0);
    }
    let z = x * x;
    y += (((8.05374449538e-2 * z - 1.38776856032e-1) * z + 1.99777106478e-1) * z - 3.33329491539e-1) * z * x + x;
    return select(y, -y, x_in < 0.0);
}

// atan2(y, x) for x > 0 or any x (Cephes' atan2f quadrants).
fn precise_atan2(y: f32, x: f32) -> f32 {
    if x == 0.0 {
        if y > 0.0 {
            return FRAC_PI_2;
        }
        if y < 0.0 {
            return -FRAC_PI_2;
        }
        return 0.0;
    }
    if y == 0.0 {
        return select(0.0, 3.1415927, x < 0.0);
    }
    var w = 0.0;
    if x < 0.0 {
        w = select(3.1415927, -3.1415927, y < 0.0);
    }
    return w + precise_atan(y / x);
}

// tan x for |x| ≤ π/2 and somewhat beyond (Cephes' tanf: reduction by π/4 in three parts).
fn precise_tan(x_in: f32) -> f32 {
    let x = abs(x_in);
    var j = u32(x * 1.2732395);
    var y = f32(j);
    if (j & 1u) != 0u {
        j += 1u;
        y += 1.0;
    }
    let z = ((x - y * 0.78515625) - y * 2.4187564849853515625e-4) - y * 3.77489497744594108e-8;
    let zz = z * z;
    var r = z;
    if x > 1e-4 {
        r = (((((9.38540185543e-3 * zz + 3.11992232697e-3) * zz + 2.44301354525e-2) * zz + 5.34112807005e-2) * zz
            + 1.33387994085e-1) * zz + 3.33331568548e-1) * zz * z + z;
    }
    if (j & 2u) != 0u {
        r = -1.0 / r;
    }
    return select(r, -r, x_in < 0.0);
}

// Equiangular sampling (Kulla & Fajardo 2012) of t ∈ [t0, t1] on o + t·d towards c, with the
// precise atan2 and tan: (t, pdf), as `sampling::equiangular`.
fn equiangular(o: vec3<f32>, d: vec3<f32>, t0: f32, t1: f32, c: vec3<f32>, u: f32) -> vec2<f32> {
    let delta = dot(c - o, d);
    let co = abs(c - o);
    var scale = max(max(co.x, max(co.y, co.z)), abs(t0));
    if finite_f32(t1) {
        scale = max(scale, abs(t1));
    }
    let h = max(max(length_glam(c - (o + d * delta)), scale * 1e-6), F32_MIN_POSITIVE);
    let theta0 = precise_atan2(t0 - delta, h);
    let theta1 = precise_atan2(t1 - delta, h);
    // An interval too short, seen from c, to sample by angle is sampled uniformly.
    if subtends_no_angle(theta0, theta1) {
        let uniform_pdf = 1.0 / (t1 - t0);
        let ok = finite_f32(uniform_pdf) && uniform_pdf > 0.0;
        return vec2<f32>(clamp(t0 + u * (t1 - t0), t0, t1), select(0.0, uniform_pdf, ok));
    }
    let t = clamp(delta + h * precise_tan(theta0 + u * (theta1 - theta0)), t0, t1);
    let x = t - delta;
    let pdf = h / ((theta1 - theta0) * (h * h + x * x));
    return vec2<f32>(t, select(0.0, pdf, finite_f32(pdf)));
}

// Shirley–Chiu concentric map from the square to the unit disk.
fn concentric_disk(u: vec2<f32>) -> vec2<f32> {
    let o = 2.0 * u - vec2<f32>(1.0);
    if o.x == 0.0 && o.y == 0.0 {
        return vec2<f32>(0.0);
    }
    var r: f32;
    var theta: f32;
    if abs(o.x) > abs(o.y) {
        r = o.x;
        theta = FRAC_PI_4 * (o.y / o.x);
    } else {
        r = o.y;
        theta = FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y);
    }
    return r * vec2<f32>(cos(theta), sin(theta));
}

// Cosine-weighted direction on the hemisphere z ≥ 0 (Malley's method).
fn cosine_hemisphere(u: vec2<f32>) -> vec3<f32> {
    let d = concentric_disk(u);
    let z = sqrt(max(1.0 - (d.x * d.x + d.y * d.y), 0.0));
    return vec3<f32>(d.x, d.y, z);
}

// Uniform direction in the cone around +z with 1 − cos θmax = `one_minus_cos_max`.
fn uniform_cone_1mc(u: vec2<f32>, one_minus_cos_max: f32) -> vec3<f32> {
    let one_minus_cos = u.x * clamp(one_minus_cos_max, 0.0, 2.0);
    let cos_theta = 1.0 - one_minus_cos;
    let sin_theta = sqrt(max(one_minus_cos * (2.0 - one_minus_cos), 0.0));
    let phi = TAU * u.y;
    return vec3<f32>(sin_theta * cos(phi), sin_theta * sin(phi), cos_theta);
}

// x − trunc(x) (`f32::fract`).
fn fract_trunc(x: f32) -> f32 {
    return x - trunc(x);
}

// Point k of n of the randomly shifted rank-1 lattice (`sampling::shifted_lattice`).
fn shifted_lattice(k: u32, n_in: u32, shift: vec2<f32>) -> vec2<f32> {
    let n = max(n_in, 1u);
    let x = (f32(k) + 0.5) / f32(n) + shift.x;
    let y = fract_trunc(f32(k) * 0.618034) + shift.y;
    return vec2<f32>(min(x - floor(x), ONE_MINUS_EPSILON), min(y - floor(y), ONE_MINUS_EPSILON));
}

// e^x − 1, accurate for small |x| (Rust's `f32::exp_m1`): the Taylor series to x⁸/8! below
// |x| = 1/2 (relative error below 2e-7 there), exp(x) − 1 beyond.
fn expm1(x: f32) -> f32 {
    if abs(x) < 0.5 {
        var p = 1.0 / 40320.0;
        p = p * x + 1.0 / 5040.0;
        p = p * x + 1.0 / 720.0;
        p = p * x + 1.0 / 120.0;
        p = p * x + 1.0 / 24.0;
        p = p * x + 1.0 / 6.0;
        p = p * x + 0.5;
        p = p * x + 1.0;
        return p * x;
    }
    return exp(x) - 1.0;
}

// `sampling::subtends_no_angle`: whether the angles θ0 < θ1 of an interval's ends, seen from a
// point, are too close for f32 to sample between.
fn subtends_no_angle(theta0: f32, theta1: f32) -> bool {
    return !(theta1 - theta0 > 1e-4 * max(abs(theta0), abs(theta1)));
}

// `sampling::LineAngles`: the segment o + t·d, t ∈ [t0, t1], as seen from c, the distance
// floored at h_min: t(θ) = delta + h·tan θ.
struct LineAngles {
    delta: f32,
    h: f32,
    theta0: f32,
    theta1: f32,
}

fn line_angles(o: vec3<f32>, d: vec3<f32>, t0: f32, t1: f32, c: vec3<f32>, h_min: f32) -> LineAngles {
    let delta = dot(c - o, d);
    let co = abs(c - o);
    var scale = max(max(co.x, max(co.y, co.z)), abs(t0));
    if finite_f32(t1) {
        scale = max(scale, abs(t1));
    }
    var h = max(max(length_glam(c - (o + d * delta)), scale * 1e-6), F32_MIN_POSITIVE);
    if h_min > h {
        h = h_min;
    }
    return LineAngles(delta, h, precise_atan2(t0 - delta, h), precise_atan2(t1 - delta, h));
}

fn line_t(l: LineAngles, theta: f32) -> f32 {
    return l.delta + l.h * precise_tan(theta);
}

// dθ/dt at t (0 where not finite).
fn line_dtheta_dt(l: LineAngles, t: f32) -> f32 {
    let x = t - l.delta;
    let j = l.h / (l.h * l.h + x * x);
    return select(0.0, j, finite_f32(j));
}
