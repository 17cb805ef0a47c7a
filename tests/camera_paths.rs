//! Camera gather data keeps its throughput books. In a furnace the radiance is known
//! everywhere (2 in the fog and on the walls, n² · 2 inside glass), so each pixel's estimate
//! from its gather records — emission seen directly, the reflected radiance (ρ · 2 = 1) ·
//! throughput at shading points, and
//! L · (1 − transmittance) · throughput along purely scattering media segments — must be 2.
mod common;
use beamlight_scene::Rgb;
use beamlight_trace::{
    TraceScene,
    camera_paths::{CameraPathSettings, GatherSet, MediaSegment, ShadingPoint, trace_camera_paths},
    media::homogeneous_transmittance,
};
use common::*;
use glam::DVec3;

fn furnace_estimate(ts: &TraceScene, set: &GatherSet, radiance_in: impl Fn(u32) -> f32) -> Vec<DVec3> {
    let mut px: Vec<DVec3> = set.emitted.iter().map(|e| e.as_dvec3()).collect();
    for sp in &set.shading_points {
        // The walls' emission is already in `emitted`; what they reflect is 0.5 · 2.
        px[sp.pixel as usize] += Rgb::from(sp.throughput).as_dvec3();
    }
    for seg in &set.media_segments {
        let m = &ts.scene.media[seg.medium as usize];
        assert_eq!(m.sigma_a, Rgb::ZERO, "the estimate assumes purely scattering media");
        let scattered = Rgb::ONE - homogeneous_transmittance(m.sigma_t(), seg.length);
        px[seg.pixel as usize] += (Rgb::from(seg.throughput) * scattered * radiance_in(seg.medium)).as_dvec3();
    }
    px
}

#[test]
fn record_layouts_are_gpu_friendly() {
    assert_eq!(std::mem::size_of::<ShadingPoint>(), 80);
    assert_eq!(std::mem::size_of::<MediaSegment>(), 48);
}

#[test]
fn gather_throughputs_balance_in_a_furnace_with_glass_and_mirror() {
    let scene = glass_furnace(16, 48, true);
    let ts = TraceScene::new(scene);
    let (w, h) = (16, 16);
    let passes = 64;
    let mut sum = vec![DVec3::ZERO; (w * h) as usize];
    for pass in 0..passes {
        let set = trace_camera_paths(&ts, &CameraPathSettings::default(), w, h, 7, pass);
        // Medium 1 fills the glass sphere, where radiance is 1.5² · 2.
        let est = furnace_estimate(&ts, &set, |m| if m == 1 { 4.5 } else { 2.0 });
        for (s, e) in sum.iter_mut().zip(est) {
            *s += e;
        }
        assert!(!set.media_segments.is_empty() && !set.shading_points.is_empty());
    }
    let mean = sum.iter().copied().sum::<DVec3>() / (sum.len() as f64 * passes as f64);
    assert!((mean - DVec3::splat(2.0)).abs().max_element() < 0.02, "mean {mean}");
}

#[test]
fn no_media_no_segments_and_walls_are_seen_directly() {
    let mut scene = furnace(Rgb::ZERO, 0.0, None);
    scene.media.clear();
    scene.global_medium = None;
    let ts = TraceScene::new(scene);
    let set = trace_camera_paths(&ts, &CameraPathSettings::default(), 8, 8, 1, 0);
    assert!(set.media_segments.is_empty());
    assert_eq!(set.shading_points.len(), 64, "one diffuse hit per pixel");
    for sp in &set.shading_points {
        assert_eq!(sp.throughput, [1.0; 3]);
    }
    assert!(
        set.emitted.iter().all(|e| *e == Rgb::ONE),
        "every pixel sees an emitting wall"
    );
}
