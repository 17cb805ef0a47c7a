//! A scene prepared for tracing: BVH, light sampler and the media the rays start in.
use crate::{
    bvh::{Bvh, Hit},
    geometry::{face_towards, interpolation_error, offset_ray_origin, triangle_error_bound},
    lights::{LightSample, LightSampler},
    media,
};
use beamlight_scene::{Rgb, Scene, bsdf::Material, rng::Sampler, scene::MediumId};
use glam::{Vec2, Vec3};

/// Null-interface crossings after which a ray is given up on (guards against pathological,
/// e.g. self-overlapping, boundary meshes; a sane scene never gets close).
pub const MAX_CROSSINGS: u32 = 256;

/// Surface data at a ray hit.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    pub p: Vec3,
    /// Per-axis bound on the rounding error of `p`.
    pub p_error: Vec3,
    /// Unit geometric normal, on the glTF front side (counter-clockwise winding).
    pub ng: Vec3,
    /// Unit shading normal, flipped if needed to lie on the same side as `ng`.
    pub ns: Vec3,
    pub tri: u32,
    pub material: u32,
    /// Texture coordinates, interpolated from the triangle's (only textured materials have them).
    pub uv: Option<Vec2>,
}

pub struct TraceScene {
    pub scene: Scene,
    pub bvh: Bvh,
    pub lights: LightSampler,
    /// The medium the camera sits in.
    pub camera_medium: MediumId,
    /// Whether any triangle is an invisible medium boundary (shadow rays must then walk hits).
    has_null_interfaces: bool,
    /// The planar patches of the surfaces, where a VSL's blur may treat them as walls.
    pub patches: crate::patches::Patches,
}

impl SurfaceHit {
    /// Origin for a new ray leaving this point in direction `w`.
    #[inline]
    pub fn spawn(&self, w: Vec3) -> Vec3 {
        offset_ray_origin(self.p, self.p_error, face_towards(self.ng, w))
    }
}

impl TraceScene {
    pub fn new(scene: Scene) -> Self {
        // The patches (a sort of every edge) while the BVH is built.
        let ((bvh, lights), patches) = rayon::join(
            || (Bvh::build(&scene), LightSampler::new(&scene)),
            || crate::patches::Patches::build(&scene),
        );
        let has_null_interfaces = scene
            .triangles
            .iter()
            .any(|t| scene.materials[t.material as usize].bsdf.is_none());
        let mut ts = Self {
            scene,
            bvh,
            lights,
            camera_medium: None,
            has_null_interfaces,
            patches,
        };
        ts.camera_medium = ts.medium_at(ts.scene.camera.position());
        ts
    }

    pub fn material(&self, hit: &SurfaceHit) -> &Material {
        &self.scene.materials[hit.material as usize]
    }

    pub fn surface(&self, h: &Hit) -> SurfaceHit {
        let t = &self.scene.triangles[h.tri as usize];
        let p = t.p[0] * (1.0 - h.b1 - h.b2) + t.p[1] * h.b1 + t.p[2] * h.b2;
        let ng = t.cross().normalize();
        let ns = t.shading_normal(ng, h.b1, h.b2);
        let ns = if ns.dot(ng) < 0.0 { -ns } else { ns };
        SurfaceHit {
            p,
            p_error: interpolation_error(&t.p, h.b1, h.b2),
            ng,
            ns,
            tri: h.tri,
            material: t.material,
            uv: t.uv_at(h.b1, h.b2),
        }
    }

    /// The medium a ray is in after leaving surface hit `sh` in direction `dir`: the side of a
    /// medium boundary it leaves on, or `current` for surfaces that bound no medium.
    pub fn medium_beyond(&self, sh: &SurfaceHit, dir: Vec3, current: MediumId) -> MediumId {
        match self.scene.triangles[sh.tri as usize].interface {
            Some(iface) => iface.entered(sh.ng, dir),
            None => current,
        }
    }

    /// Origin for a ray leaving the point `p` of triangle `tri` towards `w`, for points known
    /// only by position (recorded gather points and light vertices): the offset uses an error
    /// bound valid anywhere on the triangle.
    pub fn spawn_from_triangle(&self, tri: u32, p: Vec3, w: Vec3) -> Vec3 {
        let t = &self.scene.triangles[tri as usize];
        offset_ray_origin(p, triangle_error_bound(&t.p), face_towards(t.cross().normalize(), w))
    }

    pub fn intersect(&self, o: Vec3, d: Vec3, tmax: f32) -> Option<(Hit, SurfaceHit)> {
        self.bvh.closest_hit(o, d, tmax).map(|h| (h, self.surface(&h)))
    }

    /// The medium containing point `p`: found by following a ray to the first medium boundary
    /// and checking which side of it `p` is on; the global medium (or vacuum) when none is hit.
    pub fn medium_at(&self, p: Vec3) -> MediumId {
        let d = Vec3::new(0.267_261_24, 0.534_522_5, 0.801_783_7); // any fixed, non axis-aligned direction
        let mut o = p;
        for _ in 0..MAX_CROSSINGS * 4 {
            let Some((_, sh)) = self.intersect(o, d, f32::INFINITY) else {
                break;
            };
            if let Some(iface) = self.scene.triangles[sh.tri as usize].interface {
                return if d.dot(sh.ng) > 0.0 {
                    iface.inside
                } else {
                    iface.outside
                };
            }
            o = sh.spawn(d);
        }
        self.scene.global_medium
    }

    /// Transmittance of `medium` along `o + t·d`, `t ∈ (0, len)`, ignoring surfaces.
    pub fn medium_transmittance(&self, medium: MediumId, o: Vec3, d: Vec3, len: f32, s: &mut Sampler) -> Rgb {
        self.medium_transmittance_at_rate(medium, o, d, len, 1.0, s)
    }

    /// [`Self::medium_transmittance`] with ratio tracking at `rate` times the majorant
    /// ([`media::transmittance_at_rate`]).
    fn medium_transmittance_at_rate(
        &self,
        medium: MediumId,
        o: Vec3,
        d: Vec3,
        len: f32,
        rate: f32,
        s: &mut Sampler,
    ) -> Rgb {
        match medium {
            Some(i) => media::transmittance_at_rate(&self.scene.media[i as usize], o, d, len, rate, s),
            None => Rgb::ONE,
        }
    }

    /// Transmittance along a shadow ray from `o` (already offset off its surface, if any) to
    /// the light sample `ls`, starting in `medium`. Zero when an opaque or refracting surface is
    /// in the way; invisible medium boundaries are crossed and switch the medium.
    pub fn shadow_transmittance(&self, o: Vec3, ls: &LightSample, medium: MediumId, s: &mut Sampler) -> Rgb {
        self.shadow_transmittance_at_rate(o, ls, medium, 1.0, s)
    }

    /// [`Self::shadow_transmittance`] with ratio tracking at `rate` times the majorant
    /// ([`media::transmittance_at_rate`]).
    pub fn shadow_transmittance_at_rate(
        &self,
        mut o: Vec3,
        ls: &LightSample,
        mut medium: MediumId,
        rate: f32,
        s: &mut Sampler,
    ) -> Rgb {
        let (d, mut remaining) = if ls.dist.is_finite() {
            let v = ls.target - o;
            let len = v.length();
            if !(len > 0.0) {
                return Rgb::ZERO;
            }
            (v / len, len)
        } else {
            (ls.wi, f32::INFINITY)
        };
        let mut tr = Rgb::ONE;
        for _ in 0..MAX_CROSSINGS {
            if !self.has_null_interfaces {
                if self.bvh.occluded(o, d, remaining) {
                    return Rgb::ZERO;
                }
                return tr * self.medium_transmittance_at_rate(medium, o, d, remaining, rate, s);
            }
            match self.intersect(o, d, remaining) {
                None => return tr * self.medium_transmittance_at_rate(medium, o, d, remaining, rate, s),
                Some((h, sh)) => {
                    let tri = &self.scene.triangles[sh.tri as usize];
                    if self.scene.materials[tri.material as usize].bsdf.is_some() {
                        return Rgb::ZERO;
                    }
                    tr *= self.medium_transmittance_at_rate(medium, o, d, h.t, rate, s);
                    if tr == Rgb::ZERO {
                        return tr;
                    }
                    medium = self.medium_beyond(&sh, d, medium);
                    let next = sh.spawn(d);
                    remaining -= (next - o).dot(d);
                    o = next;
                    if !(remaining > 0.0) {
                        return tr;
                    }
                }
            }
        }
        Rgb::ZERO
    }
}
