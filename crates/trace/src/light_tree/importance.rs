//! A node's importance for a receiver: the cheap bound of its lights' contribution that light
//! selection descends by (the rules are in the parent module's documentation), and what it is
//! taken for, a [`Receiver`].
use super::{LightTreeNode, fade_length, free_path};
use crate::{
    camera_paths::{MediaSegment, ShadingPoint},
    light_paths::SurfaceVertex,
};
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
    /// (0 only for a black BSDF, which gathers nothing). For a `sphere` (one VSL, whose
    /// light arrives from every direction of the cone) the lobe's mean over the cone
    /// instead, at most its integral over the cone's solid angle (as [`Emission::towards`]):
    /// the largest value overrates a near VSL by up to (n + 2)/2. Not for boxes of lights or
    /// for VBLs, whose light may all arrive from the lobe's direction (with the mean there,
    /// a glossy floor's worst `Lsm` pixel doubled, `vbl_progressive.rs`).
    fn in_cone(&self, axis: Vec3, cos_a: f32, sin_a: f32, inside: bool, sphere: bool) -> f32 {
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
        let lobe = if sphere {
            let one_minus_cos = if inside { 1.0 } else { sin_a * sin_a / (1.0 + cos_a) };
            (peak * lobe).min(peak / ((self.exponent + 1.0) * one_minus_cos.max(1e-12)))
        } else {
            peak * lobe
        };
        (self.diffuse + lobe).max(1e-4 * (self.diffuse + peak))
    }
}

/// The directions a tree node's lights send their light in, as the importance weighs them. A
/// VSL on a modified Phong surface sends it in a lobe about the mirror direction of the light
/// it received: its outgoing factor relative to its selection weight's albedo is
/// `base + peak · cosⁿ(angle to the mirror direction)`, base = d/(d + s) and peak =
/// s/(d + s) · (n + 2)/2 (means over channels, as [`Gloss`]), which on car paint (n = 100)
/// reaches 40× its weight's share in the lobe and falls to a fifth outside. A node holds the
/// share of its weight that such lights carry and bounds their factors by the largest base and
/// peak, the smallest exponent and a cone around every lobe's axis; the rest of its weight
/// (Lambert VSLs, VBLs) has factor 1. Bounding the whole node's weight instead sent the
/// descent into every node with one glossy VSL whose lobe might face the receiver
/// (cars_small, `Lss`: a draw's error against gathering every VSL 5× higher than without
/// lobes). `share` 0: no lobes, every factor 1, as the tree weighed lights before.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Emission {
    /// The share of the node's weight its lights with lobes carry.
    pub share: f32,
    pub axis: Vec3,
    /// cos of the half-angle of the cone about `axis` that holds every lobe's axis.
    pub cos_spread: f32,
    pub base: f32,
    pub peak: f32,
    pub exponent: f32,
}

impl Emission {
    /// No lobe: every factor is 1.
    pub const NONE: Emission = Emission {
        share: 0.0,
        axis: Vec3::ZERO,
        cos_spread: 0.0,
        base: 0.0,
        peak: 0.0,
        exponent: 0.0,
    };

    /// The lobe of a VSL at `vpl` (none unless its BSDF is modified Phong with a specular part).
    pub fn of_vsl(scene: &Scene, vpl: &SurfaceVertex) -> Emission {
        let Some(Bsdf::Phong {
            diffuse,
            specular,
            exponent,
        }) = scene.bsdf_at(vpl.material, Some(Vec2::new(vpl.u, vpl.v)))
        else {
            return Emission::NONE;
        };
        let d = luminance_mean(diffuse.max(Rgb::ZERO));
        let s = luminance_mean(specular.max(Rgb::ZERO));
        let (n, wi) = (Vec3::from(vpl.normal), Vec3::from(vpl.wi));
        // The exponent sanitised as `Gloss::of` does.
        let exponent = if exponent.is_nan() {
            0.0
        } else {
            exponent.clamp(0.0, 1e7)
        };
        let Some(axis) = (n * (2.0 * n.dot(wi)) - wi).try_normalize() else {
            return Emission::NONE;
        };
        if !(s > 0.0 && d >= 0.0 && (d + s).is_finite()) {
            return Emission::NONE;
        }
        Emission {
            share: 1.0,
            axis,
            cos_spread: 1.0,
            base: d / (d + s),
            peak: s / (d + s) * (exponent + 2.0) * 0.5,
            exponent,
        }
    }

    /// The bound over `lights` (each with its selection weight): [`Emission::NONE`] when none
    /// has a lobe; else the share of the weight in lights with lobes, and their largest base
    /// and peak, smallest exponent and the cone around their axes.
    pub fn bound(lights: impl Iterator<Item = (Emission, f32)>) -> Emission {
        let (mut out, mut lobed, mut all) = (None::<Emission>, 0.0f32, 0.0f32);
        for (e, weight) in lights {
            all += weight;
            if e.share > 0.0 {
                lobed += weight * e.share;
                out = Some(match out {
                    None => e,
                    Some(o) => o.merged(&e),
                });
            }
        }
        match out {
            Some(o) if lobed > 0.0 && all > 0.0 => Emission {
                share: (lobed / all).min(1.0),
                ..o
            },
            _ => Emission::NONE,
        }
    }

    /// Two lobe bounds as one: the cone holding both cones (the whole sphere when they face
    /// apart), the larger base and peak, the smaller exponent.
    fn merged(&self, other: &Emission) -> Emission {
        let (axis, cos_spread) = cone_union((self.axis, self.cos_spread), (other.axis, other.cos_spread));
        Emission {
            share: 1.0,
            axis,
            cos_spread,
            base: self.base.max(other.base),
            peak: self.peak.max(other.peak),
            exponent: self.exponent.min(other.exponent),
        }
    }

    /// The factor towards a receiver that sees the node's lights within the cone of
    /// half-angle α (cos α, sin α) about `towards` (unit, from the lights to the receiver),
    /// every direction when `everywhere`: 1 without lobes; else 1 − share + share · (base +
    /// the lobed part), floored at 10⁻⁴ of base + peak so that rounding never zeroes a light
    /// that can contribute.
    ///
    /// The lobed part is the lobe's mean over the cone rather than its largest value in it: a
    /// VSL is a sphere, and its light reaches the receiver from every direction of the cone, so
    /// its contribution follows the lobe averaged over the cone. That mean is at most the
    /// largest value, peak · cosⁿ(the least angle between the cone and the lobes' cone), and at
    /// most the whole lobe over the cone's solid angle, peak · 2π/(n + 1) / (2π (1 − cos α)).
    /// The largest value alone overrated every VSL whose sphere the receiver sees wide (near
    /// ones, and every node high in the tree) by up to (n + 2)/2.
    pub fn towards(&self, towards: Vec3, cos_a: f32, sin_a: f32, everywhere: bool) -> f32 {
        if self.share == 0.0 {
            return 1.0;
        }
        let c = largest_cos(self.axis, self.cos_spread, towards, cos_a, sin_a, everywhere);
        let lobe = if c < 1.0 { c.max(0.0).powf(self.exponent) } else { 1.0 };
        // 1 − cos α without cancellation (a hemisphere when the receiver is inside the cone).
        let one_minus_cos = if everywhere { 1.0 } else { sin_a * sin_a / (1.0 + cos_a) };
        let mean = self.peak / ((self.exponent + 1.0) * one_minus_cos.max(1e-12));
        let lobed = (self.base + (self.peak * lobe).min(mean)).max(1e-4 * (self.base + self.peak));
        1.0 - self.share + self.share * lobed
    }
}

/// The cone (unit axis, cosine of its half-angle) that holds two cones: one of them when it
/// holds the other, else the cone whose edge touches both far edges, its axis turned from the
/// first's towards the second's in their common plane (the whole sphere, cosine −1, when they
/// face apart).
pub fn cone_union(a: (Vec3, f32), b: (Vec3, f32)) -> (Vec3, f32) {
    let angle = |c: f32| c.clamp(-1.0, 1.0).acos();
    let (t1, t2) = (angle(a.1), angle(b.1));
    let between = angle(a.0.dot(b.0));
    if between + t2 <= t1 {
        return a;
    }
    if between + t1 <= t2 {
        return b;
    }
    let t = 0.5 * (t1 + between + t2);
    match a.0.cross(b.0).try_normalize() {
        Some(normal) if t < std::f32::consts::PI => (glam::Quat::from_axis_angle(normal, t - t1) * a.0, t.cos()),
        _ => (a.0, -1.0),
    }
}

/// The largest cosine between a direction in the cone of unit `axis` and half-angle σ (cos σ =
/// `cos_s`) and one in the cone of half-angle α (cos α, sin α) about `towards`, every
/// direction when `everywhere`: the cone about `towards` widened to α + σ (the whole sphere
/// beyond π), then the least angle from `axis` to it.
fn largest_cos(axis: Vec3, cos_s: f32, towards: Vec3, cos_a: f32, sin_a: f32, everywhere: bool) -> f32 {
    let sin_s = (1.0 - cos_s * cos_s).max(0.0).sqrt();
    let cos_w = cos_a * cos_s - sin_a * sin_s;
    let sin_w = sin_a * cos_s + cos_a * sin_s;
    if everywhere || sin_w < 0.0 {
        return 1.0;
    }
    let cos_t = axis.dot(towards).clamp(-1.0, 1.0);
    if cos_t >= cos_w {
        return 1.0;
    }
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    cos_t * cos_w + sin_t * sin_w
}

/// [`largest_cos`] for a node's normals' cone, floored at 10⁻³ (a sphere light's rim may
/// still reach).
pub fn facing(axis: Vec3, cos_s: f32, towards: Vec3, cos_a: f32, sin_a: f32, everywhere: bool) -> f32 {
    largest_cos(axis, cos_s, towards, cos_a, sin_a, everywhere).max(1e-3)
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
            let sphere = node.is_leaf() && segment.is_none();
            let mut f = gloss.in_cone(axis, cos_a, sin_a, inside, sphere)
                * node.emission().towards(-axis, cos_a, sin_a, inside);
            if node.normal != [0.0; 3] {
                let normal = Vec3::from(node.normal);
                f *= if node.is_leaf() {
                    // A VSL gathers as a disc of radius R in its surface: p sees it from its
                    // height h above that plane, at a distance of at least max(h, d − R), and
                    // nothing from behind it or within it.
                    let h = normal.dot(p - c);
                    (h / h.max(dc - r).max(1e-12)).clamp(1e-3, 1.0)
                } else {
                    facing(normal, node.normal_cos, -axis, cos_a, sin_a, inside)
                };
            }
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
                    // The distance² floored where p is inside or near the box. For points,
                    // at rb² (the mean of 1/d² over a ball of radius rb around p is 3/rb²).
                    // For segment lights (σt > 0: VBLs) at rb·R: a point among segments is
                    // passed by some at a distance of order R, whose light falls off like
                    // 1/(h·length) (the leaves' line integral), far slower than 1/rb², so the
                    // rb² floor starved the branch holding a VBL that passes the receiver (in
                    // the furnace a VBL carrying 1.7 % of `Lsm` was drawn with probability
                    // 3.3e-5 under boxes 25 units wide). Measured, `vbl --only Lsm` at 96²
                    // and 8 passes, relMSE between seeds: 0.35–0.86 of the rb² floor's.
                    let floor2 = if node.sigma_t > 0.0 { rb * r } else { rb * rb };
                    let falloff = 1.0 / (c - p).length_squared().max(floor2).max(r * r);
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

/// [`importance`] of a point light's leaf (a VSL) for a shading point, the same terms with
/// what a box of no size leaves of them: a flat VSL draw weighs every VSL for every record,
/// and this is most of its cost.
fn point_leaf_importance(node: &LightTreeNode, p: Vec3, n: Vec3, gloss: &Gloss, r: f32) -> f32 {
    let c = Vec3::from(node.lo);
    let to = c - p;
    if n.dot(to) + r < 0.0 && node.sigma_t == 0.0 {
        return 0.0;
    }
    let d2 = to.length_squared();
    let dc = d2.sqrt();
    let inside = dc <= r;
    let (axis, sin_a) = if inside { (n, 1.0) } else { (to / dc, r / dc) };
    let cos_a = (1.0 - sin_a * sin_a).max(0.0).sqrt();
    let cos_bound = if inside {
        1.0
    } else {
        let cos_t = n.dot(axis).clamp(-1.0, 1.0);
        if cos_t >= cos_a {
            1.0
        } else {
            cos_t * cos_a + (1.0 - cos_t * cos_t).max(0.0).sqrt() * sin_a
        }
    };
    let mut f = gloss.in_cone(axis, cos_a, sin_a, inside, true);
    if node.lobe_share != 0.0 {
        f *= node.emission().towards(-axis, cos_a, sin_a, inside);
    }
    if node.normal != [0.0; 3] {
        let h = Vec3::from(node.normal).dot(p - c);
        f *= (h / h.max(dc - r).max(1e-12)).clamp(1e-3, 1.0);
    }
    node.weight * f * cos_bound.max(1e-3) / d2.max(r * r)
}

/// A leaf's importance for a flat draw ([`super::LightTree::flat_masses`]): for a VBL leaf and
/// a camera segment the pair integral itself (below), otherwise [`importance`]. `profile`:
/// where along a VBL in a density grid its light scatters ([`super::Profile`]).
pub fn flat_importance(node: &LightTreeNode, rx: &Receiver, r: f32, profile: Option<&super::Profile>) -> f32 {
    let r = r.max(1e-12);
    if let Receiver::Point { p, n, gloss } = *rx
        && node.is_leaf()
        && node.lo == node.hi
    {
        return point_leaf_importance(node, p, n, &gloss, r);
    }
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
    // In a density grid the light's density ρ along the leaf comes from its profile instead
    // of the leaf's σt: each Gauss point stands for its half of the z range, where
    // ∫ ρ G du = ∫ ρ (G du/dz) dz ≈ (G du/dz)(z_k) ∫ ρ dz, G du/dz being what is flat in z.
    // (ρ at the Gauss point itself, or its mean over the half in u, missed smoke beside or
    // far from it: `tests/light_selection.rs`.)
    let u_mid = u0 + big_h / s * 0.5 * (e - 1.0 / e);
    let in_z = profile.map(|p| p.in_z(u0, big_h / s, u_mid));
    // Two Gauss–Legendre points in z, at z_mid ± (span/2)/√3 (weights 1).
    for (k, x) in [-FRAC_1_SQRT_3, FRAC_1_SQRT_3].into_iter().enumerate() {
        let ek = e * (0.5 * span * x).exp();
        let u = (u0 + big_h / s * 0.5 * (ek - 1.0 / ek)).clamp(0.0, l);
        let seen = phases.seen_from(a + dir * u);
        // du = (H/s) cosh z dz.
        value += match in_z {
            Some(sums) => big_h / s * 0.5 * (ek + 1.0 / ek) * sums[k] * seen,
            None => fade_density(node.sigma_t, l, u) * seen * (0.5 * span * big_h / s * 0.5 * (ek + 1.0 / ek)),
        };
    }
    if node.sigma_t * l > 1.0 {
        let first = 1.0 / node.sigma_t;
        let h_a = phases.off_line(a).1;
        let start = phases.seen_from(a) * asinh(first * s / h_a) / s * h_a;
        let density = profile.map_or_else(|| fade_density(node.sigma_t, l, first), |p| p.mean(0.0, first));
        value = value.max(density * start);
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

#[cfg(test)]
mod tests {
    use super::*;

    fn glossy(axis: Vec3, exponent: f32) -> Emission {
        Emission {
            share: 1.0,
            axis,
            cos_spread: 1.0,
            base: 0.2,
            peak: 0.8 * (exponent + 2.0) * 0.5,
            exponent,
        }
    }

    /// The flat draw's shortcut for a VSL's leaf is [`importance`] itself: over receivers
    /// around Lambert and Phong VSLs (with lobes or not), near and far, inside R and below the
    /// horizon, within 10⁻⁵. Catches a term left out (the lobe, the VSL's side, the cosine).
    #[test]
    fn a_vsl_leafs_shortcut_is_its_importance() {
        use super::super::{LightTree, TreeLight};
        let mut s = beamlight_scene::rng::Sampler::new(5, 0, 0);
        let unit = |s: &mut beamlight_scene::rng::Sampler| beamlight_scene::sampling::uniform_sphere(s.next_2d());
        for case in 0..4000 {
            let q = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5;
            let emission = if case % 2 == 0 {
                Emission::NONE
            } else {
                glossy(unit(&mut s), 60.0)
            };
            let tree = LightTree::build(std::iter::once(TreeLight {
                lo: q,
                hi: q,
                weight: 0.5 + s.next_1d(),
                sigma_t: 0.0,
                g: 0.0,
                emission,
                normal: unit(&mut s),
                index: 0,
            }));
            let gloss = if case % 3 == 0 {
                Gloss::LAMBERT
            } else {
                Gloss {
                    mirror: unit(&mut s),
                    exponent: 80.0,
                    diffuse: 0.1,
                    specular: 0.6,
                }
            };
            let rx = Receiver::Point {
                p: (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5) * 2.0,
                n: unit(&mut s),
                gloss,
            };
            let r = 0.02 + 0.3 * s.next_1d();
            let (a, b) = (
                importance(&tree.nodes[0], &rx, r),
                tree.flat_importance(&tree.nodes[0], &rx, r),
            );
            assert!((a - b).abs() <= 1e-5 * a.abs().max(1e-30), "case {case}: {a} vs {b}");
        }
    }

    /// The cone union holds both cones (every axis direction of each within the union's
    /// half-angle, up to rounding) and is no wider than needed when one holds the other or
    /// they are apart by less than π. Catches an axis turned the wrong way (the far cone's
    /// axis then falls outside) and a half-angle that is not widened.
    #[test]
    fn the_cone_union_holds_both_cones() {
        let mut s = beamlight_scene::rng::Sampler::new(3, 0, 0);
        let unit = |s: &mut beamlight_scene::rng::Sampler| beamlight_scene::sampling::uniform_sphere(s.next_2d());
        for _ in 0..2000 {
            let (a, b) = (unit(&mut s), unit(&mut s));
            let (ta, tb) = (s.next_1d() * 1.2, s.next_1d() * 1.2);
            let (axis, cos) = cone_union((a, ta.cos()), (b, tb.cos()));
            let t = cos.clamp(-1.0, 1.0).acos();
            // Each cone's farthest direction from the union's axis: its own angle plus its
            // half-angle.
            for (x, tx) in [(a, ta), (b, tb)] {
                let off = axis.dot(x).clamp(-1.0, 1.0).acos() + tx;
                assert!(
                    off <= t + 1e-3 || cos <= -1.0,
                    "{off} beyond {t} ({a}, {ta}; {b}, {tb})"
                );
            }
            let between = a.dot(b).clamp(-1.0, 1.0).acos();
            assert!(
                t <= (0.5 * (ta + between + tb)).max(ta).max(tb) + 1e-3,
                "wider than needed: {t} ({a}, {ta}; {b}, {tb}; between {between})"
            );
        }
    }

    /// A VSL's lobe as the importance sees it: 1 for a light without one (bit for bit, so
    /// Lambert scenes draw as before); base + peak along a narrow cone at the mirror
    /// direction, base far from it, and in a wide cone at most the lobe's mean over it (its
    /// integral, peak · 2π/(n + 1), over the cone's solid angle); a node's factor mixes by its
    /// lobed share. Catches the maximum over a wide cone (then base + peak at 60°) and a share
    /// left out (then 9 for the half-lobed node).
    #[test]
    fn a_vsls_lobe_weighs_its_directions() {
        let e = glossy(Vec3::Z, 100.0);
        let narrow = (1e-3f32.cos(), 1e-3f32.sin());
        assert_eq!(Emission::NONE.towards(Vec3::X, narrow.0, narrow.1, false), 1.0);
        let at_peak = e.towards(Vec3::Z, narrow.0, narrow.1, false);
        assert!((at_peak - (e.base + e.peak)).abs() < 1e-3 * at_peak, "{at_peak}");
        let aside = e.towards(Vec3::X, narrow.0, narrow.1, false);
        assert!((aside - e.base).abs() < 1e-3, "{aside}");
        let wide = 1.0f32; // radians
        let got = e.towards(Vec3::Z, wide.cos(), wide.sin(), false);
        let mean = e.peak / (101.0 * (1.0 - wide.cos()));
        assert!((got - (e.base + mean)).abs() < 1e-4 * got, "{got} vs {}", e.base + mean);
        let half = Emission::bound([(e, 1.0), (Emission::NONE, 1.0)].into_iter());
        let mixed = half.towards(Vec3::Z, narrow.0, narrow.1, false);
        assert!((mixed - (0.5 + 0.5 * at_peak)).abs() < 1e-3 * mixed, "{mixed}");
        assert_eq!(Emission::bound([(Emission::NONE, 2.0)].into_iter()), Emission::NONE);
    }
}
