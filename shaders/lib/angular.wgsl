//! use lib/gather.wgsl
//! use lib/sampling.wgsl
//! hooks AngularIntegrand angular_value
// The piecewise-linear angular PDFs of the VBL kernels (`beamlight_trace::vbl::angular`):
// vertices equally spaced in the angle a segment subtends at a fixed point, and sampling by
// them. The kernel says what the density follows: `AngularIntegrand` holds what it needs and
// `angular_value(f, t)` is the (unnormalised) vertex value at line parameter t and the
// extinction there, whose transmittance from the first vertex shapes the value (`Fading`).
//
// No table is stored: the vertex values are computed once to find the area and again, up to
// the chosen segment, to walk the CDF, with the same f32 sums in the same order both times.
// lavapipe miscompiled the 64-entry private arrays this replaced (docs/rendering.md).

// Most vertices of a piecewise-linear density (`PIECEWISE_LINEAR_MAX_VERTICES`).
const PL_MAX_VERTICES: u32 = 64u;

fn pl_clean(v: f32) -> f32 {
    return select(0.0, v, finite_f32(v) && v > 0.0);
}

// `vbl::vertex_count`: vertices for an angle range `extent` of an integrand varying on the
// angular scale `scale`; a `scale` of 0 (a density grid's values) takes the most.
fn vertex_count(extent: f32, scale: f32) -> u32 {
    let most = clamp(params.pdf_vertices, 2u, PL_MAX_VERTICES);
    if !(scale > 0.0) {
        return most;
    }
    let wanted = ceil(4.0 * abs(extent) / scale) + 1.0;
    if wanted < f32(most) {
        return max(u32(wanted), 2u);
    }
    return most;
}

// The line parameter of vertex i of k (`vbl::vertex_angle`), clamped to [t0, t1].
fn vertex_t(l: LineAngles, i: u32, k: u32, t0: f32, t1: f32) -> f32 {
    let f = f32(i) / f32(k - 1u);
    return clamp(line_t(l, l.theta0 + (l.theta1 - l.theta0) * f), t0, t1);
}

// `vbl::angular::Fading`: the optical depth from the first vertex, by the trapezoid rule over
// the vertices' extinctions in increasing t, and the last vertex's t and extinction.
struct Fading {
    depth: f32,
    t: f32,
    extinction: f32,
    started: bool,
}

fn fading_start() -> Fading {
    return Fading(0.0, 0.0, 0.0, false);
}

// `Fading::next`: e^(−τ) from the first vertex to the next one, at t with `extinction`.
fn fade_next(fd: ptr<function, Fading>, t: f32, extinction: f32) -> f32 {
    if (*fd).started {
        (*fd).depth += 0.5 * ((*fd).extinction + extinction) * (t - (*fd).t);
    }
    (*fd).started = true;
    (*fd).t = t;
    (*fd).extinction = extinction;
    return exp(-(*fd).depth);
}

// The cleaned, faded value of vertex i of k (the vertices taken in order from 0 with `fd`).
fn angular_vertex(f: AngularIntegrand, l: LineAngles, i: u32, k: u32, t0: f32, t1: f32, fd: ptr<function, Fading>) -> f32 {
    let t = vertex_t(l, i, k, t0, t1);
    let v = angular_value(f, t);
    return pl_clean(v.x * fade_next(fd, t, v.y));
}

// `vbl::sample_angular`: the line parameter t ∈ [t0, t1] by a piecewise-linear density in the
// angle about the fixed point, `angular_value` at the vertices, with about four vertices per
// unit of the integrand's angular `scale`. Returns (t, pdf in t), pdf 0 when there is nothing
// to sample. The density is `PiecewiseLinear::new(θ0, θ1, values, uniform_share)`'s, whose
// area and CDF the CPU sums in f64 and this in f32 (a change of rounding only).
fn sample_angular(l: LineAngles, f: AngularIntegrand, t0: f32, t1: f32, scale: f32, u_in: f32) -> vec2<f32> {
    let x0 = l.theta0;
    let x1 = l.theta1;
    if !(finite_f32(x0) && finite_f32(x1) && x1 > x0) {
        return vec2<f32>(t0, 0.0);
    }
    let k = vertex_count(x1 - x0, scale);
    // First pass: the area in index units.
    var area = 0.0;
    var fading = fading_start();
    var previous = angular_vertex(f, l, 0u, k, t0, t1, &fading);
    for (var i = 1u; i < k; i++) {
        let v = angular_vertex(f, l, i, k, t0, t1, &fading);
        area += 0.5 * (previous + v);
        previous = v;
    }
    var share = 0.0;
    if params.uniform_share > 0.0 {
        share = min(params.uniform_share, 1.0);
    }
    var u = 0.0;
    if u_in >= 0.0 {
        u = min(u_in, ONE_MINUS_EPSILON);
    }
    // Second pass: normalised values (unit area, then share/(n − 1) added to each) and the
    // running CDF, up to the last non-empty segment starting at or below u·total. The CDF
    // only grows, so the walk stops at the first segment starting above it. `uniform` is the
    // fallback when the values give nothing to go by: two vertices of 1.
    var n = 2u;
    var f0 = 1.0;
    var f1 = 1.0;
    var c0 = 0.0;
    var c1 = 1.0;
    var total = 1.0;
    var chosen = 0u;
    if k >= 2u && area > 0.0 && finite_f32(area) {
        n = k;
        let floor_value = share / f32(n - 1u);
        let scale_value = (1.0 - share) / area;
        // The sum of the normalised trapezoids, 1 up to rounding, from the first pass's area
        // (a third pass would give the same sum rounded in a different order).
        total = scale_value * area + floor_value * f32(n - 1u);
        if !(total > 0.0 && finite_f32(total)) {
            return vec2<f32>(t0, 0.0);
        }
        let a = u * total;
        // Segment i runs from c_i to c_{i+1}; keep the last non-empty one with c_i ≤ a (the
        // first non-empty one has c_i = 0), or the last segment when all are empty.
        chosen = n - 2u;
        var found = false;
        var walk = fading_start();
        var v0 = angular_vertex(f, l, 0u, n, t0, t1, &walk) * scale_value + floor_value;
        var c = 0.0;
        for (var i = 0u; i + 1u < n; i++) {
            if c > a {
                break;
            }
            let v1 = angular_vertex(f, l, i + 1u, n, t0, t1, &walk) * scale_value + floor_value;
            let next = c + 0.5 * (v0 + v1);
            if next > c || (!found && i + 2u == n) {
                chosen = i;
                found = true;
                f0 = v0;
                f1 = v1;
                c0 = c;
                c1 = next;
            }
            c = next;
            v0 = v1;
        }
    }
    let a = u * total;
    let seg_area = c1 - c0;
    let area_in = clamp(a - c0, 0.0, seg_area);
    let disc = max(f0 * f0 + 2.0 * (f1 - f0) * area_in, 0.0);
    let denom = f0 + sqrt(disc);
    var s = 0.0;
    if denom > 0.0 {
        s = clamp(2.0 * area_in / denom, 0.0, 1.0);
    }
    let w = (x1 - x0) / f32(n - 1u);
    let theta = clamp(x0 + (f32(chosen) + s) * w, x0, x1);
    let value = f0 + (f1 - f0) * s;
    let pdf_theta = value / (total * w);
    let t = clamp(line_t(l, theta), t0, t1);
    let pdf = select(0.0, max(pdf_theta, 0.0), finite_f32(pdf_theta)) * line_dtheta_dt(l, t);
    return vec2<f32>(t, select(0.0, pdf, finite_f32(pdf) && pdf > 0.0));
}
