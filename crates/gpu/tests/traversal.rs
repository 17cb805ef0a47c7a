//! GPU ray queries equal the CPU BVH's: for 10^5 random rays against a few meshes (one with
//! over 10^5 triangles), the same hit or miss, the same triangle, and t within 1e-5 relative.
use beamlight_gpu::{GpuScene, device, layout::Ray, rays::RayTracer};
use beamlight_scene::rng::Sampler;
use beamlight_trace::bvh::Bvh;
use glam::Vec3;

/// A random triangle soup in [0, 10 scale]³.
fn soup(n: usize, scale: f32, s: &mut Sampler) -> Vec<[Vec3; 3]> {
    let mut rnd = || Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * scale;
    (0..n)
        .map(|_| {
            let c = rnd() * 10.0;
            let h = Vec3::splat(0.5 * scale);
            [c + rnd() - h, c + rnd() - h, c + rnd() - h]
        })
        .collect()
}

/// A closed, bumpy sphere of `2 · n · (n − 1)` or so triangles (a UV sphere with a radial
/// ripple), centred at 5 · scale: shared edges everywhere, the watertightness case.
fn bumpy_sphere(n: u32, scale: f32) -> Vec<[Vec3; 3]> {
    let at = |i: u32, j: u32| {
        let theta = std::f32::consts::PI * i as f32 / n as f32;
        let phi = std::f32::consts::TAU * j as f32 / n as f32;
        let r = 3.0 + 0.2 * (7.0 * phi).sin() * (5.0 * theta).sin();
        (Vec3::splat(5.0) + r * Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin())) * scale
    };
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            if i > 0 {
                tris.push([a, b, d]);
            }
            if i + 1 < n {
                tris.push([b, c, d]);
            }
        }
    }
    tris
}

fn random_rays(count: usize, scale: f32, s: &mut Sampler) -> Vec<Ray> {
    (0..count)
        .map(|k| {
            let o = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 12.0 * scale - Vec3::splat(scale);
            let d = (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5).normalize();
            // A third each: unbounded, bounded, and occlusion queries.
            let tmax = if k % 3 == 0 { f32::INFINITY } else { 4.0 * scale };
            Ray {
                o: o.into(),
                tmax,
                d: d.into(),
                any_hit: (k % 3 == 2) as u32,
            }
        })
        .collect()
}

fn compare(name: &str, tris: Vec<[Vec3; 3]>, scale: f32, rays: usize, seed: u32) {
    compare_split(name, tris, scale, rays, seed, usize::MAX);
}

/// [`compare`] with at most `per_binding` triangles in each triangle binding.
fn compare_split(name: &str, tris: Vec<[Vec3; 3]>, scale: f32, rays: usize, seed: u32, per_binding: usize) {
    let Some(gpu) = device::for_tests() else { return };
    let scene = GpuScene::geometry_split(&gpu, &tris, per_binding).unwrap();
    let tracer = RayTracer::new(&gpu, &scene).unwrap();
    let cpu = Bvh::from_positions(tris.clone());
    let mut s = Sampler::new(seed, 0, 0);
    let rays = random_rays(rays, scale, &mut s);
    let hits = tracer.trace(&gpu, &scene, &rays).unwrap().hits;
    let (mut hit_count, mut mismatches) = (0, Vec::new());
    for (k, (ray, g)) in rays.iter().zip(&hits).enumerate() {
        let (o, d) = (Vec3::from(ray.o), Vec3::from(ray.d));
        if ray.any_hit != 0 {
            let blocked = cpu.occluded(o, d, ray.tmax);
            if blocked != (g.t >= 0.0) {
                mismatches.push(format!("ray {k}: occlusion cpu {blocked}, gpu {}", g.t >= 0.0));
            }
            continue;
        }
        match cpu.closest_hit(o, d, ray.tmax) {
            None if g.t < 0.0 => {}
            Some(c) if g.t >= 0.0 => {
                hit_count += 1;
                if c.tri != g.tri || (c.t - g.t).abs() > 1e-5 * c.t {
                    mismatches.push(format!(
                        "ray {k}: cpu tri {} t {}, gpu tri {} t {}",
                        c.tri, c.t, g.tri, g.t
                    ));
                }
            }
            c => mismatches.push(format!(
                "ray {k}: cpu {:?}, gpu t {} tri {}",
                c.map(|h| (h.tri, h.t)),
                g.t,
                g.tri
            )),
        }
    }
    assert!(
        mismatches.is_empty(),
        "{name}: {} of {} rays differ:\n{}",
        mismatches.len(),
        rays.len(),
        mismatches[..mismatches.len().min(10)].join("\n")
    );
    // The rays must actually test something.
    assert!(hit_count > rays.len() / 20, "{name}: only {hit_count} hits");
}

#[test]
fn soup_matches_cpu_at_every_scale() {
    for (i, scale) in [1e-3f32, 1.0, 1e3].into_iter().enumerate() {
        let mut s = Sampler::new(11, i as u32, 0);
        compare(
            &format!("soup at scale {scale}"),
            soup(3000, scale, &mut s),
            scale,
            30_000,
            7 + i as u32,
        );
    }
}

#[test]
fn large_closed_mesh_matches_cpu() {
    let tris = bumpy_sphere(226, 1.0);
    assert!(tris.len() >= 100_000, "{} triangles", tris.len());
    compare("bumpy sphere", tris, 1.0, 100_000, 3);
}

/// Triangles split over two bindings (as a scene beyond 128 MiB of triangles is on lavapipe)
/// trace the same as in one.
#[test]
fn triangles_split_over_two_bindings_match_cpu() {
    let tris = bumpy_sphere(100, 1.0);
    let n = tris.len();
    compare_split("split sphere", tris, 1.0, 20_000, 9, n / 3);
}

#[test]
fn empty_scene_misses() {
    let Some(gpu) = device::for_tests() else { return };
    let scene = GpuScene::geometry_only(&gpu, &[]).unwrap();
    let tracer = RayTracer::new(&gpu, &scene).unwrap();
    let hits = tracer
        .trace(&gpu, &scene, &random_rays(100, 1.0, &mut Sampler::new(1, 0, 0)))
        .unwrap()
        .hits;
    assert!(hits.iter().all(|h| h.t < 0.0));
}

/// A scene of two million triangles uploads within lavapipe's limits (128 MiB per storage
/// binding) and traces like the CPU.
#[test]
fn two_million_triangles() {
    let Some(gpu) = device::for_tests() else { return };
    let tris = bumpy_sphere(1001, 1.0);
    assert!(tris.len() >= 2_000_000, "{} triangles", tris.len());
    let flat = beamlight_gpu::scene::FlatBvh::build(&tris);
    eprintln!(
        "{} triangles: {} BVH nodes ({} MiB), triangles {} MiB",
        tris.len(),
        flat.nodes.len(),
        (flat.nodes.len() * 32) >> 20,
        (flat.triangles.len() * 48) >> 20
    );
    drop(flat);
    let _ = gpu;
    compare("two million triangles", tris, 1.0, 20_000, 5);
}
