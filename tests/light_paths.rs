//! Light tracing keeps its flux books: in a closed scene every emitted watt is eventually
//! absorbed, so the flux the light set says was absorbed (at surfaces, from the VPLs; in media,
//! by the track-length estimate along the VRLs) must add up to the emitted power.
mod common;
use beamlight_scene::{Rgb, bsdf::Bsdf, light::PunctualLight};
use beamlight_trace::{
    TraceScene,
    light_paths::{Keep, LightSegment, LightSet, LightTracerSettings, SurfaceVertex, trace_light_paths},
    media::homogeneous_transmittance,
};
use common::*;
use glam::{DVec3, Vec3};

const PATHS: u32 = 200_000;

fn albedo_of(ts: &TraceScene, v: &SurfaceVertex) -> Rgb {
    match ts.scene.materials[v.material as usize].bsdf {
        Some(Bsdf::Lambert { albedo }) => albedo,
        _ => panic!("test scenes use Lambert surfaces"),
    }
}

/// Absorbed flux per path: (1 − ρ) of every VPL's incident flux plus, for every VRL (which
/// runs to the next surface), the share σa/σt (1 − e^(−σt L)) of its entering flux that the
/// medium absorbs along it.
/// (Summed in f64: millions of f32 additions would drift by a percent.)
fn absorbed(ts: &TraceScene, set: &LightSet) -> Rgb {
    let mut total = DVec3::ZERO;
    for v in &set.vpls {
        total += (Rgb::from(v.power) * (Rgb::ONE - albedo_of(ts, v))).as_dvec3();
    }
    for seg in &set.vrls {
        let m = &ts.scene.media[seg.medium as usize];
        let absorbed_share = m.sigma_a / m.sigma_t() * (Rgb::ONE - homogeneous_transmittance(m.sigma_t(), seg.length));
        total += (Rgb::from(seg.power) * absorbed_share).as_dvec3();
    }
    (total / set.paths as f64).as_vec3()
}

/// A closed box (walls Lambert `albedo`) with a one-sided square emitter under its ceiling.
fn closed_box(albedo: f32, radiance: f32) -> (beamlight_scene::Scene, f32) {
    let mut s = empty_scene(Vec3::new(0.0, 0.0, 0.5), Vec3::ZERO, 60.0, 4, 4);
    let wall = add_material(&mut s, lambert("wall", albedo));
    add_box_inward(&mut s, Vec3::splat(-1.0), Vec3::splat(1.0), wall);
    let light = add_material(&mut s, emitter("light", radiance));
    add_quad(
        &mut s,
        Vec3::new(-0.25, 0.9, -0.25),
        Vec3::new(0.5, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.5),
        light,
    );
    let power = std::f32::consts::PI * radiance * 0.25;
    (s, power)
}

#[test]
fn record_layouts_are_gpu_friendly() {
    assert_eq!(std::mem::size_of::<LightSegment>(), 48);
    assert_eq!(std::mem::size_of::<SurfaceVertex>(), 64);
}

#[test]
fn surfaces_absorb_all_emitted_power() {
    for albedo in [0.0f32, 0.5, 0.9] {
        let (s, power) = closed_box(albedo, 3.0);
        let ts = TraceScene::new(s);
        let set = trace_light_paths(&ts, &LightTracerSettings::default(), PATHS, 1, 0);
        let got = absorbed(&ts, &set);
        assert!(
            ((got - Rgb::splat(power)) / power).abs().max_element() < 0.01,
            "ρ {albedo}: absorbed {got}, emitted {power}"
        );
        assert!(set.vrls.is_empty() && set.photon_beams.is_empty() && set.caustic_photons.is_empty());
    }
}

#[test]
fn media_and_surfaces_absorb_all_emitted_power() {
    for (sigma_s, sigma_a, g) in [(0.8f32, 0.3f32, 0.0f32), (2.0, 0.5, 0.7), (0.3, 1.5, -0.5)] {
        let (mut s, power) = closed_box(0.6, 2.0);
        s.media.push(homogeneous(Rgb::splat(sigma_s), Rgb::splat(sigma_a), g));
        s.global_medium = Some(0);
        let ts = TraceScene::new(s);
        let set = trace_light_paths(&ts, &LightTracerSettings::default(), PATHS, 2, 0);
        let got = absorbed(&ts, &set);
        assert!(
            ((got - Rgb::splat(power)) / power).abs().max_element() < 0.015,
            "σs {sigma_s} σa {sigma_a} g {g}: absorbed {got}, emitted {power}"
        );
        // Photon beams are the first segments of each path (no specular surfaces here).
        assert!(!set.photon_beams.is_empty() && set.photon_beams.len() <= PATHS as usize);
        assert!(set.caustic_photons.is_empty());
    }
}

#[test]
fn point_lights_emit_four_pi_times_their_intensity() {
    let (mut s, _) = closed_box(0.0, 0.0);
    s.triangles.retain(|t| s.materials[t.material as usize].name != "light");
    s.lights.push(PunctualLight::Point {
        position: Vec3::new(0.2, -0.1, 0.3),
        intensity: Rgb::new(1.0, 2.0, 0.5),
    });
    let ts = TraceScene::new(s);
    let set = trace_light_paths(&ts, &LightTracerSettings::default(), PATHS, 3, 0);
    let got = absorbed(&ts, &set);
    let expected = Rgb::new(1.0, 2.0, 0.5) * 4.0 * std::f32::consts::PI;
    assert!(
        ((got - expected) / expected).abs().max_element() < 0.01,
        "{got} vs {expected}"
    );
}

#[test]
fn caustic_photons_arrive_through_specular_bounces() {
    // A point light above a mirror, a diffuse floor below: photons reach the floor directly
    // (VPLs, not caustics) and via the mirror (caustic photons).
    let (mut s, _) = closed_box(0.5, 0.0);
    s.triangles.retain(|t| s.materials[t.material as usize].name != "light");
    let mirror = add_material(
        &mut s,
        material("mirror", Some(Bsdf::Mirror { reflectance: Rgb::ONE }), Rgb::ZERO, false),
    );
    add_quad(
        &mut s,
        Vec3::new(-0.5, 0.95, -0.5),
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(1.0, 0.0, 0.0),
        mirror,
    );
    s.lights.push(PunctualLight::Point {
        position: Vec3::new(0.0, 0.5, 0.0),
        intensity: Rgb::ONE,
    });
    let ts = TraceScene::new(s);
    let set = trace_light_paths(&ts, &LightTracerSettings::default(), 20_000, 4, 0);
    assert!(!set.caustic_photons.is_empty());
    // Every caustic photon is also a VPL, and there are far fewer of them.
    assert!(set.caustic_photons.len() < set.vpls.len() / 2);
    for p in &set.caustic_photons {
        assert!(set.vpls.contains(p));
        // On the floor, light can only arrive through the mirror from above (the mirror's top
        // side also reflects light from the walls into the ceiling: those are caustics too).
        if p.pos[1] < -0.99 {
            assert!(p.wi[1] > 0.0, "caustic photon on the floor arriving from below: {p:?}");
        }
    }
    // Without specular surfaces there are no caustic photons at all.
    let (mut plain, _) = closed_box(0.5, 0.0);
    plain
        .triangles
        .retain(|t| plain.materials[t.material as usize].name != "light");
    plain.lights.push(PunctualLight::Point {
        position: Vec3::new(0.0, 0.5, 0.0),
        intensity: Rgb::ONE,
    });
    let plain_set = trace_light_paths(&TraceScene::new(plain), &LightTracerSettings::default(), 20_000, 4, 0);
    assert!(plain_set.caustic_photons.is_empty() && !plain_set.vpls.is_empty());
}

#[test]
fn double_sided_emitters_emit_from_both_faces() {
    let (mut s, one_side) = closed_box(0.3, 2.0);
    for m in &mut s.materials {
        if m.name == "light" {
            m.double_sided = true;
        }
    }
    let ts = TraceScene::new(s);
    let set = trace_light_paths(&ts, &LightTracerSettings::default(), PATHS, 5, 0);
    let got = absorbed(&ts, &set);
    assert!(
        ((got - Rgb::splat(2.0 * one_side)) / one_side).abs().max_element() < 0.02,
        "{got} vs {}",
        2.0 * one_side
    );
}

#[test]
fn a_trace_keeping_some_records_stores_exactly_those_of_the_full_trace() {
    // Glass and a mirror in a fog: every kind of record occurs.
    let ts = TraceScene::new(glass_furnace(8, 16, true));
    let full = trace_light_paths(&ts, &LightTracerSettings::default(), 2_000, 9, 3);
    assert!(!full.caustic_photons.is_empty() && !full.photon_beams.is_empty());
    for keep in [Keep::CAUSTIC_PHOTONS, Keep::PHOTON_BEAMS] {
        let settings = LightTracerSettings {
            keep,
            ..Default::default()
        };
        let part = trace_light_paths(&ts, &settings, 2_000, 9, 3);
        assert_eq!(part.paths, full.paths);
        assert_eq!(part.vrls, if keep.vrls { full.vrls.clone() } else { vec![] });
        assert_eq!(part.vpls, if keep.vpls { full.vpls.clone() } else { vec![] });
        let photons = if keep.caustic_photons {
            full.caustic_photons.clone()
        } else {
            vec![]
        };
        assert_eq!(part.caustic_photons, photons);
        let beams = if keep.photon_beams {
            full.photon_beams.clone()
        } else {
            vec![]
        };
        assert_eq!(part.photon_beams, beams);
    }
}

/// A light path whose power turns NaN (here at a Lambert floor with a NaN albedo, under a
/// point lamp) is counted in `nonfinite_paths`, which the renders report as dropped light
/// paths, instead of ending unseen. Each path that reaches the floor leaves its vertex there
/// (with the power it arrived with, still finite) and then dies: exactly one count per floor
/// vertex. The same with a sane albedo: none. (Before the count existed, such paths vanished;
/// made to fail by not counting the roulette's non-finite exit: 0 counted.)
#[test]
fn a_path_whose_power_turns_nan_is_counted() {
    for (albedo, broken) in [(f32::NAN, true), (0.5, false)] {
        let mut s = empty_scene(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 40.0, 4, 4);
        let floor = add_material(
            &mut s,
            material(
                "floor",
                Some(Bsdf::Lambert {
                    albedo: Rgb::splat(albedo),
                }),
                Rgb::ZERO,
                false,
            ),
        );
        add_quad(
            &mut s,
            Vec3::new(-5.0, -5.0, 0.0),
            Vec3::X * 10.0,
            Vec3::Y * 10.0,
            floor,
        );
        s.lights.push(PunctualLight::Point {
            position: Vec3::new(0.0, 0.0, 1.0),
            intensity: Rgb::ONE,
        });
        let ts = TraceScene::new(s);
        let set = trace_light_paths(&ts, &LightTracerSettings::default(), 4000, 5, 0);
        assert!(set.vpls.len() > 1000, "{} paths reached the floor", set.vpls.len());
        assert!(set.vpls.iter().all(|v| Rgb::from(v.power).is_finite()));
        let want = if broken { set.vpls.len() as u32 } else { 0 };
        assert_eq!(set.nonfinite_paths, want, "albedo {albedo}");
    }
}

/// A glass ball that bounds a medium scattering nothing is clear glass in fog (how CARS' globes
/// are modelled): light paths from a point light at its centre and camera paths from a camera
/// looking through it keep no record inside it, where a ball of the room's fog would hold the
/// first stretch of every light path. Fails if glass stops switching the medium (the fog would
/// fill the ball: tried, by leaving the interface off) or if a medium that scatters nothing
/// keeps records again.
#[test]
fn clear_glass_holds_no_fog() {
    use beamlight_scene::scene::MediumInterface;
    use beamlight_testkit::gltf_writer::shapes;
    use beamlight_trace::camera_paths::{CameraPathSettings, trace_camera_paths};
    let (centre, radius) = (Vec3::new(0.0, 0.0, -0.5), 0.4);
    for clear in [true, false] {
        let mut s = empty_scene(Vec3::new(0.0, 0.0, 0.9), centre, 40.0, 16, 16);
        let wall = add_material(&mut s, lambert("wall", 0.5));
        add_box_inward(&mut s, Vec3::splat(-1.0), Vec3::splat(1.0), wall);
        s.media.push(homogeneous(Rgb::splat(0.5), Rgb::splat(0.1), 0.3));
        s.global_medium = Some(0);
        let glass = add_material(&mut s, glass("glass", 1.5));
        s.media.push(homogeneous(Rgb::ZERO, Rgb::ZERO, 0.0));
        let interface = clear.then_some(MediumInterface {
            inside: Some(1),
            outside: Some(0),
        });
        add_mesh(&mut s, shapes::uv_sphere(centre, radius, 16, 32), glass, interface);
        s.lights.push(PunctualLight::Point {
            position: centre,
            intensity: Rgb::ONE,
        });
        let ts = TraceScene::new(s);
        let lights = trace_light_paths(&ts, &LightTracerSettings::default(), 2000, 3, 0);
        let cameras = trace_camera_paths(&ts, &CameraPathSettings::default(), 16, 16, 3, 0);
        // Midpoints well inside the ball (its facets reach in to 0.98 r).
        let inside = |o: [f32; 3], d: [f32; 3], len: f32| {
            (Vec3::from(o) + Vec3::from(d) * (0.5 * len) - centre).length() < 0.9 * radius
        };
        let vrls_inside = lights.vrls.iter().filter(|v| inside(v.origin, v.dir, v.length)).count();
        let segments_inside = cameras
            .media_segments
            .iter()
            .filter(|v| inside(v.origin, v.dir, v.length))
            .count();
        assert!(lights.vrls.len() > 2000 && !cameras.media_segments.is_empty());
        if clear {
            assert_eq!(vrls_inside, 0, "VRLs inside clear glass");
            assert_eq!(segments_inside, 0, "camera media segments inside clear glass");
            assert!(lights.vrls.iter().chain(&lights.photon_beams).all(|v| v.medium == 0));
        } else {
            // Foggy glass: every path starts with a stretch from the centre to the glass.
            assert!(vrls_inside >= 2000, "{vrls_inside} VRLs inside foggy glass");
            assert!(segments_inside > 0);
        }
    }
}
