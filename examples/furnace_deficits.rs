//! Issue 19's measurement: how far `vbl`'s mean in the grey furnace (walls emitting 1 with
//! albedo 0.5, σs = 1, σa = 0: 2.0 everywhere) lies from the answer, per transport component
//! against the path tracer's split, over many seeds, with a coarse map of the beauty's deficit.
//! Settings by environment: G (0.5), SCALE (R0 as a multiple of the cube's default, 2), SIZE
//! (12), SEEDS (48), PASSES (16), ALPHA (0.7), SPP (the reference's, 4096), SLAB=1 (a flat
//! 7 × 2 × 7 box whose side walls are out of view, to tell walls from edges and corners).
//!
//! `cargo run --release --example furnace_deficits` (1536 seeds at 12²: about a minute).
#[path = "../tests/common/mod.rs"]
mod common;
use beamlight_render::{Budget, Method, RenderOptions, many_lights::ManyLightSettings, render};
use beamlight_scene::Rgb;
use beamlight_trace::TraceScene;
use common::*;
use glam::Vec3;
use std::time::Instant;

fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

fn main() {
    let g: f32 = env("G", 0.5);
    let scale: f32 = env("SCALE", 2.0);
    let size: u32 = env("SIZE", 12);
    let seeds: u32 = env("SEEDS", 48);
    let passes: u64 = env("PASSES", 16);
    let alpha: f32 = env("ALPHA", 0.7);
    let spp: u32 = env("SPP", 4096);
    let slab: bool = env("SLAB", 0u32) == 1;
    let mut scene = if slab {
        let camera = empty_scene(Vec3::ZERO, Vec3::new(0.3, -1.0, 0.2), 50.0, size, size);
        furnace_box(
            camera,
            Vec3::new(-3.5, -1.0, -3.5),
            Vec3::new(3.5, 1.0, 3.5),
            Rgb::ONE,
            g,
            None,
        )
    } else {
        furnace(Rgb::ONE, g, None)
    };
    scene.render.width = size;
    scene.render.height = size;
    let ts = TraceScene::new(scene);
    let (pt, pt_se) = pt_components_with_errors(&ts, spp, 7);
    // The cube's default R0 (10 % of its diagonal), also for the slab.
    let r0 = 0.1 * 12f32.sqrt() * scale;
    let mut per_seed: Vec<[f64; 8]> = Vec::new();
    let mut map = vec![0.0f64; (size * size) as usize];
    for seed in 0..seeds {
        let opts = RenderOptions {
            method: Method::Vbl,
            width: size,
            height: size,
            budget: Budget::Passes(passes),
            seed: 1000 + seed,
            first_pass: 0,
            path_tracer: Default::default(),
            start: Instant::now(),
            components: true,
            many_lights: ManyLightSettings {
                radius: r0,
                alpha,
                ..Default::default()
            },
            gpu: None,
        };
        let r = render(&ts, &opts, |_| true).unwrap();
        let mut row = [0.0; 8];
        row[0] = r.film.image().mean().as_dvec3().element_sum() / 3.0;
        for (c, f) in r.components.iter().enumerate() {
            row[c + 1] = f.image().mean().as_dvec3().element_sum() / 3.0;
        }
        let img = r.film.image();
        for (i, m) in map.iter_mut().enumerate() {
            let p = img.pixels[i];
            *m += (p.x + p.y + p.z) as f64 / 3.0;
        }
        per_seed.push(row);
    }
    let n = per_seed.len() as f64;
    let names = ["beauty", "direct", "Lsm", "Lmm", "Lms", "Lss", "cs", "cv"];
    let pt_tot: f64 = pt.iter().map(|v| v.element_sum() / 3.0).sum();
    eprintln!("g {g} scale {scale} R0 {r0} size {size} seeds {seeds} passes {passes} alpha {alpha}");
    for c in 0..6 {
        let mean = per_seed.iter().map(|r| r[c]).sum::<f64>() / n;
        let se = (per_seed.iter().map(|r| (r[c] - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
        let (refv, rse) = if c == 0 {
            (2.0, 0.0)
        } else {
            (
                pt[c - 1].element_sum() / 3.0,
                pt_se[c - 1].element_sum() / 3.0 / 3f64.sqrt(),
            )
        };
        eprintln!(
            "{:>7}: vbl {mean:.5} ± {se:.5}  ref {refv:.5} ± {rse:.5}  diff {:+.5} ({:+.2} %), of total {:+.3} %",
            names[c],
            mean - refv,
            (mean / refv - 1.0) * 100.0,
            (mean - refv) / 2.0 * 100.0
        );
    }
    eprintln!("pt total {pt_tot:.5}");
    // coarse map of the beauty ratio to 2
    let b = 4usize;
    let cells = size as usize / b;
    for cy in 0..cells {
        let mut line = String::new();
        for cx in 0..cells {
            let mut s = 0.0;
            for y in 0..b {
                for x in 0..b {
                    s += map[(cy * b + y) * size as usize + cx * b + x];
                }
            }
            line += &format!(" {:+6.2}", (s / (b * b) as f64 / n / 2.0 - 1.0) * 100.0);
        }
        eprintln!("{line}");
    }
}
