//! Perspective pinhole camera (glTF convention: looks down the node's −Z, +Y up, +X right).
use glam::{Mat4, Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Camera {
    /// Camera-to-world transform (rigid; any scale in the glTF node is removed).
    pub to_world: Mat4,
    /// Vertical field of view in radians.
    pub yfov: f32,
    /// Name of the glTF camera node, if it came from one.
    pub name: Option<String>,
}

impl Camera {
    pub fn position(&self) -> Vec3 {
        self.to_world.w_axis.truncate()
    }

    /// Unit world-space direction through the film point `film` ∈ [0,1)², (0,0) the top-left
    /// corner of the image, for an image of aspect ratio `aspect` = width / height.
    pub fn direction(&self, film: Vec2, aspect: f32) -> Vec3 {
        let tan_half = (0.5 * self.yfov).tan();
        let x = (2.0 * film.x - 1.0) * tan_half * aspect;
        let y = (1.0 - 2.0 * film.y) * tan_half;
        self.to_world.transform_vector3(Vec3::new(x, y, -1.0)).normalize()
    }

    /// Forward (viewing) direction in world space.
    pub fn forward(&self) -> Vec3 {
        self.to_world.transform_vector3(-Vec3::Z).normalize()
    }
}
