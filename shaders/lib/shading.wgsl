//! use lib/sampling.wgsl
// The Henyey–Greenstein phase function and the Lambert and modified-Phong BSDFs (evaluation,
// densities, sampling): twins of `beamlight_scene::{phase, bsdf}`.

const PI: f32 = 3.14159265358979;
const FRAC_1_PI: f32 = 0.318309886183791;

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


// ---- Sampling the BSDFs and the phase function (the VBL/VSL kernels' lobe directions) ----

// Mean of the three channels (`luminance_mean`).
fn luminance_mean(c: vec3<f32>) -> f32 {
    return (c.x + c.y + c.z) * (1.0 / 3.0);
}

fn max_component(c: vec3<f32>) -> f32 {
    return max(c.x, max(c.y, c.z));
}

// Probability of sampling the Phong specular lobe: mean(ks) / (mean(kd) + mean(ks)).
fn phong_specular_probability(kd: vec3<f32>, ks: vec3<f32>) -> f32 {
    let d = luminance_mean(max(kd, vec3<f32>(0.0)));
    let s = luminance_mean(max(ks, vec3<f32>(0.0)));
    return select(0.0, s / (d + s), d + s > 0.0);
}

// Density of the Phong sampler's directions for wo, wi both in the upper hemisphere
// (`bsdf::phong_pdf`).
fn phong_pdf(p_spec: f32, n: f32, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    var diffuse = 0.0;
    if p_spec < 1.0 {
        diffuse = (1.0 - p_spec) * (max(wi.z, 0.0) * FRAC_1_PI);
    }
    var specular = 0.0;
    if p_spec > 0.0 {
        specular = p_spec * (n + 1.0) * 0.5 * FRAC_1_PI * phong_lobe(n, vec3<f32>(-wo.x, -wo.y, wo.z), wi);
    }
    return diffuse + specular;
}

// Solid-angle density of `bsdf_sample_dir` producing wi (`Bsdf::pdf`), local frame.
fn bsdf_pdf(b: Bsdf, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    if b.kind == BSDF_NONE || !same_side(wo, wi) {
        return 0.0;
    }
    if b.kind == BSDF_LAMBERT {
        return max(abs(wi.z), 0.0) * FRAC_1_PI;
    }
    let p_spec = phong_specular_probability(b.diffuse, b.specular);
    return phong_pdf(p_spec, b.exponent, vec3<f32>(wo.x, wo.y, abs(wo.z)), vec3<f32>(wi.x, wi.y, abs(wi.z)));
}

// Direction with density (n + 1)/(2π) cos^n α about r (`bsdf::sample_phong_lobe`).
fn sample_phong_lobe(n: f32, r: vec3<f32>, u: vec2<f32>) -> vec3<f32> {
    let ln_cos = log(max(1.0 - u.x, F32_MIN_POSITIVE)) / (n + 1.0);
    let one_minus_cos = -expm1(ln_cos);
    let cos_alpha = exp(ln_cos);
    let sin_alpha = sqrt(max(one_minus_cos * (2.0 - one_minus_cos), 0.0));
    let phi = TAU * u.y;
    let local = vec3<f32>(sin_alpha * cos(phi), sin_alpha * sin(phi), cos_alpha);
    return normalize_glam(to_world(frame_from_normal(r), local));
}

// `Bsdf::sample` (radiance transport) of a Lambert or Phong BSDF, the direction only:
// (wi, 1), or w = 0 where the CPU returns `None`. Local frame.
fn bsdf_sample_dir(b: Bsdf, wo: vec3<f32>, u: vec2<f32>, u_lobe: f32) -> vec4<f32> {
    let none = vec4<f32>(0.0);
    if b.kind == BSDF_LAMBERT {
        if wo.z == 0.0 || max_component(b.diffuse) <= 0.0 {
            return none;
        }
        let wi = cosine_hemisphere(u);
        if !(max(wi.z, 0.0) * FRAC_1_PI > 0.0) {
            return none;
        }
        return vec4<f32>(wi.x, wi.y, select(wi.z, -wi.z, wo.z < 0.0), 1.0);
    }
    if b.kind != BSDF_PHONG || wo.z == 0.0 {
        return none;
    }
    let p_spec = phong_specular_probability(b.diffuse, b.specular);
    if max_component(max(b.diffuse, vec3<f32>(0.0))) <= 0.0 && max_component(max(b.specular, vec3<f32>(0.0))) <= 0.0 {
        return none;
    }
    let wo_up = vec3<f32>(wo.x, wo.y, abs(wo.z));
    var wi: vec3<f32>;
    if u_lobe < p_spec {
        wi = sample_phong_lobe(b.exponent, vec3<f32>(-wo_up.x, -wo_up.y, wo_up.z), u);
    } else {
        wi = cosine_hemisphere(u);
    }
    if !(wi.z > 0.0) {
        return none;
    }
    if !(phong_pdf(p_spec, b.exponent, wo_up, wi) > 0.0) {
        return none;
    }
    return vec4<f32>(wi.x, wi.y, select(wi.z, -wi.z, wo.z < 0.0), 1.0);
}

// `phase::hg_sample_cos_theta`: (1 − cos θ, 1 + cos θ) for the uniform number u.
fn hg_sample_cos_theta(g_in: f32, u_in: f32) -> vec2<f32> {
    let g = clamp(g_in, -HG_MAX_ABS_G, HG_MAX_ABS_G);
    let u = clamp(u_in, 0.0, 1.0);
    let v = 1.0 - u;
    var d: f32;
    var one_plus_gu: f32;
    var one_minus_g_plus_gu: f32;
    if g >= 0.0 {
        d = (1.0 - g) + 2.0 * g * u;
        one_plus_gu = 1.0 + g * u;
        one_minus_g_plus_gu = (1.0 - g) + g * u;
    } else {
        d = (1.0 + g) - 2.0 * g * v;
        one_plus_gu = (1.0 + g) - g * v;
        one_minus_g_plus_gu = 1.0 - g * v;
    }
    let d2 = d * d;
    let one_minus_cos = 2.0 * (1.0 - g) * (1.0 - g) * v * one_plus_gu / d2;
    let one_plus_cos = 2.0 * (1.0 + g) * (1.0 + g) * u * one_minus_g_plus_gu / d2;
    return vec2<f32>(clamp(one_minus_cos, 0.0, 2.0), clamp(one_plus_cos, 0.0, 2.0));
}

// `HenyeyGreenstein::sample(wo, u).wi`: θ measured from the light's travel direction −wo.
fn hg_sample_dir(g: f32, wo: vec3<f32>, u: vec2<f32>) -> vec3<f32> {
    let c = hg_sample_cos_theta(g, u.x);
    var cos_theta: f32;
    if c.x <= c.y {
        cos_theta = 1.0 - c.x;
    } else {
        cos_theta = c.y - 1.0;
    }
    let sin_theta = sqrt(max(c.x * c.y, 0.0));
    let phi = TAU * u.y;
    let local = vec3<f32>(sin_theta * cos(phi), sin_theta * sin(phi), cos_theta);
    return normalize_glam(to_world(frame_from_normal(-wo), local));
}
