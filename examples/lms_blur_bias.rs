//! Issue 35's measurement: where the blur's remaining bias in `Lms` comes from. For a scene's
//! light paths and camera media segments, every VPL–segment pair is estimated with `vsl_to_media`
//! at radius R and at R ≈ 0 (1e-3, where the VSL estimator is the unbiased VPL one) with the same
//! random numbers (paired: the camera point is drawn the same way, so most of the noise cancels).
//! The sums are split by the surface the VPL lies on (material and the axis its normal points
//! along), and the difference is printed per surface, relative to that surface's `Lms` and to
//! the whole `Lms`, as mean ± standard error over independent seeds (each its own light paths
//! and camera rays).
//!
//! Settings by environment: SCENE (assets/scenes/cornell_glossy_fog.toml), SIZE (16), SEEDS
//! (64), PAIRS (8: estimates a pair per seed), R (0.3), PATHS (64 light paths a seed).
//!
//! `cargo run --release --example lms_blur_bias`
use beamlight_scene::{luminance_mean, rng::Sampler};
use beamlight_trace::{
    TraceScene,
    camera_paths::{CameraPathSettings, trace_camera_paths},
    light_paths::{LightTracerSettings, trace_light_paths},
    vbl::{VblSettings, vsl_to_media},
};
use glam::Vec3;
use std::collections::BTreeMap;

fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

/// The surface a VPL lies on: its material and the world axis its normal is closest to.
fn surface(ts: &TraceScene, material: u32, n: Vec3) -> String {
    let axes = [
        ("+x", Vec3::X),
        ("-x", Vec3::NEG_X),
        ("+y", Vec3::Y),
        ("-y", Vec3::NEG_Y),
        ("+z", Vec3::Z),
        ("-z", Vec3::NEG_Z),
    ];
    let (axis, v) = axes.iter().max_by(|a, b| n.dot(a.1).total_cmp(&n.dot(b.1))).unwrap();
    let axis = if n.dot(*v) > 0.9 { axis } else { "curved" };
    format!("{} {axis}", ts.scene.materials[material as usize].name)
}

fn main() {
    let scene_path: String = env("SCENE", "assets/scenes/cornell_glossy_fog.toml".to_string());
    let (size, seeds, pairs, paths): (u32, u32, u32, u32) =
        (env("SIZE", 16), env("SEEDS", 64), env("PAIRS", 8), env("PATHS", 64));
    let (r, r_zero): (f32, f32) = (env("R", 0.3), 1e-3);
    let scene = beamlight_scene::load::load_scene(std::path::Path::new(&scene_path)).expect("scene");
    let ts = TraceScene::new(scene);
    let settings = VblSettings::default();
    // Per surface, per seed: (Lms at R, Lms at R ≈ 0).
    let mut sums: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    for seed in 0..seeds {
        let lights = trace_light_paths(&ts, &LightTracerSettings::default(), paths, seed + 1, 5);
        let camera = trace_camera_paths(&ts, &CameraPathSettings::default(), size, size, (seed + 1) ^ 0x55, 5);
        for (j, vpl) in lights.vpls.iter().enumerate() {
            let slot = sums
                .entry(surface(&ts, vpl.material, Vec3::from(vpl.normal)))
                .or_default();
            slot.resize(seeds as usize, (0.0, 0.0));
            for (i, seg) in camera.media_segments.iter().enumerate() {
                for k in 0..pairs {
                    let estimate = |radius: f32| {
                        let mut s = Sampler::new(seed * 7919 + k, i as u32, j as u32);
                        luminance_mean(vsl_to_media(&ts, seg, vpl, radius * radius, &settings, &mut s)) as f64
                    };
                    let (blurred, sharp) = (estimate(r), estimate(r_zero));
                    slot[seed as usize].0 += blurred;
                    slot[seed as usize].1 += sharp;
                }
            }
        }
    }
    let n = seeds as f64;
    let mean_se = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / n;
        (
            m,
            (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt(),
        )
    };
    let whole: Vec<(f64, f64)> = (0..seeds as usize)
        .map(|s| sums.values().fold((0.0, 0.0), |a, v| (a.0 + v[s].0, a.1 + v[s].1)))
        .collect();
    let all = mean_se(&whole.iter().map(|x| x.1).collect::<Vec<_>>()).0;
    println!("{scene_path}: {seeds} seeds × {paths} light paths, {size}² camera rays, R {r} against R {r_zero}");
    for (name, v) in sums.iter().chain(std::iter::once((&"all".to_string(), &whole))) {
        let (sharp, _) = mean_se(&v.iter().map(|x| x.1).collect::<Vec<_>>());
        let (d, se) = mean_se(&v.iter().map(|x| x.0 - x.1).collect::<Vec<_>>());
        if sharp > 0.0 {
            println!(
                "{name:16} share {:.3}: blur {:+.2} ± {:.2} % of its own Lms, {:+.3} ± {:.3} % of the whole",
                sharp / all,
                d / sharp * 100.0,
                se / sharp * 100.0,
                d / all * 100.0,
                se / all * 100.0
            );
        }
    }
}
