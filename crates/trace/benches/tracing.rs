//! BVH build time and ray throughput on a procedural scene of ≥ 1M triangles; path-tracer
//! samples, light paths, and VRL/VPL evaluations per second on the bundled fog box, and VBL/VSL
//! evaluations there and in the smoke box (a density grid). Run with
//! `cargo bench -p beamlight-trace`.
use beamlight_scene::{Rgb, load::load_scene, rng::Sampler};
use beamlight_trace::{
    TraceScene,
    bvh::Bvh,
    camera_paths::{CameraPathSettings, GatherSet, trace_camera_paths},
    light_paths::{LightSet, LightTracerSettings, trace_light_paths},
    pt,
    vbl::{self, VblSettings},
    vpl, vrl,
};
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

/// Closest-hit rays of [`rays`] against `bvh`.
fn bench_closest_hits(b: Bencher, bvh: &Bvh) {
    let rays = rays();
    b.counter(ItemsCount::new(RAYS)).bench(|| {
        rays.iter()
            .filter(|(o, d)| bvh.closest_hit(*o, *d, f32::INFINITY).is_some())
            .count()
    });
}

/// Visibility (any-hit) rays of [`rays`] against `bvh`.
fn bench_visibility(b: Bencher, bvh: &Bvh) {
    let rays = rays();
    b.counter(ItemsCount::new(RAYS))
        .bench(|| rays.iter().filter(|(o, d)| bvh.occluded(*o, *d, f32::INFINITY)).count());
}

#[divan::bench(sample_count = 10)]
fn closest_hit_rays(b: Bencher) {
    bench_closest_hits(b, &big_scene().1);
}

#[divan::bench(sample_count = 10)]
fn visibility_rays(b: Bencher) {
    bench_visibility(b, &big_scene().1);
}

/// The same bumpy sphere with 4096 triangles: the whole BVH fits in the caches, so these rates
/// measure the traversal's arithmetic rather than memory latency.
fn small_scene() -> &'static Bvh {
    static SCENE: OnceLock<Bvh> = OnceLock::new();
    SCENE.get_or_init(|| Bvh::from_positions(bumpy_sphere(32, 64)))
}

#[divan::bench(sample_count = 10)]
fn closest_hit_rays_4k_triangles(b: Bencher) {
    bench_closest_hits(b, small_scene());
}

#[divan::bench(sample_count = 10)]
fn visibility_rays_4k_triangles(b: Bencher) {
    bench_visibility(b, small_scene());
}

fn fog_box() -> &'static TraceScene {
    static SCENE: OnceLock<TraceScene> = OnceLock::new();
    SCENE.get_or_init(|| bundled("cornell_fog"))
}

/// The smoke box: a plume in a density grid, where every transmittance is a walk.
fn smoke_box() -> &'static TraceScene {
    static SCENE: OnceLock<TraceScene> = OnceLock::new();
    SCENE.get_or_init(|| bundled("cornell_smoke"))
}

fn bundled(name: &str) -> TraceScene {
    let path = format!("{}/../../assets/scenes/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    TraceScene::new(load_scene(std::path::Path::new(&path)).expect("bundled scene"))
}

/// One path-traced sample for every pixel of the 256×256 fog box, on one thread.
#[divan::bench(sample_count = 5)]
fn path_tracer_fog_box(b: Bencher) {
    let ts = fog_box();
    let (w, h) = (ts.scene.render.width, ts.scene.render.height);
    let settings = pt::PathTracerSettings::default();
    let mut pass = 0;
    b.counter(ItemsCount::new((w * h) as usize)).bench_local(|| {
        pass += 1;
        let mut sum = 0.0;
        for y in 0..h {
            for x in 0..w {
                let mut s = Sampler::new(0, pass, y * w + x);
                sum += pt::sample_pixel(ts, &settings, x, y, w, h, &mut s).x;
            }
        }
        sum
    });
}

/// Light paths traced into VRLs, VPLs, caustic photons and beams on the fog box, one thread
/// (items: light paths).
#[divan::bench(sample_count = 10)]
fn light_paths_fog_box(b: Bencher) {
    let ts = fog_box();
    let settings = LightTracerSettings::default();
    let mut pass = 0;
    b.counter(ItemsCount::new(4096usize)).bench_local(|| {
        pass += 1;
        trace_light_paths(ts, &settings, 4096, 0, pass)
    });
}

/// One pass's gather data and light set of the fog box at 64×64, for the evaluation benches.
fn gather_fixture() -> &'static (GatherSet, LightSet) {
    static DATA: OnceLock<(GatherSet, LightSet)> = OnceLock::new();
    DATA.get_or_init(|| one_pass(fog_box()))
}

/// The same for the smoke box.
fn smoke_fixture() -> &'static (GatherSet, LightSet) {
    static DATA: OnceLock<(GatherSet, LightSet)> = OnceLock::new();
    DATA.get_or_init(|| one_pass(smoke_box()))
}

fn one_pass(ts: &TraceScene) -> (GatherSet, LightSet) {
    let gather = trace_camera_paths(ts, &CameraPathSettings::default(), 64, 64, 0, 0);
    let lights = trace_light_paths(ts, &LightTracerSettings::default(), 64, 0, 0);
    (gather, lights)
}

/// Unclamped VRL evaluations (`Lsm` at shading points and `Lmm` along media segments, each
/// with its shadow ray and transmittances), one thread (items: gather point × VRL pairs).
#[divan::bench(sample_count = 5)]
fn vrl_evaluations_fog_box(b: Bencher) {
    let ts = fog_box();
    let (gather, lights) = gather_fixture();
    let pairs = (gather.shading_points.len() + gather.media_segments.len()) * lights.vrls.len();
    b.counter(ItemsCount::new(pairs)).bench_local(|| {
        let mut s = Sampler::new(1, 0, 0);
        let mut sum = Rgb::ZERO;
        for v in &lights.vrls {
            for sp in &gather.shading_points {
                sum += vrl::vrl_to_surface(ts, sp, v, 0.0, &mut s);
            }
            for seg in &gather.media_segments {
                sum += vrl::vrl_to_media(ts, seg, v, 0.0, &mut s);
            }
        }
        sum
    });
}

/// Unclamped VPL evaluations (`Lss` and `Lms`), one thread (items: gather point × VPL pairs).
#[divan::bench(sample_count = 5)]
fn vpl_evaluations_fog_box(b: Bencher) {
    let ts = fog_box();
    let (gather, lights) = gather_fixture();
    let pairs = (gather.shading_points.len() + gather.media_segments.len()) * lights.vpls.len();
    b.counter(ItemsCount::new(pairs)).bench_local(|| {
        let mut s = Sampler::new(1, 0, 0);
        let mut sum = Rgb::ZERO;
        for v in &lights.vpls {
            for sp in &gather.shading_points {
                sum += vpl::vpl_to_surface(ts, sp, v, 0.0, &mut s);
            }
            for seg in &gather.media_segments {
                sum += vpl::vpl_to_media(ts, seg, v, 0.0, &mut s);
            }
        }
        sum
    });
}

/// VBL/VSL evaluations per component on the same gather data (items: gather point × light
/// pairs), one thread, with a mid-render radius (the 100th pass of R0 = 10 % of the diagonal,
/// 64 paths per pass: R ≈ 0.087).
fn vbl_bench(b: Bencher, (ts, (gather, lights)): (&TraceScene, &(GatherSet, LightSet)), component: &str) {
    let settings = VblSettings::default();
    let r2 = 0.087f32 * 0.087;
    let (points, segments) = (&gather.shading_points, &gather.media_segments);
    let pairs = match component {
        "Lsm" => points.len() * lights.vrls.len(),
        "Lmm" => segments.len() * lights.vrls.len(),
        "Lss" => points.len() * lights.vpls.len(),
        _ => segments.len() * lights.vpls.len(),
    };
    b.counter(ItemsCount::new(pairs)).bench_local(|| {
        let mut s = Sampler::new(1, 0, 0);
        let mut sum = Rgb::ZERO;
        match component {
            "Lsm" => lights.vrls.iter().for_each(|v| {
                points
                    .iter()
                    .for_each(|p| sum += vbl::vbl_to_surface(ts, p, v, r2, &settings, &mut s))
            }),
            "Lmm" => lights.vrls.iter().for_each(|v| {
                segments
                    .iter()
                    .for_each(|g| sum += vbl::vbl_to_media(ts, g, v, r2, &settings, &mut s))
            }),
            "Lss" => lights.vpls.iter().for_each(|v| {
                points
                    .iter()
                    .for_each(|p| sum += vbl::vsl_to_surface(ts, p, v, r2, &settings, &mut s))
            }),
            _ => lights.vpls.iter().for_each(|v| {
                segments
                    .iter()
                    .for_each(|g| sum += vbl::vsl_to_media(ts, g, v, r2, &settings, &mut s))
            }),
        }
        sum
    });
}

#[divan::bench(sample_count = 3, args = ["Lsm", "Lmm", "Lms", "Lss"])]
fn vbl_evaluations_fog_box(b: Bencher, component: &str) {
    vbl_bench(b, (fog_box(), gather_fixture()), component);
}

/// The same in the smoke box, whose pairs walk their transmittances through the grid (`Lmm`
/// and `Lms` at 4× the majorant's rate, `vbl::MEDIA_PAIR_TRACKING_RATE`) and shape their
/// angular PDFs by its density.
#[divan::bench(sample_count = 3, args = ["Lsm", "Lmm", "Lms", "Lss"])]
fn vbl_evaluations_smoke_box(b: Bencher, component: &str) {
    vbl_bench(b, (smoke_box(), smoke_fixture()), component);
}
