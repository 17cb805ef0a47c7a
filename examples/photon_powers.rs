//! How heavy-tailed the flux of a scene's light sets is: light paths are traced for a few
//! passes and, for the caustic photons, the VRLs and the VPLs, the flux's relative second
//! moment E[Φ²]/E[Φ]² (the variance an estimate over them inherits, per record), how many
//! records carry over 5, 20 and 50 times the mean flux, and the largest multiple. Fog inside
//! solid glass shows here (docs/rendering.md, "Media"): CARS with foggy globes has VRLs at 9.4,
//! with clear globes 1.07.
//!
//! Settings by environment: SCENE (assets/scenes/cars.toml), PATHS per pass (200 000), PASSES
//! (4), SEED (1).
//!
//! `cargo run --release --example photon_powers`
use beamlight_scene::{Rgb, luminance_mean};
use beamlight_trace::{
    TraceScene,
    light_paths::{LightTracerSettings, trace_light_paths},
};
fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}
fn report(what: &str, all: &[f32]) {
    let n = all.len();
    let mean: f64 = all.iter().map(|a| *a as f64).sum::<f64>() / n as f64;
    let m2: f64 = all.iter().map(|a| (*a as f64).powi(2)).sum::<f64>() / n as f64;
    let largest = all.iter().fold(0.0f32, |m, a| m.max(*a));
    let over: Vec<usize> = [5.0f64, 20.0, 50.0]
        .iter()
        .map(|k| all.iter().filter(|a| **a as f64 > k * mean).count())
        .collect();
    println!(
        "{what}: {n}, rel 2nd moment {:.4}, over 5/20/50x mean {:?}, max {:.1}x",
        m2 / (mean * mean),
        over,
        largest as f64 / mean
    );
}
fn main() {
    let scene_path: String = env("SCENE", "assets/scenes/cars.toml".to_string());
    let paths: u32 = env("PATHS", 200000);
    let passes: u32 = env("PASSES", 4);
    let seed: u32 = env("SEED", 1);
    let scene = beamlight_scene::load::load_scene(std::path::Path::new(&scene_path)).expect("scene");
    let ts = TraceScene::new(scene);
    let flux = |p: [f32; 3]| luminance_mean(Rgb::from(p));
    let (mut photons, mut vrls, mut vpls) = (Vec::new(), Vec::new(), Vec::new());
    for pass in 0..passes {
        // The default settings keep every kind of record.
        let set = trace_light_paths(&ts, &LightTracerSettings::default(), paths, seed, pass);
        photons.extend(set.caustic_photons.iter().map(|p| flux(p.power)));
        vrls.extend(set.vrls.iter().map(|v| flux(v.power)));
        vpls.extend(set.vpls.iter().map(|v| flux(v.power)));
    }
    report("caustic photons", &photons);
    report("vrls", &vrls);
    report("vpls", &vpls);
}
