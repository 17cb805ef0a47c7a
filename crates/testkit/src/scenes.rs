//! Scenes built in code: materials, media, a camera, quads, boxes and meshes, for tests that
//! need a scene without a file.
use beamlight_scene::{
    Rgb, Scene,
    bsdf::{Bsdf, Material},
    camera::Camera,
    medium::Medium,
    scene::{MediumInterface, RenderSettings, Triangle},
};
use glam::{Mat4, Vec3};

pub fn material(name: &str, bsdf: Option<Bsdf>, emission: Rgb, double_sided: bool) -> Material {
    Material {
        name: name.into(),
        bsdf,
        emission,
        double_sided,
        base_color_texture: None,
    }
}

/// A black (non-reflecting) surface emitting `radiance` from its front face.
pub fn emitter(name: &str, radiance: f32) -> Material {
    material(
        name,
        Some(Bsdf::Lambert { albedo: Rgb::ZERO }),
        Rgb::splat(radiance),
        false,
    )
}

pub fn lambert(name: &str, albedo: f32) -> Material {
    material(
        name,
        Some(Bsdf::Lambert {
            albedo: Rgb::splat(albedo),
        }),
        Rgb::ZERO,
        false,
    )
}

/// Clear, untinted glass of index `ior`.
pub fn glass(name: &str, ior: f32) -> Material {
    material(name, Some(Bsdf::Glass { ior, tint: Rgb::ONE }), Rgb::ZERO, false)
}

/// An empty scene with a camera at `eye` looking at `target`.
pub fn empty_scene(eye: Vec3, target: Vec3, yfov_deg: f32, width: u32, height: u32) -> Scene {
    let forward = (target - eye).normalize();
    let up = if forward.y.abs() > 0.99 { Vec3::Z } else { Vec3::Y };
    let right = forward.cross(up).normalize();
    let to_world = Mat4::from_cols(
        right.extend(0.0),
        right.cross(forward).extend(0.0),
        (-forward).extend(0.0),
        eye.extend(1.0),
    );
    Scene {
        source: "test".into(),
        triangles: Vec::new(),
        meshes: vec!["mesh".into()],
        materials: Vec::new(),
        textures: Vec::new(),
        media: Vec::new(),
        global_medium: None,
        lights: Vec::new(),
        camera: Camera {
            to_world,
            yfov: yfov_deg.to_radians(),
            name: None,
        },
        render: RenderSettings { width, height },
        warnings: Vec::new(),
    }
}

pub fn add_material(scene: &mut Scene, m: Material) -> u32 {
    scene.materials.push(m);
    scene.materials.len() as u32 - 1
}

/// Adds the quad `corner + a·u + b·v`, a, b ∈ \[0, 1\]; its front face looks along u × v.
pub fn add_quad(scene: &mut Scene, corner: Vec3, u: Vec3, v: Vec3, material: u32) {
    let p = [corner, corner + u, corner + u + v, corner + v];
    for idx in [[0, 1, 2], [0, 2, 3]] {
        scene.triangles.push(Triangle {
            p: idx.map(|i| p[i]),
            n: None,
            uv: None,
            material,
            interface: None,
            mesh: 0,
        });
    }
}

/// Adds the six faces of the box [lo, hi], front faces pointing inwards.
pub fn add_box_inward(scene: &mut Scene, lo: Vec3, hi: Vec3, material: u32) {
    let e = hi - lo;
    let (x, y, z) = (Vec3::X * e.x, Vec3::Y * e.y, Vec3::Z * e.z);
    add_quad(scene, lo, x, y, material); // z = lo, normal +z
    add_quad(scene, lo + z, y, x, material); // z = hi, normal −z
    add_quad(scene, lo, z, x, material); // y = lo, normal +y
    add_quad(scene, lo + y, x, z, material); // y = hi, normal −y
    add_quad(scene, lo, y, z, material); // x = lo, normal +x
    add_quad(scene, lo + x, z, y, material); // x = hi, normal −x
}

pub fn homogeneous(sigma_s: Rgb, sigma_a: Rgb, g: f32) -> Medium {
    Medium {
        name: "medium".into(),
        sigma_s,
        sigma_a,
        g,
        density: None,
    }
}

/// Adds an indexed mesh (e.g. from `gltf_writer::shapes`) as triangles of mesh `mesh_index`.
pub fn add_mesh(scene: &mut Scene, mesh: (Vec<Vec3>, Vec<u32>), material: u32, interface: Option<MediumInterface>) {
    let (p, idx) = mesh;
    let mesh_index = scene.meshes.len() as u32;
    scene.meshes.push(format!("mesh{mesh_index}"));
    for t in idx.chunks_exact(3) {
        scene.triangles.push(Triangle {
            p: [p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]],
            n: None,
            uv: None,
            material,
            interface,
            mesh: mesh_index,
        });
    }
}
