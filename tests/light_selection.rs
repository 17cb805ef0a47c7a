//! Light selection (`--light-samples K`, `beamlight_trace::light_tree`) against the all-pairs
//! gather it replaces, which stays the oracle: on one pass's records and light set, the mean of
//! the sampled estimate over independent selection and pair streams must equal the mean of the
//! all-pairs estimate over independent pair streams, per component (Lss, Lsm, Lms, Lmm), in a
//! fog box with Lambert walls, with glossy walls and g = 0.7, in a lumpy (grid) medium and in
//! a plume of dense smoke in clear air (the smoke box's case, where a VBL's leaf holds only the
//! stretch where its light scatters, `VblStretch`).
//!
//! The tolerance is 4.5 combined standard errors of the two means (both estimated from the
//! spread over streams), per channel of the image sum. It catches a probability that is not
//! the one the light was drawn with, a missing 1/p, lights the bound wrongly culls (a box
//! above the horizon given 0) and correlated strata; it cannot see a bias smaller than about
//! 4.5 standard errors, here 1–3 % of each component.
mod common;
use beamlight_scene::{Rgb, Scene, rng::pcg_hash};
use beamlight_trace::{
    TraceScene,
    camera_paths::MediaSegment,
    camera_paths::{CameraPathSettings, trace_camera_paths},
    light_paths::LightSegment,
    light_paths::{LightTracerSettings, trace_light_paths},
    light_tree::{Draw, Drawing, FLAT_GROUP, LightTree, Receiver, VblStretch, flat_draw_receiver, vbl_weight},
    streams::{self, GatherKind},
    vbl::{self, VblSettings},
};
use common::*;
use glam::{DVec3, UVec3, Vec3};

/// Mean and standard error of a set of per-stream totals, per channel.
fn mean_se(v: &[DVec3]) -> (DVec3, DVec3) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<DVec3>() / n;
    let var = v.iter().map(|x| (*x - mean) * (*x - mean)).sum::<DVec3>() / (n - 1.0);
    (mean, (var / n).map(f64::sqrt))
}

/// The VBLs' and VSLs' radius in these tests.
const R: f32 = 0.15;

fn selection_matches_all_pairs(name: &str, scene: Scene) {
    let ts = TraceScene::new(scene);
    let (w, h) = (ts.scene.render.width, ts.scene.render.height);
    let (seed, pass) = (7, 3);
    let gather = trace_camera_paths(&ts, &CameraPathSettings::default(), w, h, seed, pass);
    let lights = trace_light_paths(&ts, &LightTracerSettings::default(), 24, seed, pass);
    let (vpls, vrls) = (&lights.vpls, &lights.vrls);
    let (sps, segs) = (&gather.shading_points, &gather.media_segments);
    let vsl_tree = LightTree::over_vsls(&ts.scene, vpls);
    let vbl_tree = LightTree::over_vbls(&ts.scene, vrls, R);
    vsl_tree.validate(vpls.len()).unwrap();
    vbl_tree.validate(vrls.len()).unwrap();
    let r = R;
    let r2 = r * r;
    let settings = VblSettings::default();
    let k = 2;
    // Independent streams: the pair seed is all that changes between repetitions.
    let (all_runs, drawn_runs) = (12u32, 160u32);
    let ps = |run: u32| pcg_hash(run.wrapping_mul(0x9e37_79b9) ^ 0x51ed);
    eprintln!(
        "{name}: {} points, {} segments, {} VSLs, {} VBLs",
        sps.len(),
        segs.len(),
        vpls.len(),
        vrls.len()
    );

    // One component: f(record, light, stream) over the records of `records`, gathered from
    // the lights of `tree` (all of them, or k drawn ones).
    fn compare<R: Sync>(
        what: &str,
        records: &[R],
        n_lights: usize,
        tree: &LightTree,
        receiver: impl Fn(&R) -> Receiver + Sync,
        (kind, drawing): (GatherKind, Drawing),
        r: f32,
        k: u32,
        (all_runs, drawn_runs): (u32, u32),
        ps: impl Fn(u32) -> u32,
        f: impl Fn(&R, usize, &mut beamlight_scene::rng::Sampler) -> Rgb,
    ) {
        let pass = 3;
        let all: Vec<DVec3> = (0..all_runs)
            .map(|run| {
                let pair_seed = ps(run);
                let mut total = DVec3::ZERO;
                for (i, rec) in records.iter().enumerate() {
                    for j in 0..n_lights {
                        let mut s = streams::pair_sampler(pair_seed, pass, kind, i as u32, j as u32);
                        total += f(rec, j, &mut s).as_dvec3();
                    }
                }
                total
            })
            .collect();
        let drawn: Vec<DVec3> = (0..drawn_runs)
            .map(|run| {
                let pair_seed = ps(1000 + run);
                let mut total = DVec3::ZERO;
                // `Lmm`'s flat draw shares masses by groups of records; the VSLs' is each
                // record's own.
                let groups = (Drawing::of(kind, drawing) == Drawing::Flat)
                    .then(|| tree.group_masses(records.len(), r, |i| receiver(&records[i])));
                for (i, rec) in records.iter().enumerate() {
                    let draw = match (&groups, drawing) {
                        (Some(g), _) => Draw::Flat(&g[i / FLAT_GROUP]),
                        (None, Drawing::Flat) => Draw::Own,
                        (None, Drawing::Descent) => Draw::Descent,
                    };
                    let xi = streams::selection_number(pair_seed, pass, kind, i as u32);
                    let descent = |slot| streams::selection_sampler(pair_seed, pass, kind, i as u32, slot);
                    let v = tree.estimate(&receiver(rec), r, k, xi, draw, descent, |slot, j| {
                        f(
                            rec,
                            j,
                            &mut streams::drawn_pair_sampler(pair_seed, pass, kind, i as u32, slot),
                        )
                    });
                    assert!(v.is_finite(), "{what}: record {i} gave {v}");
                    total += v.as_dvec3();
                }
                total
            })
            .collect();
        let ((ma, sa), (mb, sb)) = (mean_se(&all), mean_se(&drawn));
        let z = ((mb - ma) / (sa * sa + sb * sb).map(f64::sqrt)).abs().max_element();
        eprintln!("  {what}: all pairs {ma:.4} ± {sa:.4}, {k} drawn {mb:.4} ± {sb:.4}, |z| {z:.2}");
        assert!(ma.max_element() > 0.0, "{what}: the scene must have some");
        assert!(
            z < 4.5,
            "{what}: the sampled mean differs from the all-pairs mean by {z:.1} standard errors"
        );
    }
    let runs = (all_runs, drawn_runs);
    compare(
        "Lss",
        sps,
        vpls.len(),
        &vsl_tree,
        |sp| Receiver::at_point(&ts.scene, sp),
        (GatherKind::VplToSurface, Drawing::Descent),
        r,
        k,
        runs,
        ps,
        |sp, j, s| vbl::vsl_to_surface(&ts, sp, &vpls[j], r2, &settings, s),
    );
    compare(
        "Lss drawn flat",
        sps,
        vpls.len(),
        &vsl_tree,
        |sp| Receiver::at_point(&ts.scene, sp),
        (GatherKind::VplToSurface, Drawing::Flat),
        r,
        k,
        runs,
        ps,
        |sp, j, s| vbl::vsl_to_surface(&ts, sp, &vpls[j], r2, &settings, s),
    );
    compare(
        "Lsm",
        sps,
        vrls.len(),
        &vbl_tree,
        |sp| Receiver::at_point(&ts.scene, sp),
        (GatherKind::VrlToSurface, Drawing::Descent),
        r,
        k,
        runs,
        ps,
        |sp, j, s| vbl::vbl_to_surface(&ts, sp, &vrls[j], r2, &settings, s),
    );
    compare(
        "Lms",
        segs,
        vpls.len(),
        &vsl_tree,
        |seg| Receiver::along_segment(&ts.scene, seg),
        (GatherKind::VplToMedia, Drawing::Descent),
        r,
        k,
        runs,
        ps,
        |seg, j, s| vbl::vsl_to_media(&ts, seg, &vpls[j], r2, &settings, s),
    );
    compare(
        "Lms drawn flat",
        segs,
        vpls.len(),
        &vsl_tree,
        |seg| Receiver::along_segment(&ts.scene, seg),
        (GatherKind::VplToMedia, Drawing::Flat),
        r,
        k,
        runs,
        ps,
        |seg, j, s| vbl::vsl_to_media(&ts, seg, &vpls[j], r2, &settings, s),
    );
    compare(
        "Lmm",
        segs,
        vrls.len(),
        &vbl_tree,
        |seg| Receiver::along_segment(&ts.scene, seg),
        (GatherKind::VrlToMedia, Drawing::Descent),
        r,
        k,
        runs,
        ps,
        |seg, j, s| vbl::vbl_to_media(&ts, seg, &vrls[j], r2, &settings, s),
    );
    compare(
        "Lmm drawn flat",
        segs,
        vrls.len(),
        &vbl_tree,
        |seg| flat_draw_receiver(&ts.scene, seg),
        (GatherKind::VrlToMedia, Drawing::Flat),
        r,
        k,
        runs,
        ps,
        |seg, j, s| vbl::vbl_to_media(&ts, seg, &vrls[j], r2, &settings, s),
    );
}

#[test]
fn drawn_lights_match_all_pairs_in_a_fog_box() {
    selection_matches_all_pairs("fog box", fog_box(8, 8, false));
}

#[test]
fn drawn_lights_match_all_pairs_with_glossy_walls_and_forward_scattering() {
    selection_matches_all_pairs("glossy fog box", glossy_fog_box(8, 8));
}

#[test]
fn drawn_lights_match_all_pairs_in_a_lumpy_medium() {
    selection_matches_all_pairs("lumpy fog box", fog_box(8, 8, true));
}

/// The furnace (walls that emit and reflect, a chromatic scatterer filling the box): VBLs
/// start on every wall and cross the whole box.
#[test]
fn drawn_lights_match_all_pairs_in_the_furnace() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/furnace.toml");
    let mut scene = beamlight_scene::load::load_scene(&path).unwrap();
    scene.render.width = 8;
    scene.render.height = 8;
    selection_matches_all_pairs("furnace", scene);
}

/// The fog box's medium made smoke: 16³ voxels over the box, `density` in the voxels whose
/// (x, y) indices `inside` takes, clear air elsewhere.
fn smoke(scene: &mut Scene, density: f32, inside: impl Fn(u32, u32) -> bool) {
    let res = UVec3::splat(16);
    let values = (0..res.x * res.y * res.z)
        .map(|i| if inside(i % 16, i / 16 % 16) { density } else { 0.0 })
        .collect();
    scene.media[0].density = Some(beamlight_scene::medium::DensityGrid::new(
        res,
        Vec3::splat(-1.0),
        Vec3::splat(1.0),
        values,
    ));
}

/// A plume: [`smoke`] where the voxel's x index is in `xs` (the slab 0 ≤ x < 0.5 for 8..12).
fn plume(scene: &mut Scene, xs: std::ops::Range<u32>, density: f32) {
    smoke(scene, density, |x, _| xs.contains(&x));
}

/// Dense smoke (4× the fog box's extinction) in a slab of clear air: most VBLs cross
/// both, and their leaves hold the stretch in the smoke.
#[test]
fn drawn_lights_match_all_pairs_in_a_plume_of_smoke() {
    let mut scene = fog_box(8, 8, false);
    plume(&mut scene, 8..11, 4.0);
    selection_matches_all_pairs("plume", scene);
}

/// A VBL's leaf in a density grid (`VblStretch::of`): its weight is the light it scatters, flux
/// × ∫ σs(u) T(u) du, against that integral by a fine midpoint rule (100 000 steps; the march
/// takes two a voxel, and along an axis the trilinear density is piecewise linear: 1 % is
/// far above the march's error, 0.1 % here, and below what the densest σs and σt give,
/// 1.32× here); the stretch lies in the slab that holds the medium; a VBL in clear air keeps
/// a small positive weight; a homogeneous medium's leaf is the bound's, up to 8 mean free
/// paths. Made to fail by weighting with the bound (`vbl_weight`) in the grid: 1.703 against
/// 1.292.
#[test]
fn a_vbl_leaf_holds_the_stretch_where_its_light_scatters() {
    let mut scene = fog_box(4, 4, false);
    let homogeneous = scene.clone();
    plume(&mut scene, 8..12, 4.0);
    let m = &scene.media[0];
    let grid = m.density.as_ref().unwrap();
    let vbl = |x0: f32, len: f32| LightSegment {
        origin: [x0, 0.1, 0.05],
        length: len,
        dir: [1.0, 0.0, 0.0],
        medium: 0,
        power: [2.0, 1.0, 0.5],
        flags: 0,
    };
    let crossing = vbl(-0.9, 1.8);
    let stretch = VblStretch::of(&scene, &crossing, 0.0);
    let (sigma_s, sigma_t) = (m.sigma_s.max_element() as f64, m.sigma_t().max_element() as f64);
    let steps = 100_000;
    let h = crossing.length as f64 / steps as f64;
    let (mut scattered, mut tau) = (0f64, 0f64);
    for i in 0..steps {
        let x = crossing.origin[0] as f64 + (i as f64 + 0.5) * h;
        let d = grid.density(Vec3::new(x as f32, 0.1, 0.05)) as f64;
        scattered += sigma_s * d * h * (-(tau + 0.5 * sigma_t * d * h)).exp();
        tau += sigma_t * d * h;
    }
    let expected = 2.0 * scattered;
    let ratio = stretch.weight as f64 / expected;
    assert!(
        (ratio - 1.0).abs() < 0.01,
        "weight {} against {expected}",
        stretch.weight
    );
    // The density is positive for x in (−0.0625, 0.5625): half a voxel beyond the slab's
    // voxel centres, where the trilinear interpolation reaches 0.
    let (a, b) = (-0.9 + stretch.start, -0.9 + stretch.end);
    assert!(
        a > -0.0625 - 0.06 && b < 0.5625 + 0.06 && b - a > 0.3,
        "stretch {a}..{b}"
    );
    assert!(
        stretch.sigma_t > 0.0 && stretch.sigma_t < sigma_t as f32 * 4.0,
        "{stretch:?}"
    );

    let clear = VblStretch::of(&scene, &vbl(-0.9, 0.7), 0.0);
    let (bound, _) = vbl_weight(&scene, &vbl(-0.9, 0.7));
    assert!(
        clear.weight > 0.0 && clear.weight <= 1e-3 * bound * 1.0001,
        "{clear:?}, bound {bound}"
    );

    let (weight, sigma_t) = vbl_weight(&homogeneous, &crossing);
    let plain = VblStretch::of(&homogeneous, &crossing, 0.1);
    assert_eq!(
        plain,
        VblStretch {
            start: 0.0,
            end: crossing.length.min(8.0 / sigma_t),
            sigma_t,
            weight,
            profile: None,
        }
    );
}

/// The flat draw weighs a camera segment's VBLs along the stretch of it where light scatters
/// (`flat_draw_receiver`): in the slab of smoke for a segment crossing clear air into it, the
/// whole segment in a homogeneous medium. Made to fail by returning the whole segment.
#[test]
fn a_flat_draw_weighs_vbls_where_the_camera_ray_meets_the_medium() {
    let mut scene = fog_box(4, 4, false);
    let homogeneous = scene.clone();
    plume(&mut scene, 8..12, 4.0);
    let seg = MediaSegment {
        origin: [-0.9, 0.1, 0.05],
        length: 1.8,
        dir: [1.0, 0.0, 0.0],
        medium: 0,
        throughput: [1.0; 3],
        pixel: 0,
    };
    let Receiver::Segment { o, len, .. } = flat_draw_receiver(&scene, &seg) else {
        panic!("a camera segment's receiver is a segment");
    };
    // The density is positive for x in (−0.0625, 0.5625) (see above); light reaches the
    // camera from the near side of the slab.
    assert!(
        o.x > -0.0625 - 0.06 && o.x + len < 0.5625 + 0.06 && len > 0.2,
        "{o} + {len}"
    );
    let whole = |rx: Receiver| match rx {
        Receiver::Segment { o, d, len, g } => (o, d, len, g),
        _ => panic!("a camera segment's receiver is a segment"),
    };
    assert_eq!(
        whole(flat_draw_receiver(&homogeneous, &seg)),
        whole(Receiver::along_segment(&homogeneous, &seg))
    );
}

/// A flat draw weighs a VBL in a density grid by where along it the light scatters
/// (`Profile`), not only by its stretch and mean σt. A VBL crosses two slabs of smoke with
/// clear air between them (its stretch spans all three); of two short camera segments in
/// clear air above it, one beside the clear stretch and one beside the far slab, the first
/// must weigh the VBL less, as the pair integral ∫∫ σs T F / d² du dt (by a fine midpoint
/// rule; the camera segments cross no smoke, so only the VBL's side is weighted) does: its
/// ratio 0.56, the profile's 0.94, the leaf's homogeneous fading's 1.65. The check: within a
/// factor 2 of the pair integral's (deterministic; made to fail by weighing without the
/// profile, and with the profile's mean over each half in u instead of its integral in z,
/// 1.29).
#[test]
fn a_flat_draw_weighs_a_vbl_where_its_light_scatters() {
    let mut scene = fog_box(4, 4, false);
    // Two slabs, −0.75 ≤ x < −0.5 and 0.5 ≤ x < 0.75, below y = −0.375.
    smoke(&mut scene, 4.0, |x, y| {
        ((2..4).contains(&x) || (12..14).contains(&x)) && y < 5
    });
    let vbl = LightSegment {
        origin: [-0.95, -0.5, 0.0],
        length: 1.9,
        dir: [1.0, 0.0, 0.0],
        medium: 0,
        power: [1.0; 3],
        flags: 0,
    };
    let r = 0.05;
    let tree = LightTree::over_vbls(&scene, std::slice::from_ref(&vbl), r);
    assert!(
        tree.profiles.first().is_some_and(Option::is_some),
        "the VBL has a profile"
    );
    let leaf = &tree.nodes[0];
    // Short camera segments along z, 0.2 above the VBL's line, in clear air (y > −0.375).
    let receiver = |x: f32| Receiver::Segment {
        o: Vec3::new(x, -0.3, -0.1),
        d: Vec3::Z,
        len: 0.2,
        g: scene.media[0].g,
    };
    let (beside_clear, beside_far) = (receiver(0.0), receiver(0.62));
    let with = (tree.flat_importance(leaf, &beside_clear, r) / tree.flat_importance(leaf, &beside_far, r)) as f64;
    let without = (beamlight_trace::light_tree::flat_importance(leaf, &beside_clear, r, None)
        / beamlight_trace::light_tree::flat_importance(leaf, &beside_far, r, None)) as f64;
    // The pair integral: ∫∫ σs(u) T(u) F / d² du dt, F both HG phase functions.
    let m = &scene.media[0];
    let grid = m.density.as_ref().unwrap();
    let hg = |g: f64, c: f64| (1.0 - g * g) / (1.0 + g * g - 2.0 * g * c).powf(1.5);
    let pair = |x: f32| {
        let (n, k) = (2000, 400);
        let (hu, ht) = (vbl.length as f64 / n as f64, 0.2 / k as f64);
        let (mut total, mut tau) = (0.0, 0.0);
        for i in 0..n {
            let y = DVec3::new(-0.95 + (i as f64 + 0.5) * hu, -0.5, 0.0);
            // (The test's σt is the fog box's largest, 0.7, times the density.)
            let density = grid.density(y.as_vec3()) as f64;
            let light = density * (-(tau + 0.5 * 0.7 * density * hu)).exp() * hu;
            tau += 0.7 * density * hu;
            for j in 0..k {
                let p = DVec3::new(x as f64, -0.3, -0.1 + (j as f64 + 0.5) * ht);
                let w = (p - y).normalize();
                let f = hg(m.g as f64, w.x) * hg(m.g as f64, -w.z);
                total += light * f * ht / (p - y).length_squared();
            }
        }
        total
    };
    let exact = pair(0.0) / pair(0.62);
    assert!(
        (with / exact).max(exact / with) < 2.0,
        "beside the clear air / beside the far slab: {with} with the profile, {without} without, {exact} by the pair integral"
    );
}
