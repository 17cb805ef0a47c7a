//! The reference path tracer against answers computed independently of the renderer:
//! furnaces, closed-form absorption, the single-scattering airlight integral, Lambert's
//! polygon irradiance formula, and point/spot lights.
mod common;
use beamlight_scene::{Rgb, light::PunctualLight, medium::DensityGrid};
use common::*;
use glam::{UVec3, Vec3};
use std::f64::consts::PI;

fn rmse_to(film: &beamlight_render::Film, v: f32) -> f64 {
    let img = film.image();
    let se: f64 = img
        .pixels
        .iter()
        .map(|p| ((*p - Rgb::splat(v)).length_squared()) as f64)
        .sum();
    (se / (3 * img.pixels.len()) as f64).sqrt()
}

#[test]
fn furnace_converges_to_two_for_any_medium() {
    for (sigma_s, g) in [
        (Rgb::new(0.5, 1.0, 2.0), 0.0),
        (Rgb::splat(3.0), 0.9),
        (Rgb::new(0.1, 4.0, 1.0), -0.7),
    ] {
        let grey = sigma_s.max_element() == sigma_s.min_element();
        let film = render_pt(furnace(sigma_s, g, None), if grey { 256 } else { 1024 }, 1, None);
        let mean = film.image().mean();
        assert!(
            (mean - Rgb::splat(2.0)).abs().max_element() < 0.02,
            "σs {sigma_s} g {g}: mean {mean}"
        );
        if grey {
            assert_pixels_match(&film, 5.0, 0.0, &format!("furnace σs {sigma_s} g {g}"), |_, _| {
                [2.0; 3]
            });
        } else {
            // Chromatic media make the per-channel weights heavy-tailed, so a pixel's sample
            // variance is itself noisy at this spp: ask for 98 % of pixels within 3 σ instead.
            let frac = fraction_within(&film, 3.0, |_, _| [2.0; 3]);
            assert!(frac >= 0.98, "σs {sigma_s} g {g}: only {frac} of pixels within 3σ of 2");
        }
    }
}

#[test]
fn furnace_with_heterogeneous_density_converges_to_two() {
    // A lumpy density field: delta tracking must still conserve energy exactly.
    let res = UVec3::new(16, 16, 16);
    let values = (0..res.x * res.y * res.z)
        .map(|i| {
            let (x, y, z) = ((i % 16) as f32, (i / 16 % 16) as f32, (i / 256) as f32);
            2.0 * (0.5 + 0.5 * (x * 0.7).sin() * (y * 0.5 + z * 0.3).cos()).powi(2)
        })
        .collect();
    let grid = DensityGrid::new(res, Vec3::splat(-1.0), Vec3::splat(1.0), values);
    let film = render_pt(furnace(Rgb::new(0.5, 2.0, 1.0), 0.5, Some(grid)), 256, 2, None);
    let mean = film.image().mean();
    assert!((mean - Rgb::splat(2.0)).abs().max_element() < 0.02, "mean {mean}");
}

#[test]
fn furnace_error_shrinks_like_inverse_sqrt_spp() {
    let scene = furnace(Rgb::splat(1.0), 0.3, None);
    let e1 = rmse_to(&render_pt(scene.clone(), 16, 3, None), 2.0);
    let e4 = rmse_to(&render_pt(scene, 256, 4, None), 2.0);
    let ratio = e1 / e4;
    // 16× the samples: the error must drop by √16 = 4 (within statistical slack).
    assert!((3.0..5.3).contains(&ratio), "error ratio {ratio} (rmse {e1} → {e4})");
}

/// Pure absorber in a box of black walls emitting 1: each camera ray sees exp(−σa·d), with d
/// the distance from the camera (at the centre) to the box along the ray.
#[test]
fn absorption_matches_closed_form() {
    let sigma_a = Rgb::new(0.2, 0.7, 1.5);
    let (w, h, fov) = (10u32, 8u32, 80f32);
    let mut s = empty_scene(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), fov, w, h);
    let wall = add_material(&mut s, emitter("wall", 1.0));
    add_box_inward(&mut s, Vec3::splat(-1.0), Vec3::splat(1.0), wall);
    s.media.push(homogeneous(Rgb::ZERO, sigma_a, 0.0));
    s.global_medium = Some(0);
    let film = render_pt(s, 1024, 5, None);
    let tan = (fov.to_radians() as f64 * 0.5).tan();
    let aspect = w as f64 / h as f64;
    let n = 16;
    assert_pixels_match(&film, 4.0, 0.002, "absorption", |x, y| {
        let mut expected = [0f64; 3];
        for j in 0..n {
            for i in 0..n {
                let fx = (x as f64 + (i as f64 + 0.5) / n as f64) / w as f64;
                let fy = (y as f64 + (j as f64 + 0.5) / n as f64) / h as f64;
                let d = [(2.0 * fx - 1.0) * tan * aspect, (1.0 - 2.0 * fy) * tan, -1.0];
                let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let dist = d.iter().map(|c| len / c.abs()).fold(f64::INFINITY, f64::min);
                for c in 0..3 {
                    expected[c] += (-(sigma_a[c] as f64) * dist).exp() / (n * n) as f64;
                }
            }
        }
        expected
    });
}

fn hg(g: f64, cos: f64) -> f64 {
    (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * cos).powf(1.5))
}

fn adaptive_simpson(f: &dyn Fn(f64) -> f64, a: f64, b: f64, eps: f64, depth: u32) -> f64 {
    fn rec(f: &dyn Fn(f64) -> f64, a: f64, b: f64, fa: f64, fm: f64, fb: f64, whole: f64, eps: f64, depth: u32) -> f64 {
        let m = 0.5 * (a + b);
        let (lm, rm) = (0.5 * (a + m), 0.5 * (m + b));
        let (flm, frm) = (f(lm), f(rm));
        let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
        let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
        if depth == 0 || (left + right - whole).abs() <= 15.0 * eps {
            return left + right + (left + right - whole) / 15.0;
        }
        rec(f, a, m, fa, flm, fm, left, eps / 2.0, depth - 1) + rec(f, m, b, fm, frm, fb, right, eps / 2.0, depth - 1)
    }
    let (fa, fb, fm) = (f(a), f(b), f(0.5 * (a + b)));
    rec(f, a, b, fa, fm, fb, (b - a) / 6.0 * (fa + 4.0 * fm + fb), eps, depth)
}

/// Single scattering of a point light in an unbounded homogeneous medium (the airlight
/// integral), with an anisotropic phase function, rendered with `--max-depth 1`.
#[test]
fn single_scattering_matches_airlight_integral() {
    let sigma_s = Rgb::new(0.3, 0.15, 0.05);
    let sigma_a = Rgb::new(0.05, 0.1, 0.0);
    let g = 0.5f32;
    let light = Vec3::new(0.4, 0.1, -2.0);
    let intensity = Rgb::new(10.0, 20.0, 5.0);
    let (w, h, fov) = (6u32, 6u32, 30f32);
    let mut s = empty_scene(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), fov, w, h);
    s.media.push(homogeneous(sigma_s, sigma_a, g));
    s.global_medium = Some(0);
    s.lights.push(PunctualLight::Point {
        position: light,
        intensity,
    });
    let film = render_pt(s, 1024, 6, Some(1));
    let tan = (fov.to_radians() as f64 * 0.5).tan();
    let l = [light.x as f64, light.y as f64, light.z as f64];
    let n = 4;
    assert_pixels_match(&film, 4.0, 0.01, "airlight", |x, y| {
        let mut expected = [0f64; 3];
        for j in 0..n {
            for i in 0..n {
                let fx = (x as f64 + (i as f64 + 0.5) / n as f64) / w as f64;
                let fy = (y as f64 + (j as f64 + 0.5) / n as f64) / h as f64;
                let d = [(2.0 * fx - 1.0) * tan, (1.0 - 2.0 * fy) * tan, -1.0];
                let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let d = d.map(|c| c / len);
                for c in 0..3 {
                    let st = (sigma_s[c] + sigma_a[c]) as f64;
                    let f = |t: f64| {
                        let v = [t * d[0] - l[0], t * d[1] - l[1], t * d[2] - l[2]];
                        let r2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
                        let r = r2.sqrt();
                        // Light travels along v/r, then towards the camera along −d.
                        let cos = -(v[0] * d[0] + v[1] * d[1] + v[2] * d[2]) / r;
                        sigma_s[c] as f64 * (-st * (t + r)).exp() * hg(g as f64, cos) * intensity[c] as f64 / r2
                    };
                    let far = 80.0 / st.max(0.05);
                    expected[c] += adaptive_simpson(&f, 0.0, far, 1e-9, 40) / (n * n) as f64;
                }
            }
        }
        expected
    });
}

/// Irradiance at `p` (normal `n`) from a polygon of uniform radiance `radiance` (Lambert's formula).
fn polygon_irradiance(p: [f64; 3], n: [f64; 3], poly: &[[f64; 3]], radiance: f64) -> f64 {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let norm = |a: [f64; 3]| {
        let l = dot(a, a).sqrt();
        [a[0] / l, a[1] / l, a[2] / l]
    };
    let mut sum = 0.0;
    for i in 0..poly.len() {
        let a = norm(sub(poly[i], p));
        let b = norm(sub(poly[(i + 1) % poly.len()], p));
        let angle = dot(a, b).clamp(-1.0, 1.0).acos();
        sum += angle * dot(norm(cross(a, b)), n);
    }
    (0.5 * radiance * sum).abs()
}

/// Adds a large floor (y = 0) of material `floor` and a 0.5 × 0.6 black quad light at height 1
/// facing down, emitting `radiance`; returns the light's corner and edges (c, u, v).
fn floor_under_quad_light(s: &mut beamlight_scene::Scene, floor: u32, radiance: f32) -> (Vec3, Vec3, Vec3) {
    let light = add_material(s, emitter("light", radiance));
    add_quad(
        s,
        Vec3::new(-10.0, 0.0, 10.0),
        Vec3::new(20.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -20.0),
        floor,
    );
    // Front face = u × v = −y.
    let (c, u, v) = (
        Vec3::new(-0.3, 1.0, -0.4),
        Vec3::new(0.5, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.6),
    );
    add_quad(s, c, u, v, light);
    (c, u, v)
}

/// A Lambert floor lit by a square area light (direct only through geometry: the light is
/// black, the floor is the only reflector), against Lambert's polygon irradiance formula.
/// Exercises light sampling, BSDF sampling and their MIS weights together.
#[test]
fn area_light_on_lambert_floor_matches_polygon_formula() {
    let (w, h, fov) = (8u32, 6u32, 20f32);
    let eye = Vec3::new(0.0, 0.6, 2.5);
    let target = Vec3::new(0.0, 0.0, 0.0);
    let mut s = empty_scene(eye, target, fov, w, h);
    let albedo = 0.6f32;
    let floor = add_material(&mut s, lambert("floor", albedo));
    let radiance = 5.0f32;
    let (c, u, v) = floor_under_quad_light(&mut s, floor, radiance);
    let cam = s.camera.clone();
    let film = render_pt(s, 1024, 7, None);
    let poly: Vec<[f64; 3]> = [c, c + u, c + u + v, c + v]
        .iter()
        .map(|p| [p.x as f64, p.y as f64, p.z as f64])
        .collect();
    let n = 6;
    assert_pixels_match(&film, 4.0, 0.005, "area light", |x, y| {
        let mut expected = 0.0;
        for j in 0..n {
            for i in 0..n {
                let film = glam::Vec2::new(
                    (x as f32 + (i as f32 + 0.5) / n as f32) / w as f32,
                    (y as f32 + (j as f32 + 0.5) / n as f32) / h as f32,
                );
                let d = cam.direction(film, w as f32 / h as f32);
                let t = -eye.y / d.y;
                let p = eye + d * t;
                let e = polygon_irradiance(
                    [p.x as f64, p.y as f64, p.z as f64],
                    [0.0, 1.0, 0.0],
                    &poly,
                    radiance as f64,
                );
                expected += albedo as f64 / PI * e / (n * n) as f64;
            }
        }
        [expected; 3]
    });
}

/// A glossy (modified Phong) floor under a quad light, seen around the light's highlight,
/// against direct numerical integration over the light's area with an independently written
/// Phong formula. A wrong Phong normalisation, or a sampling pdf that disagrees with the one
/// MIS uses, shows up here as bias.
#[test]
fn area_light_on_phong_floor_matches_quadrature() {
    let (w, h, fov) = (8u32, 8u32, 30f32);
    let eye = Vec3::new(0.0, 0.6, 2.5);
    let mut s = empty_scene(eye, Vec3::new(0.0, 0.0, 1.4), fov, w, h);
    let (kd, ks, exponent) = (0.2f64, 0.6f64, 40f64);
    let floor = add_material(
        &mut s,
        material(
            "floor",
            Some(beamlight_scene::bsdf::Bsdf::Phong {
                diffuse: Rgb::splat(kd as f32),
                specular: Rgb::splat(ks as f32),
                exponent: exponent as f32,
            }),
            Rgb::ZERO,
            false,
        ),
    );
    let radiance = 4.0f64;
    let (c, u, v) = floor_under_quad_light(&mut s, floor, radiance as f32);
    let cam = s.camera.clone();
    let film = render_pt(s, 1024, 16, None);
    let (pixel_n, light_n) = (4, 64);
    let to64 = |v: Vec3| [v.x as f64, v.y as f64, v.z as f64];
    let (c, u, v, eye64) = (to64(c), to64(u), to64(v), to64(eye));
    let area = 0.5 * 0.6;
    assert_pixels_match(&film, 4.0, 0.01, "phong floor", |x, y| {
        let mut expected = 0.0;
        for j in 0..pixel_n {
            for i in 0..pixel_n {
                let f = glam::Vec2::new(
                    (x as f32 + (i as f32 + 0.5) / pixel_n as f32) / w as f32,
                    (y as f32 + (j as f32 + 0.5) / pixel_n as f32) / h as f32,
                );
                let d = to64(cam.direction(f, 1.0));
                let t = -eye64[1] / d[1];
                let p = [eye64[0] + d[0] * t, 0.0, eye64[2] + d[2] * t];
                let wo = [-d[0], -d[1], -d[2]];
                let r = [-wo[0], wo[1], -wo[2]]; // mirror direction of wo about +y
                let mut l = 0.0;
                for b in 0..light_n {
                    for a in 0..light_n {
                        let (sa, sb) = ((a as f64 + 0.5) / light_n as f64, (b as f64 + 0.5) / light_n as f64);
                        let q = [0, 1, 2].map(|k| c[k] + u[k] * sa + v[k] * sb);
                        let to = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
                        let d2 = to[0] * to[0] + to[1] * to[1] + to[2] * to[2];
                        let wi = to.map(|x| x / d2.sqrt());
                        let cos_alpha = (wi[0] * r[0] + wi[1] * r[1] + wi[2] * r[2]).max(0.0);
                        let brdf = kd / PI + ks * (exponent + 2.0) / (2.0 * PI) * cos_alpha.powf(exponent);
                        // cos at the floor and at the light (facing down) are both wi.y.
                        l += brdf * radiance * wi[1] * wi[1] / d2 * area / (light_n * light_n) as f64;
                    }
                }
                expected += l / (pixel_n * pixel_n) as f64;
            }
        }
        [expected; 3]
    });
}

/// Point and glTF spot lights on a Lambert floor: L = ρ/π · I(ω) · cosθ / d².
#[test]
fn punctual_lights_on_lambert_floor() {
    let (w, h, fov) = (8u32, 8u32, 60f32);
    let eye = Vec3::new(0.0, 3.0, 0.01);
    for spot in [false, true] {
        let mut s = empty_scene(eye, Vec3::ZERO, fov, w, h);
        let floor = add_material(&mut s, lambert("floor", 0.5));
        add_quad(
            &mut s,
            Vec3::new(-10.0, 0.0, 10.0),
            Vec3::new(20.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -20.0),
            floor,
        );
        let pos = Vec3::new(0.3, 1.0, 0.2);
        let intensity = Rgb::splat(4.0);
        let (cos_inner, cos_outer) = (20f32.to_radians().cos(), 35f32.to_radians().cos());
        s.lights.push(if spot {
            PunctualLight::Spot {
                position: pos,
                direction: -Vec3::Y,
                intensity,
                cos_inner,
                cos_outer,
            }
        } else {
            PunctualLight::Point {
                position: pos,
                intensity,
            }
        });
        let cam = s.camera.clone();
        let light = s.lights[0].clone();
        let film = render_pt(s, 512, 8, None);
        let n = 16;
        assert_pixels_match(
            &film,
            4.0,
            0.005,
            if spot { "spot light" } else { "point light" },
            |x, y| {
                let mut expected = 0.0f64;
                for j in 0..n {
                    for i in 0..n {
                        let film = glam::Vec2::new(
                            (x as f32 + (i as f32 + 0.5) / n as f32) / w as f32,
                            (y as f32 + (j as f32 + 0.5) / n as f32) / h as f32,
                        );
                        let d = cam.direction(film, 1.0);
                        let p = eye + d * (-eye.y / d.y);
                        let to = pos - p;
                        let r2 = to.length_squared() as f64;
                        let cos = (to.y as f64) / r2.sqrt();
                        let i_dir = light.intensity_towards(-to.normalize()).x as f64;
                        expected += 0.5 / PI * i_dir * cos / r2 / (n * n) as f64;
                    }
                }
                [expected; 3]
            },
        );
    }
}

/// A density grid of constant 1 must give the same image as the homogeneous medium.
#[test]
fn constant_grid_matches_homogeneous_medium() {
    let make = |grid: bool| {
        let mut s = empty_scene(Vec3::new(0.0, 0.0, 0.9), Vec3::new(0.0, 0.0, -1.0), 60.0, 16, 16);
        let wall = add_material(&mut s, lambert("wall", 0.7));
        let light = add_material(&mut s, emitter("light", 8.0));
        add_box_inward(&mut s, Vec3::splat(-1.0), Vec3::splat(1.0), wall);
        add_quad(
            &mut s,
            Vec3::new(-0.3, 0.99, -0.3),
            Vec3::new(0.6, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.6),
            light,
        );
        let mut m = homogeneous(Rgb::new(0.8, 0.4, 1.6), Rgb::new(0.2, 0.1, 0.0), 0.4);
        if grid {
            m.density = Some(DensityGrid::constant(
                UVec3::new(9, 7, 11),
                Vec3::splat(-1.5),
                Vec3::splat(1.5),
                1.0,
            ));
        }
        s.media.push(m);
        s.global_medium = Some(0);
        s
    };
    let a = render_pt(make(false), 256, 10, None);
    let b = render_pt(make(true), 256, 11, None);
    let (ma, mb) = (a.image().mean(), b.image().mean());
    assert!(((ma - mb) / ma).abs().max_element() < 0.02, "means {ma} vs {mb}");
    let agree = z_agreement(&a, &b, 3.0);
    assert!(agree > 0.98, "only {agree} of pixels agree within 3σ");
}

/// Media bounded by invisible (index-matched) meshes: the camera inside one box of absorber,
/// looking through a second, separate box. Each ray's transmittance is exp(−σa · length of the
/// ray inside the boxes), computed here with the slab method.
#[test]
fn bounded_media_switch_at_invisible_boundaries() {
    use beamlight_scene::scene::MediumInterface;
    use beamlight_testkit::gltf_writer::shapes;
    let (w, h, fov) = (8u32, 8u32, 70f32);
    let mut s = empty_scene(Vec3::new(0.0, 0.0, 0.5), Vec3::new(0.2, 0.1, -1.0), fov, w, h);
    let wall = add_material(&mut s, emitter("wall", 1.0));
    add_box_inward(&mut s, Vec3::splat(-1.0), Vec3::splat(1.0), wall);
    let boundary = add_material(&mut s, material("boundary", None, Rgb::ZERO, false));
    let boxes = [
        (
            Vec3::new(-0.3, -0.3, 0.2),
            Vec3::new(0.3, 0.3, 0.8),
            Rgb::new(1.0, 2.0, 0.5),
        ),
        (
            Vec3::new(-0.9, -0.9, -0.9),
            Vec3::new(0.9, 0.9, -0.2),
            Rgb::new(0.8, 0.3, 1.5),
        ),
    ];
    for (i, (lo, hi, sigma_a)) in boxes.iter().enumerate() {
        s.media.push(homogeneous(Rgb::ZERO, *sigma_a, 0.0));
        add_mesh(
            &mut s,
            shapes::cuboid(*lo, *hi, true),
            boundary,
            Some(MediumInterface {
                inside: Some(i as u32),
                outside: None,
            }),
        );
    }
    let cam = s.camera.clone();
    let eye = cam.position();
    let film = render_pt(s, 64, 12, None);
    let n = 8;
    let chord = |o: Vec3, d: Vec3, lo: Vec3, hi: Vec3| -> f64 {
        let (t0, t1) = ((lo - o) / d, (hi - o) / d);
        let near = t0.min(t1).max_element().max(0.0);
        let far = t0.max(t1).min_element();
        (far - near).max(0.0) as f64
    };
    assert_pixels_match(&film, 4.0, 0.003, "bounded media", |x, y| {
        let mut e = [0f64; 3];
        for j in 0..n {
            for i in 0..n {
                let f = glam::Vec2::new(
                    (x as f32 + (i as f32 + 0.5) / n as f32) / w as f32,
                    (y as f32 + (j as f32 + 0.5) / n as f32) / h as f32,
                );
                let d = cam.direction(f, 1.0);
                let mut od = [0f64; 3];
                for (lo, hi, sa) in &boxes {
                    let len = chord(eye, d, *lo, *hi);
                    for c in 0..3 {
                        od[c] += sa[c] as f64 * len;
                    }
                }
                for c in 0..3 {
                    e[c] += (-od[c]).exp() / (n * n) as f64;
                }
            }
        }
        e
    });
}

/// Lossless specular objects keep the furnace at 2. Checks refraction, the 1/η² radiance
/// scaling, media switching at refracting boundaries, and MIS across delta vertices (shadow
/// rays cannot see through glass).
#[test]
fn furnace_with_glass_and_mirror_stays_at_two() {
    let film = render_pt(glass_furnace(12, 48, true), 1024, 13, None);
    let mean = film.image().mean();
    assert!((mean - Rgb::splat(2.0)).abs().max_element() < 0.02, "mean {mean}");
    let frac = fraction_within(&film, 3.0, |_, _| [2.0; 3]);
    assert!(frac >= 0.98, "only {frac} of pixels within 3σ of 2");
}

/// The same scene scaled by `s` (media by 1/s) must give the same image: ray offsets and
/// intersection tolerances must scale with the scene, not be fixed epsilons.
#[test]
fn scene_scale_does_not_change_the_image() {
    for scale in [1e-3f32, 1e4] {
        let mut s = glass_furnace(8, 32, false);
        for t in &mut s.triangles {
            t.p = t.p.map(|p| p * scale);
        }
        s.camera.to_world.w_axis = (s.camera.position() * scale).extend(1.0);
        for m in &mut s.media {
            m.sigma_s /= scale;
            m.sigma_a /= scale;
        }
        let film = render_pt(s, 512, 14, None);
        let mean = film.image().mean();
        assert!(
            (mean - Rgb::splat(2.0)).abs().max_element() < 0.03,
            "scale {scale}: mean {mean}"
        );
    }
}

/// Extreme media (almost no extinction, extinction 10⁴ per unit, |g| = 0.999) never produce a
/// NaN or Inf sample (`render_pt` asserts none was dropped), and thin media stay exact.
#[test]
fn extreme_media_stay_finite() {
    for (sigma_s, g, exact) in [
        (1e-6f32, 0.999f32, true),
        (1e-6, -0.999, true),
        (50.0, -0.999, false),
        (1e4, 0.9, false),
    ] {
        let mut s = furnace(Rgb::new(sigma_s, sigma_s * 0.5, sigma_s), g, None);
        s.render.width = 8;
        s.render.height = 8;
        let img = render_pt(s, 16, 15, None).image();
        assert!(
            img.pixels.iter().all(|p| p.is_finite() && p.min_element() >= 0.0),
            "σs {sigma_s} g {g}"
        );
        if exact {
            let mean = img.mean();
            assert!(
                (mean - Rgb::splat(2.0)).abs().max_element() < 0.05,
                "σs {sigma_s} g {g}: mean {mean}"
            );
        }
    }
}

/// A camera inside the glass sphere of the furnace sees the equilibrium radiance of a
/// dielectric, n² times the outside one: 1.5² · 2 = 4.5 (radiance / n² is what is conserved).
#[test]
fn camera_inside_glass_sees_n_squared_radiance() {
    let mut s = glass_furnace(8, 48, false);
    s.camera = empty_scene(Vec3::new(-0.3, 0.05, -0.25), Vec3::new(0.5, 0.2, -1.0), 90.0, 8, 8).camera;
    let ts_medium = beamlight_trace::TraceScene::new(s.clone()).camera_medium;
    assert_eq!(ts_medium, Some(1), "the camera must start in the sphere's medium");
    let film = render_pt(s, 1024, 17, None);
    let mean = film.image().mean();
    assert!((mean - Rgb::splat(4.5)).abs().max_element() < 0.05, "mean {mean}");
}

/// The path tracer restricted to some components (what `--method auto` gives it) estimates
/// each of them as the whole path tracer does, and nothing else: per wanted component the
/// image mean agrees with the unrestricted one's within 5 combined standard errors (batch
/// means, 16 batches; the restricted run has its own seed), and every other component is
/// exactly zero. Scenes: a grey and a chromatic homogeneous fog box (forced collisions in
/// both media cases), the lumpy one (a density grid: paths are cut, never forced), the glossy
/// one, and the glass furnace (specular chains and caustics keep paths alive through glass).
/// What this catches: a dropped or doubled contribution (a wrong class, a forced collision
/// where the far surface mattered, a missing weight), each tens of standard errors here
/// (errors print ~0.5-2 % of each mean); what it cannot: a bias below ~5 standard errors.
#[test]
fn restricted_path_tracer_matches_its_components() {
    use beamlight_trace::{TraceScene, components::Component, pt::PathTracerSettings};
    let mut grey = fog_box(12, 12, false);
    grey.media[0].sigma_s = Rgb::splat(0.5);
    let scenes = [
        ("grey fog", grey),
        ("chromatic fog", fog_box(12, 12, false)),
        ("lumpy fog", fog_box(12, 12, true)),
        ("glossy fog", glossy_fog_box(12, 12)),
        ("glass furnace", glass_furnace(12, 16, true)),
    ];
    use Component::*;
    let masks: [&[Component]; 7] = [
        &[Direct],
        &[Lmm],
        &[Lms],
        &[Lsm, Lss],
        &[Lmm, Lms],
        &[CausticSurface, CausticVolume],
        &[Lsm, Lmm, Lms, Lss, CausticSurface, CausticVolume],
    ];
    for (name, scene) in scenes {
        let ts = TraceScene::new(scene);
        let (full, full_se) = pt_components_with_errors(&ts, 512, 1);
        for mask in masks {
            let settings = PathTracerSettings {
                components: std::array::from_fn(|k| mask.contains(&Component::ALL[k])),
                ..Default::default()
            };
            let (ours, ours_se) = pt_components_with_errors_using(&ts, &settings, 512, 2);
            let present: Vec<Component> = mask
                .iter()
                .copied()
                .filter(|&c| full[c as usize].min_element() > 0.0)
                .collect();
            let label = format!(
                "{name}, path tracer for {:?}",
                mask.iter().map(|c| c.name()).collect::<Vec<_>>()
            );
            assert_components_within_errors(&label, (&ours, &ours_se), (&full, &full_se), &present, 5.0);
            for c in Component::ALL.into_iter().filter(|c| !mask.contains(c)) {
                assert_eq!(ours[c as usize], glam::DVec3::ZERO, "{label}: {} leaked", c.name());
            }
        }
    }
}

/// [`adaptive_simpson`] to a tolerance relative to the integral (estimated on a coarse grid).
fn relative_simpson(f: &dyn Fn(f64) -> f64, a: f64, b: f64, rel: f64) -> f64 {
    let k = 8;
    let h = (b - a) / k as f64;
    let coarse: f64 = (0..=k)
        .map(|i| {
            f(a + i as f64 * h)
                * if i == 0 || i == k {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                }
        })
        .sum::<f64>()
        * h
        / 3.0;
    adaptive_simpson(f, a, b, rel * coarse.abs() + 1e-300, 40)
}

/// Direct light in fog next to a small area light (a 10 × 10 cm emitter of radiance 300 facing
/// down in the plane y = 0, fog of albedo 0.93 and g 0.5, black walls, single scattering only),
/// against quadrature:
/// per pixel (2 × 2 sub-pixel rays) the emitter seen through the fog, if the ray ends on it,
/// plus the single-scattering integral along the ray, ∫ σs Tr(t) ∫_A Le f_HG cos_l Tr(r)/r² dA dt.
/// `eye`, `target`, `fov`: a camera whose rays all pass beside the light or all end on it
/// (never an edge, which sub-pixel rays could not integrate). Catches a wrong equiangular
/// density, phase function or transmittance on either leg, or a missing or doubled share of
/// the light, by more than 1 % + 4 standard errors in a pixel.
fn direct_next_to_small_light(eye: Vec3, target: Vec3, fov: f32, sigma_s: f32, what: &str) {
    let (sigma_a, g) = (0.08 * sigma_s, 0.5f32);
    let radiance = 300.0f32;
    let (w, h) = (4u32, 4u32);
    let mut s = empty_scene(eye, target, fov, w, h);
    s.media.push(homogeneous(Rgb::splat(sigma_s), Rgb::splat(sigma_a), g));
    s.global_medium = Some(0);
    let wall = add_material(&mut s, lambert("wall", 0.0));
    let (lo, hi) = (Vec3::splat(-2.0), Vec3::splat(2.0));
    add_box_inward(&mut s, lo, hi, wall);
    let light = add_material(&mut s, emitter("light", radiance));
    let (c, u, v) = (
        Vec3::new(-0.05, 0.0, -0.05),
        Vec3::new(0.1, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.1),
    );
    add_quad(&mut s, c, u, v, light); // front face u × v = −y
    let film = render_pt(s, 4096, 11, Some(1));

    let tan = (fov.to_radians() as f64 * 0.5).tan();
    let (st, ss, le) = ((sigma_s + sigma_a) as f64, sigma_s as f64, radiance as f64);
    let (c, u, v) = (c.as_dvec3(), u.as_dvec3(), v.as_dvec3());
    // The camera frame of `empty_scene`.
    let (eye, forward) = (eye.as_dvec3(), (target - eye).as_dvec3().normalize());
    let up = if forward.y.abs() > 0.99 {
        glam::DVec3::Z
    } else {
        glam::DVec3::Y
    };
    let right = forward.cross(up).normalize();
    let up = right.cross(forward);
    let n = 2;
    assert_pixels_match(&film, 4.0, 0.01, what, |x, y| {
        let mut sum = 0.0;
        for j in 0..n {
            for i in 0..n {
                let fx = (x as f64 + (i as f64 + 0.5) / n as f64) / w as f64;
                let fy = (y as f64 + (j as f64 + 0.5) / n as f64) / h as f64;
                let d = (right * (2.0 * fx - 1.0) * tan + up * (1.0 - 2.0 * fy) * tan + forward).normalize();
                // Where the ray ends: on the light's front, or on a wall of the box.
                let t_plane = -eye.y / d.y;
                let q = eye + t_plane * d - c;
                let on_light = t_plane > 0.0 && d.y > 0.0 && (0.0..=0.1).contains(&q.x) && (0.0..=0.1).contains(&q.z);
                let t_end = if on_light {
                    t_plane
                } else {
                    (0..3)
                        .map(|k| {
                            if d[k] > 0.0 {
                                (hi[k] as f64 - eye[k]) / d[k]
                            } else {
                                (lo[k] as f64 - eye[k]) / d[k]
                            }
                        })
                        .fold(f64::INFINITY, f64::min)
                };
                // Radiance scattered towards the camera at p, per unit σs: over the solid
                // angle the light subtends, in polar coordinates (α from the light's normal, φ
                // about it) around p's foot on the light's plane, where dA cos_l / r² = sin α
                // dα dφ and nothing is singular however close p is.
                let in_scattered = |p: glam::DVec3| {
                    let height = -p.y;
                    if height <= 0.0 {
                        return 0.0;
                    }
                    let (fx, fz) = (p.x, p.z);
                    let (x0, x1, z0, z1) = (c.x, c.x + u.x, c.z, c.z + v.z);
                    // Distances along direction φ from the foot at which the ray is inside.
                    let span = |phi: f64| {
                        let (dx, dz) = (phi.cos(), phi.sin());
                        let slab = |f: f64, d: f64, lo: f64, hi: f64| {
                            if d.abs() < 1e-15 {
                                if (lo..=hi).contains(&f) {
                                    (f64::NEG_INFINITY, f64::INFINITY)
                                } else {
                                    (1.0, 0.0)
                                }
                            } else {
                                let (a, b) = ((lo - f) / d, (hi - f) / d);
                                (a.min(b), a.max(b))
                            }
                        };
                        let (ax, bx) = slab(fx, dx, x0, x1);
                        let (az, bz) = slab(fz, dz, z0, z1);
                        (ax.max(az).max(0.0), bx.min(bz))
                    };
                    let over_phi = |phi: f64| {
                        let (near, far) = span(phi);
                        if far <= near {
                            return 0.0;
                        }
                        let over_alpha = |alpha: f64| {
                            let rho = height * alpha.tan();
                            let r = height / alpha.cos();
                            // From the light point to p, unit length.
                            let to_p = glam::DVec3::new(-rho * phi.cos(), -height, -rho * phi.sin()) / r;
                            le * hg(g as f64, -to_p.dot(d)) * (-st * r).exp() * alpha.sin()
                        };
                        relative_simpson(&over_alpha, (near / height).atan(), (far / height).atan(), 1e-7)
                    };
                    // φ in pieces between the corners' directions, where the span has kinks.
                    let mut cuts: Vec<f64> = [(x0, z0), (x1, z0), (x1, z1), (x0, z1)]
                        .iter()
                        .map(|&(x, z)| (z - fz).atan2(x - fx).rem_euclid(2.0 * PI))
                        .collect();
                    cuts.push(0.0);
                    cuts.push(2.0 * PI);
                    cuts.sort_by(f64::total_cmp);
                    cuts.windows(2)
                        .map(|w| relative_simpson(&over_phi, w[0], w[1], 1e-6))
                        .sum::<f64>()
                };
                let along = |t: f64| ss * (-st * t).exp() * in_scattered(eye + t * d);
                // In pieces that shrink towards the ray's closest approach to the light, where
                // the integrand peaks (a single adaptive rule can step over a narrow peak).
                let t_near = (-(eye - (c + 0.5 * (u + v))).dot(d)).clamp(0.0, t_end);
                let mut cuts: Vec<f64> = [0.0, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0]
                    .iter()
                    .flat_map(|&e| [t_near - e, t_near + e])
                    .chain([0.0, t_end])
                    .map(|t| t.clamp(0.0, t_end))
                    .collect();
                cuts.sort_by(f64::total_cmp);
                cuts.dedup();
                sum += cuts
                    .windows(2)
                    .map(|w| relative_simpson(&along, w[0], w[1], 1e-5))
                    .sum::<f64>();
                if on_light {
                    sum += le * (-st * t_end).exp();
                }
            }
        }
        [sum / (n * n) as f64; 3]
    });
}

/// Rays passing 1–2 cm below the light.
#[test]
fn single_scattering_beside_a_small_light_matches_quadrature() {
    // At z = 0 the image spans y = −0.015 ± 0.005.
    direct_next_to_small_light(
        Vec3::new(0.0, -0.015, 1.5),
        Vec3::new(0.0, -0.015, 0.0),
        0.4,
        0.25,
        "single scattering beside a small light",
    );
}

/// Rays ending on the light, through fog dense enough that the light scattered in front of it
/// is about a quarter of what the pixels see (the emitter itself, dimmed by the fog, the rest).
#[test]
fn single_scattering_in_front_of_a_small_light_matches_quadrature() {
    // From 0.5 m below, a 6° field of view sees only the 10-cm light (±2.6 cm of it).
    direct_next_to_small_light(
        Vec3::new(0.01, -0.5, 0.0),
        Vec3::new(0.01, 0.0, 0.0),
        6.0,
        4.0,
        "single scattering in front of a small light",
    );
}

/// A path whose throughput turns NaN (here a mirror with a NaN reflectance, which no light
/// sample or emitter hit would expose: the reflected ray leaves the scene) must reach the film
/// as a rejected sample, so the count that `--stats` and the tests read sees it. Before, the
/// path ended silently and the image was merely black (failed: 0 rejected of 64).
#[test]
fn a_nan_throughput_is_counted_by_the_film() {
    let mut s = empty_scene(Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, 20.0, 4, 4);
    let mirror = add_material(
        &mut s,
        material(
            "mirror",
            Some(beamlight_scene::bsdf::Bsdf::Mirror {
                reflectance: Rgb::splat(f32::NAN),
            }),
            Rgb::ZERO,
            false,
        ),
    );
    add_quad(&mut s, Vec3::new(-1.0, -1.0, 0.0), Vec3::X * 2.0, Vec3::Y * 2.0, mirror);
    let ts = beamlight_trace::TraceScene::new(s);
    let opts = beamlight_render::RenderOptions {
        method: beamlight_render::Method::Pt,
        width: 4,
        height: 4,
        budget: beamlight_render::Budget::Passes(4),
        seed: 1,
        first_pass: 0,
        path_tracer: Default::default(),
        start: std::time::Instant::now(),
        components: false,
        many_lights: Default::default(),
        gpu: None,
    };
    let film = beamlight_render::render(&ts, &opts, |_| true).unwrap().film;
    assert_eq!(film.rejected, 4 * 4 * 4, "every sample's path lost its throughput");
}

/// A light whose power is not finite cannot be chosen in proportion to it, so light selection
/// never samples it (`Distribution1D` gives it no share): the light sampler counts it
/// (`LightSampler::unusable`, which the command line prints as a warning) instead of the light
/// vanishing unseen. Here a point lamp with a NaN intensity (the loader refuses that one; an
/// emission whose power overflows f32 it does not) beside a sane one. Before, nothing counted
/// it (the field did not exist; made to fail by counting nothing: 0).
#[test]
fn a_light_that_cannot_be_sampled_is_counted() {
    let mut s = empty_scene(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 30.0, 4, 4);
    let floor = add_material(&mut s, lambert("floor", 0.5));
    add_quad(&mut s, Vec3::new(-2.0, -2.0, 0.0), Vec3::X * 4.0, Vec3::Y * 4.0, floor);
    for intensity in [f32::NAN, 1.0] {
        s.lights.push(PunctualLight::Point {
            position: Vec3::new(0.0, 0.0, 1.0),
            intensity: Rgb::splat(intensity),
        });
    }
    let ts = beamlight_trace::TraceScene::new(s);
    assert_eq!(ts.lights.unusable, 1);
    assert!(!ts.lights.is_empty(), "the sane lamp is still sampled");
}

/// The split path tracer (`pt::sample_pixel_components`, what `--components` and `auto` run)
/// is the plain one with its contributions sorted by component: from the same random stream its
/// components add up to the plain sample, pixel by pixel and pass by pass, up to the order of
/// the f32 sums. Scenes: a chromatic fog box (every non-caustic component) and the glass
/// furnace (caustics through specular chains). Catches a contribution the split drops or
/// doubles (a wrong index, a sink not called), which the statistical component tests see only
/// beyond their noise; not a contribution filed under the wrong component (the sum is the same).
#[test]
fn split_samples_add_up_to_the_plain_ones() {
    use beamlight_scene::rng::Sampler;
    use beamlight_trace::{TraceScene, pt};
    let settings = pt::PathTracerSettings::default();
    for (name, scene) in [
        ("chromatic fog", fog_box(12, 12, false)),
        ("glass furnace", glass_furnace(12, 16, true)),
    ] {
        let ts = TraceScene::new(scene);
        let (w, h) = (12, 12);
        let mut nonzero = 0;
        for pass in 0..16 {
            for y in 0..h {
                for x in 0..w {
                    let pixel = y * w + x;
                    let plain = pt::sample_pixel(&ts, &settings, x, y, w, h, &mut Sampler::new(3, pass, pixel));
                    let split =
                        pt::sample_pixel_components(&ts, &settings, x, y, w, h, &mut Sampler::new(3, pass, pixel));
                    let sum: Rgb = split.iter().copied().sum();
                    let scale: f32 = split.iter().map(|c| c.abs().max_element()).sum::<f32>() + 1e-30;
                    assert!(
                        (sum - plain).abs().max_element() <= 1e-5 * scale,
                        "{name}, pass {pass}, pixel ({x}, {y}): components {split:?} add up to {sum}, the plain sample is {plain}"
                    );
                    nonzero += (plain != Rgb::ZERO) as u32;
                }
            }
        }
        // The comparison is not vacuous: most samples carry light.
        assert!(nonzero > 16 * w * h / 2, "{name}: only {nonzero} samples with light");
    }
}
