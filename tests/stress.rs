//! Numerical stress: a grid of extreme media, phase functions and materials rendered by every
//! method on both backends, extreme radii and pass indices, and degenerate virtual-light
//! geometry. Every case asserts that no NaN or Inf reaches any layer; where a closed form
//! applies (the furnace), the image's mean is bounded by it; the GPU twins stay within
//! tolerance of the CPU across the grid.
//!
//! The normal test run uses tiny images; `cargo xtask stress` sets `BEAMLIGHT_STRESS=full` for
//! larger images and more passes.
mod common;
use beamlight_gpu::{
    GpuBackend,
    gather::{GatherInputs, GatherKernel, KERNELS},
};
use beamlight_render::{
    Budget, Method, RenderOptions, RenderResult,
    many_lights::{ManyLightSettings, VslDraw},
    render,
};
use beamlight_scene::{Rgb, Scene, bsdf::Bsdf};
use beamlight_testkit::gltf_writer::shapes;
use beamlight_trace::{
    TraceScene,
    camera_paths::{MediaSegment, ShadingPoint},
    direct,
    light_paths::{LightSegment, SurfaceVertex},
    light_tree::Drawing,
    streams::{self, GatherKind},
    vbl::{self, VblSettings},
    vpl, vrl,
};
use common::*;
use glam::Vec3;
use std::{sync::Arc, time::Instant};

/// Image side and passes of each render: tiny in the normal run, larger under xtask.
fn size() -> (u32, u64) {
    if std::env::var("BEAMLIGHT_STRESS").is_ok_and(|v| v == "full") {
        (32, 16)
    } else {
        (6, 2)
    }
}

const METHODS: [Method; 4] = [Method::Pt, Method::Vrl, Method::VrlClamped, Method::Vbl];

/// A fog box with a Phong cube: the grid's medium and the cube's exponent.
fn extreme_box(sigma_t: f32, albedo: f32, g: f32, exponent: f32) -> Scene {
    let (n, _) = size();
    let mut s = fog_box(n, n, false);
    let sigma_s = sigma_t * albedo;
    s.media[0] = homogeneous(Rgb::splat(sigma_s), Rgb::splat(sigma_t - sigma_s), g);
    let phong = add_material(
        &mut s,
        material(
            "phong",
            Some(Bsdf::Phong {
                diffuse: Rgb::splat(0.2),
                specular: Rgb::splat(0.7),
                exponent,
            }),
            Rgb::ZERO,
            false,
        ),
    );
    add_mesh(
        &mut s,
        shapes::cuboid(Vec3::new(-0.5, -1.0, -0.6), Vec3::new(0.1, -0.4, 0.0), false),
        phong,
        None,
    );
    s
}

fn options(method: Method, w: u32, passes: u64, gpu: Option<Arc<GpuBackend>>) -> RenderOptions {
    RenderOptions {
        method,
        width: w,
        height: w,
        budget: Budget::Passes(passes),
        seed: 5,
        first_pass: 0,
        path_tracer: Default::default(),
        start: Instant::now(),
        components: true,
        many_lights: ManyLightSettings {
            light_paths_per_pass: 8,
            ..Default::default()
        },
        gpu,
    }
}

/// No NaN, ∞ or negative value in any layer, none dropped by the film, and none discarded by
/// the estimators' guard on the way (`many_lights::admit`, which would otherwise turn a NaN or
/// sign bug into quietly missing light).
fn assert_finite(what: &str, r: &RenderResult) {
    let discarded = r.discarded;
    assert!(
        !discarded.any(),
        "{what}: estimates discarded per component, light paths dropped: {discarded}"
    );
    assert_eq!(r.film.rejected, 0, "{what}: non-finite samples reached the film");
    for (k, f) in std::iter::once(&r.film).chain(&r.components).enumerate() {
        assert_eq!(f.rejected, 0, "{what}: layer {k} dropped non-finite samples");
        for p in f.image().pixels {
            assert!(p.is_finite() && p.min_element() >= 0.0, "{what}: layer {k} has {p}");
        }
    }
}

/// Finite and non-negative: what an estimate must be before anything cleans it.
fn sane(v: glam::Vec3) -> bool {
    v.is_finite() && v.min_element() >= 0.0
}

/// g × σt × albedo (50 media), each with a Phong exponent from 1 to 10⁵, by every method on
/// the CPU; the many-light methods also on the GPU, where the image must match the CPU's.
#[test]
fn extreme_media_and_materials_stay_finite_for_every_method_and_backend() {
    let gpu_on = beamlight_gpu::device::for_tests().is_some();
    let (w, passes) = size();
    let exponents = [1.0, 10.0, 1e3, 1e5];
    let mut cases = 0;
    for (i, &g) in [-0.999f32, -0.9, 0.0, 0.9, 0.999].iter().enumerate() {
        for (j, &sigma_t) in [1e-6f32, 1e-2, 1.0, 1e2, 1e4].iter().enumerate() {
            for albedo in [0.0f32, 1.0] {
                let exponent = exponents[(i + j) % exponents.len()];
                let scene = extreme_box(sigma_t, albedo, g, exponent);
                let what = format!("g {g}, σt {sigma_t}, albedo {albedo}, Phong n {exponent}");
                let ts = TraceScene::new(scene);
                let backend = gpu_on.then(|| Arc::new(GpuBackend::open(&ts).unwrap()));
                for method in METHODS {
                    let cpu = render(&ts, &options(method, w, passes, None), |_| true).unwrap();
                    assert_finite(&format!("{what}, {} on the CPU", method.name()), &cpu);
                    cases += 1;
                    let Some(b) = &backend else { continue };
                    if method == Method::Pt {
                        continue;
                    }
                    // The CPU's VSLs drawn as the GPU's kernels draw them (by the descent; the
                    // CPU's default draws them flat), so that the totals compare.
                    let descent = |gpu: Option<Arc<GpuBackend>>| RenderOptions {
                        many_lights: ManyLightSettings {
                            vsl_drawing: VslDraw::Descent,
                            ..options(method, w, passes, None).many_lights
                        },
                        ..options(method, w, passes, gpu)
                    };
                    let cpu = match method {
                        Method::Vbl => render(&ts, &descent(None), |_| true).unwrap(),
                        _ => cpu,
                    };
                    let gpu = render(&ts, &descent(Some(b.clone())), |_| true).unwrap();
                    let what = format!("{what}, {} on the GPU", method.name());
                    assert_finite(&what, &gpu);
                    // f32 on both sides: the image's total within 1e-3 of the CPU's.
                    let total = |r: &RenderResult| {
                        r.film
                            .image()
                            .pixels
                            .iter()
                            .map(|p| p.element_sum() as f64)
                            .sum::<f64>()
                    };
                    let (a, b) = (total(&cpu), total(&gpu));
                    assert!(
                        (a - b).abs() <= 1e-3 * a.abs().max(1e-12),
                        "{what}: total {b} vs the CPU's {a}"
                    );
                    cases += 1;
                }
            }
        }
    }
    eprintln!("{cases} renders, every layer finite");
}

/// In the furnace (walls emitting 1 with albedo 0.5, a purely scattering medium) radiance is 2
/// everywhere. No method may exceed it by more than 4 standard errors (batch means) at any σs
/// and g, and where the estimators converge in a few passes (optical depth up to 2; not the
/// many-light methods at g = ±0.999, see below) the mean must also reach it within 4 standard
/// errors (plus the stated allowances; made to fail once with every mean scaled by 0.9).
/// With g = ±0.999, `vbl` reaches it over many passes since the camera paths walk through sharp media (issue 15 item
/// 3, `components`): before, the near-delta phase functions put the many-light estimators'
/// expected value into connections they almost never sampled, and `vbl` gave 0.85 ± 0.04 at
/// g = 0.999 and 0.92 ± 0.12 at −0.999 after 1024 passes (8×8, σs = 1, 8 paths per pass,
/// batch-mean standard errors; `vbl_furnace_converges_to_two` run on the code before); now
/// 2.00 ± 0.03 and 1.98 ± 0.04 after 512 passes (mean over 8 seeds), and that test checks it
/// at standard errors. At σs = 1000 (optical depth 2000, albedo 1) a path needs
/// ~10⁶ bounces to reach a wall, Russian roulette (survival ≤ 0.95) ends it long before, and
/// every method, `pt` included, gives 0 in practice: unbiased in expectation, useless in
/// practice.
#[test]
fn furnace_bound_holds_at_the_extremes() {
    let (_, passes) = size();
    for &g in &[-0.999f32, 0.0, 0.999] {
        for &sigma_s in &[1e-6f32, 1.0, 1e3] {
            let scene = furnace(Rgb::splat(sigma_s), g, None);
            let (w, h) = (scene.render.width, scene.render.height);
            let ts = TraceScene::new(scene);
            for method in METHODS {
                let mut opts = options(method, w, passes * 4, None);
                opts.height = h;
                // Image means with standard errors from batch means (one pass a batch).
                let run = render_with_errors(&ts, &opts, passes * 4);
                let what = format!("furnace σs {sigma_s}, g {g}, {}", method.name());
                assert_finite(&what, &run.result);
                let (mean, se) = (run.image, run.image_error);
                eprintln!("{what}: {mean:.4} ± {:.4}", se.max_element());
                // Nothing may exceed 2 by more than 4 standard errors (clamping only loses
                // light; the blur's bias is within a few percent): an explosion or light counted
                // twice fails. Where a few passes converge (optical depth ≤ 2), the unbiased
                // `pt` and `vrl` must also reach 2 within 4 standard errors, and `vbl` within
                // them plus 5 % (its blur at R0 with a handful of passes: about −2.5 % in the
                // furnace, tests/vbl_progressive.rs); `vrl-clamped` must keep at least half
                // (its clamp's loss, which depends on the scene). Not at g = ±0.999 for the
                // many-light methods: there the light scattered at a VRL towards a camera record
                // sits in the phase function's spike, which 8 passes rarely draw, so the sample
                // mean is low and its batch error too small (measured: `vrl` 1.30 ± 0.02 at
                // g = 0.999, `vbl` 1.81 ± 0.12 at −0.999); `vbl` there is judged over 16 seeds
                // of 1024 passes in tests/vbl_progressive.rs, `vrl` is not (it is not the
                // method for sharp media). Percent-level bias is judged with many passes
                // elsewhere (tests/many_lights.rs, tests/vbl_progressive.rs).
                let converges = sigma_s <= 1.0 && (g.abs() < 0.99 || method == Method::Pt);
                let allowance = match method {
                    Method::Vbl => 0.1,
                    Method::VrlClamped => 1.0,
                    _ => 0.0,
                };
                for c in 0..3 {
                    assert!(
                        mean[c] < 2.0 + 4.0 * se[c],
                        "{what}: mean {mean} ± {se}, above the furnace's 2"
                    );
                    assert!(
                        !converges || mean[c] > 2.0 - allowance - 4.0 * se[c],
                        "{what}: mean {mean} ± {se}, below the furnace's 2"
                    );
                }
            }
        }
    }
}

/// Issue 19's acceptance check: `vbl` in the grey furnace (σs = 1, σa = 0, walls emitting 1
/// with albedo 0.5: 2.0 everywhere) after 16 passes at default settings, with R0 at ½, 1 and 2×
/// its default and g = 0, 0.5 and 0.9, must be within 1 % of 2.0: the image mean over many
/// seeds (independent renders) may not lie more than 2 standard errors outside [1.98, 2.02].
/// Full size (`cargo xtask stress`, about 23 minutes): 24², every case, 600 seeds (standard
/// error ≈ 0.12 %; ≈ 1 % at g = 0.9, whose renders are heavy-tailed). The normal run: 12²,
/// g = 0.5 at R0 and 2 R0, 48 seeds (standard error ≈ 0.4 %), which catches a loss of about
/// 2 % (without the renormalisation of cut discs: −2.9 % at 2 R0, 4.5 standard errors outside,
/// fails), not the 1.3 % that 2 R0 lost before the cuts at the walls next to each VSL centre
/// (`vbl::Walls`; now −0.29 ± 0.14 % there over 400 seeds at 12², g = 0.5), which only the
/// full run resolves.
#[test]
fn vbl_furnace_within_one_percent_at_every_radius() {
    let full = std::env::var("BEAMLIGHT_STRESS").is_ok_and(|v| v == "full");
    let (size, seeds, cases): (u32, u32, Vec<(f32, f32)>) = if full {
        let gs = [0.0f32, 0.5, 0.9];
        let scales = [0.5f32, 1.0, 2.0];
        (24, 600, gs.iter().flat_map(|&g| scales.map(|k| (g, k))).collect())
    } else {
        (12, 48, vec![(0.5, 1.0), (0.5, 2.0)])
    };
    let mut failed = Vec::new();
    for (g, scale) in cases {
        let ts = TraceScene::new(furnace(Rgb::ONE, g, None));
        let r0 = beamlight_render::radius::default_radius(&ts.scene) * scale;
        let means: Vec<f64> = (0..seeds)
            .map(|seed| {
                let opts = RenderOptions {
                    method: Method::Vbl,
                    width: size,
                    height: size,
                    budget: Budget::Passes(16),
                    seed: 1000 + seed,
                    first_pass: 0,
                    path_tracer: Default::default(),
                    start: Instant::now(),
                    components: false,
                    many_lights: ManyLightSettings {
                        radius: r0,
                        ..Default::default()
                    },
                    gpu: None,
                };
                let r = render(&ts, &opts, |_| true).unwrap();
                assert_eq!(r.film.rejected, 0);
                r.film.image().mean().as_dvec3().element_sum() / 3.0
            })
            .collect();
        let n = means.len() as f64;
        let mean = means.iter().sum::<f64>() / n;
        let se = (means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
        let outside = ((mean - 2.0).abs() - 0.02).max(0.0) / se;
        eprintln!(
            "vbl furnace g = {g}, R0 × {scale}: {mean:.4} ± {se:.4} ({:+.2} %, {outside:.1} standard errors outside 1 %)",
            (mean / 2.0 - 1.0) * 100.0
        );
        if outside > 2.0 {
            failed.push(format!("g {g}, R0 × {scale}: {mean:.4} ± {se:.4}"));
        }
    }
    assert!(failed.is_empty(), "vbl furnace more than 1 % off 2.0: {failed:?}");
}

/// R0 from 1e-8 to the scene's size, and passes a million deep into the radius schedule.
#[test]
fn extreme_radii_and_pass_indices_stay_finite() {
    let (w, passes) = size();
    let ts = TraceScene::new(extreme_box(1.0, 0.8, 0.7, 30.0));
    for radius in [1e-8f32, 1e-3, 2.0, 10.0] {
        for first_pass in [0u64, 1_000_000] {
            let mut opts = options(Method::Vbl, w, passes, None);
            opts.many_lights.radius = radius;
            opts.many_lights.photon_radius = radius;
            opts.first_pass = first_pass;
            let r = render(&ts, &opts, |_| true).unwrap();
            assert_finite(&format!("vbl R0 {radius}, first pass {first_pass}"), &r);
        }
    }
}

/// Degenerate virtual-light geometry, evaluated directly by every CPU estimator and by the GPU
/// kernels: a shading point on a VRL, a zero-length VRL, a camera segment along a VRL, nearly
/// parallel segments, a VPL at the shading point, grazing directions.
#[test]
fn degenerate_virtual_light_geometry_stays_finite() {
    let ts = TraceScene::new(extreme_box(1.0, 0.9, 0.9, 100.0));
    let floor = ts
        .scene
        .triangles
        .iter()
        .position(|t| t.p.iter().all(|p| p.y == -1.0))
        .expect("a floor triangle") as u32;
    let p = Vec3::new(0.3, -1.0, 0.4);
    let sp = ShadingPoint {
        pos: p.into(),
        material: ts.scene.triangles[floor as usize].material,
        normal: [0.0, 1.0, 0.0],
        tri: floor,
        wo: Vec3::new(0.0, 1e-7, 1.0).normalize().into(), // grazing
        pixel: 0,
        throughput: [1.0; 3],
        medium: 0,
        uv: [0.0; 2],
        _pad2: [0; 2],
    };
    let seg = |o: Vec3, d: Vec3, len: f32| MediaSegment {
        origin: o.into(),
        length: len,
        dir: d.normalize().into(),
        medium: 0,
        throughput: [1.0; 3],
        pixel: 0,
    };
    let vrl_at = |o: Vec3, d: Vec3, len: f32| LightSegment {
        origin: o.into(),
        length: len,
        dir: d.normalize().into(),
        medium: 0,
        power: [1.0; 3],
        flags: 0,
    };
    let vrls = [
        vrl_at(p, Vec3::X, 0.5),                                           // starts at the shading point
        vrl_at(p - Vec3::X * 0.25, Vec3::X, 0.5),                          // passes through it
        vrl_at(Vec3::new(0.0, 0.0, 0.0), Vec3::Y, 0.0),                    // zero length
        vrl_at(Vec3::new(-0.5, 0.0, 0.0), Vec3::new(1.0, 1e-7, 0.0), 1.0), // along the camera ray
    ];
    let segments = [
        seg(Vec3::new(-0.5, 0.0, 0.0), Vec3::X, 1.0),
        seg(Vec3::new(-0.5, 1e-6, 0.0), Vec3::X, 1.0),
        seg(Vec3::new(0.0, 0.0, 0.0), Vec3::Z, 0.0),
    ];
    let vpls = [SurfaceVertex {
        pos: p.into(),
        material: sp.material,
        normal: [0.0, 1.0, 0.0],
        tri: floor,
        wi: [0.0, 1.0, 0.0],
        u: 0.0,
        power: [1.0; 3],
        v: 0.0,
    }];
    let settings = VblSettings::default();
    let pair_seed = streams::pair_seed(1);
    let s = |kind, i: usize, j: usize| streams::pair_sampler(pair_seed, 0, kind, i as u32, j as u32);
    for r2 in [0.0f32, 1e-12, 0.01] {
        for (j, v) in vrls.iter().enumerate() {
            let a = vrl::vrl_to_surface(&ts, &sp, v, 0.0, &mut s(GatherKind::VrlToSurface, 0, j));
            let b = vbl::vbl_to_surface(&ts, &sp, v, r2, &settings, &mut s(GatherKind::VrlToSurface, 0, j));
            assert!(sane(a) && sane(b), "VRL {j} at the shading point: {a} {b}");
            for (i, c) in segments.iter().enumerate() {
                let a = vrl::vrl_to_media(&ts, c, v, 0.0, &mut s(GatherKind::VrlToMedia, i, j));
                let b = vbl::vbl_to_media(&ts, c, v, r2, &settings, &mut s(GatherKind::VrlToMedia, i, j));
                assert!(sane(a) && sane(b), "VRL {j}, segment {i}, R² {r2}: {a} {b}");
            }
        }
        for (i, c) in segments.iter().enumerate() {
            let a = vpl::vpl_to_media(&ts, c, &vpls[0], 0.0, &mut s(GatherKind::VplToMedia, i, 0));
            let b = vbl::vsl_to_media(&ts, c, &vpls[0], r2, &settings, &mut s(GatherKind::VplToMedia, i, 0));
            assert!(sane(a) && sane(b), "VPL, segment {i}: {a} {b}");
        }
        let a = vpl::vpl_to_surface(&ts, &sp, &vpls[0], 0.0, &mut s(GatherKind::VplToSurface, 0, 0));
        let b = vbl::vsl_to_surface(
            &ts,
            &sp,
            &vpls[0],
            r2,
            &settings,
            &mut s(GatherKind::VplToSurface, 0, 0),
        );
        assert!(sane(a) && sane(b), "VPL at the shading point: {a} {b}");
    }
    // A pair whose sampling density fails (a VPL or a VRL at infinity, a VRL or camera segment
    // of NaN length, as a broken path would leave them): every estimator returns NaN, which the gathers' `admit`
    // counts, never a silent zero (`failed::FAILED_ESTIMATE`; made to fail once by returning
    // zero again). The GPU kernels must count the same pairs, below.
    let far_vpl = SurfaceVertex {
        pos: [f32::INFINITY, 0.0, 0.0],
        ..vpls[0]
    };
    let far_vrl = vrl_at(Vec3::new(f32::INFINITY, 0.0, 0.0), Vec3::X, 1.0);
    let nan_vrl = vrl_at(Vec3::new(0.0, -0.5, 0.0), Vec3::Y, f32::NAN);
    let r2 = 0.01;
    let failed = [
        vpl::vpl_to_media(&ts, &segments[0], &far_vpl, 0.0, &mut s(GatherKind::VplToMedia, 0, 0)),
        vbl::vsl_to_media(
            &ts,
            &segments[0],
            &far_vpl,
            r2,
            &settings,
            &mut s(GatherKind::VplToMedia, 0, 0),
        ),
        vrl::vrl_to_surface(&ts, &sp, &far_vrl, 0.0, &mut s(GatherKind::VrlToSurface, 0, 0)),
        vbl::vbl_to_surface(
            &ts,
            &sp,
            &far_vrl,
            r2,
            &settings,
            &mut s(GatherKind::VrlToSurface, 0, 0),
        ),
        vrl::vrl_to_media(&ts, &segments[0], &nan_vrl, 0.0, &mut s(GatherKind::VrlToMedia, 0, 0)),
        vbl::vbl_to_media(
            &ts,
            &segments[0],
            &nan_vrl,
            r2,
            &settings,
            &mut s(GatherKind::VrlToMedia, 0, 0),
        ),
        // Direct light along a camera segment of NaN length (the CPU's own estimator).
        direct::direct_in_medium(
            &ts,
            &MediaSegment {
                length: f32::NAN,
                ..segments[0]
            },
            &mut s(GatherKind::VplToMedia, 0, 0),
        ),
    ];
    for (k, v) in failed.iter().enumerate() {
        assert!(v.is_nan(), "estimator {k}: {v}, a failed estimate not counted");
    }
    // What the GPU must count for these lights against the shading point and segment 0: the
    // CPU twins' NaNs per kernel, over every pair (all-pairs gathers, one stream each).
    let (failing_vpls, failing_vrls) = ([far_vpl], [far_vrl, nan_vrl]);
    let nans = |f: &dyn Fn(usize) -> Rgb, n: usize| (0..n).filter(|&j| f(j).is_nan()).count() as u64;
    let pair_stream = |kind, j| s(kind, 0, j);
    let expected: [u64; KERNELS] = [
        nans(
            &|j| {
                vpl::vpl_to_surface(
                    &ts,
                    &sp,
                    &failing_vpls[j],
                    0.0,
                    &mut pair_stream(GatherKind::VplToSurface, j),
                )
            },
            1,
        ),
        nans(
            &|j| {
                vrl::vrl_to_surface(
                    &ts,
                    &sp,
                    &failing_vrls[j],
                    0.0,
                    &mut pair_stream(GatherKind::VrlToSurface, j),
                )
            },
            2,
        ),
        nans(
            &|j| {
                vpl::vpl_to_media(
                    &ts,
                    &segments[0],
                    &failing_vpls[j],
                    0.0,
                    &mut pair_stream(GatherKind::VplToMedia, j),
                )
            },
            1,
        ),
        nans(
            &|j| {
                vrl::vrl_to_media(
                    &ts,
                    &segments[0],
                    &failing_vrls[j],
                    0.0,
                    &mut pair_stream(GatherKind::VrlToMedia, j),
                )
            },
            2,
        ),
        nans(
            &|j| {
                vbl::vsl_to_surface(
                    &ts,
                    &sp,
                    &failing_vpls[j],
                    r2,
                    &settings,
                    &mut pair_stream(GatherKind::VplToSurface, j),
                )
            },
            1,
        ),
        nans(
            &|j| {
                vbl::vbl_to_surface(
                    &ts,
                    &sp,
                    &failing_vrls[j],
                    r2,
                    &settings,
                    &mut pair_stream(GatherKind::VrlToSurface, j),
                )
            },
            2,
        ),
        nans(
            &|j| {
                vbl::vsl_to_media(
                    &ts,
                    &segments[0],
                    &failing_vpls[j],
                    r2,
                    &settings,
                    &mut pair_stream(GatherKind::VplToMedia, j),
                )
            },
            1,
        ),
        nans(
            &|j| {
                vbl::vbl_to_media(
                    &ts,
                    &segments[0],
                    &failing_vrls[j],
                    r2,
                    &settings,
                    &mut pair_stream(GatherKind::VrlToMedia, j),
                )
            },
            2,
        ),
    ];
    eprintln!("failed estimates per kernel (CPU): {expected:?}");
    // The GPU kernels on the same records.
    let Some(_) = beamlight_gpu::device::for_tests() else {
        return;
    };
    let backend = GpuBackend::open(&ts).unwrap();
    // Every kernel, all pairs, on the GPU.
    let gather_all_pairs = |sp: &ShadingPoint,
                            segments: &[MediaSegment],
                            (vpls, vpl_walls): (&[SurfaceVertex], &[vbl::Walls]),
                            vrls: &[LightSegment],
                            r2: f32| {
        let inputs = GatherInputs {
            shading_points: std::slice::from_ref(sp),
            media_segments: segments,
            vpls,
            vpl_walls,
            vrls,
            paths: 1,
            pair_seed,
            pass: 0,
            clamp: 0.0,
            radius2: r2,
            vbl: settings,
            light_samples: 0,
            media_light_samples: 0,
            media_drawing: Drawing::Descent,
            media_masses: &[],
            vsl_tree: &[],
            vbl_tree: &[],
            inject_nan: false,
        };
        backend
            .gathers
            .run(&backend.gpu, &backend.scene, &ts.scene, &inputs, [true; KERNELS])
            .unwrap()
    };
    for r2 in [0.0f32, 0.01] {
        let vpl_walls = vbl::vpl_walls_all(&ts, &vpls, r2);
        let g = gather_all_pairs(&sp, &segments, (&vpls, &vpl_walls), &vrls, r2);
        for k in GatherKernel::ALL {
            for v in &g.results[k as usize] {
                assert!(sane(*v), "{} with R² {r2}: {v}", k.name());
            }
            assert_eq!(
                g.discarded[k as usize],
                0,
                "{} with R² {r2}: discarded estimates",
                k.name()
            );
        }
    }
    let vpl_walls = vbl::vpl_walls_all(&ts, &failing_vpls, r2);
    let g = gather_all_pairs(&sp, &segments[..1], (&failing_vpls, &vpl_walls), &failing_vrls, r2);
    assert_eq!(
        g.discarded, expected,
        "failed estimates counted per kernel, GPU against CPU"
    );
}

/// The same scene scaled by 10⁻³ and 10⁵ (media by the inverse) gives the same image with the
/// many-light methods too: every radius, offset and clamp must scale with the scene.
#[test]
fn scene_scale_does_not_change_many_light_images() {
    let (w, passes) = size();
    let scaled = |scale: f32| {
        let mut s = extreme_box(1.0, 0.8, 0.6, 30.0);
        for t in &mut s.triangles {
            t.p = t.p.map(|p| p * scale);
        }
        s.camera.to_world.w_axis = (s.camera.position() * scale).extend(1.0);
        for m in &mut s.media {
            m.sigma_s /= scale;
            m.sigma_a /= scale;
        }
        TraceScene::new(s)
    };
    let reference = scaled(1.0);
    for method in [Method::Vrl, Method::VrlClamped, Method::Vbl] {
        // 32 passes in the normal run: a rounding difference that flips one decision swaps one
        // heavy-tailed sample for another, which moved `vbl`'s mean over 8 passes by up to 2 %
        // (seeds 5–8: +0.9, −0.2, −0.1, −1.7 % at scale 10⁻³ with the defaults; +2.0, −0.2,
        // −1.0, −0.9 % with 8 lights drawn and 4 directions), over 32 by at most 1 % (with
        // those). A scale bug (an absolute epsilon, a radius that does not scale) moves it by
        // far more.
        let mean = |ts: &TraceScene| {
            let r = render(ts, &options(method, w, passes * 16, None), |_| true).unwrap();
            assert_finite(method.name(), &r);
            r.film.image().mean()
        };
        let want = mean(&reference);
        for scale in [1e-3f32, 1e5] {
            let got = mean(&scaled(scale));
            // The same random numbers: only rounding differs, and rarely a decision with it.
            assert!(
                (got - want).abs().max_element() <= 0.02 * want.max_element(),
                "{} at scale {scale}: mean {got} vs {want} at scale 1",
                method.name()
            );
        }
    }
}

/// The camera inside a glass sphere full of fog, and a point light inside that sphere, by
/// every method on both backends. In the furnace, radiance inside glass of index n is 2·n²
/// (radiance crossing a dielectric boundary scales with n², so L/n² is what stays 2): 4.5
/// for the sphere's n = 1.5. Only `pt` is held to it from below: inside the glass nearly all
/// light arrives as caustics (photon beams), which a few passes of 8 light paths sample
/// sparsely (at 8 passes about 2.9; at these 16: `vrl` 4.71/4.37/5.89 ± 1.9, `vbl`
/// 4.18/4.25/4.64 ± 1.3, against `pt`'s 4.59/4.34/4.58 ± 0.17); measured at 64 passes × 32
/// paths: `vrl` 4.68, `vbl` 4.40 against `pt`'s 4.53 at 256 spp.
/// With the light inside, this test checks finiteness only; how much light comes out is
/// judged by `light_inside_glass_vbl_and_vrl_agree`.
#[test]
fn camera_and_light_inside_glass() {
    let (_, passes) = size();
    let gpu_on = beamlight_gpu::device::for_tests().is_some();
    let centre = Vec3::new(-0.3, 0.0, -0.3); // the glass sphere of `glass_furnace`
    for light_inside in [false, true] {
        let mut s = glass_furnace(6, 24, false);
        if light_inside {
            // Walls dark, so the light inside the glass is all there is.
            for m in &mut s.materials {
                m.emission = Rgb::ZERO;
            }
            s.lights.push(beamlight_scene::light::PunctualLight::Point {
                position: centre + Vec3::new(0.1, 0.05, 0.0),
                intensity: Rgb::splat(1.0),
            });
        } else {
            s.camera.to_world.w_axis = (centre + Vec3::new(0.0, 0.0, 0.2)).extend(1.0);
        }
        let (w, h) = (s.render.width, s.render.height);
        let ts = TraceScene::new(s);
        assert!(
            light_inside || ts.camera_medium == Some(1),
            "the camera is in the sphere's fog"
        );
        let backend = gpu_on.then(|| Arc::new(GpuBackend::open(&ts).unwrap()));
        for method in METHODS {
            for gpu in [None, backend.clone()] {
                if gpu.is_some() && method == Method::Pt {
                    continue;
                }
                let on = if gpu.is_some() { "GPU" } else { "CPU" };
                let mut opts = options(method, w, passes * 8, gpu);
                opts.height = h;
                let run = render_with_errors(&ts, &opts, 16);
                let what = format!("{} on the {on}, light inside glass {light_inside}", method.name());
                assert_finite(&what, &run.result);
                let (mean, se) = (run.image, run.image_error);
                let inside = 2.0 * 1.5f64.powi(2);
                eprintln!("{what}: {mean:.4} ± {:.4}", se.max_element());
                if light_inside {
                    continue; // no closed form: `light_inside_glass_vbl_and_vrl_agree`
                }
                // Nothing may exceed 2n² by 4 standard errors (batch means over 16 batches:
                // light counted twice fails), and `pt` must reach it within 4 of them. 16
                // passes of 6×6: a standard error of about 3.7 % for `pt` (it catches about
                // 15 %), 20–40 % for the others (gross errors only). Made to fail once by
                // judging against 1.2 × 2n² (`pt` z −4.9 to −7.5 per channel).
                for c in 0..3 {
                    assert!(
                        mean[c] < inside + 4.0 * se[c],
                        "{what}: mean {mean} ± {se} above 2n² = {inside}"
                    );
                    assert!(
                        method != Method::Pt || mean[c] > inside - 4.0 * se[c],
                        "{what}: mean {mean} ± {se} below 2n² = {inside}"
                    );
                }
            }
        }
    }
}

/// The point light inside the glass sphere of fog, with dark walls (no closed form): `vbl` and
/// `vrl` must agree within 4 standard errors (batch means over 16 batches of 128 passes each;
/// their difference's relative error is 2.6–4.2 % per channel, so a disagreement of about 10–17 %
/// fails: made to fail once with `vbl` scaled by 1.2, z 7.0/4.5/5.4; unscaled |z| < 0.7). They reach the light through
/// different virtual lights (beams and spheres against rays), while their caustics (photon maps
/// and beams, the light's way out through the glass) are the same code. `pt` is no reference
/// here: a path from a wall cannot reach a point light through glass (a delta light behind a
/// delta surface), so it misses the unscattered caustic (measured, 6×6: `pt` 0.27/0.16/0.33 at
/// 4096 spp against `vbl` 0.38/0.34/0.41 and `vrl` 0.38/0.34/0.42 at 256 passes).
#[test]
fn light_inside_glass_vbl_and_vrl_agree() {
    let centre = Vec3::new(-0.3, 0.0, -0.3); // the glass sphere of `glass_furnace`
    let mut s = glass_furnace(6, 24, false);
    for m in &mut s.materials {
        m.emission = Rgb::ZERO;
    }
    s.lights.push(beamlight_scene::light::PunctualLight::Point {
        position: centre + Vec3::new(0.1, 0.05, 0.0),
        intensity: Rgb::splat(1.0),
    });
    let (w, h) = (s.render.width, s.render.height);
    let ts = TraceScene::new(s);
    let run = |method: Method| {
        let mut opts = options(method, w, 128, None);
        opts.height = h;
        let run = render_with_errors(&ts, &opts, 16);
        assert_finite(method.name(), &run.result);
        eprintln!("{}: {:.4} ± {:.4}", method.name(), run.image, run.image_error);
        (run.image, run.image_error)
    };
    let ((a, sa), (b, sb)) = (run(Method::Vbl), run(Method::Vrl));
    let z = (a - b) / (sa * sa + sb * sb).powf(0.5);
    assert!(a.min_element() > 0.0, "vbl: no light out of the glass");
    assert!(
        z.abs().max_element() < 4.0,
        "vbl {a:.4} ± {sa:.4} against vrl {b:.4} ± {sb:.4}: z {z:.2}"
    );
}
