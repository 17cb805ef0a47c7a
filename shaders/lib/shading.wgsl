// Local frames, the Henyey–Greenstein phase function, the Lambert and modified-Phong BSDFs
// and equiangular sampling: twins of `beamlight_scene::{frame, phase, bsdf, sampling}`.

const PI: f32 = 3.14159265358979;
const FRAC_1_PI: f32 = 0.318309886183791;

// An orthonormal frame around a unit normal (Duff et al. 2017), as `Frame::from_normal`.
struct Frame {
    s: vec3<f32>,
    t: vec3<f32>,
    n: vec3<f32>,
}

fn frame_from_normal(n: vec3<f32>) -> Frame {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let s = vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let t = vec3<f32>(b, sign + n.y * n.y * a, -n.y);
    return Frame(s, t, n);
}

fn to_local(f: Frame, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(v, f.s), dot(v, f.t), dot(v, f.n));
}

const HG_MAX_ABS_G: f32 = 0.999999;

// HG density for cos θ = −wo·wi, from 1 ∓ cos θ computed without cancellation.
fn hg_eval(g_in: f32, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    let g = clamp(g_in, -HG_MAX_ABS_G, HG_MAX_ABS_G);
    let one_minus_cos = 0.5 * dot(wo + wi, wo + wi);
    let one_plus_cos = 0.5 * dot(wo - wi, wo - wi);
    var denom: f32;
    if g >= 0.0 {
        denom = (1.0 - g) * (1.0 - g) + 2.0 * g * max(one_minus_cos, 0.0);
    } else {
        denom = (1.0 + g) * (1.0 + g) - 2.0 * g * max(one_plus_cos, 0.0);
    }
    return (1.0 - g) * (1.0 + g) * (0.25 * FRAC_1_PI) / (denom * sqrt(denom));
}

// A BSDF with its texture already applied (`Bsdf` in crates/gpu/src/layout.rs).
struct Bsdf {
    // Lambert albedo, or the Phong diffuse colour.
    diffuse: vec3<f32>,
    exponent: f32,
    specular: vec3<f32>,
    // BSDF_NONE, BSDF_LAMBERT or BSDF_PHONG.
    kind: u32,
}

// No BSDF (a null interface), or a delta one (mirror, glass): nothing to evaluate.
const BSDF_NONE: u32 = 0u;
const BSDF_LAMBERT: u32 = 1u;
const BSDF_PHONG: u32 = 2u;

fn same_side(a: vec3<f32>, b: vec3<f32>) -> bool {
    return (a.z > 0.0 && b.z > 0.0) || (a.z < 0.0 && b.z < 0.0);
}

// max(cos α, 0)^n about the mirror direction r, as exp(n ln(1 − x)) with x = |wi − r|²/2.
fn phong_lobe(n: f32, r: vec3<f32>, wi: vec3<f32>) -> f32 {
    let x = 0.5 * dot(wi - r, wi - r);
    if !(x < 1.0) {
        return 0.0;
    }
    return exp(n * log_1p(-x));
}

// ln(1 + y) accurate for small y (Goldberg's trick: the rounding of 1 + y cancels out).
fn log_1p(y: f32) -> f32 {
    let u = 1.0 + y;
    if u == 1.0 {
        return y;
    }
    return log(u) * (y / (u - 1.0));
}

// f(wo, wi) without the cosine, in the local frame; two-sided like the CPU's `Bsdf::eval`.
fn bsdf_eval(b: Bsdf, wo: vec3<f32>, wi: vec3<f32>) -> vec3<f32> {
    if b.kind == BSDF_NONE || !same_side(wo, wi) {
        return vec3<f32>(0.0);
    }
    if b.kind == BSDF_LAMBERT {
        return b.diffuse * FRAC_1_PI;
    }
    let uo = vec3<f32>(wo.x, wo.y, abs(wo.z));
    let ui = vec3<f32>(wi.x, wi.y, abs(wi.z));
    let lobe = phong_lobe(b.exponent, vec3<f32>(-uo.x, -uo.y, uo.z), ui);
    return max(b.diffuse, vec3<f32>(0.0)) * FRAC_1_PI
        + max(b.specular, vec3<f32>(0.0)) * ((b.exponent + 2.0) * 0.5 * FRAC_1_PI * lobe);
}

// Equiangular sampling (Kulla & Fajardo 2012) of t ∈ [t0, t1] on o + t·d towards c:
// returns (t, pdf), as `sampling::equiangular`.
fn equiangular(o: vec3<f32>, d: vec3<f32>, t0: f32, t1: f32, c: vec3<f32>, u: f32) -> vec2<f32> {
    let delta = dot(c - o, d);
    let co = abs(c - o);
    var scale = max(max(max(co.x, co.y), co.z), abs(t0));
    if abs(t1) <= 3.4028235e38 {
        scale = max(scale, abs(t1));
    }
    let h = max(max(length(c - (o + d * delta)), scale * 1e-6), 1.1754944e-38);
    let theta0 = atan2(t0 - delta, h);
    let theta1 = atan2(t1 - delta, h);
    let t = clamp(delta + h * tan(theta0 + u * (theta1 - theta0)), t0, t1);
    let x = t - delta;
    var pdf = h / ((theta1 - theta0) * (h * h + x * x));
    if !(abs(pdf) <= 3.4028235e38) {
        pdf = 0.0;
    }
    return vec2<f32>(t, pdf);
}
