//! BVH build time and ray throughput on a procedural scene of ≥ 1M triangles, and path-tracer
//! samples per second on the bundled fog box. Run with `cargo bench -p beamlight-trace`.
use beamlight_scene::{load::load_scene, rng::Sampler};
use beamlight_trace::{TraceScene, bvh::Bvh, pt};
use divan::{Bencher, counter::ItemsCount};
use glam::Vec3;
use std::sync::OnceLock;

fn main() {
    divan::main();
}

/// A bumpy sphere of `2·rings·segments` triangles (1 048 576 for 512 × 1024).
fn bumpy_sphere(rings: u32, segments: u32) -> Vec<[Vec3; 3]> {
    let point = |i: u32, j: u32| {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        let phi = std::f32::consts::TAU * j as f32 / segments as f32;
        let r = 1.0 + 0.05 * (7.0 * theta).sin() * (11.0 * phi).cos();
        Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()) * r
    };
    let mut tris = Vec::with_capacity((2 * rings * segments) as usize);
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1));
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    tris
}

fn big_scene() -> &'static (Vec<[Vec3; 3]>, Bvh) {
    static SCENE: OnceLock<(Vec<[Vec3; 3]>, Bvh)> = OnceLock::new();
    SCENE.get_or_init(|| {
        let tris = bumpy_sphere(512, 1024);
        let bvh = Bvh::from_positions(tris.clone());
        (tris, bvh)
    })
}

#[divan::bench(sample_count = 3, sample_size = 1)]
fn bvh_build_1m_triangles(b: Bencher) {
    let tris = big_scene().0.clone();
    b.counter(ItemsCount::new(tris.len()))
        .bench(|| Bvh::from_positions(tris.clone()));
}

const RAYS: usize = 100_000;

fn rays() -> Vec<(Vec3, Vec3)> {
    let mut s = Sampler::new(1, 0, 0);
    (0..RAYS)
        .map(|_| {
            // From random points around the sphere towards random points near its centre.
            let o = (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5) * 6.0;
            let t = (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5) * 0.5;
            (o, (t - o).normalize())
        })
        .collect()
}

#[divan::bench(sample_count = 10)]
fn closest_hit_rays(b: Bencher) {
    let bvh = &big_scene().1;
    let rays = rays();
    b.counter(ItemsCount::new(RAYS)).bench(|| {
        rays.iter()
            .filter(|(o, d)| bvh.closest_hit(*o, *d, f32::INFINITY).is_some())
            .count()
    });
}

#[divan::bench(sample_count = 10)]
fn visibility_rays(b: Bencher) {
    let bvh = &big_scene().1;
    let rays = rays();
    b.counter(ItemsCount::new(RAYS))
        .bench(|| rays.iter().filter(|(o, d)| bvh.occluded(*o, *d, f32::INFINITY)).count());
}

/// One path-traced sample for every pixel of the 256×256 fog box, on one thread.
#[divan::bench(sample_count = 5)]
fn path_tracer_fog_box(b: Bencher) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/scenes/cornell_fog.toml");
    let ts = TraceScene::new(load_scene(std::path::Path::new(path)).expect("bundled scene"));
    let (w, h) = (ts.scene.render.width, ts.scene.render.height);
    let settings = pt::PathTracerSettings::default();
    let mut pass = 0;
    b.counter(ItemsCount::new((w * h) as usize)).bench_local(|| {
        pass += 1;
        let mut sum = 0.0;
        for y in 0..h {
            for x in 0..w {
                let mut s = Sampler::new(0, pass, y * w + x);
                sum += pt::sample_pixel(&ts, &settings, x, y, w, h, &mut s).x;
            }
        }
        sum
    });
}
