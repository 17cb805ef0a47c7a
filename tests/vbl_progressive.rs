//! `--method vbl` through the orchestrator: its components converge to the path tracer's, its
//! error shrinks as passes go on (noise and, with the radius, blur), it renders the furnace at
//! 2.0, and it has none of the isolated extreme pixels unclamped VRLs leave next to a glossy
//! surface.
mod common;
use beamlight_render::{Budget, Film, Method, RenderOptions, many_lights::ManyLightSettings, render};
use beamlight_scene::{Rgb, Scene, bsdf::Bsdf};
use beamlight_trace::{TraceScene, components::Component, pt::PathTracerSettings};
use common::*;
use glam::DVec3;
use std::{rc::Rc, time::Instant};

fn options(method: Method, w: u32, h: u32, passes: u64, paths: u32, seed: u32) -> RenderOptions {
    RenderOptions {
        method,
        width: w,
        height: h,
        budget: Budget::Passes(passes),
        seed,
        first_pass: 0,
        path_tracer: PathTracerSettings::default(),
        start: Instant::now(),
        components: true,
        many_lights: ManyLightSettings {
            light_paths_per_pass: paths,
            ..Default::default()
        },
        gpu: None,
    }
}

/// Every component of `vbl` against the path tracer's, at the default R0 (0.35 here, a 4×4
/// image of a 2-unit box that is almost all walls and corners, where the blur's light loss
/// showed: before issue 19's correction Lsm sat 6 % low here), judged by standard errors from
/// batch means, so a bias of about 4 standard errors (printed; ≈ 1–2 % here) fails.
/// Every light gathered (`--light-samples all`): the estimator against the path tracer. The
/// default light selection is checked against this one, its oracle, by z-tests in
/// `tests/light_selection.rs`.
#[test]
fn vbl_components_converge_to_the_path_tracer() {
    let (w, h) = (4u32, 4u32);
    let ts = TraceScene::new(fog_box(w, h, false));
    let mut opts = options(Method::Vbl, w, h, 384, 200, 12);
    opts.many_lights.light_samples = None;
    assert_components_converge(&ts, &opts, 16384);
}

/// The same in a sharp medium (g = 0.98 ≥ `components::SHARP_PHASE_G`), with the default
/// light selection: its camera segments connect to no virtual light, and their `Lms` and `Lmm`
/// come from the walks (issue 15 item 3), each walk record credited to the class of the path's
/// first two vertices. Fails if a walk record is credited to the wrong component, if the
/// segments' own gathers still ran (light counted twice), or if a class of walk vertex is
/// missed (light lost); what it cannot see is a bias below about 4 standard errors (printed).
#[test]
fn vbl_components_converge_to_the_path_tracer_in_a_sharp_medium() {
    let (w, h) = (4u32, 4u32);
    let mut scene = fog_box(w, h, false);
    scene.media[0].g = 0.98;
    assert!(beamlight_trace::components::is_sharp(scene.media[0].g));
    let ts = TraceScene::new(scene);
    assert_components_converge(&ts, &options(Method::Vbl, w, h, 4096, 64, 12), 65536);
}

/// A render by `opts` against `pt_spp` samples per pixel of the path tracer, per component
/// (direct, Lss, Lsm, Lms, Lmm) within 4 standard errors of both (batch means over 16 batches);
/// nothing rejected or discarded.
fn assert_components_converge(ts: &TraceScene, opts: &RenderOptions, pt_spp: u32) {
    let reference = pt_components_with_errors(ts, pt_spp, 11);
    let run = render_with_errors(ts, opts, 16);
    let result = &run.result;
    assert_eq!(result.film.rejected, 0);
    assert_eq!(
        result.discarded,
        Default::default(),
        "estimates discarded per component, light paths dropped"
    );
    eprintln!(
        "{}: {} passes in {:?}",
        opts.method.name(),
        result.passes,
        result.elapsed
    );
    let components = [
        Component::Direct,
        Component::Lss,
        Component::Lsm,
        Component::Lms,
        Component::Lmm,
    ];
    assert_components_within_errors(
        opts.method.name(),
        (&run.components, &run.component_errors),
        (&reference.0, &reference.1),
        &components,
        4.0,
    );
}

/// Per-pixel relative RMS error of `film` against reference means.
fn rel_rms(film: &Film, reference: &[DVec3]) -> f64 {
    let image = film.image();
    let sum: f64 = image
        .pixels
        .iter()
        .zip(reference)
        .map(|(p, r)| (((p.as_dvec3() - *r) / r.max(DVec3::splat(1e-6))).length_squared()) / 3.0)
        .sum();
    (sum / reference.len() as f64).sqrt()
}

/// Four times the passes must lower the relative RMS error clearly (1/2 for variance alone;
/// the blur's bias shrinks more slowly): the median over twelve seeds of each seed's ratio
/// must be below 0.7. In a 6×6 image a seed's error is set by a few heavy-tailed passes, so
/// any one seed's ratio ranges widely (0.35–2.8 over these seeds; one seed's error tripled
/// between 12 and 48 passes) and a pooled RMS over a few seeds follows its outliers: over
/// seeds 5–7 it was 0.70 with this code, over seeds 14–16 1.14 with the code before the
/// transmittance-shaped angular PDFs. The median over these twelve was 0.58 before and 0.59
/// after. It catches error that stops shrinking: made to fail (median 0.78) by tracing every
/// pass's light paths with pass 0's streams, so that passes repeat the same virtual lights.
#[test]
fn vbl_error_shrinks_as_passes_go_on() {
    let (w, h) = (6u32, 6u32);
    let ts = TraceScene::new(glossy_fog_box(w, h));
    let reference = render_pt(glossy_fog_box(w, h), 8192, 3, None).image();
    let reference: Vec<DVec3> = reference.pixels.iter().map(|p| p.as_dvec3()).collect();
    let p = 12u64;
    let mut ratios: Vec<f64> = (5..17)
        .map(|seed| {
            let mut at_p = f64::NAN;
            let result = render(&ts, &options(Method::Vbl, w, h, 4 * p, 64, seed), |progress| {
                if progress.passes == p {
                    at_p = rel_rms(progress.film, &reference);
                }
                true
            })
            .unwrap();
            let at_4p = rel_rms(&result.film, &reference);
            eprintln!(
                "seed {seed}: relative RMS error {at_p:.4} after {p} passes, {at_4p:.4} after {}",
                4 * p
            );
            at_4p / at_p
        })
        .collect();
    ratios.sort_by(f64::total_cmp);
    let median = 0.5 * (ratios[5] + ratios[6]);
    assert!(
        median < 0.7,
        "error must shrink: median ratio {median} over the seeds ({ratios:?})"
    );
}

/// Bias measured directly as passes go on (the test above measures RMS error, which mixes
/// noise and bias): 32 independent renders (seeds) of the glossy fog box, each component's
/// image mean and the whole image's after 4, 16 and 64 passes averaged over the seeds, against
/// the path tracer's split of the same components with its own standard error. Each gives
/// z = (mean − reference) / (the seeds' standard error ⊕ the reference's), per channel. The
/// blur's bias (a radius that shrinks with the passes) may show at 4 passes; at 16 and 64
/// every |z| must stay below 4. At 64 passes the image is judged to 1.0 % and direct to 0.7 %
/// (relative errors, printed), the others to 1.8–3.5 %: a 5 % bias of the whole estimate
/// fails (made to fail once, every estimate scaled by 1.05: image z 5.4, direct 9.7), one of a
/// single virtual-light component only above about 4 of its own errors (7–14 %).
#[test]
fn vbl_bias_vanishes_as_passes_go_on() {
    let (w, h) = (6u32, 6u32);
    let ts = TraceScene::new(glossy_fog_box(w, h));
    let (ref_mean, ref_se) = pt_components_with_errors(&ts, 16384, 3);
    const SEEDS: u32 = 32;
    const CHECKPOINTS: [u64; 3] = [4, 16, 64];
    const N: usize = Component::ALL.len();
    // The whole image is the components' sum: its reference and error from the split's.
    let ref_image = ref_mean.iter().sum::<DVec3>();
    let ref_image_se = ref_se.iter().map(|e| *e * *e).sum::<DVec3>().powf(0.5);
    // Per checkpoint: each seed's component means, and its image mean (in slot 0).
    let mut seeds: [(BatchMeans, BatchMeans); CHECKPOINTS.len()] = Default::default();
    for seed in 0..SEEDS {
        render(&ts, &options(Method::Vbl, w, h, 64, 64, 100 + seed), |progress| {
            if let Some(k) = CHECKPOINTS.iter().position(|&p| p == progress.passes) {
                let mean = |film: &Film| film.image().mean().as_dvec3();
                seeds[k]
                    .0
                    .push(&std::array::from_fn::<_, N, _>(|c| mean(&progress.components[c])));
                seeds[k].1.push(&[mean(progress.film)]);
            }
            true
        })
        .unwrap();
    }
    let mut failed = Vec::new();
    for (k, &passes) in CHECKPOINTS.iter().enumerate() {
        let (components, image) = &seeds[k];
        let (means, errors) = (components.means(), components.standard_errors());
        let names = Component::ALL.iter().map(|c| c.name()).chain(["image"]);
        for (c, name) in names.enumerate() {
            let (mean, error, reference, reference_se) = if c < N {
                (means[c], errors[c], ref_mean[c], ref_se[c])
            } else {
                (image.means()[0], image.standard_errors()[0], ref_image, ref_image_se)
            };
            if reference.max_element() <= 0.0 {
                continue; // no light in this component here (caustics: no glass)
            }
            let se = (error * error + reference_se * reference_se).powf(0.5);
            let z = ((mean - reference) / se.max(DVec3::splat(1e-12))).abs().max_element();
            eprintln!(
                "vbl after {passes:>2} passes, {name:<15} {:.4} vs pt {:.4}, relative error {:.3} (z {z:.2})",
                mean.element_sum() / 3.0,
                reference.element_sum() / 3.0,
                (se / reference).max_element()
            );
            if passes >= 16 && !(z < 4.0) {
                failed.push(format!("{name} after {passes} passes: z {z:.2}"));
            }
        }
    }
    assert!(failed.is_empty(), "bias left: {failed:?}");
}

/// The furnace (emitting, half-reflecting walls around a non-absorbing medium) renders 2.0
/// everywhere, so `vbl` must: the bundled asset (chromatic σs, g = 0.3) with default settings,
/// and a grey furnace (σs = 1) at g = 0, 0.5 and 0.9 with the radius held at R0 (α = 0.99), the
/// default 10 % of the diagonal (0.35), where the blur's light loss is largest (issue 19: the
/// uncorrected blur gave 1.87 at g = 0.5). Judged by 4 standard errors of the image mean (batch
/// means), so a loss of about 1–3 % (printed per case) fails; and the grey furnace at
/// g = ±0.999 with default settings, where all but the first scattering's light comes from the
/// camera paths' walks through the sharp medium (`components`): there the mean of 16
/// independent renders (seeds) is judged, with the larger of the pooled batch-mean error and
/// the seeds' own spread (about 0.43 %; one seed alone was ±1.5–1.7 %, so |z| < 4 allowed
/// ±7 %), so a 2 % loss or gain fails most of the time (checked once by judging against 2.04:
/// z 4.7 and 5.5, both failed) and 3 % always. Not checked: the residual of about 1 % at R0
/// measured with many seeds (receivers within R of the wall their camera ray ends on, and near
/// corners; docs/rendering.md), which is within these errors.
#[test]
fn vbl_furnace_converges_to_two() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/furnace.toml");
    // Scenes shared by several cases (the seeds of one g).
    let asset = Rc::new(TraceScene::new(beamlight_scene::load::load_scene(&path).unwrap()));
    let mut cases = vec![(
        "asset, default settings".to_string(),
        asset,
        options(Method::Vbl, 8, 8, 768, 128, 4),
    )];
    for g in [0.0f32, 0.5, 0.9] {
        let mut opts = options(Method::Vbl, 8, 8, 512, 64, 5);
        opts.many_lights.alpha = 0.99;
        let ts = Rc::new(TraceScene::new(furnace(Rgb::ONE, g, None)));
        opts.many_lights.radius = beamlight_render::radius::default_radius(&ts.scene);
        cases.push((format!("σs = 1, g = {g}, R = R0"), ts, opts));
    }
    // Near-delta phase functions (issue 15 item 3), at default settings: the camera paths'
    // walks through the sharp medium carry what position sampling could not find (before
    // them: 1.06 ± 0.03 after 512 passes at g = 0.999).
    const SEEDS: u32 = 16;
    for g in [0.999f32, -0.999] {
        let ts = Rc::new(TraceScene::new(furnace(Rgb::ONE, g, None)));
        for seed in 0..SEEDS {
            cases.push((
                format!("σs = 1, g = {g}, seed {seed}"),
                ts.clone(),
                options(Method::Vbl, 8, 8, 1024, 8, 6 + seed),
            ));
        }
    }
    let mut failed = Vec::new();
    let mut judge = |name: &str, mean: DVec3, se: DVec3| {
        let z = ((mean - DVec3::splat(2.0)) / se).abs().max_element();
        eprintln!("vbl furnace, {name}: {mean:.4} ± {:.4} (z {z:.2})", se.max_element());
        if !(z < 4.0) {
            failed.push(name.to_string());
        }
    };
    // Per near-delta g: the seeds' image means (slot 0), and their batch-mean errors.
    let mut pooled: Vec<(String, BatchMeans, Vec<DVec3>)> = Vec::new();
    for (name, ts, opts) in &cases {
        let run = render_with_errors(ts, opts, 16);
        assert_eq!(run.result.film.rejected, 0);
        assert_eq!(
            run.result.discarded,
            Default::default(),
            "estimates discarded per component, light paths dropped"
        );
        let Some((case, _)) = name.split_once(", seed ") else {
            judge(name, run.image, run.image_error);
            continue;
        };
        let k = pooled.iter().position(|(c, _, _)| c == case).unwrap_or_else(|| {
            pooled.push((case.to_string(), BatchMeans::default(), Vec::new()));
            pooled.len() - 1
        });
        let (_, seeds, errors) = &mut pooled[k];
        let mut image = [DVec3::ZERO; 7];
        image[0] = run.image;
        seeds.push(&image);
        errors.push(run.image_error);
    }
    for (case, seeds, errors) in &pooled {
        let n = errors.len() as f64;
        let batch_se = errors.iter().map(|e| *e * *e).sum::<DVec3>().powf(0.5) / n;
        let seed_se = seeds.standard_errors()[0];
        judge(&format!("{case}, {n} seeds"), seeds.means()[0], batch_se.max(seed_se));
    }
    assert!(
        failed.is_empty(),
        "furnace off 2.0 by more than 4 standard errors: {failed:?}"
    );
}

/// The fog box (Lambert walls, g = 0.7) with a glossy floor (Phong exponent `n`): VRLs from the
/// ceiling light end on the floor, so shading points near their ends see them at vanishing
/// distance.
fn glossy_floor_box(w: u32, h: u32, n: f32) -> Scene {
    let mut scene = fog_box(w, h, false);
    let floor = add_material(
        &mut scene,
        material(
            "floor",
            Some(Bsdf::Phong {
                diffuse: Rgb::splat(0.1),
                specular: Rgb::splat(0.8),
                exponent: n,
            }),
            Rgb::ZERO,
            false,
        ),
    );
    // The floor quad of the box (y = −1, facing up) is the box's 5th and 6th triangles.
    for t in scene.triangles.iter_mut().filter(|t| t.p.iter().all(|p| p.y == -1.0)) {
        t.material = floor;
    }
    scene.media[0].g = 0.7;
    scene
}

/// Unclamped VRLs ending on (or passing close to) a glossy surface light single pixels far
/// above their expected value (the paper's Fig. 3 singularities); VBLs spread that light over
/// their radius. Measured on the `Lsm` layer (media → surface, where the singularity is) as
/// the largest ratio of a pixel to the path tracer's `Lsm` there, at equal passes, over four
/// seeds (the worst pixel of one short render is itself a random variable).
#[test]
fn vbl_has_no_singular_pixels_where_vrl_does() {
    let (w, h) = (24u32, 24u32);
    let ts = TraceScene::new(glossy_floor_box(w, h, 80.0));
    let reference = render(&ts, &options(Method::Pt, w, h, 2048, 64, 9), |_| true).unwrap();
    let reference = reference.components[Component::Lsm as usize].image();
    // `vbl` gathering every light (the estimator whose singularities are in question), and
    // with light selection at about the same number of pair evaluations per record (24 drawn
    // of the ~100 lights of 64 paths) and the same light paths (so the same radii).
    let ratios = |method: Method, seed: u32, light_samples: Option<u32>| -> Vec<f32> {
        let mut opts = options(method, w, h, 4, 64, seed);
        opts.many_lights.light_samples = light_samples;
        let r = render(&ts, &opts, |_| true).unwrap();
        let image = r.components[Component::Lsm as usize].image();
        let mut ratios: Vec<f32> = image
            .pixels
            .iter()
            .zip(&reference.pixels)
            .map(|(p, q)| p.element_sum() / q.element_sum().max(1e-6))
            .collect();
        ratios.sort_by(|a, b| a.total_cmp(b));
        ratios
    };
    let (mut worst_vrl, mut worst_vbl, mut worst_drawn) = (0.0f32, 0.0f32, 0.0f32);
    for seed in 21..25 {
        let (a, b) = (ratios(Method::Vrl, seed, None), ratios(Method::Vbl, seed, None));
        let c = ratios(Method::Vbl, seed, Some(24));
        let n = a.len();
        eprintln!(
            "seed {seed}: Lsm pixel / reference: vrl 99th percentile {:.2}, max {:.2}; vbl {:.2}, {:.2}; vbl drawing 24 {:.2}, {:.2}",
            a[n * 99 / 100],
            a[n - 1],
            b[n * 99 / 100],
            b[n - 1],
            c[n * 99 / 100],
            c[n - 1]
        );
        worst_vrl += a[n - 1] / 4.0;
        worst_vbl += b[n - 1] / 4.0;
        worst_drawn += c[n - 1] / 4.0;
    }
    eprintln!(
        "mean of the worst pixels: vrl {worst_vrl:.2}, vbl {worst_vbl:.2}, vbl drawing 24 lights {worst_drawn:.2}"
    );
    assert!(worst_vrl > 6.0, "the scene must show VRL singularities ({worst_vrl})");
    assert!(worst_vbl < 0.6 * worst_vrl, "vbl {worst_vbl} vs vrl {worst_vrl}");
    // Light selection multiplies each drawn pair by 1/(K p), and the tree's importance starves
    // some VBLs that dominate a glossy pixel (a long VBL whose far end lies in the Phong lobe,
    // drawn with p ≈ 5·10⁻³ where it carries most of the pixel: its subtree's box bound loses
    // to compact clusters nearer the point). Issue 19's boundary correction raised the light
    // of VSLs within R of the floor by up to 2×, and these draws with it: the drawn worst pixel
    // went from 6.6 to 8.9 (all pairs 4.9 to 5.3), so the bound against `vrl` is 0.7 here
    // (it was 0.6), and the selection may at most double the all-pairs worst pixel.
    assert!(
        worst_drawn < 0.7 * worst_vrl,
        "vbl drawing lights {worst_drawn} vs vrl {worst_vrl}"
    );
    assert!(
        worst_drawn < 2.0 * worst_vbl,
        "vbl drawing lights {worst_drawn} vs all pairs {worst_vbl}"
    );
}
