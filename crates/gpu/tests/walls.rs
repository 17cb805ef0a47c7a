//! `walls_around` in `shaders/lib/walls.wgsl` against the CPU's `vbl::Walls::around`, query by
//! query, through the test kernel `shaders/test/walls_probe.wgsl`: the walls a VBL point finds
//! cut its blur, so a twin that found other walls would change `Lmm` and `Lsm` on the GPU.
//!
//! The scene: a room with an opaque block, a tessellated ball (oblique hits, planes rejected by
//! the head-on test), a lamp's plate under the ceiling (looked past) and an invisible medium
//! boundary (passed over). The room's normals face out (but for one triangle) and the plate's
//! two triangles are wound against each other, so that open edges are judged from the side a
//! probe comes from (the room's walls from their back, the block's faces from their front) and
//! through a patch's flipped triangle. Centres are drawn over
//! the room, half of them within 0.05 of a surface of the block, where several walls meet.
//! Every query must find the same number of walls with the same normals (to 1e-5) and points
//! (to 1e-4 of the room); the probes' hit distances may differ by rounding, the tests on them
//! (head-on, within 2R, the same wall twice) only at their thresholds, which these random
//! queries do not meet.
use beamlight_gpu::{
    Gpu, GpuScene,
    compute::{self, Kernel, Slot},
    device,
    layout::{self, Walls},
};
use beamlight_scene::{Rgb, Scene, rng::Sampler, scene::MediumInterface};
use beamlight_testkit::{
    gltf_writer::shapes,
    scenes::{add_material, add_mesh, emitter, empty_scene, homogeneous, lambert, material},
};
use beamlight_trace::{TraceScene, vbl};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;

/// `WallsQuery` in `shaders/test/walls_probe.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct WallsQuery {
    centre: [f32; 3],
    r: f32,
}

/// `WallsBatch` in `shaders/test/walls_probe.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct WallsBatch {
    count: u32,
    row: u32,
    _pad: [u32; 2],
}

const BLOCK_LO: Vec3 = Vec3::new(-0.5, -1.0, -0.6);
const BLOCK_HI: Vec3 = Vec3::new(0.1, -0.4, 0.0);

fn scene() -> Scene {
    let mut s = empty_scene(Vec3::new(0.0, 0.0, 0.9), Vec3::new(0.0, 0.0, -1.0), 60.0, 8, 8);
    let wall = add_material(&mut s, lambert("wall", 0.5));
    // The room wound inside out, with one triangle of its x = −1 wall (a patch of two) wound
    // back: that patch's open edges are judged through its flipped triangle.
    let (p, mut idx) = shapes::cuboid(Vec3::splat(-1.0), Vec3::splat(1.0), true);
    idx.swap(1, 2);
    add_mesh(&mut s, (p, idx), wall, None);
    add_mesh(&mut s, shapes::cuboid(BLOCK_LO, BLOCK_HI, true), wall, None);
    let light = add_material(&mut s, emitter("light", 10.0));
    let (p, mut idx) = shapes::quad(
        Vec3::new(-0.3, 0.99, -0.3),
        Vec3::new(0.0, 0.0, 0.6),
        Vec3::new(0.6, 0.0, 0.0),
    );
    idx.swap(4, 5);
    add_mesh(&mut s, (p, idx), light, None);
    add_mesh(
        &mut s,
        shapes::uv_sphere(Vec3::new(0.5, 0.3, -0.2), 0.3, 12, 24),
        wall,
        None,
    );
    // A medium region behind an invisible boundary, which the probes pass over.
    let boundary = add_material(&mut s, material("boundary", None, Rgb::ZERO, false));
    s.media.push(homogeneous(Rgb::splat(0.5), Rgb::ZERO, 0.0));
    add_mesh(
        &mut s,
        shapes::cuboid(Vec3::new(-0.9, 0.2, -0.9), Vec3::new(-0.2, 0.9, -0.1), true),
        boundary,
        Some(MediumInterface {
            inside: Some(0),
            outside: None,
        }),
    );
    s
}

fn queries(n: u32) -> Vec<WallsQuery> {
    let mut s = Sampler::new(5, 0, 0);
    (0..n)
        .map(|i| {
            let u = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d());
            let centre = if i % 2 == 0 {
                Vec3::splat(-0.98) + u * 1.96
            } else {
                // Next to the block: a point of its box pushed out to within 0.05 of a face.
                let p = BLOCK_LO + u * (BLOCK_HI - BLOCK_LO);
                let axis = (s.next_1d() * 3.0) as usize % 3;
                let mut q = p;
                q[axis] = if s.next_1d() < 0.5 {
                    BLOCK_LO[axis]
                } else {
                    BLOCK_HI[axis]
                } + (s.next_1d() - 0.5) * 0.1;
                q
            };
            WallsQuery {
                centre: centre.into(),
                r: 0.05 + 0.45 * s.next_1d(),
            }
        })
        // Only in the room's free space, where photons are: the block's bottom lies on the
        // floor, and a probe from inside the block or from under the floor meets the two
        // coincident faces at the same distance, the two traversals either one (the floor's
        // plane goes on past the block's edges, the block's bottom does not).
        .filter(|q| {
            let c = Vec3::from(q.centre);
            let in_block = c.cmpgt(BLOCK_LO).all() && c.cmplt(BLOCK_HI).all();
            c.abs().max_element() < 1.0 && !in_block
        })
        .collect()
}

fn gpu_answers(gpu: &Gpu, scene: &GpuScene, queries: &[WallsQuery]) -> Vec<Walls> {
    let layout = compute::bind_group_layout(gpu, "walls batch", &[Slot::Uniform, Slot::Read, Slot::ReadWrite]);
    let kernel = Kernel::new(gpu, "test/walls_probe.wgsl", vec![scene.layout.clone(), layout]).unwrap();
    let (x, y, row) = compute::dispatch_size(gpu, queries.len() as u32);
    let batch = WallsBatch {
        count: queries.len() as u32,
        row,
        ..Default::default()
    };
    let params = compute::uniform(gpu, "walls batch", &batch);
    let input = compute::storage(gpu, "walls queries", queries).unwrap();
    let output = compute::output::<Walls>(gpu, "walls results", queries.len()).unwrap();
    let group = compute::bind_group(gpu, "walls batch", &kernel.layouts[1], &[&params, &input, &output]);
    kernel.dispatch(gpu, &[&scene.bind_group, &group], (x, y));
    compute::read_back(gpu, &output, queries.len()).unwrap()
}

#[test]
fn gpu_probes_find_the_cpus_walls() {
    let Some(gpu) = device::for_tests() else {
        return;
    };
    let scene = scene();
    let gpu_scene = GpuScene::upload(&gpu, &scene).unwrap();
    let ts = TraceScene::new(scene);
    let qs = queries(20_000);
    let answers = gpu_answers(&gpu, &gpu_scene, &qs);
    let (mut differ, mut counts) = (Vec::new(), [0usize; 7]);
    for (q, g) in qs.iter().zip(&answers) {
        let centre = Vec3::from(q.centre);
        let c = layout::Walls::from(&vbl::Walls::around(&ts, centre, centre, q.r, None));
        counts[c.count as usize] += 1;
        let same = c.count == g.count
            && (0..c.count as usize).all(|i| {
                let (a, b) = (c.planes[i], g.planes[i]);
                Vec3::from(a.normal).distance(b.normal.into()) <= 1e-5
                    && Vec3::from(a.point).distance(b.point.into()) <= 1e-4
            });
        if !same {
            differ.push((q, c, *g));
        }
    }
    eprintln!(
        "{} queries: walls found 0..6: {counts:?}; {} differ",
        qs.len(),
        differ.len()
    );
    for (q, c, g) in differ.iter().take(5) {
        eprintln!("  centre {:?} r {}: CPU {c:?}\n    GPU {g:?}", q.centre, q.r);
    }
    // The check must see walls, and several at once, to be able to fail.
    assert!(
        counts[2..].iter().sum::<usize>() > 1000,
        "too few queries near walls: {counts:?}"
    );
    assert!(differ.is_empty(), "{} of {} queries differ", differ.len(), qs.len());
}
