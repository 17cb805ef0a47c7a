//! Unclamped virtual point lights estimate surface-to-surface light (`Lss`) without bias: in a
//! closed box of Lambert walls (no media, no specular surfaces), Lss is everything the path
//! tracer finds beyond direct light, so VPL gathering from camera shading points must converge
//! to pt(all) − pt(max depth 1).
mod common;
use beamlight_trace::{
    TraceScene,
    camera_paths::{CameraPathSettings, trace_camera_paths},
    light_paths::{LightTracerSettings, trace_light_paths},
    vpl::vpl_to_surface,
};
use common::*;
use glam::{DVec3, Vec3};

#[test]
fn vpls_converge_to_the_path_tracers_indirect_light() {
    let (w, h) = (8u32, 8u32);
    let mut scene = empty_scene(Vec3::new(0.0, 0.0, 0.9), Vec3::new(0.2, -0.3, -1.0), 70.0, w, h);
    let wall = add_material(&mut scene, lambert("wall", 0.6));
    add_box_inward(&mut scene, Vec3::splat(-1.0), Vec3::splat(1.0), wall);
    let light = add_material(&mut scene, emitter("light", 10.0));
    add_quad(
        &mut scene,
        Vec3::new(-0.3, 0.99, -0.3),
        Vec3::new(0.6, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.6),
        light,
    );

    let all = render_pt(scene.clone(), 2048, 1, None).image().mean();
    let direct = render_pt(scene.clone(), 2048, 2, Some(1)).image().mean();
    let indirect_pt = all - direct;

    let ts = TraceScene::new(scene);
    let (passes, paths) = (64u32, 400u32);
    let mut sum = DVec3::ZERO;
    for pass in 0..passes {
        let gather = trace_camera_paths(&ts, &CameraPathSettings::default(), w, h, 3, pass);
        let lights = trace_light_paths(&ts, &LightTracerSettings::default(), paths, 4, pass);
        for (i, sp) in gather.shading_points.iter().enumerate() {
            let mut s = beamlight_scene::rng::Sampler::new(5, pass, i as u32);
            for vpl in &lights.vpls {
                sum += (vpl_to_surface(&ts, sp, vpl, 0.0, &mut s) / lights.paths as f32).as_dvec3();
            }
        }
    }
    let indirect_vpl = (sum / (passes as f64 * (w * h) as f64)).as_vec3();
    let rel = ((indirect_vpl - indirect_pt) / indirect_pt).abs().max_element();
    assert!(
        indirect_pt.min_element() > 0.05 * all.min_element(),
        "the test scene needs real indirect light"
    );
    eprintln!("VPL indirect {indirect_vpl}, path tracer {indirect_pt}, relative difference {rel}");
    assert!(
        rel < 0.04,
        "VPL indirect {indirect_vpl} vs path tracer {indirect_pt} (direct {direct})"
    );
}
