//! A node's importance for a receiver: the cheap bound of its lights' contribution that light
//! selection descends by (the rules are in the parent module's documentation), and what it is
//! taken for, a [`Receiver`].
use super::{LightTreeNode, fade_length, free_path};
use crate::camera_paths::{MediaSegment, ShadingPoint};
use beamlight_scene::{Rgb, Scene, bsdf::Bsdf, luminance_mean};
use glam::{Vec2, Vec3};

/// What receives light: a camera shading point or a camera media segment.
#[derive(Clone, Copy, Debug)]
pub enum Receiver {
    /// A shading point and its normal on the side light is gathered from.
    Point { p: Vec3, n: Vec3, gloss: Gloss },
    /// A stretch `o + d t`, t in [0, len], of a camera ray in a medium of phase function g.
    Segment { o: Vec3, d: Vec3, len: f32, g: f32 },
}

/// A shading point's BSDF as the importance sees it: the modified Phong lobe
/// `diffuse + specular · (n + 2)/2 · cosⁿ(angle to mirror)` (the BSDF times π, mean over
/// channels); Lambert is `specular` = 0, where the factor is the same for every light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gloss {
    pub mirror: Vec3,
    pub exponent: f32,
    pub diffuse: f32,
    pub specular: f32,
}

impl Gloss {
    pub const LAMBERT: Gloss = Gloss {
        mirror: Vec3::Z,
        exponent: 0.0,
        diffuse: 1.0,
        specular: 0.0,
    };

    /// The gloss of BSDF `b` at a point with shading normal `n` seen from `wo`.
    pub fn of(b: Option<Bsdf>, n: Vec3, wo: Vec3) -> Gloss {
        match b {
            Some(Bsdf::Phong {
                diffuse,
                specular,
                exponent,
            }) => Gloss {
                mirror: n * (2.0 * n.dot(wo)) - wo,
                // The CPU's exponent sanitising (as `gather::resolve_bsdf` does for the GPU).
                exponent: if exponent.is_nan() {
                    0.0
                } else {
                    exponent.clamp(0.0, 1e7)
                },
                diffuse: luminance_mean(diffuse.max(Rgb::ZERO)),
                specular: luminance_mean(specular.max(Rgb::ZERO)),
            },
            Some(Bsdf::Lambert { albedo }) => Gloss {
                diffuse: luminance_mean(albedo.max(Rgb::ZERO)),
                ..Gloss::LAMBERT
            },
            _ => Gloss {
                diffuse: 0.0,
                ..Gloss::LAMBERT
            },
        }
    }

    /// The largest factor over directions within the cone of half-angle α (cos α, sin α) about
    /// `axis`, floored at 10⁻⁴ of the peak so that rounding never zeroes a reachable light
    /// (0 only for a black BSDF, which gathers nothing).
    fn max_in_cone(&self, axis: Vec3, cos_a: f32, sin_a: f32, inside: bool) -> f32 {
        let peak = self.specular * (self.exponent + 2.0) * 0.5;
        if peak == 0.0 {
            return self.diffuse;
        }
        let lobe = if inside {
            1.0
        } else {
            let cos_t = self.mirror.dot(axis).clamp(-1.0, 1.0);
            let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            let c = if cos_t >= cos_a {
                1.0
            } else {
                cos_t * cos_a + sin_t * sin_a
            };
            c.max(0.0).powf(self.exponent)
        };
        (self.diffuse + peak * lobe).max(1e-4 * (self.diffuse + peak))
    }
}

impl Receiver {
    /// A camera shading point, gathering on the side of its normal (the side of `wo`).
    pub fn at_point(scene: &Scene, sp: &ShadingPoint) -> Receiver {
        let n = Vec3::from(sp.normal);
        Receiver::Point {
            p: Vec3::from(sp.pos),
            n,
            gloss: Gloss::of(
                scene.bsdf_at(sp.material, Some(Vec2::from(sp.uv))),
                n,
                Vec3::from(sp.wo),
            ),
        }
    }

    /// A camera media segment.
    pub fn along_segment(scene: &Scene, seg: &MediaSegment) -> Receiver {
        Receiver::Segment {
            o: Vec3::from(seg.origin),
            d: Vec3::from(seg.dir),
            len: seg.length,
            g: scene.media[seg.medium as usize].g,
        }
    }
}

/// A Henyey–Greenstein phase function of asymmetry `g` for light turning by angle θ (cos θ
/// between the directions of travel before and after), relative to the isotropic 1/(4π):
/// (1 − g²) / (1 + g² − 2g cos θ)^(3/2). Positive for |g| < 1.
fn phase_ratio(g: f32, cos: f32) -> f32 {
    let q = (1.0 + g * g - 2.0 * g * cos).max(1e-12);
    (1.0 - g * g) / (q * q.sqrt())
}

/// asinh(x) = ln(1 + |x| + x²/(1 + √(1 + x²))) with the sign of x, accurate near 0 (as the
/// WGSL twin computes it: the GPU's own `asinh` may cancel there, and a choice in the descent
/// would then differ from the CPU's).
fn asinh(x: f32) -> f32 {
    exp_asinh_m1(x.abs()).ln_1p().copysign(x)
}

/// The phase ratio for light travelling along `travel` that turns towards `to` (neither need
/// be unit; 1 when either has no length).
fn phase_towards(g: f32, travel: Vec3, to: Vec3) -> f32 {
    let len = travel.length() * to.length();
    if len > 0.0 {
        phase_ratio(g, (travel.dot(to) / len).clamp(-1.0, 1.0))
    } else {
        1.0
    }
}

/// The density of a segment light's scattered light at `t` along it (length `len`, fading
/// with `sigma_t`), normalised over the segment: e^(−σt t) / ∫₀^L e^(−σt u) du.
fn fade_density(sigma_t: f32, len: f32, t: f32) -> f32 {
    (-sigma_t * t).exp() / fade_length(sigma_t, len)
}

/// A node's importance for a receiver (see the module documentation); `r` is the pass's VBL
/// radius. Positive unless the node provably cannot light the receiver. The WGSL twin is
/// `light_importance` in `shaders/lib/light_tree.wgsl`.
pub fn importance(node: &LightTreeNode, rx: &Receiver, r: f32) -> f32 {
    let (lo, hi) = (Vec3::from(node.lo), Vec3::from(node.hi));
    let c = 0.5 * (lo + hi);
    let half = 0.5 * (hi - lo);
    let rb = half.length();
    let r = r.max(1e-12);
    // A leaf's segment light (a VBL): its own geometry instead of its box's.
    let segment = (node.is_leaf() && lo != hi).then(|| node.segment());
    match *rx {
        Receiver::Point { p, n, gloss } => {
            // Highest point of the box (grown by R) above the tangent plane.
            let top = n.dot(c - p) + n.abs().dot(half) + r;
            // Segment lights' bounds leave out their faint far ends ([`CLIP_FREE_PATHS`]),
            // which may still reach above the horizon: only point lights are culled.
            if top < 0.0 && node.sigma_t == 0.0 {
                return 0.0;
            }
            // The cosine and the BSDF bounded over the cone of the box's bounding sphere
            // grown by R (all directions when p is inside it).
            let to = c - p;
            let dc = to.length();
            let reach = rb + r;
            let inside = dc <= reach;
            let axis = if inside { n } else { to / dc };
            let sin_a = if inside { 1.0 } else { reach / dc };
            let cos_a = (1.0 - sin_a * sin_a).max(0.0).sqrt();
            let cos_bound = if inside {
                1.0
            } else {
                let cos_t = n.dot(axis).clamp(-1.0, 1.0);
                let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                // cos(θ − α) when θ > α, else 1 (the normal points into the cone).
                if cos_t >= cos_a {
                    1.0
                } else {
                    cos_t * cos_a + sin_t * sin_a
                }
            };
            let f = gloss.max_in_cone(axis, cos_a, sin_a, inside);
            match segment {
                // A segment: its light's density along it at the point closest to p times
                // ∫ cos θ dt / (H² + (t − t₀)²) over the part above the horizon (H the
                // distance floored at R; the cosine's height lifted by R, as the sphere
                // reaches that far above its centre), or if larger all of it at the start.
                // Segments start on surfaces, often the receiver's own: their light arrives at
                // grazing angles there, which the box's cosine bound would not see.
                Some((a, b)) => {
                    let len = (b - a).length();
                    let dir = (b - a) / len;
                    let v = p - a;
                    let t0 = v.dot(dir);
                    let d2 = v.length_squared();
                    let h = (d2 - t0 * t0).max(0.0).sqrt().max(r);
                    // The height above the tangent plane plus R: e(t) = e0 + β t.
                    let (e0, beta) = (n.dot(a - p) + r, n.dot(dir));
                    let (mut lo_t, mut hi_t) = (0.0f32, len);
                    if beta > 0.0 {
                        lo_t = lo_t.max(-e0 / beta);
                    } else if beta < 0.0 {
                        hi_t = hi_t.min(-e0 / beta);
                    } else if e0 < 0.0 {
                        hi_t = lo_t;
                    }
                    // With s = t − t₀: ∫ (α + β s) / (H² + s²)^(3/2) ds, α = e(t₀), over the
                    // part of [t_a, t_b] above the horizon.
                    let alpha = e0 + beta * t0;
                    let prim = |s: f32| {
                        let q = (h * h + s * s).sqrt();
                        alpha * s / (h * h * q) - beta / q
                    };
                    let cosine_line = |t_a: f32, t_b: f32| {
                        let (t_a, t_b) = (t_a.max(lo_t), t_b.min(hi_t));
                        if t_b > t_a {
                            (prim(t_b - t0) - prim(t_a - t0)).max(0.0)
                        } else {
                            0.0
                        }
                    };
                    // The density at the closest point over the whole segment, or the least
                    // density of its first mean free path over that stretch (where a fast
                    // fading segment's light is).
                    let closest = fade_density(node.sigma_t, len, t0.clamp(0.0, len)) * cosine_line(0.0, len);
                    let first = free_path(node.sigma_t, len);
                    let start = fade_density(node.sigma_t, len, first) * cosine_line(0.0, first);
                    // A floor for rounding (and for the faint end beyond the clipped bounds).
                    let floor = 1e-3 / d2.max(r * r);
                    // (No phase function here: taken at the closest point alone it misjudges
                    // VBLs that pass a shading point, whose light reaches it from along their
                    // whole length; in the glossy-floor box it doubled the worst `Lsm` pixel.)
                    node.weight * f * closest.max(start).max(floor)
                }
                None => {
                    let falloff = 1.0 / (c - p).length_squared().max(rb * rb).max(r * r);
                    // The box reaches above the horizon (top ≥ 0): keep a floor so that
                    // rounding in the bound never gives such a box a zero probability.
                    node.weight * f * cos_bound.max(1e-3) * falloff
                }
            }
        }
        Receiver::Segment { o, d, len, g } => {
            // The point of the camera segment closest to y.
            let nearest = |y: Vec3| o + d * (y - o).dot(d).clamp(0.0, len);
            // ∫₀^len dt / (h² + (t − tc)²) = (atan((len − tc)/h) + atan(tc/h)) / h along the
            // camera segment, seen from the light's point `y` at distance h from its line.
            let seen_from = |y: Vec3, floor: f32| {
                let v = y - o;
                let tc = v.dot(d);
                let h = (v.length_squared() - tc * tc).max(0.0).sqrt().max(floor).max(r);
                (((len - tc).atan2(h) + tc.atan2(h)).max(0.0), h)
            };
            match segment {
                // A segment light: ∫ ρ(u) du ∫ dt / d², ρ its light's density along it, with
                // ρ and the angle the camera segment subtends taken at the light's point
                // closest to the camera line and the distance growing like
                // √(H² + (u − u₀)² sin²θ) away from it: ρ(u₀) · angle ·
                // [asinh((L − u₀) s/H) + asinh(u₀ s/H)] / s, s = sin θ; or if larger, all of
                // the light at the start.
                Some((a, b)) => {
                    let Closest { l, dir, u0, sin2 } = Closest::of(a, b, o, d, len);
                    let (angle, h) = seen_from(a + dir * u0, 0.0);
                    let s = sin2.sqrt().max(1e-3);
                    let along = (asinh((l - u0) * s / h) + asinh(u0 * s / h)) / s;
                    let closest = fade_density(node.sigma_t, l, u0) * angle * along;
                    // The least density of the first mean free path over that stretch, seen
                    // from its start (where a fast fading segment's light is).
                    let first = free_path(node.sigma_t, l);
                    let (angle_a, h_a) = seen_from(a, 0.0);
                    let start = fade_density(node.sigma_t, l, first) * angle_a * asinh(first * s / h_a) / s;
                    // Both phase functions between the two closest points: the VBL's turning
                    // its light towards the camera segment, the camera medium's turning it
                    // towards the camera.
                    let y = a + dir * u0;
                    let to = nearest(y) - y;
                    let phase = phase_towards(node.g, dir, to) * phase_towards(g, to, -d);
                    node.weight * phase * closest.max(start)
                }
                None => {
                    let (angle, h) = seen_from(c, rb);
                    // A point light's leaf: the camera medium's phase function turning its
                    // light towards the camera.
                    let phase = if node.is_leaf() {
                        phase_towards(g, nearest(c) - c, -d)
                    } else {
                        1.0
                    };
                    node.weight * phase * angle / h
                }
            }
        }
    }
}

/// A segment light `a`→`b` seen from the camera line `o + d t` (a segment of length `len`):
/// its length and direction, its point u₀ closest to the line (for parallel lines the one
/// beside the camera segment's middle), clamped to it, and the squared sine between the lines.
struct Closest {
    l: f32,
    dir: Vec3,
    u0: f32,
    sin2: f32,
}

impl Closest {
    fn of(a: Vec3, b: Vec3, o: Vec3, d: Vec3, len: f32) -> Closest {
        let l = (b - a).length();
        let dir = (b - a) / l;
        let w = a - o;
        let cos = dir.dot(d);
        let sin2 = (1.0 - cos * cos).max(0.0);
        let u0 = if sin2 > 1e-6 {
            (cos * d.dot(w) - dir.dot(w)) / sin2
        } else {
            (o + d * (0.5 * len) - a).dot(dir)
        }
        .clamp(0.0, l);
        Closest { l, dir, u0, sin2 }
    }
}

/// A leaf's importance for a flat draw ([`super::LightTree::flat_masses`]): for a VBL leaf and
/// a camera segment the pair integral itself (below), otherwise [`importance`].
pub fn flat_importance(node: &LightTreeNode, rx: &Receiver, r: f32) -> f32 {
    let r = r.max(1e-12);
    let (Receiver::Segment { o, d, len, g }, true) = (*rx, node.is_leaf() && node.lo != node.hi) else {
        return importance(node, rx, r);
    };
    let (a, b) = node.segment();
    // A segment light: ∫ ρ(u) du ∫ F dt / d², ρ its light's density along it and
    // F the two phase functions at the pair's own direction ([`Phases`]). Along
    // the light in z, u − u₀ = (H/s) sinh z (u₀ its point closest to the camera
    // line, H that distance floored at R, s the sine between the lines), where
    // du / dist(y(u), camera line) is flat: two Gauss–Legendre points. One point,
    // the middle of the z range, is cheaper and in the glossy fog box nearly as
    // good (a draw's relative variance 2.5 against 2.0, `examples/lmm_variance.rs`),
    // but for lights running against the camera ray, whose light reaches the
    // camera from the stretch beside the camera segment only, it can sit beyond
    // that stretch: against the pair integral by quadrature (crates/trace/tests/
    // light_tree.rs, a third of the configurations such lights) the 5 % quantile of
    // importance / integral was 0.023 with one point, 0.43 with two. Or, if larger, a
    // light fading within its length: its first mean free path seen from its start.
    let Closest { l, dir, u0, sin2 } = Closest::of(a, b, o, d, len);
    let s = sin2.sqrt().max(1e-3);
    let phases = Phases {
        dir,
        g_light: node.g,
        o,
        d,
        len,
        g,
        r,
    };
    let big_h = phases.off_line(a + dir * u0).1;
    // z_b = asinh(B), z_a = −asinh(A): e^(z_b) = 1 + p, e^(−z_a) = 1 + q, so the
    // middle's e^z = √((1 + p)/(1 + q)) and the range z_b − z_a = ln((1 + p)(1 + q)).
    let (p, q) = (exp_asinh_m1((l - u0) * s / big_h), exp_asinh_m1(u0 * s / big_h));
    // (ln, not ln_1p: an importance needs no more, and ln is the cheaper.)
    let span = (1.0 + (p + q + p * q)).ln();
    let e = ((1.0 + p) / (1.0 + q)).sqrt();
    let mut value = 0.0;
    // Two Gauss–Legendre points in z, at z_mid ± (span/2)/√3 (weights 1).
    for x in [-FRAC_1_SQRT_3, FRAC_1_SQRT_3] {
        let ek = e * (0.5 * span * x).exp();
        let u = (u0 + big_h / s * 0.5 * (ek - 1.0 / ek)).clamp(0.0, l);
        // du = (H/s) cosh z dz.
        let jacobian = 0.5 * span * big_h / s * 0.5 * (ek + 1.0 / ek);
        value += fade_density(node.sigma_t, l, u) * phases.seen_from(a + dir * u) * jacobian;
    }
    if node.sigma_t * l > 1.0 {
        let first = 1.0 / node.sigma_t;
        let h_a = phases.off_line(a).1;
        let start = phases.seen_from(a) * asinh(first * s / h_a) / s * h_a;
        value = value.max(fade_density(node.sigma_t, l, first) * start);
    }
    node.weight * value
}

/// The phase functions between a segment light (direction `dir`, HG `g_light`) and a camera
/// segment `o + d t`, t in [0, len], of HG `g`, for [`Phases::seen_from`].
struct Phases {
    dir: Vec3,
    g_light: f32,
    o: Vec3,
    d: Vec3,
    len: f32,
    g: f32,
    r: f32,
}

impl Phases {
    /// ∫ F(x(t) − y) dt / |x(t) − y|² along the camera segment from the light's point `y`,
    /// F the light's phase function turning its light towards x times the camera medium's
    /// turning it towards the camera, y's distance h to the camera line floored at r. With
    /// t − t_c = h tan φ the integral is (1/h) ∫ F dφ over the angle the segment subtends,
    /// here by the midpoint rule on eight panels, the directions found by bisection: no
    /// trigonometry but one arctangent, for the angle (`examples/lmm_variance.rs`, measured
    /// with one point along the VBL: a draw's variance 2.5 at 0.27 µs a light; four panels 3.2
    /// at 0.22 µs; Simpson's rule, whose end points sit on the phase functions' forward peaks,
    /// 19).
    ///
    /// Why the phase functions at every direction and not at the closest points (a right
    /// angle): a light running against the camera ray close beside it sends its light
    /// forward along the ray from every point of it, where both phase functions peak (HG g =
    /// 0.7: 19× isotropic each, against 0.28× at a right angle); taken at the closest points
    /// its importance was some 4 600× too small, and in the glossy fog box such lights were
    /// drawn with p ≈ 1.5·10⁻³ where they carry a quarter of a segment's light (measured
    /// with `examples/lmm_variance.rs`).
    fn seen_from(&self, y: Vec3) -> f32 {
        let (tc, h, n) = self.off_line(y);
        // Directions to the camera point as (cos φ, sin φ) about n: cos φ n + sin φ d.
        let unit = |c: f32, s: f32| {
            let k = 1.0 / (c * c + s * s).sqrt();
            (c * k, s * k)
        };
        let (a, b) = (unit(h, -tc), unit(h, self.len - tc));
        let angle = arc_angle(a.0 * b.1 - a.1 * b.0, a.0 * b.0 + a.1 * b.1);
        let (dir_n, dir_d) = (self.dir.dot(n), self.dir.dot(self.d));
        let f = |(c, s): (f32, f32)| phase_ratio(self.g_light, c * dir_n + s * dir_d) * phase_ratio(self.g, -s);
        // The midpoint rule on eight panels: the directions at 1/16, 3/16, …, 15/16 of the
        // angle, by bisection (h > 0 keeps the angle below π). The bisector of two unit
        // vectors at angle θ is their sum over 2 cos(θ/2), the same for every pair of a level.
        let level = |p: (f32, f32), q: (f32, f32)| {
            let (x, y) = (p.0 + q.0, p.1 + q.1);
            1.0 / (x * x + y * y).sqrt()
        };
        let mid = |p: (f32, f32), q: (f32, f32), k: f32| ((p.0 + q.0) * k, (p.1 + q.1) * k);
        let k1 = level(a, b);
        let m = mid(a, b, k1);
        let k2 = level(a, m);
        let (q1, q3) = (mid(a, m, k2), mid(m, b, k2));
        let k3 = level(a, q1);
        let (e1, e3, e5, e7) = (mid(a, q1, k3), mid(q1, m, k3), mid(m, q3, k3), mid(q3, b, k3));
        let k4 = level(a, e1);
        let sum = f(mid(a, e1, k4))
            + f(mid(e1, q1, k4))
            + f(mid(q1, e3, k4))
            + f(mid(e3, m, k4))
            + f(mid(m, e5, k4))
            + f(mid(e5, q3, k4))
            + f(mid(q3, e7, k4))
            + f(mid(e7, b, k4));
        0.125 * angle * sum / h
    }

    /// Where `y` lies from the camera line: its foot's parameter t_c, its distance floored at
    /// r, and the unit direction from y towards the line, perpendicular to it (for y on the
    /// line: the light's direction's perpendicular part, or any perpendicular when that is
    /// parallel too).
    fn off_line(&self, y: Vec3) -> (f32, f32, Vec3) {
        let v = y - self.o;
        let tc = v.dot(self.d);
        let perp = v - self.d * tc;
        let dist = perp.length();
        let n = if dist > 0.0 {
            -perp / dist
        } else {
            let q = self.dir - self.d * self.dir.dot(self.d);
            if q.length_squared() > 1e-12 {
                q.normalize()
            } else {
                // Any perpendicular.
                let other = if self.d.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
                self.d.cross(other).normalize()
            }
        };
        (tc, dist.max(self.r), n)
    }
}

/// 1/√3, the two-point Gauss–Legendre rule's nodes on [−1, 1].
const FRAC_1_SQRT_3: f32 = 0.577_350_26;

/// e^(asinh x) − 1 = x + x²/(1 + √(1 + x²)) for x ≥ 0, accurate near 0.
fn exp_asinh_m1(x: f32) -> f32 {
    x + x * x / (1.0 + (1.0 + x * x).sqrt())
}

/// The angle in [0, π] of a direction (cos, sin) = (`x`, `y`) with `y` ≥ 0 (negative `y` is
/// taken as 0), by a polynomial for atan on [0, 1] (Abramowitz & Stegun 4.4.49, error
/// ≤ 1·10⁻⁵) with the octants folded onto it: only +, −, ×, ÷, a fifth of the cost of
/// `atan2`.
fn arc_angle(y: f32, x: f32) -> f32 {
    let y = y.max(0.0);
    let atan01 = |t: f32| {
        let t2 = t * t;
        t * (0.999_866 + t2 * (-0.330_299_5 + t2 * (0.180_141 + t2 * (-0.085_133 + t2 * 0.020_835_1))))
    };
    if y == 0.0 {
        return if x < 0.0 { std::f32::consts::PI } else { 0.0 };
    }
    if x >= y {
        atan01(y / x)
    } else if x >= -y {
        std::f32::consts::FRAC_PI_2 - atan01(x / y)
    } else {
        std::f32::consts::PI - atan01(y / -x)
    }
}
