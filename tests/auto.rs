//! `--method auto` (`beamlight_render::auto`): the combination of `pt` and `vbl` converges to
//! the same answers as each alone (the furnace's 2.0, the path tracer's component split), it
//! is a pure function of the seed with a pass budget, and components only `vbl` can reach
//! come from it.
mod common;
use beamlight_render::{Budget, Method, RenderOptions, RenderResult, many_lights::ManyLightSettings, render};
use beamlight_trace::{TraceScene, components::Component, pt::PathTracerSettings};
use common::*;
use glam::DVec3;
use std::time::Instant;

fn options(w: u32, h: u32, rounds: u64, seed: u32) -> RenderOptions {
    RenderOptions {
        method: Method::Auto,
        width: w,
        height: h,
        budget: Budget::Passes(rounds),
        seed,
        first_pass: 0,
        path_tracer: PathTracerSettings::default(),
        start: Instant::now(),
        components: true,
        many_lights: ManyLightSettings::default(),
        gpu: None,
    }
}

/// Component image means of `seeds` independent `auto` renders, with standard errors from
/// their spread (the combination is not a running mean of passes, so the batches are whole
/// renders), and the image's.
fn means_over_seeds(ts: &TraceScene, rounds: u64, seeds: u32) -> ([DVec3; 7], [DVec3; 7], DVec3, DVec3, RenderResult) {
    let (w, h) = (ts.scene.render.width, ts.scene.render.height);
    let mut parts = BatchMeans::default();
    let mut whole = BatchMeans::default();
    let (mut sum, mut image) = ([DVec3::ZERO; 7], DVec3::ZERO);
    let mut last = None;
    for seed in 0..seeds {
        let result = render(ts, &options(w, h, rounds, 100 + seed), |_| true).unwrap();
        assert_eq!(result.film.rejected, 0);
        assert_eq!(
            result.discarded,
            Default::default(),
            "estimates discarded per component, light paths dropped"
        );
        let means: [DVec3; 7] = std::array::from_fn(|c| result.components[c].image().mean().as_dvec3());
        let mut beauty = [DVec3::ZERO; 7];
        beauty[0] = result.film.image().mean().as_dvec3();
        for c in 0..7 {
            sum[c] += means[c] / seeds as f64;
        }
        image += beauty[0] / seeds as f64;
        parts.push(&means);
        whole.push(&beauty);
        last = Some(result);
    }
    (
        sum,
        per_component(parts.standard_errors()),
        image,
        whole.standard_errors()[0],
        last.expect("a render"),
    )
}

/// The furnace (a closed white box of albedo-1 fog, emission 1 everywhere) is 2.0 in every
/// pixel. Fails if the combination loses or doubles light (weights not summing to one, a
/// component combined twice or dropped), to about 4 standard errors (printed).
#[test]
fn auto_furnace_converges_to_two() {
    let ts = TraceScene::new(furnace(beamlight_scene::Rgb::ONE, 0.5, None));
    let (_, _, mean, se, last) = means_over_seeds(&ts, 16, 16);
    let z = ((mean - DVec3::splat(2.0)) / se).abs().max_element();
    let report = last.auto.as_ref().expect("auto reports its schedule");
    eprintln!(
        "auto furnace: {mean:.4} ± {:.4} (z {z:.2}); {:?}",
        se.max_element(),
        report.lines()
    );
    assert!(z < 4.0, "furnace {mean} ± {se}, not 2.0");
    // A pass budget's fixed schedule path-traces, per round, half its samples over every
    // component the scene has and half over one of them alone, in turn.
    let half = 16 * beamlight_render::auto::PT_SPP_PER_ROUND as u64 / 2;
    let served: Vec<usize> = (0..7).filter(|&k| report.needed[k]).collect();
    assert!(served.len() > 1, "the furnace has direct light and Lmm at least");
    for &k in &served {
        assert!(
            report.pt_spp[k] >= half,
            "{}: {} samples",
            Component::ALL[k].name(),
            report.pt_spp[k]
        );
    }
    assert_eq!(served.iter().map(|&k| report.pt_spp[k] - half).sum::<u64>(), half);
}

/// Per component, `auto` against the path tracer alone in the fog box (every component but
/// the caustics), to 4 standard errors. Fails if a component's combination is biased by more
/// (a weight applied to the wrong estimate, the vbl passes' components credited wrongly).
#[test]
fn auto_components_match_the_path_tracer() {
    let ts = TraceScene::new(fog_box(4, 4, false));
    let (means, errors, _, _, last) = means_over_seeds(&ts, 48, 16);
    let reference = pt_components_with_errors(&ts, 16384, 11);
    let report = last.auto.as_ref().expect("auto reports its schedule");
    for line in report.lines() {
        eprintln!("{line}");
    }
    // Both estimators must have taken part, or this tests only one of them.
    assert!(report.vbl_passes.iter().all(|&n| n == 48 || n == 0));
    assert!(report.vbl_weight.iter().any(|&w| w > 0.05), "vbl had no weight");
    assert_components_within_errors(
        "auto",
        (&means, &errors),
        (&reference.0, &reference.1),
        &[
            Component::Direct,
            Component::Lss,
            Component::Lsm,
            Component::Lms,
            Component::Lmm,
        ],
        4.0,
    );
}

/// With a pass budget the schedule is fixed: the same seed gives the same image, bit for bit,
/// and another seed another image.
#[test]
fn auto_is_deterministic_with_a_pass_budget() {
    let ts = TraceScene::new(fog_box(6, 4, false));
    let run = |seed| render(&ts, &options(6, 4, 4, seed), |_| true).unwrap().film.image();
    let (a, b, c) = (run(3), run(3), run(4));
    assert_eq!(a.pixels, b.pixels);
    assert_ne!(a.pixels, c.pixels);
}

/// A point lamp and a glass ball: paths from the lamp through the ball (the caustics, and the
/// walls lit by the caustic on the floor) are beyond the path tracer (a delta light through a
/// delta surface), so `auto` takes every component but `direct` from `vbl` alone, and not the
/// path tracer's estimate that lacks that light; and, the seed shared, those components are
/// `vbl`'s own image with that seed (common random numbers). Fails if a `pt` share leaks into
/// them, or if `auto`'s `vbl` passes draw from another stream than `vbl` alone (made to fail
/// so with `vbl` alone on the unsalted seed).
#[test]
fn auto_takes_what_the_path_tracer_cannot_reach_from_vbl() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_glass_ball_scene(dir.path());
    let mut scene = beamlight_scene::load::load_scene(&path).unwrap();
    scene.render.width = 8;
    scene.render.height = 8;
    let ts = TraceScene::new(scene);
    let only = beamlight_render::auto::vbl_only(&ts);
    assert!(!only[Component::Direct as usize]);
    assert!(Component::ALL[1..].iter().all(|&c| only[c as usize]));
    let result = render(&ts, &options(8, 8, 4, 1), |_| true).unwrap();
    let report = result.auto.as_ref().unwrap();
    // `vbl` alone with the same seed: `auto`'s passes are its passes.
    let mut vbl = options(8, 8, 4, 1);
    vbl.method = Method::Vbl;
    let alone = render(&ts, &vbl, |_| true).unwrap();
    for c in &Component::ALL[1..] {
        assert_eq!(report.vbl_weight[*c as usize], 1.0, "{}", c.name());
        let (mixed, alone) = (
            result.components[*c as usize].image(),
            alone.components[*c as usize].image(),
        );
        assert!(mixed.mean().max_element() > 0.0, "{}: no light", c.name());
        assert_eq!(mixed.pixels, alone.pixels, "{}: not vbl's image", c.name());
    }
}

/// With glass and an area light, `auto` takes the caustics from `vbl`'s photon estimators
/// alone and keeps both estimators for every other component (the path tracer reaches them,
/// heavy-tailed where lit through glass: the error model weighs that).
#[test]
fn auto_takes_the_caustics_from_the_photon_estimators() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/caustic_sphere.toml");
    let ts = TraceScene::new(beamlight_scene::load::load_scene(&path).unwrap());
    let only = beamlight_render::auto::vbl_only(&ts);
    for c in Component::ALL {
        let caustic = matches!(c, Component::CausticSurface | Component::CausticVolume);
        assert_eq!(only[c as usize], caustic, "{}", c.name());
    }
}

/// A lamp inside a glass globe (`lamp_in_glass`, and CARS's bulbs, and `cars_small`'s): all of
/// its power leaves through glass, so next-event estimation never reaches it and the path
/// tracer's estimate of every component but `direct` is heavy-tailed hits of the bulb behind
/// the globe. `auto` takes them from `vbl` alone. A small light over a glass ball
/// (`caustic_sphere`) sends the ball a few percent of its power: there only the caustics are
/// `vbl`'s. Fails if the rays start on the wrong side of the emitter (the bulb then hits
/// itself: share 0) or if glass is not told from the walls.
#[test]
fn auto_takes_light_behind_glass_from_vbl() {
    let scenes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let load = |name: &str| TraceScene::new(beamlight_scene::load::load_scene(&scenes.join(name)).unwrap());
    for name in ["lamp_in_glass.toml", "cars_small.toml"] {
        let ts = load(name);
        let share = beamlight_render::combine::power_through_delta(&ts);
        assert!(share > 0.99, "{name}: {share}");
        let only = beamlight_render::auto::vbl_only(&ts);
        assert!(!only[Component::Direct as usize], "{name}");
        assert!(
            Component::ALL[1..].iter().all(|&c| only[c as usize]),
            "{name}: {only:?}"
        );
    }
    let share = beamlight_render::combine::power_through_delta(&load("caustic_sphere.toml"));
    assert!(share < 0.2, "caustic_sphere: {share}");
}
