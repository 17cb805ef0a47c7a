//! Light selection and sampling for next-event estimation: emissive triangles and punctual
//! lights, chosen in proportion to their power.
use crate::geometry::{face_towards, offset_ray_origin, triangle_error_bound};
use beamlight_scene::{Rgb, Scene, light::PunctualLight, luminance_mean, rng::Sampler, sampling};
use glam::Vec3;

#[derive(Clone, Copy, Debug)]
enum LightRef {
    /// Index into [`LightSampler::area`].
    Triangle(u32),
    /// Index into the scene's punctual lights.
    Punctual(u32),
}

/// An emissive triangle with what next-event estimation needs from it, precomputed: a light
/// sample reads this one record instead of the triangle and its material, and recomputes no
/// normal or area (the same values, so the same bits as computing them on the spot).
#[derive(Clone, Copy, Debug)]
struct AreaLight {
    /// Index into the scene's triangles.
    tri: u32,
    p: [Vec3; 3],
    /// Unit geometric normal.
    n: Vec3,
    /// Density of a point drawn on it: selection pmf / area.
    pdf: f32,
    emission: Rgb,
    double_sided: bool,
}

/// A sampled light point as seen from a reference point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Point on the light (unused for directional lights).
    pub p: Vec3,
    /// Geometric normal of an area light; `None` for punctual lights.
    pub n: Option<Vec3>,
    /// Unit direction from the reference point towards the light.
    pub wi: Vec3,
    /// Distance to `p` (∞ for directional lights).
    pub dist: f32,
    /// Where a shadow ray should end: `p` moved off the emitting surface towards the reference
    /// point (so the light's own triangle does not occlude it), or the punctual light's position.
    pub target: Vec3,
    /// Incident radiance divided by the solid-angle pdf (for delta lights: intensity / d² / pmf),
    /// unoccluded and without transmittance.
    pub contribution: Rgb,
    /// Solid-angle pdf including the light selection; 0 for delta lights.
    pub pdf: f32,
}

/// A point chosen on a light, independent of any viewer.
#[derive(Clone, Copy, Debug)]
pub struct LightPoint {
    /// The point (a punctual light's position; unused for directional lights).
    pub p: Vec3,
    /// Bound on the rounding error of `p`.
    pub p_error: Vec3,
    light: LightRef,
    /// Probability density of the choice: selection pmf / area for emissive triangles, the
    /// selection pmf for punctual lights.
    pub pdf: f32,
}

/// A sampled start of a light path: a point, a direction and the flux the path carries.
#[derive(Clone, Copy, Debug)]
pub struct EmissionSample {
    pub p: Vec3,
    /// Unit direction the light leaves in.
    pub dir: Vec3,
    /// Flux carried by the path: emitted radiance (or intensity) × cos / (pdf of position,
    /// direction and light choice), so the mean over paths is the scene's total emitted power.
    pub power: Rgb,
    /// For area lights: the emitting triangle, whose surface the path must leave cleanly.
    pub surface: Option<(u32, Vec3)>,
}

pub struct LightSampler {
    lights: Vec<LightRef>,
    area: Vec<AreaLight>,
    /// Bounding sphere of the scene (directional lights enter through its cross-section).
    center: Vec3,
    radius: f32,
    select: sampling::Distribution1D,
    /// Selection probability of each scene triangle (0 for non-emitters), for MIS on hits.
    tri_pmf: Vec<f32>,
    /// Lights whose power is not finite (a NaN or an overflowing emission): light selection
    /// cannot weigh them, so they are never sampled, and this says so (the command line warns).
    pub unusable: u32,
}

impl LightSampler {
    pub fn new(scene: &Scene) -> Self {
        let (lo, hi) = scene.bounds();
        let finite = lo.is_finite() && hi.is_finite();
        let radius = if finite {
            (0.5 * (hi - lo).length()).max(1e-3)
        } else {
            1.0
        };
        let center = if finite { 0.5 * (lo + hi) } else { Vec3::ZERO };
        let mut lights = Vec::new();
        let mut power = Vec::new();
        let mut area = Vec::new();
        for (i, t) in scene.triangles.iter().enumerate() {
            let m = &scene.materials[t.material as usize];
            if m.is_emissive() {
                let sides = if m.double_sided { 2.0 } else { 1.0 };
                lights.push(LightRef::Triangle(area.len() as u32));
                power.push(std::f32::consts::PI * luminance_mean(m.emission) * t.area() * sides);
                area.push(AreaLight {
                    tri: i as u32,
                    p: t.p,
                    n: t.cross().normalize(),
                    pdf: 0.0, // set below, once the selection pmf is known
                    emission: m.emission,
                    double_sided: m.double_sided,
                });
            }
        }
        for (i, l) in scene.lights.iter().enumerate() {
            lights.push(LightRef::Punctual(i as u32));
            power.push(l.power(radius));
        }
        // A light whose power is NaN or infinite cannot be chosen in proportion to it:
        // `Distribution1D` gives it no share. Counted, not silent.
        let unusable = power.iter().filter(|p| !p.is_finite()).count() as u32;
        let select = sampling::Distribution1D::new(&power);
        // Emissive triangles come first in `lights`: area light `a` is selection entry `a`.
        let mut tri_pmf = vec![0.0; scene.triangles.len()];
        for (a, light) in area.iter_mut().enumerate() {
            let pmf = select.pmf(a);
            tri_pmf[light.tri as usize] = pmf;
            light.pdf = pmf / scene.triangles[light.tri as usize].area();
        }
        Self {
            lights,
            area,
            center,
            radius,
            select,
            tri_pmf,
            unusable,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.select.total <= 0.0
    }

    /// Samples a light as seen from `p`; `None` when nothing can arrive (back face, no lights).
    pub fn sample(&self, scene: &Scene, p: Vec3, s: &mut Sampler) -> Option<LightSample> {
        let lp = self.sample_point(scene, s)?;
        self.connect(scene, &lp, p)
    }

    /// Chooses a light (in proportion to power) and a point on it (uniform by area), without
    /// regard to where it will be seen from; [`LightSampler::connect`] then turns it into a
    /// sample as seen from any point. Consumes three random numbers.
    pub fn sample_point(&self, scene: &Scene, s: &mut Sampler) -> Option<LightPoint> {
        let u_select = s.next_1d();
        let u = s.next_2d();
        if self.is_empty() {
            return None;
        }
        let (k, pmf) = self.select.sample(u_select);
        Some(match self.lights[k] {
            LightRef::Triangle(a) => {
                let t = &self.area[a as usize];
                let b = sampling::uniform_triangle(u);
                LightPoint {
                    p: t.p[0] * (1.0 - b.x - b.y) + t.p[1] * b.x + t.p[2] * b.y,
                    // Not the interpolation's own bound: on a light whose plane passes
                    // through the origin that is zero across the plane, the shadow ray's
                    // target is not moved off the light, and the ray hits the light itself
                    // at its end about a third of the time (rounding): direct light there
                    // came out 20-30 % dark. The triangle's bound has its extent in it.
                    p_error: triangle_error_bound(&t.p),
                    light: LightRef::Triangle(a),
                    pdf: t.pdf,
                }
            }
            LightRef::Punctual(li) => LightPoint {
                p: scene.lights[li as usize].position().unwrap_or(Vec3::ZERO),
                p_error: Vec3::ZERO,
                light: LightRef::Punctual(li),
                pdf: pmf,
            },
        })
    }

    /// The light point `lp` as seen from `p`: direction, distance, shadow-ray target and the
    /// arriving radiance over the solid-angle pdf. `None` when nothing arrives (back face).
    pub fn connect(&self, scene: &Scene, lp: &LightPoint, p: Vec3) -> Option<LightSample> {
        match lp.light {
            LightRef::Triangle(a) => {
                let t = &self.area[a as usize];
                let (q, n) = (lp.p, t.n);
                let to = q - p;
                let dist2 = to.length_squared();
                let dist = dist2.sqrt();
                if !(dist > 0.0) {
                    return None;
                }
                let wi = to / dist;
                let cos_l = -n.dot(wi);
                if cos_l <= 0.0 && !t.double_sided || cos_l == 0.0 {
                    return None;
                }
                let pdf = lp.pdf * dist2 / cos_l.abs();
                // An infinite density (a grazing cosine that underflowed) is a connection whose
                // contribution vanishes. A NaN or zero one cannot come from a sampled point: it
                // flows on as a non-finite contribution, for the estimators to count.
                if pdf == f32::INFINITY {
                    return None;
                }
                let target = offset_ray_origin(q, lp.p_error, face_towards(n, -wi));
                Some(LightSample {
                    p: q,
                    n: Some(n),
                    wi,
                    dist,
                    target,
                    contribution: t.emission / pdf,
                    pdf,
                })
            }
            LightRef::Punctual(li) => {
                let pmf = lp.pdf;
                let l = &scene.lights[li as usize];
                match l {
                    PunctualLight::Directional { direction, irradiance } => Some(LightSample {
                        p: p - *direction,
                        n: None,
                        wi: -*direction,
                        dist: f32::INFINITY,
                        target: p,
                        contribution: *irradiance / pmf,
                        pdf: 0.0,
                    }),
                    _ => {
                        let q = lp.p;
                        let to = q - p;
                        let dist2 = to.length_squared();
                        if !(dist2 > 0.0) {
                            return None;
                        }
                        let dist = dist2.sqrt();
                        let wi = to / dist;
                        // Not finite only for a lamp on the point itself (dist² underflowing) or a
                        // broken light: returned as it is, for the estimators to count.
                        let contribution = l.intensity_towards(-wi) / (dist2 * pmf);
                        Some(LightSample {
                            p: q,
                            n: None,
                            wi,
                            dist,
                            target: q,
                            contribution,
                            pdf: 0.0,
                        })
                    }
                }
            }
        }
    }

    /// Starts a light path: a light chosen in proportion to its power, a point on it and a
    /// direction (cosine-weighted for area lights, uniform within the cone for point and spot
    /// lights, a uniform point on the scene's cross-section for directional lights).
    pub fn sample_emission(&self, scene: &Scene, s: &mut Sampler) -> Option<EmissionSample> {
        let u_select = s.next_1d();
        let (u_pos, u_dir) = (s.next_2d(), s.next_2d());
        if self.is_empty() {
            return None;
        }
        let (k, pmf) = self.select.sample(u_select);
        let sample = match self.lights[k] {
            LightRef::Triangle(a) => {
                let ti = self.area[a as usize].tri;
                let t = &scene.triangles[ti as usize];
                let m = &scene.materials[t.material as usize];
                let b = sampling::uniform_triangle(u_pos);
                let p = t.p[0] * (1.0 - b.x - b.y) + t.p[1] * b.x + t.p[2] * b.y;
                let mut n = t.cross().normalize();
                // Double-sided emitters pick a side with probability ½ (hence the factor 2).
                let mut sides = 1.0;
                if m.double_sided {
                    sides = 2.0;
                    if u_dir.x < 0.5 {
                        n = -n;
                    }
                }
                let u_dir = glam::Vec2::new(if m.double_sided { (u_dir.x * 2.0) % 1.0 } else { u_dir.x }, u_dir.y);
                let local = sampling::cosine_hemisphere(u_dir);
                let dir = beamlight_scene::frame::Frame::from_normal(n).to_world(local);
                // Le cosθ / (pdf_area · pdf_dir) = Le · π · area.
                let power = m.emission * (std::f32::consts::PI * t.area() * sides / pmf);
                EmissionSample {
                    p,
                    dir,
                    power,
                    surface: Some((ti, n)),
                }
            }
            LightRef::Punctual(li) => match &scene.lights[li as usize] {
                PunctualLight::Point { position, intensity } => EmissionSample {
                    p: *position,
                    dir: sampling::uniform_sphere(u_dir),
                    power: *intensity / (sampling::uniform_sphere_pdf() * pmf),
                    surface: None,
                },
                l @ PunctualLight::Spot {
                    position,
                    direction,
                    cos_outer,
                    ..
                } => {
                    let local = sampling::uniform_cone(u_dir, *cos_outer);
                    let dir = beamlight_scene::frame::Frame::from_normal(*direction).to_world(local);
                    let pdf = sampling::uniform_cone_pdf(*cos_outer);
                    EmissionSample {
                        p: *position,
                        dir,
                        power: l.intensity_towards(dir) / (pdf * pmf),
                        surface: None,
                    }
                }
                PunctualLight::Directional { direction, irradiance } => {
                    // Enter through a disc of the bounding sphere's radius, one radius upstream.
                    let frame = beamlight_scene::frame::Frame::from_normal(*direction);
                    let d = sampling::concentric_disk(u_pos) * self.radius;
                    let p = self.center - *direction * self.radius + frame.s * d.x + frame.t * d.y;
                    let area = std::f32::consts::PI * self.radius * self.radius;
                    EmissionSample {
                        p,
                        dir: *direction,
                        power: *irradiance * (area / pmf),
                        surface: None,
                    }
                }
            },
        };
        // No power (outside a spot's cone, a black emitter): no path. A non-finite power is
        // returned for the light tracer to count (`LightSet::nonfinite_paths`).
        (sample.power != Rgb::ZERO).then_some(sample)
    }

    /// Solid-angle pdf with which `sample` from `from` would have produced the point `q` on
    /// emissive triangle `tri` (for MIS when a scattered ray hits an emitter).
    pub fn pdf_hit(&self, scene: &Scene, from: Vec3, tri: u32, q: Vec3) -> f32 {
        let pmf = self.tri_pmf[tri as usize];
        if pmf == 0.0 {
            return 0.0;
        }
        let t = &scene.triangles[tri as usize];
        let to = q - from;
        let dist2 = to.length_squared();
        let cos_l = t.cross().normalize().dot(to).abs() / dist2.sqrt();
        let pdf = pmf / t.area() * dist2 / cos_l;
        // A grazing hit (cos_l = 0): light sampling yields nothing there (`connect`), so it takes
        // no MIS weight from the BSDF sample: density 0.
        // A NaN (a hit at distance 0) flows on, for the estimators to count.
        if pdf == f32::INFINITY { 0.0 } else { pdf }
    }
}
