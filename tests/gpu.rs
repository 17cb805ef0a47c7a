//! The GPU gathers against their CPU twins, on lavapipe in the normal test run: per gather
//! record one pass's kernel result equals the CPU estimator's with the same random streams,
//! and whole `vrl` and `vbl` renders on both backends agree per pixel.
mod common;
use beamlight_gpu::{
    GpuBackend,
    gather::{GatherInputs, GatherKernel},
};
use beamlight_render::{Budget, Method, RenderOptions, many_lights::ManyLightSettings, render};
use beamlight_scene::{Rgb, Scene, bsdf::Bsdf, gltf_writer::shapes, scene::MediumInterface};
use beamlight_trace::{
    TraceScene,
    camera_paths::{CameraPathSettings, trace_camera_paths},
    light_paths::{LightTracerSettings, trace_light_paths},
    light_tree::{LightTree, Receiver},
    streams::{self, GatherKind},
    vbl::{self, AngularPdf, VblSettings},
    vpl, vrl,
};
use common::*;
use glam::Vec3;
use std::{sync::Arc, time::Instant};

fn phong(s: &mut Scene, n: f32) -> u32 {
    add_material(
        s,
        material(
            "phong",
            Some(Bsdf::Phong {
                diffuse: Rgb::new(0.3, 0.25, 0.2),
                specular: Rgb::splat(0.5),
                exponent: n,
            }),
            Rgb::ZERO,
            false,
        ),
    )
}

/// The fog box (global medium: shadow rays take the occlusion fast path) with a glossy cube.
fn glossy_fog_box(lumpy: bool) -> Scene {
    let mut s = fog_box(24, 24, lumpy);
    let m = phong(&mut s, 30.0);
    add_mesh(
        &mut s,
        shapes::cuboid(Vec3::new(-0.5, -1.0, -0.6), Vec3::new(0.1, -0.4, 0.0), false),
        m,
        None,
    );
    s
}

/// A room in vacuum with a sphere of chromatic fog behind an invisible boundary (shadow rays
/// walk the boundary's hits) and a glossy floor.
fn bounded_fog(lumpy: bool) -> Scene {
    let mut s = empty_scene(Vec3::new(0.0, 0.1, 0.95), Vec3::new(0.0, -0.2, -1.0), 70.0, 24, 24);
    let wall = add_material(&mut s, lambert("wall", 0.6));
    add_box_inward(&mut s, Vec3::splat(-1.0), Vec3::splat(1.0), wall);
    let glossy = phong(&mut s, 80.0);
    add_quad(
        &mut s,
        Vec3::new(-0.99, -0.99, -0.99),
        Vec3::Z * 1.98,
        Vec3::X * 1.98,
        glossy,
    );
    let light = add_material(&mut s, emitter("light", 10.0));
    add_quad(
        &mut s,
        Vec3::new(-0.3, 0.99, -0.3),
        Vec3::new(0.6, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.6),
        light,
    );
    let boundary = add_material(&mut s, material("boundary", None, Rgb::ZERO, false));
    let mut m = homogeneous(Rgb::new(2.0, 1.2, 0.8), Rgb::splat(0.2), 0.5);
    if lumpy {
        let res = glam::UVec3::splat(10);
        let values = (0..res.x * res.y * res.z)
            .map(|i| {
                let c = glam::UVec3::new(i % 10, i / 10 % 10, i / 100);
                // Lumps and empty cells, so ratio tracking meets every case.
                if (c.x + c.y).is_multiple_of(4) {
                    0.0
                } else {
                    0.5 + (c.z as f32 * 0.7).sin().abs() * 2.0
                }
            })
            .collect();
        m.density = Some(beamlight_scene::medium::DensityGrid::new(
            res,
            Vec3::new(-0.6, -0.7, -0.8),
            Vec3::new(0.4, 0.3, 0.2),
            values,
        ));
    }
    s.media.push(m);
    add_mesh(
        &mut s,
        shapes::uv_sphere(Vec3::new(-0.1, -0.2, -0.3), 0.5, 12, 24),
        boundary,
        Some(MediumInterface {
            inside: Some(0),
            outside: None,
        }),
    );
    s
}

/// Per gather record, the sum over all lights of `f(record index, record, light index, light)`
/// divided by the light path count `m`: one pass's CPU estimate of a component.
fn per_record<R, L>(records: &[R], lights: &[L], m: f32, f: impl Fn(usize, &R, usize, &L) -> Rgb) -> Vec<Rgb> {
    records
        .iter()
        .enumerate()
        .map(|(i, r)| lights.iter().enumerate().map(|(j, l)| f(i, r, j, l)).sum::<Rgb>() / m)
        .collect()
}

/// One kernel's results against the CPU's, record by record: nearly every record agrees to
/// 1e-4 and the component's total to 1e-4.
fn check_kernel(name: &str, k: GatherKernel, gpu: &[Rgb], cpu: &[Rgb]) {
    assert_eq!(gpu.len(), cpu.len(), "{name} {}", k.name());
    assert!(!cpu.is_empty(), "{name} {}: no records", k.name());
    // Relative 1e-4, or absolute 1e-4 of the component's mean for values near zero.
    let mean = cpu.iter().map(|c| c.max_element() as f64).sum::<f64>() / cpu.len() as f64;
    assert!(mean > 0.0, "{name} {}: the CPU estimate is black", k.name());
    let mut errors: Vec<(f64, usize)> = gpu
        .iter()
        .zip(cpu)
        .enumerate()
        .map(|(i, (a, b))| {
            let err = (0..3)
                .map(|c| {
                    let (a, b) = (a[c] as f64, b[c] as f64);
                    assert!(a.is_finite(), "{name} {} record {i}: {a}", k.name());
                    (a - b).abs() / b.abs().max(1e-4 * mean)
                })
                .fold(0.0, f64::max);
            (err, i)
        })
        .collect();
    errors.sort_by(|a, b| b.0.total_cmp(&a.0));
    let beyond = |tol: f64| errors.iter().filter(|e| e.0 > tol).count();
    let worst = errors[0];
    eprintln!(
        "  {:<10} worst relative difference {:.2e} (record {}); beyond 1e-4: {}, beyond 1e-3: {}, of {}",
        k.name(),
        worst.0,
        worst.1,
        beyond(1e-4),
        beyond(1e-3),
        errors.len()
    );
    for &(err, i) in errors.iter().take_while(|e| e.0 > 1e-4).take(5) {
        eprintln!(
            "    record {i}: relative difference {err:.2e}, GPU {:?} vs CPU {:?}",
            gpu[i], cpu[i]
        );
    }
    // Nearly every record agrees to 1e-4. The few that may not are ill-conditioned in
    // f32 on both sides, so CPU and GPU rounding (the GPU may fuse multiply-adds; its exp
    // and log are not libm's, its atan and tan ours) land apart: an equiangular sample next to a nearly
    // singular VRL–camera-ray pair, where t = δ + h·tan θ with θ → ±π/2 amplifies one ulp
    // of θ by x²/h, or a ratio-tracking step whose comparison against a cell boundary
    // flips and changes the number of draws. Neither shifts a component's total.
    let n = errors.len() as f64;
    assert!(
        beyond(1e-4) as f64 <= 0.01 * n && beyond(1e-3) as f64 <= 0.005 * n,
        "{name} {}: too many records differ; worst is record {}: GPU {:?} vs CPU {:?}",
        k.name(),
        worst.1,
        gpu[worst.1],
        cpu[worst.1]
    );
    let total = |v: &[Rgb]| v.iter().map(|c| c.element_sum() as f64).sum::<f64>();
    let (tg, tc) = (total(gpu), total(cpu));
    assert!(
        (tg - tc).abs() <= 1e-4 * tc,
        "{name} {}: totals GPU {tg} vs CPU {tc}",
        k.name()
    );
}

/// One pass's GPU gathers against the CPU estimators, record by record: the `vrl` kernels
/// (clamped at `clamp`; not with `None`), then the `vbl` kernels with `vbl_settings` for each
/// VBL/VSL radius in `radii`.
fn compare_gathers(name: &str, scene: Scene, clamp: Option<f32>, radii: &[f32], vbl_settings: VblSettings) {
    compare_gathers_chunked(name, scene, clamp, radii, vbl_settings, None);
}

/// [`compare_gathers`] with the records split into dispatches of `chunk` records, as the
/// binding limit splits large images.
fn compare_gathers_chunked(
    name: &str,
    scene: Scene,
    clamp: Option<f32>,
    radii: &[f32],
    vbl_settings: VblSettings,
    chunk: Option<usize>,
) {
    let Some(_) = beamlight_gpu::device::for_tests() else {
        return;
    };
    let ts = TraceScene::new(scene);
    let mut backend = GpuBackend::open(&ts.scene).unwrap();
    if let Some(records) = chunk {
        backend.gathers.set_chunk_limit(records);
    }
    let (w, h) = (ts.scene.render.width, ts.scene.render.height);
    let (seed, pass) = (7, 3);
    let gather = trace_camera_paths(&ts, &CameraPathSettings::default(), w, h, seed, pass);
    let lights = trace_light_paths(&ts, &LightTracerSettings::default(), 32, seed, pass);
    let pair_seed = streams::pair_seed(seed);
    let vsl_tree = LightTree::over_vsls(&ts.scene, &lights.vpls);
    let vbl_tree = LightTree::over_vbls(&ts.scene, &lights.vrls);
    // `light_samples` lights drawn per record from the trees, or 0 for all pairs.
    let run = |kernels: [GatherKernel; 4], radius2: f32, light_samples: u32| {
        let inputs = GatherInputs {
            shading_points: &gather.shading_points,
            media_segments: &gather.media_segments,
            vpls: &lights.vpls,
            vrls: &lights.vrls,
            paths: lights.paths,
            pair_seed,
            pass,
            clamp: clamp.unwrap_or(0.0),
            radius2,
            vbl: vbl_settings,
            light_samples,
            vsl_tree: if light_samples > 0 { &vsl_tree.nodes } else { &[] },
            vbl_tree: if light_samples > 0 { &vbl_tree.nodes } else { &[] },
        };
        let clock = Instant::now();
        let g = backend
            .gathers
            .run(
                &backend.gpu,
                &backend.scene,
                &ts.scene,
                &inputs,
                std::array::from_fn(|k| kernels.contains(&GatherKernel::ALL[k])),
            )
            .unwrap();
        (g, clock.elapsed())
    };
    let m = lights.paths as f32;
    let pair = |kind, i: usize, j: usize| streams::pair_sampler(pair_seed, pass, kind, i as u32, j as u32);
    let (sps, segs) = (&gather.shading_points, &gather.media_segments);
    let (vpls, vrls) = (&lights.vpls, &lights.vrls);

    if let Some(clamp) = clamp {
        let (g, gpu_time) = run(GatherKernel::RAYS, 0.0, 0);
        let clock = Instant::now();
        let cpu: [Vec<Rgb>; 4] = [
            per_record(sps, vpls, m, |i, sp, j, v| {
                vpl::vpl_to_surface(&ts, sp, v, clamp, &mut pair(GatherKind::VplToSurface, i, j))
            }),
            per_record(sps, vrls, m, |i, sp, j, v| {
                vrl::vrl_to_surface(&ts, sp, v, clamp, &mut pair(GatherKind::VrlToSurface, i, j))
            }),
            per_record(segs, vpls, m, |i, seg, j, v| {
                vpl::vpl_to_media(&ts, seg, v, clamp, &mut pair(GatherKind::VplToMedia, i, j))
            }),
            per_record(segs, vrls, m, |i, seg, j, v| {
                vrl::vrl_to_media(&ts, seg, v, clamp, &mut pair(GatherKind::VrlToMedia, i, j))
            }),
        ];
        let cpu_time = clock.elapsed();
        eprintln!(
            "{name}: {} points, {} segments, {} VPLs, {} VRLs; GPU {:.0} ms (kernels {:?} s), CPU {:.0} ms",
            sps.len(),
            segs.len(),
            vpls.len(),
            vrls.len(),
            gpu_time.as_secs_f64() * 1e3,
            &g.kernel_seconds[..4],
            cpu_time.as_secs_f64() * 1e3
        );
        for (k, cpu) in GatherKernel::RAYS.into_iter().zip(&cpu) {
            check_kernel(name, k, &g.results[k as usize], cpu);
        }
    }

    for &r in radii {
        let r2 = r * r;
        let (g, gpu_time) = run(GatherKernel::BEAMS, r2, 0);
        let clock = Instant::now();
        let s = &vbl_settings;
        let cpu: [Vec<Rgb>; 4] = [
            per_record(sps, vpls, m, |i, sp, j, v| {
                vbl::vsl_to_surface(&ts, sp, v, r2, s, &mut pair(GatherKind::VplToSurface, i, j))
            }),
            per_record(sps, vrls, m, |i, sp, j, v| {
                vbl::vbl_to_surface(&ts, sp, v, r2, s, &mut pair(GatherKind::VrlToSurface, i, j))
            }),
            per_record(segs, vpls, m, |i, seg, j, v| {
                vbl::vsl_to_media(&ts, seg, v, r2, s, &mut pair(GatherKind::VplToMedia, i, j))
            }),
            per_record(segs, vrls, m, |i, seg, j, v| {
                vbl::vbl_to_media(&ts, seg, v, r2, s, &mut pair(GatherKind::VrlToMedia, i, j))
            }),
        ];
        let cpu_time = clock.elapsed();
        eprintln!(
            "{name}, VBL/VSL radius {r}: GPU {:.0} ms (kernels {:?} s), CPU {:.0} ms",
            gpu_time.as_secs_f64() * 1e3,
            &g.kernel_seconds[4..],
            cpu_time.as_secs_f64() * 1e3
        );
        for (k, cpu) in GatherKernel::BEAMS.into_iter().zip(&cpu) {
            check_kernel(&format!("{name}, R = {r}"), k, &g.results[k as usize], cpu);
        }

        // Light selection: the same lights drawn per record on both sides (the WGSL tree
        // descent is the CPU's twin), each over its probability.
        let samples = 3;
        let (g, _) = run(GatherKernel::BEAMS, r2, samples);
        let drawn = |kind, i: usize, slot: u32| streams::drawn_pair_sampler(pair_seed, pass, kind, i as u32, slot);
        let cpu: [Vec<Rgb>; 4] = [
            per_drawn(
                sps,
                &vsl_tree,
                r,
                samples,
                m,
                |sp| Receiver::at_point(&ts.scene, sp),
                GatherKind::VplToSurface,
                (pair_seed, pass),
                |i, sp, slot, j| {
                    let kind = GatherKind::VplToSurface;
                    vbl::vsl_to_surface(&ts, sp, &vpls[j], r2, s, &mut drawn(kind, i, slot))
                },
            ),
            per_drawn(
                sps,
                &vbl_tree,
                r,
                samples,
                m,
                |sp| Receiver::at_point(&ts.scene, sp),
                GatherKind::VrlToSurface,
                (pair_seed, pass),
                |i, sp, slot, j| {
                    let kind = GatherKind::VrlToSurface;
                    vbl::vbl_to_surface(&ts, sp, &vrls[j], r2, s, &mut drawn(kind, i, slot))
                },
            ),
            per_drawn(
                segs,
                &vsl_tree,
                r,
                samples,
                m,
                |seg| Receiver::along_segment(&ts.scene, seg),
                GatherKind::VplToMedia,
                (pair_seed, pass),
                |i, seg, slot, j| {
                    let kind = GatherKind::VplToMedia;
                    vbl::vsl_to_media(&ts, seg, &vpls[j], r2, s, &mut drawn(kind, i, slot))
                },
            ),
            per_drawn(
                segs,
                &vbl_tree,
                r,
                samples,
                m,
                |seg| Receiver::along_segment(&ts.scene, seg),
                GatherKind::VrlToMedia,
                (pair_seed, pass),
                |i, seg, slot, j| {
                    let kind = GatherKind::VrlToMedia;
                    vbl::vbl_to_media(&ts, seg, &vrls[j], r2, s, &mut drawn(kind, i, slot))
                },
            ),
        ];
        for (k, cpu) in GatherKernel::BEAMS.into_iter().zip(&cpu) {
            check_kernel(
                &format!("{name}, R = {r}, {samples} drawn lights"),
                k,
                &g.results[k as usize],
                cpu,
            );
        }
    }
}

/// Per record, [`LightTree::estimate`] with the record's selection streams for kernel `kind`
/// of `f(record index, record, slot, light index)`, over `m` light paths.
fn per_drawn<R>(
    records: &[R],
    tree: &LightTree,
    r: f32,
    samples: u32,
    m: f32,
    receiver: impl Fn(&R) -> Receiver,
    kind: GatherKind,
    (pair_seed, pass): (u32, u32),
    f: impl Fn(usize, &R, u32, usize) -> Rgb,
) -> Vec<Rgb> {
    records
        .iter()
        .enumerate()
        .map(|(i, rec)| {
            let xi = streams::selection_number(pair_seed, pass, kind, i as u32);
            let descent = |slot| streams::selection_sampler(pair_seed, pass, kind, i as u32, slot);
            tree.estimate(&receiver(rec), r, samples, xi, descent, |slot, j| f(i, rec, slot, j)) / m
        })
        .collect()
}

#[test]
fn gathers_match_cpu_in_a_homogeneous_fog_box() {
    compare_gathers(
        "glossy fog box",
        glossy_fog_box(false),
        Some(0.0),
        &[0.1, 0.3],
        VblSettings::default(),
    );
}

#[test]
fn gathers_match_cpu_in_a_heterogeneous_fog_box() {
    compare_gathers(
        "lumpy glossy fog box",
        glossy_fog_box(true),
        Some(0.0),
        &[0.1, 0.3],
        VblSettings::default(),
    );
}

#[test]
fn gathers_match_cpu_through_invisible_boundaries() {
    let v = VblSettings::default();
    compare_gathers("bounded fog", bounded_fog(false), Some(0.0), &[0.1, 0.3], v);
    compare_gathers("bounded lumpy fog", bounded_fog(true), Some(0.0), &[0.1, 0.3], v);
}

/// Records split into many dispatches (each binding a range of the record arrays, with the
/// record offset keeping every pair's random stream) give the same results.
#[test]
fn chunked_dispatches_match_cpu() {
    compare_gathers_chunked(
        "glossy fog box in chunks of 48 records",
        glossy_fog_box(false),
        Some(0.0),
        &[0.1],
        VblSettings::default(),
        Some(48),
    );
}

#[test]
fn clamped_gathers_match_cpu() {
    compare_gathers(
        "clamped glossy fog box",
        glossy_fog_box(false),
        Some(0.1),
        &[],
        VblSettings::default(),
    );
}

/// The `vbl` kernels with settings other than the default: the VRL paper's vertex values
/// without the uniform share and with the most vertices, many directions; a single direction
/// (never split between the cone and a lobe); and R = 0 (the VRL/VPL limit).
#[test]
fn vbl_gathers_match_cpu_with_other_settings() {
    let rich = VblSettings {
        directions: 100,
        pdf_vertices: 64,
        pdf: AngularPdf::Vrl,
        uniform_share: 0.0,
    };
    compare_gathers(
        "lumpy glossy fog box, rich settings",
        glossy_fog_box(true),
        None,
        &[0.2],
        rich,
    );
    let single = VblSettings {
        directions: 1,
        pdf_vertices: 2,
        ..VblSettings::default()
    };
    compare_gathers("bounded fog, one direction", bounded_fog(false), None, &[0.2], single);
    compare_gathers(
        "glossy fog box, R = 0",
        glossy_fog_box(false),
        None,
        &[0.0],
        VblSettings::default(),
    );
}

/// `vrl` renders on the GPU and the CPU backends, same seed: the same image per pixel.
#[test]
fn vrl_renders_match_across_backends() {
    compare_renders(Method::Vrl);
}

/// `vbl` renders (VBLs/VSLs with the default radius, shrinking over the passes) on the GPU
/// and the CPU backends, same seed: the same image per pixel.
#[test]
fn vbl_renders_match_across_backends() {
    compare_renders(Method::Vbl);
}

/// Three passes of `method` on both backends: per pixel, nearly every pixel of the beauty
/// image agrees to 1e-3 and the image means to 1e-4.
fn compare_renders(method: Method) {
    let Some(_) = beamlight_gpu::device::for_tests() else {
        return;
    };
    let ts = TraceScene::new(bounded_fog(true));
    let backend = Arc::new(GpuBackend::open(&ts.scene).unwrap());
    let opts = |gpu: Option<Arc<GpuBackend>>| RenderOptions {
        method,
        width: 24,
        height: 24,
        budget: Budget::Passes(3),
        seed: 11,
        first_pass: 0,
        path_tracer: Default::default(),
        start: Instant::now(),
        components: true,
        many_lights: ManyLightSettings {
            light_paths_per_pass: 24,
            ..Default::default()
        },
        gpu,
    };
    let cpu = render(&ts, &opts(None), |_| true).unwrap();
    let gpu = render(&ts, &opts(Some(backend)), |_| true).unwrap();
    let images = |r: &beamlight_render::RenderResult| -> Vec<Vec<Rgb>> {
        std::iter::once(r.film.image().pixels)
            .chain(r.components.iter().map(|f| f.image().pixels))
            .collect()
    };
    let (a, b) = (images(&cpu), images(&gpu));
    let peak = a[0].iter().map(|p| p.max_element()).fold(0.0f32, f32::max);
    let names = [
        "beauty",
        "direct",
        "Lsm",
        "Lmm",
        "Lms",
        "Lss",
        "caustic_surface",
        "caustic_volume",
    ];
    let mut beyond = 0;
    for (k, (ia, ib)) in a.iter().zip(&b).enumerate() {
        let mut worst = (0.0f32, 0usize);
        let mut count = 0;
        for (i, (p, q)) in ia.iter().zip(ib).enumerate() {
            let err = (0..3)
                .map(|c| (p[c] - q[c]).abs() / p[c].abs().max(1e-4 * peak))
                .fold(0.0, f32::max);
            count += (err > 1e-3) as usize;
            if err > worst.0 {
                worst = (err, i);
            }
        }
        if k == 0 {
            beyond = count;
        }
        eprintln!(
            "{} cpu vs gpu, {:<15} worst per-pixel relative difference {:.2e} (pixel {}: {:?} vs {:?}), {} pixels beyond 1e-3",
            method.name(),
            names[k],
            worst.0,
            worst.1,
            ia[worst.1],
            ib[worst.1],
            count
        );
    }
    let mean = |v: &[Rgb]| v.iter().map(|c| c.element_sum() as f64).sum::<f64>();
    let (ma, mb) = (mean(&a[0]), mean(&b[0]));
    assert!((ma - mb).abs() <= 1e-4 * ma, "image means {ma} vs {mb}");
    assert!(
        beyond * 100 <= a[0].len(),
        "{beyond} of {} pixels differ by more than 1e-3",
        a[0].len()
    );
    assert!(peak > 0.0);
}
