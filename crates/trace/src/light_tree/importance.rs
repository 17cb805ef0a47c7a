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
    let a = x.abs();
    (a + a * a / (1.0 + (1.0 + a * a).sqrt())).ln_1p().copysign(x)
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
                    let l = (b - a).length();
                    let dir = (b - a) / l;
                    let w = a - o;
                    let cos = dir.dot(d);
                    let sin2 = (1.0 - cos * cos).max(0.0);
                    let u0 = if sin2 > 1e-6 {
                        (cos * d.dot(w) - dir.dot(w)) / sin2
                    } else {
                        // Parallel: the point beside the camera segment's middle.
                        (o + d * (0.5 * len) - a).dot(dir)
                    }
                    .clamp(0.0, l);
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
