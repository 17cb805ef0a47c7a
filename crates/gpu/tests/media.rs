//! `shaders/lib/media.wgsl` against the CPU functions it twins (`media::transmittance` through
//! `TraceScene::medium_transmittance`, `TraceScene::shadow_transmittance`,
//! `Medium::density_at`), query by query on the same sampler keys, through the test kernel
//! `shaders/test/media_probe.wgsl`.
//!
//! Scenes, all inside an opaque room with an opaque block in it:
//! * a homogeneous chromatic box region (one channel without extinction) bounded by null
//!   interfaces, with a sphere region of another medium nested inside it;
//! * the same with both media heterogeneous (lumpy density grids with empty majorant cells);
//! * no null interfaces, only a global medium (the `occluded()` fast path), homogeneous and
//!   heterogeneous.
//!
//! Tolerance: 1e-4 relative, measured against max(|cpu|, 1e-4) so values below 1e-4 are held to
//! an absolute error; the number of random numbers drawn must be equal too. Every query must
//! agree. Ratio tracking compares float distances with cell borders and with the roulette
//! threshold, so a driver that rounded one of them an ulp differently (fused multiply-adds, its
//! own `log`) could move a collision across a border and diverge from there. On lavapipe none
//! does: with 100 000 shadow rays per scene, all 233 333 queries agree, within 2e-5 and mostly
//! bit for bit. Should another adapter show a few such flips, the printed cases tell them from
//! a porting bug: same inputs, draw counts that part late, a collision at a border.
use beamlight_gpu::{
    Gpu, GpuScene,
    compute::{self, Kernel, Slot},
    device,
    layout::NO_MEDIUM,
    shaders,
};
use beamlight_scene::{
    Rgb, Scene,
    camera::Camera,
    medium::{DensityGrid, Medium},
    rng::Sampler,
    scene::{MediumId, MediumInterface, RenderSettings},
};
use beamlight_testkit::{
    gltf_writer::shapes,
    scenes::{add_mesh, lambert, material},
};
use beamlight_trace::{TraceScene, lights::LightSample};
use bytemuck::{Pod, Zeroable};
use glam::{Mat4, UVec3, Vec3};

const QUERY_SHADOW: u32 = 0;
const QUERY_TRANSMITTANCE: u32 = 1;
const QUERY_DENSITY: u32 = 2;

/// `MediaQuery` in `shaders/test/media_probe.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct MediaQuery {
    o: [f32; 3],
    medium: u32,
    v: [f32; 3],
    kind: u32,
    tmax: f32,
    seed: u32,
    pass_index: u32,
    index: u32,
}

/// `MediaBatch` in `shaders/test/media_probe.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct MediaBatch {
    count: u32,
    row: u32,
    _pad: [u32; 2],
}

// ---- scenes ----

/// The room [-1.5, 1.5]³ of the scenes.
const ROOM: f32 = 1.5;
/// The medium box region of scenes (a) and (b).
const BOX_LO: Vec3 = Vec3::new(-0.9, -0.8, -0.9);
const BOX_HI: Vec3 = Vec3::new(0.8, 0.9, 0.7);
/// The sphere region nested in the box.
const SPHERE_C: Vec3 = Vec3::new(-0.2, 0.1, -0.1);
const SPHERE_R: f32 = 0.5;
/// The opaque block.
const BLOCK_LO: Vec3 = Vec3::new(0.95, -1.3, -1.2);
const BLOCK_HI: Vec3 = Vec3::new(1.4, 0.5, -0.1);

fn medium(name: &str, sigma_s: Rgb, sigma_a: Rgb, density: Option<DensityGrid>) -> Medium {
    Medium {
        name: name.into(),
        sigma_s,
        sigma_a,
        g: 0.3,
        density,
    }
}

/// The opaque room (normals inwards) and block; the camera in a corner.
fn room() -> Scene {
    let mut s = Scene {
        source: "media test".into(),
        triangles: Vec::new(),
        meshes: Vec::new(),
        materials: vec![lambert("wall", 0.5)],
        textures: Vec::new(),
        media: Vec::new(),
        global_medium: None,
        lights: Vec::new(),
        camera: Camera {
            to_world: Mat4::from_translation(Vec3::new(-1.3, 1.2, 1.3)),
            yfov: 1.0,
            name: None,
        },
        render: RenderSettings { width: 8, height: 8 },
        warnings: Vec::new(),
    };
    add_mesh(
        &mut s,
        shapes::cuboid(Vec3::splat(-ROOM), Vec3::splat(ROOM), false),
        0,
        None,
    );
    add_mesh(&mut s, shapes::cuboid(BLOCK_LO, BLOCK_HI, true), 0, None);
    s
}

/// A lumpy density over `res` voxels: smooth waves cut off at zero (so some voxels are
/// exactly empty), and one corner block of voxels zeroed so that its majorant cell is empty.
fn lumpy(res: UVec3, phase: f32) -> Vec<f32> {
    let mut values = Vec::new();
    for z in 0..res.z {
        for y in 0..res.y {
            for x in 0..res.x {
                let c = UVec3::new(x, y, z).as_vec3() / res.as_vec3();
                let v = 1.3 * (7.1 * c.x + phase).sin() * (5.3 * c.y - 0.4).cos()
                    + 0.8 * (9.7 * c.z + 2.0 * c.x).sin()
                    + 0.45
                    + 0.2 * ((x * 7 + y * 13 + z * 5) % 11) as f32 / 11.0;
                // Majorant cell (0, *, last) reads voxels x ≤ 8 and z ≥ 8·(last) − 1.
                let empty_cell = x <= 9 && z + 10 >= res.z;
                values.push(if empty_cell { 0.0 } else { v.max(0.0) });
            }
        }
    }
    values
}

/// Scenes (a) and (b): a box region (medium 0, vacuum outside) holding a sphere region
/// (medium 1), both bounded by null interfaces; heterogeneous media with `grids`.
fn nested_regions(grids: bool) -> Scene {
    let mut s = room();
    s.materials.push(material("<medium boundary>", None, Rgb::ZERO, false));
    let boundary = s.materials.len() as u32 - 1;
    let (grid0, grid1) = if grids {
        let r0 = UVec3::new(21, 18, 27);
        let r1 = UVec3::new(13, 16, 9);
        // The sphere's grid covers only part of it: the rest of the sphere is empty.
        let (lo1, hi1) = (
            SPHERE_C - Vec3::new(0.3, 0.55, 0.6),
            SPHERE_C + Vec3::new(0.6, 0.2, 0.35),
        );
        (
            Some(DensityGrid::new(r0, BOX_LO, BOX_HI, lumpy(r0, 0.3))),
            Some(DensityGrid::new(r1, lo1, hi1, lumpy(r1, 1.7))),
        )
    } else {
        (None, None)
    };
    // Chromatic, with a channel that has no extinction at all (the 0·∞ rule's case). With
    // grids: denser, so that ratio tracking takes many steps, and with some extinction in
    // every channel, since a clear channel keeps the ratio at 1 and Russian roulette idle.
    let (k, green) = if grids { (4.0, 0.6) } else { (1.0, 0.0) };
    s.media.push(medium(
        "box",
        k * Rgb::new(0.8, green, 1.5),
        k * Rgb::new(0.2, 0.0, 0.1),
        grid0,
    ));
    s.media.push(medium(
        "sphere",
        k * Rgb::new(2.5, 1.2, 0.4),
        k * Rgb::new(0.3, 0.9, 0.2),
        grid1,
    ));
    add_mesh(
        &mut s,
        shapes::cuboid(BOX_LO, BOX_HI, true),
        boundary,
        Some(MediumInterface {
            inside: Some(0),
            outside: None,
        }),
    );
    add_mesh(
        &mut s,
        shapes::uv_sphere(SPHERE_C, SPHERE_R, 9, 14),
        boundary,
        Some(MediumInterface {
            inside: Some(1),
            outside: Some(0),
        }),
    );
    s
}

/// The density grid of scene (c)'s global medium: most of the room.
const GRID_C: (Vec3, Vec3) = (Vec3::new(-1.2, -1.4, -1.3), Vec3::new(1.3, 1.1, 0.9));

/// Scene (c): a global medium and opaque geometry only, so shadow rays take `occluded()`.
fn global_medium(grid: bool) -> Scene {
    let mut s = room();
    let density = grid.then(|| {
        let res = UVec3::new(30, 25, 26);
        DensityGrid::new(res, GRID_C.0, GRID_C.1, lumpy(res, 0.9))
    });
    let k = if grid { 3.0 } else { 1.0 };
    s.media.push(medium(
        "fog",
        k * Rgb::new(0.5, 0.9, 0.2),
        k * Rgb::new(0.1, 0.0, 0.3),
        density,
    ));
    s.global_medium = Some(0);
    s
}

// ---- queries ----

fn medium_code(m: MediumId) -> u32 {
    m.unwrap_or(NO_MEDIUM)
}

fn point_in_room(s: &mut Sampler) -> Vec3 {
    (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 2.0 - 1.0) * (ROOM - 0.02)
}

fn direction(s: &mut Sampler) -> Vec3 {
    let u = s.next_1d();
    let v = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5;
    // A fifth lie in a coordinate plane or along an axis: exact zero components exercise the
    // parallel-slab and never-crossed-axis paths of the DDA.
    let v = if u < 0.1 {
        Vec3::new(v.x, v.y, 0.0)
    } else if u < 0.15 {
        Vec3::new(0.0, v.y, v.z)
    } else if u < 0.2 {
        [Vec3::X, -Vec3::Y, Vec3::Z, -Vec3::X][(u * 80.0) as usize % 4]
    } else {
        v
    };
    v.normalize()
}

/// Random shadow rays between points of the room (starting in the medium the CPU finds
/// there), direct transmittance queries in every medium (and vacuum), and density samples.
fn queries(ts: &TraceScene, seed: u32, shadows: usize, segments: usize, densities: usize) -> Vec<MediaQuery> {
    let mut r = Sampler::new(seed, 999, 0);
    let media = ts.scene.media.len() as u32;
    let mut out = Vec::new();
    let mut push = |q: MediaQuery| {
        let index = out.len() as u32;
        out.push(MediaQuery {
            seed,
            pass_index: index % 7,
            index,
            ..q
        });
    };
    for _ in 0..shadows {
        let o = point_in_room(&mut r);
        let target = point_in_room(&mut r);
        push(MediaQuery {
            o: o.into(),
            medium: medium_code(ts.medium_at(o)),
            v: target.into(),
            kind: QUERY_SHADOW,
            ..Default::default()
        });
    }
    for k in 0..segments {
        let mut o = point_in_room(&mut r);
        let mut d = direction(&mut r);
        // Some segments run parallel to a density grid's face, in its plane (outside the grid,
        // on the CPU) or just inside it.
        if k % 25 == 0
            && let Some(g) = ts.scene.media.iter().find_map(|m| m.density.as_ref())
        {
            d = Vec3::new(d.x, d.y, 0.0).try_normalize().unwrap_or(Vec3::X);
            o.z = if k % 50 == 0 { g.lo.z } else { g.hi.z.next_down() };
        }
        let medium = if k % 10 == 9 { NO_MEDIUM } else { k as u32 % media };
        push(MediaQuery {
            o: o.into(),
            medium,
            v: d.into(),
            kind: QUERY_TRANSMITTANCE,
            tmax: 4.0 * r.next_1d(),
            ..Default::default()
        });
    }
    for k in 0..densities {
        let o = point_in_room(&mut r);
        push(MediaQuery {
            o: o.into(),
            medium: k as u32 % media,
            kind: QUERY_DENSITY,
            ..Default::default()
        });
    }
    out
}

/// The CPU's answer: rgb and the random numbers drawn.
fn cpu(ts: &TraceScene, q: &MediaQuery) -> [f32; 4] {
    let mut s = Sampler::new(q.seed, q.pass_index, q.index);
    let medium = (q.medium != NO_MEDIUM).then_some(q.medium);
    let (o, v) = (Vec3::from(q.o), Vec3::from(q.v));
    let r = match q.kind {
        QUERY_SHADOW => {
            let dist = (v - o).length();
            let ls = LightSample {
                p: v,
                n: None,
                wi: (v - o) / dist,
                dist,
                target: v,
                contribution: Rgb::ONE,
                pdf: 0.0,
            };
            ts.shadow_transmittance(o, &ls, medium, &mut s)
        }
        QUERY_TRANSMITTANCE => ts.medium_transmittance(medium, o, v, q.tmax, &mut s),
        _ => Rgb::splat(ts.scene.media[q.medium as usize].density_at(o)),
    };
    [r.x, r.y, r.z, s.dimension() as f32]
}

fn gpu_answers(gpu: &Gpu, scene: &GpuScene, queries: &[MediaQuery]) -> Vec<[f32; 4]> {
    let layout = compute::bind_group_layout(gpu, "media batch", &[Slot::Uniform, Slot::Read, Slot::ReadWrite]);
    let kernel = Kernel::new(gpu, "test/media_probe.wgsl", vec![scene.layout.clone(), layout]).unwrap();
    let (x, y, row) = compute::dispatch_size(gpu, queries.len() as u32);
    let batch = MediaBatch {
        count: queries.len() as u32,
        row,
        ..Default::default()
    };
    let params = compute::uniform(gpu, "media batch", &batch);
    let input = compute::storage(gpu, "media queries", queries).unwrap();
    let output = compute::output::<[f32; 4]>(gpu, "media results", queries.len()).unwrap();
    let group = compute::bind_group(gpu, "media batch", &kernel.layouts[1], &[&params, &input, &output]);
    kernel.dispatch(gpu, &[&scene.bind_group, &group], (x, y));
    compute::read_back(gpu, &output, queries.len()).unwrap()
}

/// The largest channel error, relative to max(|cpu|, 1e-4).
fn error(cpu: &[f32; 4], gpu: &[f32; 4]) -> f32 {
    (0..3)
        .map(|c| (cpu[c] - gpu[c]).abs() / cpu[c].abs().max(1e-4))
        .fold(0.0, f32::max)
}

/// Same draws and the same values to 1e-4; a NaN agrees only with a NaN in the same channel
/// (a broken grid reported alike). `error` alone would not see a NaN on one side: its fold
/// with `f32::max` drops NaN, so a NaN against 0 read as agreement before.
fn agrees(cpu: &[f32; 4], gpu: &[f32; 4]) -> bool {
    let nan_alike = (0..3).all(|c| cpu[c].is_nan() == gpu[c].is_nan());
    nan_alike && cpu[3] == gpu[3] && !(error(cpu, gpu) > 1e-4)
}

/// Whether the segment o → target passes through the box [lo, hi].
fn segment_meets_box(o: Vec3, target: Vec3, lo: Vec3, hi: Vec3) -> bool {
    let d = target - o;
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return false;
            }
        } else {
            let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
    }
    t0 <= t1
}

/// Compares every query (printing what was measured and the first differing cases) and fails
/// unless all agree. `region`: a box many shadow rays should cross unblocked.
fn compare(name: &str, gpu: &Gpu, scene: Scene, seed: u32, region: (Vec3, Vec3)) {
    let gpu_scene = GpuScene::upload(gpu, &scene).unwrap();
    let ts = TraceScene::new(scene);
    let qs = queries(&ts, seed, 12_000, 12_000, 4_000);
    let answers = gpu_answers(gpu, &gpu_scene, &qs);
    let (mut differ, mut blocked, mut crossing, mut drawn) = (Vec::new(), 0, 0, 0.0f64);
    let mut differ_by_kind = [0usize; 3];
    // Over the queries that agree: the worst error and how many are bit for bit the CPU's.
    let (mut worst, mut identical) = (0.0f32, 0);
    for (k, (q, g)) in qs.iter().zip(&answers).enumerate() {
        let c = cpu(&ts, q);
        drawn += c[3] as f64;
        if q.kind == QUERY_SHADOW {
            blocked += (c[..3] == [0.0; 3]) as usize;
            crossing += (c[..3] != [0.0; 3] && segment_meets_box(q.o.into(), q.v.into(), region.0, region.1)) as usize;
        }
        if agrees(&c, g) {
            worst = worst.max(error(&c, g));
            identical += (c.map(f32::to_bits) == g.map(f32::to_bits)) as usize;
        } else {
            differ_by_kind[q.kind as usize] += 1;
            differ.push(format!(
                "query {k} (kind {}, medium {}, o {:?}, v {:?}, tmax {}, pass {}): cpu {:?}, gpu {:?}",
                q.kind, q.medium as i32, q.o, q.v, q.tmax, q.pass_index, c, g
            ));
        }
    }
    let fraction = differ.len() as f64 / qs.len() as f64;
    eprintln!(
        "{name}: {} of {} queries differ ({:.4} %; shadow / transmittance / density: {:?}); {blocked} shadow rays \
         blocked, {crossing} unblocked through the region, {:.1} draws per query; of those agreeing, {identical} bit for bit, \
         worst relative error {worst:.2e}",
        differ.len(),
        qs.len(),
        100.0 * fraction,
        differ_by_kind,
        drawn / qs.len() as f64
    );
    // The queries must actually test something.
    let shadows = qs.iter().filter(|q| q.kind == QUERY_SHADOW).count();
    assert!(blocked > shadows / 50, "{name}: only {blocked} blocked shadow rays");
    assert!(
        crossing > shadows / 5,
        "{name}: only {crossing} shadow rays through the region"
    );
    assert!(
        differ.is_empty(),
        "{name}: {} queries differ:\n{}",
        differ.len(),
        differ[..differ.len().min(12)].join("\n")
    );
}

#[test]
fn probe_query_layout_matches_wgsl() {
    let source = shaders::compose("test/media_probe.wgsl").unwrap();
    let module = naga::front::wgsl::parse_str(&source).unwrap();
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    for (handle, ty) in module.types.iter() {
        let (Some(name), naga::TypeInner::Struct { members, .. }) = (&ty.name, &ty.inner) else {
            continue;
        };
        let offsets: Vec<u32> = members.iter().map(|m| m.offset).collect();
        let size = layouter[handle].size as usize;
        match name.as_str() {
            "MediaQuery" => {
                assert_eq!(size, size_of::<MediaQuery>());
                assert_eq!(offsets, [0, 12, 16, 28, 32, 36, 40, 44]);
                assert_eq!(std::mem::offset_of!(MediaQuery, kind), 28);
                assert_eq!(std::mem::offset_of!(MediaQuery, index), 44);
            }
            "MediaBatch" => assert_eq!(size, size_of::<MediaBatch>()),
            _ => {}
        }
    }
}

#[test]
fn homogeneous_regions_match_cpu() {
    let Some(gpu) = device::for_tests() else { return };
    compare("homogeneous regions", &gpu, nested_regions(false), 21, (BOX_LO, BOX_HI));
}

#[test]
fn heterogeneous_regions_match_cpu() {
    let Some(gpu) = device::for_tests() else { return };
    compare(
        "heterogeneous regions",
        &gpu,
        nested_regions(true),
        22,
        (BOX_LO, BOX_HI),
    );
}

#[test]
fn global_medium_without_null_interfaces_matches_cpu() {
    let Some(gpu) = device::for_tests() else { return };
    compare("global homogeneous medium", &gpu, global_medium(false), 23, GRID_C);
    compare("global heterogeneous medium", &gpu, global_medium(true), 24, GRID_C);
}

/// A grid whose majorants are too small (half the density): ratio tracking's factors go
/// negative, which both sides turn into a NaN transmittance for the gathers' counters
/// (`media::null_fraction`) in the same channels and after the same draws, rather than the
/// roulette ending the walk at 0 (an opaque wall nobody reports). The finite answers are held
/// to 1e-2 only: factors near 0 (no longer bounded away from it by a true majorant) amplify
/// the two sides' rounding (measured: 4 of 28 000 queries beyond 1e-4, the worst 2.3e-4).
#[test]
fn a_majorant_too_small_gives_nan_on_both_sides() {
    let Some(gpu) = device::for_tests() else { return };
    let mut scene = global_medium(true);
    let grid = scene.media[0].density.as_mut().expect("a grid");
    grid.majorants.iter_mut().for_each(|m| *m *= 0.5);
    let gpu_scene = GpuScene::upload(&gpu, &scene).unwrap();
    let ts = TraceScene::new(scene);
    let qs = queries(&ts, 26, 4000, 4000, 0);
    let answers = gpu_answers(&gpu, &gpu_scene, &qs);
    let mut nan = 0;
    for (k, (q, g)) in qs.iter().zip(&answers).enumerate() {
        let c = cpu(&ts, q);
        nan += c[..3].iter().any(|v| v.is_nan()) as usize;
        for ch in 0..3 {
            assert_eq!(
                c[ch].is_nan(),
                g[ch].is_nan(),
                "query {k}, channel {ch}: cpu {c:?}, gpu {g:?}"
            );
        }
        assert_eq!(c[3], g[3], "query {k}: draws differ: cpu {c:?}, gpu {g:?}");
        assert!(!(error(&c, g) > 1e-2), "query {k}: cpu {c:?}, gpu {g:?}");
    }
    assert!(
        nan > 400,
        "only {nan} of 8000 queries NaN: the grid is not broken enough to test this"
    );
}

/// A strongly chromatic grid (green 1000× thinner than red, blue within the ratio of red):
/// transmittance walks per group of channels (`media::extinction_groups`), in the same order
/// and with the same draws on the GPU.
#[test]
fn strongly_chromatic_grid_matches_cpu() {
    let Some(gpu) = device::for_tests() else { return };
    let mut scene = global_medium(true);
    scene.media[0].sigma_s = Rgb::new(8.0, 0.008, 3.0);
    scene.media[0].sigma_a = Rgb::new(1.0, 0.001, 0.0);
    assert_eq!(
        beamlight_trace::media::extinction_groups(scene.media[0].sigma_t()).count(),
        2
    );
    compare("global strongly chromatic medium", &gpu, scene, 25, GRID_C);
}
