//! A base-colour texture end to end: written by the glTF writer (embedded PNG), loaded with a
//! sidecar, rendered by the path tracer, and checked against the closed form
//! ρ(uv)/π · I cosθ / d² of a point light over a textured Lambert floor.
mod common;
use beamlight_scene::load::load_scene;
use beamlight_scene::texture::Wrap;
use beamlight_testkit::gltf_writer::{GltfBuilder, MaterialDesc, shapes};
use common::*;
use glam::{Vec2, Vec3};
use std::f64::consts::PI;

/// 2×2 checker, row 0 (v = 0) first; every channel differs so a flipped axis shows.
const CHECKER: [[u8; 3]; 4] = [[230, 40, 40], [40, 230, 40], [40, 40, 230], [250, 250, 250]];
const FACTOR: [f32; 3] = [0.9, 0.8, 1.0];

fn srgb_to_linear(c: u8) -> f64 {
    let c = c as f64 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The albedo at `uv`: factor × bilinear filtering of the checker with CLAMP_TO_EDGE, written
/// independently of the renderer (texel centres at 1/4 and 3/4).
fn rho(u: f64, v: f64) -> [f64; 3] {
    let wx = (2.0 * u - 0.5).clamp(0.0, 1.0);
    let wy = (2.0 * v - 0.5).clamp(0.0, 1.0);
    let t = |x: usize, y: usize, c: usize| srgb_to_linear(CHECKER[2 * y + x][c]);
    std::array::from_fn(|c| {
        let top = t(0, 0, c) * (1.0 - wx) + t(1, 0, c) * wx;
        let bottom = t(0, 1, c) * (1.0 - wx) + t(1, 1, c) * wx;
        FACTOR[c] as f64 * (top * (1.0 - wy) + bottom * wy)
    })
}

#[test]
fn point_light_on_a_textured_lambert_floor() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = GltfBuilder::new();
    let tex = b.texture_png("checker", 2, 2, &CHECKER, Wrap::ClampToEdge, Wrap::ClampToEdge);
    let floor = b.material(MaterialDesc::lambert("Floor", FACTOR).with_base_color_texture(tex));
    // The floor [−2, 2]² at y = 0, facing +Y; u = (x + 2)/4, v = (z + 2)/4.
    let (p, i) = shapes::quad(Vec3::new(-2.0, 0.0, 2.0), Vec3::X * 4.0, Vec3::NEG_Z * 4.0);
    let uv: Vec<Vec2> = p
        .iter()
        .map(|q| Vec2::new((q.x + 2.0) / 4.0, (q.z + 2.0) / 4.0))
        .collect();
    let mesh = b.mesh("Floor", &p, &i, None, Some(floor));
    b.texcoords(mesh, &uv);
    let eye = Vec3::new(0.0, 3.0, 0.0);
    b.camera_look_at("Cam", eye, Vec3::ZERO, Vec3::NEG_Z, 60f32.to_radians(), None);
    let pos = Vec3::new(0.3, 1.0, 0.2);
    let intensity = 4.0f32;
    b.point_light("Bulb", pos, [1.0; 3], intensity);
    b.write_glb(&dir.path().join("floor.glb")).unwrap();
    let toml = dir.path().join("floor.toml");
    std::fs::write(&toml, "gltf = \"floor.glb\"\n[render]\nwidth = 16\nheight = 16\n").unwrap();
    let s = load_scene(&toml).unwrap();
    assert_eq!(s.textures.len(), 1);
    assert!(s.triangles.iter().all(|t| t.uv.is_some()));

    let (w, h) = (s.render.width, s.render.height);
    let cam = s.camera.clone();
    let film = render_pt(s, 512, 11, None);
    let n = 16;
    assert_pixels_match(&film, 4.0, 0.005, "textured floor", |x, y| {
        let mut expected = [0.0f64; 3];
        for j in 0..n {
            for i in 0..n {
                let film = glam::Vec2::new(
                    (x as f32 + (i as f32 + 0.5) / n as f32) / w as f32,
                    (y as f32 + (j as f32 + 0.5) / n as f32) / h as f32,
                );
                let d = cam.direction(film, w as f32 / h as f32).as_dvec3();
                let e = cam.position().as_dvec3();
                let p = e + d * (-e.y / d.y);
                let to = pos.as_dvec3() - p;
                let r2 = to.length_squared();
                let cos = to.y / r2.sqrt();
                let albedo = rho((p.x + 2.0) / 4.0, (p.z + 2.0) / 4.0);
                for c in 0..3 {
                    expected[c] += albedo[c] / PI * intensity as f64 * cos / r2 / (n * n) as f64;
                }
            }
        }
        expected
    });
}
