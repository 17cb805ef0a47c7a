//! Light selection and sampling for next-event estimation: emissive triangles and punctual
//! lights, chosen in proportion to their power.
use crate::geometry::{face_towards, interpolation_error, offset_ray_origin};
use beamlight_scene::{Rgb, Scene, light::PunctualLight, luminance_mean, rng::Sampler, sampling};
use glam::Vec3;

#[derive(Clone, Copy, Debug)]
enum LightRef {
    Triangle(u32),
    Punctual(u32),
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

pub struct LightSampler {
    lights: Vec<LightRef>,
    select: sampling::Distribution1D,
    /// Selection probability of each scene triangle (0 for non-emitters), for MIS on hits.
    tri_pmf: Vec<f32>,
}

impl LightSampler {
    pub fn new(scene: &Scene) -> Self {
        let (lo, hi) = scene.bounds();
        let radius = if lo.is_finite() && hi.is_finite() {
            0.5 * (hi - lo).length()
        } else {
            1.0
        };
        let mut lights = Vec::new();
        let mut power = Vec::new();
        for (i, t) in scene.triangles.iter().enumerate() {
            let m = &scene.materials[t.material as usize];
            if m.is_emissive() {
                let sides = if m.double_sided { 2.0 } else { 1.0 };
                lights.push(LightRef::Triangle(i as u32));
                power.push(std::f32::consts::PI * luminance_mean(m.emission) * t.area() * sides);
            }
        }
        for (i, l) in scene.lights.iter().enumerate() {
            lights.push(LightRef::Punctual(i as u32));
            power.push(l.power(radius));
        }
        let select = sampling::Distribution1D::new(&power);
        let mut tri_pmf = vec![0.0; scene.triangles.len()];
        for (k, l) in lights.iter().enumerate() {
            if let LightRef::Triangle(t) = l {
                tri_pmf[*t as usize] = select.pmf(k);
            }
        }
        Self {
            lights,
            select,
            tri_pmf,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.select.total <= 0.0
    }

    /// Samples a light as seen from `p`; `None` when nothing can arrive (back face, no lights).
    pub fn sample(&self, scene: &Scene, p: Vec3, s: &mut Sampler) -> Option<LightSample> {
        let u_select = s.next_1d();
        let u = s.next_2d();
        if self.is_empty() {
            return None;
        }
        let (k, pmf) = self.select.sample(u_select);
        match self.lights[k] {
            LightRef::Triangle(ti) => {
                let t = &scene.triangles[ti as usize];
                let m = &scene.materials[t.material as usize];
                let b = sampling::uniform_triangle(u);
                let q = t.p[0] * (1.0 - b.x - b.y) + t.p[1] * b.x + t.p[2] * b.y;
                let n = t.cross().normalize();
                let to = q - p;
                let dist2 = to.length_squared();
                let dist = dist2.sqrt();
                if !(dist > 0.0) {
                    return None;
                }
                let wi = to / dist;
                let cos_l = -n.dot(wi);
                if cos_l <= 0.0 && !m.double_sided || cos_l == 0.0 {
                    return None;
                }
                let pdf = pmf / t.area() * dist2 / cos_l.abs();
                if !(pdf.is_finite() && pdf > 0.0) {
                    return None;
                }
                let target = offset_ray_origin(q, interpolation_error(&t.p, b.x, b.y), face_towards(n, -wi));
                Some(LightSample {
                    p: q,
                    n: Some(n),
                    wi,
                    dist,
                    target,
                    contribution: m.emission / pdf,
                    pdf,
                })
            }
            LightRef::Punctual(li) => {
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
                        let q = l.position().unwrap();
                        let to = q - p;
                        let dist2 = to.length_squared();
                        if !(dist2 > 0.0) {
                            return None;
                        }
                        let dist = dist2.sqrt();
                        let wi = to / dist;
                        let contribution = l.intensity_towards(-wi) / (dist2 * pmf);
                        contribution.is_finite().then_some(LightSample {
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
        if pdf.is_finite() { pdf } else { 0.0 }
    }
}
