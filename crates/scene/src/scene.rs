//! The flattened scene: world-space triangles plus everything they refer to by index.
use crate::{
    Rgb,
    bsdf::{Bsdf, Material},
    camera::Camera,
    light::PunctualLight,
    medium::Medium,
    texture::Texture,
};
use glam::{Vec2, Vec3};
use std::path::PathBuf;

/// Index into [`Scene::media`]; `None` means vacuum.
pub type MediumId = Option<u32>;

/// Which medium lies on each side of a triangle that bounds a medium region.
/// "Inside" is the side the geometric normal points away from (glTF winding: counter-clockwise
/// seen from outside), "outside" the side it points to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MediumInterface {
    pub inside: MediumId,
    pub outside: MediumId,
}

impl MediumInterface {
    /// The medium a ray travelling along `dir` enters when it crosses a triangle with geometric normal `ng`.
    #[inline]
    pub fn entered(&self, ng: Vec3, dir: Vec3) -> MediumId {
        if dir.dot(ng) < 0.0 { self.inside } else { self.outside }
    }
}

/// One world-space triangle.
#[derive(Clone, Debug)]
pub struct Triangle {
    pub p: [Vec3; 3],
    /// Per-vertex shading normals, when the glTF primitive had them.
    pub n: Option<[Vec3; 3]>,
    /// Per-vertex texture coordinates (glTF convention, see [`crate::texture`]); only present
    /// when the triangle's material has a base-colour texture.
    pub uv: Option<[Vec2; 3]>,
    /// Index into [`Scene::materials`].
    pub material: u32,
    /// `Some` when the triangle is part of the closed mesh that bounds a medium.
    pub interface: Option<MediumInterface>,
    /// Index into [`Scene::meshes`] (for messages and for identifying medium regions).
    pub mesh: u32,
}

impl Triangle {
    /// Unnormalized geometric normal (p1−p0)×(p2−p0); its length is twice the area.
    #[inline]
    pub fn cross(&self) -> Vec3 {
        (self.p[1] - self.p[0]).cross(self.p[2] - self.p[0])
    }

    #[inline]
    pub fn area(&self) -> f32 {
        0.5 * self.cross().length()
    }

    /// Shading normal at barycentrics (b1, b2) (weights of p1 and p2); the geometric normal
    /// `ng` (the caller's unit normal, so that a hit computes it once) if none.
    pub fn shading_normal(&self, ng: Vec3, b1: f32, b2: f32) -> Vec3 {
        match self.n {
            Some(n) => {
                let s = (n[0] * (1.0 - b1 - b2) + n[1] * b1 + n[2] * b2).normalize_or_zero();
                if s == Vec3::ZERO { ng } else { s }
            }
            None => ng,
        }
    }

    /// Texture coordinates at barycentrics (b1, b2) (weights 1 − b1 − b2, b1, b2), if any.
    #[inline]
    pub fn uv_at(&self, b1: f32, b2: f32) -> Option<Vec2> {
        self.uv.map(|uv| uv[0] * (1.0 - b1 - b2) + uv[1] * b1 + uv[2] * b2)
    }
}

/// Render settings from the sidecar's `[render]` table (or defaults).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
}

/// The whole scene, ready for rendering.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The file the scene was loaded from (the TOML sidecar or the glTF).
    pub source: PathBuf,
    pub triangles: Vec<Triangle>,
    /// Names of the glTF meshes, indexed by [`Triangle::mesh`].
    pub meshes: Vec<String>,
    pub materials: Vec<Material>,
    /// Base-colour textures, indexed by [`Material::base_color_texture`].
    pub textures: Vec<Texture>,
    pub media: Vec<Medium>,
    /// The medium with `region = "global"`: it fills all space not inside a medium region.
    pub global_medium: MediumId,
    pub lights: Vec<PunctualLight>,
    pub camera: Camera,
    pub render: RenderSettings,
    /// Warnings collected while loading (ignored textures, skipped degenerate triangles...).
    pub warnings: Vec<String>,
}

impl Scene {
    /// Axis-aligned bounds of all triangles and punctual lights (and the camera).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for t in &self.triangles {
            for p in t.p {
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        for l in &self.lights {
            if let Some(p) = l.position() {
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        lo = lo.min(self.camera.position());
        hi = hi.max(self.camera.position());
        (lo, hi)
    }

    /// The BSDF of `material` at texture coordinates `uv`: the material's BSDF with its base
    /// colour (Lambert albedo, Phong diffuse) multiplied by its base-colour texture at `uv`
    /// (`baseColorFactor` is already part of the material's BSDF, so the result is
    /// texture × factor). Untextured materials, or `uv = None`, give the material's BSDF
    /// unchanged (a plain copy). `None` for an invisible medium boundary.
    #[inline]
    pub fn bsdf_at(&self, material: u32, uv: Option<Vec2>) -> Option<Bsdf> {
        let m = &self.materials[material as usize];
        let bsdf = m.bsdf?;
        match (m.base_color_texture, uv) {
            (Some(t), Some(uv)) => Some(bsdf.with_base_color_scaled(self.textures[t as usize].sample(uv))),
            _ => Some(bsdf),
        }
    }

    /// Emitted radiance of a material, zero for non-emitters.
    pub fn emission(&self, material: u32) -> Rgb {
        self.materials[material as usize].emission
    }

    /// The medium with name `name`, if any.
    pub fn medium_index(&self, name: &str) -> Option<u32> {
        self.media.iter().position(|m| m.name == name).map(|i| i as u32)
    }

    /// True when some medium exists.
    pub fn has_media(&self) -> bool {
        !self.media.is_empty()
    }
}
