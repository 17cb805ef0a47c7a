//! The showcase scenes (`assets/scenes/{buddha,cars,smokyroom}.toml`, the paper's BUDDHA, CARS
//! and SMOKYROOM analogues) load from disk and render with every method on both backends, with
//! no NaN, Inf or negative value in any layer; and `vbl`'s beauty image after a few passes agrees
//! with a longer `pt` render at a small resolution.
//!
//! `cars.glb` (2.26 M triangles) is generated, not committed: `cargo xtask ci` writes it before
//! the tests. Elsewhere the cars tests skip with a message when it is missing.
mod common;
use beamlight_render::{
    Budget, Method, RenderOptions, RenderResult, compare::compare, many_lights::ManyLightSettings, render,
};
use beamlight_scene::load::load_scene;
use beamlight_trace::TraceScene;
use std::{path::PathBuf, sync::Arc, time::Instant};

fn scene_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("assets/scenes/{name}.toml"))
}

/// The scene, or `None` (skip) when its generated mesh is missing outside CI.
fn load(name: &str) -> Option<TraceScene> {
    let path = scene_path(name);
    if name == "cars" && !path.with_extension("glb").exists() {
        assert!(
            std::env::var_os("CI").is_none(),
            "assets/scenes/cars.glb is missing: `cargo xtask ci` generates it (`cargo xtask assets`)"
        );
        beamlight_gpu::device::report_skipped_test(&format!(
            "{name} needs assets/scenes/cars.glb; run `cargo xtask assets` to generate it"
        ));
        return None;
    }
    let scene = load_scene(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
    Some(TraceScene::new(scene))
}

fn options(method: Method, (width, height): (u32, u32), budget: Budget, seed: u32) -> RenderOptions {
    RenderOptions {
        method,
        width,
        height,
        budget,
        seed,
        first_pass: 0,
        path_tracer: Default::default(),
        start: Instant::now(),
        components: true,
        many_lights: ManyLightSettings {
            light_paths_per_pass: 16,
            ..Default::default()
        },
        gpu: None,
    }
}

/// Every layer of the result is finite and non-negative.
/// Every layer finite and non-negative, no sample dropped by a film, and no estimate discarded
/// on the way (`many_lights::admit`: a NaN or sign bug would otherwise only show as missing
/// light).
fn assert_sane(r: &RenderResult, what: &str) {
    let discarded = r.discarded;
    assert!(
        !discarded.any(),
        "{what}: estimates discarded per component, light paths dropped: {discarded}"
    );
    for (k, film) in std::iter::once(&r.film).chain(&r.components).enumerate() {
        assert_eq!(film.rejected, 0, "{what}: layer {k} dropped non-finite samples");
        for p in film.image().pixels {
            assert!(
                p.is_finite() && p.min_element() >= 0.0,
                "{what}: layer {k} has the pixel {p:?}"
            );
        }
    }
}

/// One pass of each method on the CPU and of each many-light method on the GPU.
fn renders_everywhere(name: &str, size: (u32, u32)) {
    let Some(ts) = load(name) else { return };
    for method in [Method::Pt, Method::Vrl, Method::VrlClamped, Method::Vbl] {
        let r = render(&ts, &options(method, size, Budget::Passes(1), 3), |_| true).unwrap();
        assert_sane(&r, &format!("{name} {} cpu", method.name()));
        // One `pt` sample per pixel can miss every light in cars (bulbs behind glass).
        if method != Method::Pt {
            assert!(
                r.film.image().mean().max_element() > 0.0,
                "{name} {} cpu: black image",
                method.name()
            );
        }
    }
    if beamlight_gpu::device::for_tests().is_none() {
        return;
    }
    let gpu = Arc::new(beamlight_gpu::GpuBackend::open(&ts).unwrap());
    for method in [Method::Vrl, Method::VrlClamped, Method::Vbl] {
        let mut opts = options(method, size, Budget::Passes(1), 3);
        opts.gpu = Some(gpu.clone());
        let r = render(&ts, &opts, |_| true).unwrap();
        assert_sane(&r, &format!("{name} {} gpu", method.name()));
        assert!(
            r.film.image().mean().max_element() > 0.0,
            "{name} {} gpu: black image",
            method.name()
        );
    }
}

/// `vbl` after `passes` against `pt` after `spp`: the relMSE of 4×4-pixel tile means, which
/// may exceed what the two renders' noise gives it (from the tiles' own standard errors) by 4
/// of that noise's standard deviations plus [`TILE_BIAS`]; and the image means, which must
/// agree within 4 standard errors of their difference. Standard errors are from batch means
/// over 16 batches of each render's passes (a pass of `vbl` shares its light paths across
/// pixels, so per-pixel variances would understate its error). Both are printed: a bias of
/// `vbl` larger than that fails, and nothing smaller is claimed.
fn vbl_against_pt(name: &str, size: (u32, u32), passes: u64, spp: u64) {
    let Some(ts) = load(name) else { return };
    let mut opts = options(Method::Vbl, size, Budget::Passes(passes), 5);
    opts.many_lights.light_paths_per_pass = 32;
    let vbl = common::render_with_errors(&ts, &opts, 16);
    let pt = common::render_with_errors(&ts, &options(Method::Pt, size, Budget::Passes(spp), 6), 16);
    let se = (vbl.image_error * vbl.image_error + pt.image_error * pt.image_error).powf(0.5);
    let z = (vbl.image - pt.image) / se;
    let (a, b) = (vbl.result.film.image(), pt.result.film.image());
    // Means of 4×4-pixel tiles: the picture's structure, not the per-pixel noise that a few
    // passes cannot remove.
    let (a_tiles, b_tiles) = (a.downsample(common::TILE), b.downsample(common::TILE));
    let rel_mse = compare(&a_tiles, &b_tiles).unwrap().rel_mse;
    // What the two renders' noise alone gives that relMSE, from their tiles' batch-mean errors:
    // E[(a − b)²] = se_a² + se_b² per tile and channel, weighted as `compare` weighs; each
    // term is a scaled χ²₁ (variance 2w²).
    let n = (b_tiles.pixels.len() * 3) as f64;
    let (mut expected, mut variance, mut allowance) = (0.0, 0.0, 0.0);
    for ((ea, eb), y) in vbl.tile_errors.iter().zip(&pt.tile_errors).zip(&b_tiles.pixels) {
        for c in 0..3 {
            let y2 = y[c] as f64 * y[c] as f64;
            let w = (ea[c] * ea[c] + eb[c] * eb[c]) / (y2 + 1e-2) / n;
            expected += w;
            variance += 2.0 * w * w;
            allowance += TILE_BIAS * TILE_BIAS * y2 / (y2 + 1e-2) / n;
        }
    }
    let max_rel_mse = expected + 4.0 * variance.sqrt() + allowance;
    eprintln!(
        "{name}: vbl {passes} passes vs pt {spp} spp at {}x{}: relMSE of 4x4 tiles {rel_mse:.2e} (from noise {expected:.2e} ± {:.2e}, \
         bound {max_rel_mse:.2e}); \
         image means {:.4} vs {:.4}, z {z:.2} (relative standard error {:.4})",
        size.0,
        size.1,
        variance.sqrt(),
        vbl.image,
        pt.image,
        (se / pt.image).max_element()
    );
    assert!(rel_mse < max_rel_mse, "{name}: relMSE {rel_mse} ≥ {max_rel_mse}");
    assert!(
        z.abs().max_element() < 4.0,
        "{name}: image means differ by {z:.2} standard errors"
    );
}

#[test]
fn buddha_renders_everywhere() {
    renders_everywhere("buddha", (12, 12));
}

#[test]
fn smokyroom_renders_everywhere() {
    renders_everywhere("smokyroom", (12, 12));
}

#[test]
fn cars_renders_everywhere() {
    renders_everywhere("cars", (16, 9));
}

/// A relative bias of every tile that the tile check allows beyond the noise: room for `vbl`'s
/// blur at 256 passes' radii (about 1 % in the furnace at 2 R0 before the walls' cuts, more
/// in corners) and its light selection's rare large draws not yet drawn. A tile structure
/// wrong by more than about 3 % beyond the noise fails where the noise is small.
const TILE_BIAS: f64 = 0.03;

// Measured (`cargo test --release --test showcase -- --nocapture` prints it), buddha /
// smokyroom / cars after 256 passes: tile relMSE 6.7e-4 / 1.6e-4 / 1.65e-2 against 1.0e-3 /
// 1.45e-4 / 1.81e-2 from noise (before the noise-derived bound, fixed bounds 0.01 / 0.005 / 0.1 from
// measurements), image means within z 0.64 / −2.97 / −1.95 of `pt`'s
// at relative standard errors of 1.4 / 0.5 / 2.4 %, so the means catch a bias of about
// 6 / 2 / 10 %. smokyroom's −1.5 % (z −3, close to the bound) is `vbl`'s blur at these radii
// or its light selection's rare large f/p not yet drawn (an earlier note measured 0.8 % with
// all-pairs passes); the two are not separated here.
// Made to fail once: `vbl`'s means scaled by 1.05 (z up to 5.0 / 7.1 / 0.15: buddha and smokyroom
// failed, cars did not, as its error says); and `vbl`'s tiles scaled by 1.05 (relMSE 3.2e-3 /
// 1.6e-3 / 1.7e-2 against bounds 2.5e-3 / 9.7e-4 / 3.1e-2: the same two failed).

/// A small bulb in dense g = 0.7 fog: `pt` is noisy here, so its reference gets many samples.
#[test]
fn buddha_vbl_agrees_with_pt() {
    vbl_against_pt("buddha", (24, 24), 256, 16384);
}

#[test]
fn smokyroom_vbl_agrees_with_pt() {
    vbl_against_pt("smokyroom", (24, 24), 256, 4096);
}

/// All direct light is caustic (bulbs in glass): `pt` finds it only by hitting a bulb through a
/// globe, so its reference has fireflies and the tolerance is the loosest.
#[test]
fn cars_vbl_agrees_with_pt() {
    vbl_against_pt("cars", (32, 18), 256, 4096);
}
