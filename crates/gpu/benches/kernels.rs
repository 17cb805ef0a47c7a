//! Kernel microbenchmarks: visibility rays and gathers per second on the GPU (kernel time
//! from timestamp queries) against the CPU twins on the same inputs (all cores, rayon), as
//! ratios measured in one run. Run with `cargo bench -p beamlight-gpu` (lavapipe runs on the
//! same cores as the CPU twins, so on a machine without a GPU this compares two ways of
//! using the same cores).
use beamlight_gpu::{
    GpuBackend,
    gather::{GatherInputs, GatherKernel},
    layout::Ray,
    rays::RayTracer,
};
use beamlight_scene::{Rgb, load::load_scene, rng::Sampler};
use beamlight_trace::{
    TraceScene,
    camera_paths::{CameraPathSettings, trace_camera_paths},
    light_paths::{LightTracerSettings, trace_light_paths},
    light_tree::{Draw, Drawing, LightTree, Receiver},
    streams::{self, GatherKind},
    vbl::{self, VblSettings},
    vpl, vrl,
};
use glam::Vec3;
use rayon::prelude::*;
use std::time::Instant;

fn main() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/cornell_glossy_fog.toml");
    let scene = load_scene(&path).expect("bundled scene");
    let ts = TraceScene::new(scene);
    let backend = match GpuBackend::open(&ts) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("no GPU: {e}");
            return;
        }
    };
    println!("adapter: {}", backend.gpu.describe());
    println!("scene: {} ({} triangles)", path.display(), ts.scene.triangles.len());
    rays(&ts, &backend);
    gathers(&ts, &backend);
}

fn rays(ts: &TraceScene, b: &GpuBackend) {
    let (lo, hi) = ts.scene.bounds();
    let mut s = Sampler::new(1, 0, 0);
    let n = 1 << 20;
    for any_hit in [0u32, 1] {
        let rays: Vec<Ray> = (0..n)
            .map(|_| {
                let o = lo + (hi - lo) * Vec3::new(s.next_1d(), s.next_1d(), s.next_1d());
                let d = (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5).normalize();
                Ray {
                    o: o.into(),
                    tmax: if any_hit == 1 {
                        0.5 * (hi - lo).length()
                    } else {
                        f32::INFINITY
                    },
                    d: d.into(),
                    any_hit,
                }
            })
            .collect();
        let tracer = RayTracer::new(&b.gpu, &b.scene).unwrap();
        tracer.trace(&b.gpu, &b.scene, &rays[..1024]).unwrap(); // warm-up
        let gpu = tracer
            .trace(&b.gpu, &b.scene, &rays)
            .unwrap()
            .kernel_seconds
            .unwrap_or(f64::NAN);
        let clock = Instant::now();
        let hits: usize = rays
            .par_iter()
            .map(|r| {
                let (o, d) = (Vec3::from(r.o), Vec3::from(r.d));
                if any_hit == 1 {
                    ts.bvh.occluded(o, d, r.tmax) as usize
                } else {
                    ts.bvh.closest_hit(o, d, r.tmax).is_some() as usize
                }
            })
            .sum();
        let cpu = clock.elapsed().as_secs_f64();
        std::hint::black_box(hits);
        report(
            if any_hit == 1 {
                "occlusion rays"
            } else {
                "closest-hit rays"
            },
            n as f64,
            gpu,
            cpu,
        );
    }
}

fn gathers(ts: &TraceScene, b: &GpuBackend) {
    let (w, h) = (64, 64);
    let (seed, pass) = (3, 0);
    let gather = trace_camera_paths(ts, &CameraPathSettings::default(), w, h, seed, pass);
    let lights = trace_light_paths(ts, &LightTracerSettings::default(), 64, seed, pass);
    let pair_seed = streams::pair_seed(seed);
    // The default first-pass VBL radius (10 % of the diagonal, × 64^((α−1)/2) for 64 paths).
    let (lo, hi) = ts.scene.bounds();
    let radius2 = (0.1 * (hi - lo).length() * 0.535f32).powi(2);
    let vbl = VblSettings::default();
    let vpl_walls = vbl::vpl_walls_all(ts, &lights.vpls, radius2);
    let inputs = GatherInputs {
        shading_points: &gather.shading_points,
        media_segments: &gather.media_segments,
        vpls: &lights.vpls,
        vpl_walls: &vpl_walls,
        vrls: &lights.vrls,
        paths: lights.paths,
        pair_seed,
        pass,
        clamp: 0.0,
        radius2,
        vbl,
        light_samples: 0,
        media_light_samples: 0,
        media_drawing: Drawing::Descent,
        media_masses: &[],
        vsl_tree: &[],
        vbl_tree: &[],
        inject_nan: false,
    };
    b.gathers
        .run(
            &b.gpu,
            &b.scene,
            &ts.scene,
            &inputs,
            [true; beamlight_gpu::gather::KERNELS],
        )
        .unwrap(); // warm-up
    let g = b
        .gathers
        .run(
            &b.gpu,
            &b.scene,
            &ts.scene,
            &inputs,
            [true; beamlight_gpu::gather::KERNELS],
        )
        .unwrap();
    let pair = |kind, i: usize, j: usize| streams::pair_sampler(pair_seed, pass, kind, i as u32, j as u32);
    let sps = &gather.shading_points;
    let segs = &gather.media_segments;
    for k in GatherKernel::ALL.into_iter().filter(|k| k.available()) {
        let clock = Instant::now();
        let total: Rgb = match k {
            GatherKernel::VplSurface => sum_over(sps, &lights.vpls, |i, sp, j, v| {
                vpl::vpl_to_surface(ts, sp, v, 0.0, &mut pair(GatherKind::VplToSurface, i, j))
            }),
            GatherKernel::VrlSurface => sum_over(sps, &lights.vrls, |i, sp, j, v| {
                vrl::vrl_to_surface(ts, sp, v, 0.0, &mut pair(GatherKind::VrlToSurface, i, j))
            }),
            GatherKernel::VplMedia => sum_over(segs, &lights.vpls, |i, seg, j, v| {
                vpl::vpl_to_media(ts, seg, v, 0.0, &mut pair(GatherKind::VplToMedia, i, j))
            }),
            GatherKernel::VrlMedia => sum_over(segs, &lights.vrls, |i, seg, j, v| {
                vrl::vrl_to_media(ts, seg, v, 0.0, &mut pair(GatherKind::VrlToMedia, i, j))
            }),
            GatherKernel::VslSurface => sum_over(sps, &lights.vpls, |i, sp, j, v| {
                vbl::vsl_to_surface_within(
                    ts,
                    sp,
                    v,
                    &vpl_walls[j],
                    radius2,
                    &vbl,
                    &mut pair(GatherKind::VplToSurface, i, j),
                )
            }),
            GatherKernel::VblSurface => sum_over(sps, &lights.vrls, |i, sp, j, v| {
                vbl::vbl_to_surface(ts, sp, v, radius2, &vbl, &mut pair(GatherKind::VrlToSurface, i, j))
            }),
            GatherKernel::VslMedia => sum_over(segs, &lights.vpls, |i, seg, j, v| {
                vbl::vsl_to_media_within(
                    ts,
                    seg,
                    v,
                    &vpl_walls[j],
                    radius2,
                    &vbl,
                    &mut pair(GatherKind::VplToMedia, i, j),
                )
            }),
            GatherKernel::VblMedia => sum_over(segs, &lights.vrls, |i, seg, j, v| {
                vbl::vbl_to_media(ts, seg, v, radius2, &vbl, &mut pair(GatherKind::VrlToMedia, i, j))
            }),
        };
        let cpu = clock.elapsed().as_secs_f64();
        std::hint::black_box(total);
        report(
            &format!("gathers {}", k.name()),
            (k.records(&inputs) * k.lights(&inputs)) as f64,
            g.kernel_seconds[k as usize],
            cpu,
        );
        if GatherKernel::BEAMS.contains(&k) {
            report_records(
                &format!("  {} records, all {} lights", k.name(), k.lights(&inputs)),
                k.records(&inputs) as f64,
                g.kernel_seconds[k as usize],
                cpu,
            );
        }
    }
    selected_gathers(ts, b, &inputs);
}

/// The `vbl` kernels with light selection (the default 4 lights drawn per record from the
/// pass's light trees): gather records per second, GPU against the CPU twins.
fn selected_gathers(ts: &TraceScene, b: &GpuBackend, all: &GatherInputs) {
    let samples = 4;
    let vsl_tree = LightTree::over_vsls(&ts.scene, all.vpls);
    let vbl_tree = LightTree::over_vbls(&ts.scene, all.vrls, all.radius2.sqrt());
    let inputs = GatherInputs {
        light_samples: samples,
        media_light_samples: samples,
        media_drawing: Drawing::Descent,
        media_masses: &[],
        vsl_tree: &vsl_tree.nodes,
        vbl_tree: &vbl_tree.nodes,
        inject_nan: false,
        ..*all
    };
    let mut run = [false; beamlight_gpu::gather::KERNELS];
    for k in GatherKernel::BEAMS {
        run[k as usize] = true;
    }
    b.gathers.run(&b.gpu, &b.scene, &ts.scene, &inputs, run).unwrap(); // warm-up
    let g = b.gathers.run(&b.gpu, &b.scene, &ts.scene, &inputs, run).unwrap();
    let (pair_seed, pass, radius2, vbl) = (all.pair_seed, all.pass, all.radius2, all.vbl);
    let r = radius2.sqrt();
    let (sps, segs) = (all.shading_points, all.media_segments);
    let (vpls, vrls) = (all.vpls, all.vrls);
    for k in GatherKernel::BEAMS {
        let kind = match k {
            GatherKernel::VslSurface => GatherKind::VplToSurface,
            GatherKernel::VblSurface => GatherKind::VrlToSurface,
            GatherKernel::VslMedia => GatherKind::VplToMedia,
            _ => GatherKind::VrlToMedia,
        };
        let tree = if k.reads_vpls() { &vsl_tree } else { &vbl_tree };
        let drawn = |i: usize, slot: u32| streams::drawn_pair_sampler(pair_seed, pass, kind, i as u32, slot);
        let estimate = |i: usize, rx: Receiver, f: &(dyn Fn(usize, &mut Sampler) -> Rgb + Sync)| {
            let xi = streams::selection_number(pair_seed, pass, kind, i as u32);
            let descent = |slot| streams::selection_sampler(pair_seed, pass, kind, i as u32, slot);
            tree.estimate(&rx, r, samples, xi, Draw::Descent, descent, |slot, j| {
                f(j, &mut drawn(i, slot))
            })
        };
        let clock = Instant::now();
        let total: Rgb = if k.on_surfaces() {
            sps.par_iter()
                .enumerate()
                .map(|(i, sp)| {
                    estimate(i, Receiver::at_point(&ts.scene, sp), &|j, s| match k {
                        GatherKernel::VslSurface => {
                            vbl::vsl_to_surface_within(ts, sp, &vpls[j], &all.vpl_walls[j], radius2, &vbl, s)
                        }
                        _ => vbl::vbl_to_surface(ts, sp, &vrls[j], radius2, &vbl, s),
                    })
                })
                .sum()
        } else {
            segs.par_iter()
                .enumerate()
                .map(|(i, seg)| {
                    estimate(i, Receiver::along_segment(&ts.scene, seg), &|j, s| match k {
                        GatherKernel::VslMedia => {
                            vbl::vsl_to_media_within(ts, seg, &vpls[j], &all.vpl_walls[j], radius2, &vbl, s)
                        }
                        _ => vbl::vbl_to_media(ts, seg, &vrls[j], radius2, &vbl, s),
                    })
                })
                .sum()
        };
        let cpu = clock.elapsed().as_secs_f64();
        std::hint::black_box(total);
        report_records(
            &format!("  {} records, {samples} drawn", k.name()),
            k.records(&inputs) as f64,
            g.kernel_seconds[k as usize],
            cpu,
        );
    }
}

/// Σ over records (in parallel) and lights of `f(record index, record, light index, light)`.
fn sum_over<R: Sync, L: Sync>(records: &[R], lights: &[L], f: impl Fn(usize, &R, usize, &L) -> Rgb + Sync) -> Rgb {
    records
        .par_iter()
        .enumerate()
        .map(|(i, r)| lights.iter().enumerate().map(|(j, l)| f(i, r, j, l)).sum::<Rgb>())
        .sum()
}

/// Gather records per second (each against all of its lights, or its drawn ones).
fn report_records(what: &str, n: f64, gpu: f64, cpu: f64) {
    println!(
        "{what:<36} gpu {:>8.1} k/s   cpu {:>8.1} k/s ({} threads)   gpu/cpu {:>5.2}",
        n / gpu / 1e3,
        n / cpu / 1e3,
        rayon::current_num_threads(),
        cpu / gpu
    );
}

fn report(what: &str, n: f64, gpu: f64, cpu: f64) {
    println!(
        "{what:<36} gpu {:>8.2} M/s   cpu {:>8.2} M/s ({} threads)   gpu/cpu {:>5.2}",
        n / gpu / 1e6,
        n / cpu / 1e6,
        rayon::current_num_threads(),
        cpu / gpu
    );
}
