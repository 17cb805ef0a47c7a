//! Scenes built in code for the integration tests, and small render helpers.
#![allow(dead_code)]
use beamlight_render::{Budget, Film, Method, RenderOptions, render};
use beamlight_scene::rng::Sampler;
use beamlight_scene::{Rgb, Scene, bsdf::Bsdf};
pub use beamlight_testkit::scenes::*;
use beamlight_trace::{
    TraceScene,
    components::Component,
    pt::{self, PathTracerSettings},
};
use glam::{DVec3, Vec2, Vec3};
use std::time::Instant;

/// Renders `passes` samples per pixel with the path tracer.
pub fn render_pt(scene: Scene, passes: u64, seed: u32, max_depth: Option<u32>) -> Film {
    let (width, height) = (scene.render.width, scene.render.height);
    let ts = TraceScene::new(scene);
    let opts = RenderOptions {
        method: Method::Pt,
        width,
        height,
        budget: Budget::Passes(passes),
        seed,
        first_pass: 0,
        path_tracer: PathTracerSettings {
            max_depth,
            ..Default::default()
        },
        start: Instant::now(),
        components: false,
        many_lights: Default::default(),
        gpu: None,
    };
    let r = render(&ts, &opts, |_| true).unwrap();
    assert_eq!(r.film.rejected, 0, "non-finite samples reached the film");
    r.film
}

/// Fraction of pixel channels where |a − b| is within `k` combined standard errors (plus a small
/// absolute slack for pixels with zero variance estimates).
pub fn z_agreement(a: &Film, b: &Film, k: f32) -> f32 {
    let (ia, ib) = (a.image(), b.image());
    let (va, vb) = (a.variance_of_mean(), b.variance_of_mean());
    let mut ok = 0;
    let n = ia.pixels.len() * 3;
    for i in 0..ia.pixels.len() {
        for c in 0..3 {
            let sd = (va.pixels[i][c] + vb.pixels[i][c]).sqrt();
            if (ia.pixels[i][c] - ib.pixels[i][c]).abs() <= k * sd + 1e-6 {
                ok += 1;
            }
        }
    }
    ok as f32 / n as f32
}

/// Checks every pixel channel of `film` against `expected(x, y)`: the difference must lie within
/// `k` standard errors of the pixel's mean (estimated from the film) plus `rel`·expected.
pub fn assert_pixels_match(film: &Film, k: f64, rel: f64, what: &str, expected: impl Fn(u32, u32) -> [f64; 3]) {
    let (img, var) = (film.image(), film.variance_of_mean());
    let mut worst = (0.0f64, 0, 0, 0);
    for y in 0..img.height {
        for x in 0..img.width {
            let e = expected(x, y);
            for c in 0..3 {
                let got = img.get(x, y)[c] as f64;
                let sd = (var.get(x, y)[c] as f64).sqrt();
                let z = (got - e[c]).abs() / (k * sd + rel * e[c].abs() + 1e-6);
                if z > worst.0 {
                    worst = (z, x, y, c);
                }
                assert!(
                    z <= 1.0,
                    "{what}: pixel ({x},{y}) channel {c}: {got} vs expected {} (σ of mean {sd})",
                    e[c]
                );
            }
        }
    }
    eprintln!(
        "{what}: worst pixel at {:.2} of the tolerance ({}, {}, ch {})",
        worst.0, worst.1, worst.2, worst.3
    );
}

/// Fraction of pixel channels within `k` standard errors of `expected(x, y)`.
pub fn fraction_within(film: &Film, k: f64, expected: impl Fn(u32, u32) -> [f64; 3]) -> f64 {
    let (img, var) = (film.image(), film.variance_of_mean());
    let mut ok = 0;
    for y in 0..img.height {
        for x in 0..img.width {
            let e = expected(x, y);
            for c in 0..3 {
                let sd = (var.get(x, y)[c] as f64).sqrt();
                ok += ((img.get(x, y)[c] as f64 - e[c]).abs() <= k * sd) as usize;
            }
        }
    }
    ok as f64 / (3 * img.pixels.len()) as f64
}

/// Closed box whose walls emit 1 and reflect with albedo 0.5, filled with a purely scattering
/// medium: radiance is 2 everywhere, whatever σs and g are.
pub fn furnace(sigma_s: Rgb, g: f32, grid: Option<beamlight_scene::medium::DensityGrid>) -> beamlight_scene::Scene {
    let s = empty_scene(Vec3::new(0.1, -0.2, 0.3), Vec3::new(0.5, 0.3, -1.0), 70.0, 12, 12);
    furnace_box(s, Vec3::splat(-1.0), Vec3::splat(1.0), sigma_s, g, grid)
}

/// [`furnace`]'s walls and medium as the box `lo`..`hi` around the camera of `s`.
pub fn furnace_box(
    mut s: beamlight_scene::Scene,
    lo: Vec3,
    hi: Vec3,
    sigma_s: Rgb,
    g: f32,
    grid: Option<beamlight_scene::medium::DensityGrid>,
) -> beamlight_scene::Scene {
    let wall = add_material(
        &mut s,
        material(
            "wall",
            Some(beamlight_scene::bsdf::Bsdf::Lambert {
                albedo: Rgb::splat(0.5),
            }),
            Rgb::ONE,
            false,
        ),
    );
    add_box_inward(&mut s, lo, hi, wall);
    let mut m = homogeneous(sigma_s, Rgb::ZERO, g);
    m.density = grid;
    s.media.push(m);
    s.global_medium = Some(0);
    s
}

/// The furnace with lossless specular objects: a glass sphere (ior 1.5) filled with a chromatic
/// scattering medium and, optionally, a perfect mirror cube.
pub fn glass_furnace(size: u32, sphere_segments: u32, mirror: bool) -> beamlight_scene::Scene {
    use beamlight_scene::{bsdf::Bsdf, scene::MediumInterface};
    use beamlight_testkit::gltf_writer::shapes;
    let mut s = furnace(Rgb::splat(0.4), 0.2, None);
    s.camera = empty_scene(Vec3::new(0.0, 0.0, 0.9), Vec3::new(0.1, -0.1, -1.0), 80.0, size, size).camera;
    s.render.width = size;
    s.render.height = size;
    let glass = add_material(&mut s, glass("glass", 1.5));
    s.media.push(homogeneous(Rgb::new(2.0, 1.0, 3.0), Rgb::ZERO, -0.3));
    let sphere = shapes::uv_sphere(Vec3::new(-0.3, 0.0, -0.3), 0.45, sphere_segments / 2, sphere_segments);
    add_mesh(
        &mut s,
        sphere,
        glass,
        Some(MediumInterface {
            inside: Some(1),
            outside: Some(0),
        }),
    );
    if mirror {
        let m = add_material(
            &mut s,
            material("mirror", Some(Bsdf::Mirror { reflectance: Rgb::ONE }), Rgb::ZERO, false),
        );
        add_mesh(
            &mut s,
            shapes::cuboid(Vec3::new(0.2, -0.6, -0.8), Vec3::new(0.7, -0.1, -0.3), true),
            m,
            None,
        );
    }
    s
}

/// A fog box of Lambert walls (albedo 0.6) lit by a ceiling quad, camera inside; with `lumpy`
/// the fog's density is a smooth lump (a density grid) instead of uniform.
pub fn fog_box(w: u32, h: u32, lumpy: bool) -> Scene {
    let mut s = empty_scene(Vec3::new(0.0, 0.0, 0.9), Vec3::new(0.2, -0.3, -1.0), 70.0, w, h);
    let wall = add_material(&mut s, lambert("wall", 0.6));
    add_box_inward(&mut s, Vec3::splat(-1.0), Vec3::splat(1.0), wall);
    let light = add_material(&mut s, emitter("light", 10.0));
    add_quad(
        &mut s,
        Vec3::new(-0.3, 0.99, -0.3),
        Vec3::new(0.6, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.6),
        light,
    );
    let mut m = homogeneous(Rgb::new(0.6, 0.4, 0.5), Rgb::splat(0.1), 0.3);
    if lumpy {
        // A smooth lump of density over the box (zero outside it), for delta/ratio tracking.
        let res = glam::UVec3::splat(12);
        let values = (0..res.x * res.y * res.z)
            .map(|i| {
                let c = glam::UVec3::new(i % 12, i / 12 % 12, i / 144).as_vec3() / 11.0 - 0.5;
                1.5 * (-4.0 * c.length_squared()).exp()
            })
            .collect();
        m.density = Some(beamlight_scene::medium::DensityGrid::new(
            res,
            Vec3::splat(-1.0),
            Vec3::splat(1.0),
            values,
        ));
    }
    s.media.push(m);
    s.global_medium = Some(0);
    s
}

/// The fog box with glossy walls (Phong exponent 80) and a strongly forward-scattering medium
/// (g = 0.7): the case the paper's VBLs are for.
pub fn glossy_fog_box(w: u32, h: u32) -> Scene {
    let mut scene = fog_box(w, h, false);
    for m in &mut scene.materials {
        if m.name == "wall" {
            m.bsdf = Some(Bsdf::Phong {
                diffuse: Rgb::splat(0.2),
                specular: Rgb::splat(0.6),
                exponent: 80.0,
            });
        }
    }
    scene.media[0].g = 0.7;
    scene
}

/// Image means of the path tracer's components over `spp` samples per pixel.
pub fn pt_components(ts: &TraceScene, spp: u32, seed: u32) -> [DVec3; 7] {
    pt_components_with_errors(ts, spp, seed).0
}

/// Image means of the path tracer's components over `spp` samples per pixel (a multiple of
/// 16), with their standard errors from the means of 16 batches of passes.
pub fn pt_components_with_errors(ts: &TraceScene, spp: u32, seed: u32) -> ([DVec3; 7], [DVec3; 7]) {
    pt_components_with_errors_using(ts, &PathTracerSettings::default(), spp, seed)
}

/// [`pt_components_with_errors`] with the path tracer's `settings` (e.g. restricted to some
/// components).
pub fn pt_components_with_errors_using(
    ts: &TraceScene,
    settings: &PathTracerSettings,
    spp: u32,
    seed: u32,
) -> ([DVec3; 7], [DVec3; 7]) {
    assert!(spp.is_multiple_of(16), "spp must split into 16 batches");
    let mut batches = BatchMeans::default();
    let mut sum = [DVec3::ZERO; 7];
    for batch in 0..16 {
        let mut part = [DVec3::ZERO; 7];
        pt_component_sums(ts, settings, batch * spp / 16..(batch + 1) * spp / 16, seed, &mut part);
        for (s, p) in sum.iter_mut().zip(&part) {
            *s += *p;
        }
        let (w, h) = (ts.scene.render.width, ts.scene.render.height);
        batches.push(&part.map(|v| v / ((spp / 16) as f64 * (w * h) as f64)));
    }
    let (w, h) = (ts.scene.render.width, ts.scene.render.height);
    (
        sum.map(|v| v / (spp as f64 * (w * h) as f64)),
        per_component(batches.standard_errors()),
    )
}

/// Means of independent batches (of passes, or of seeds), per slot (a component, a tile), and
/// the standard error of their overall mean (the batch means' standard deviation over
/// √batches), per channel, so that a tolerance can scale with the noise actually present.
/// Every batch has the same slots.
#[derive(Default)]
pub struct BatchMeans {
    batches: Vec<Vec<DVec3>>,
}

impl BatchMeans {
    pub fn push(&mut self, means: &[DVec3]) {
        self.batches.push(means.to_vec());
    }

    /// Records a render's progress: call with the cumulative means after `passes` passes at
    /// every batch boundary, `last` starting empty; the batch's own means are recovered from
    /// the running sums (cumulative mean × passes).
    pub fn push_cumulative(&mut self, cumulative: &[DVec3], passes: u64, last: &mut (Vec<DVec3>, u64)) {
        let n = (passes - last.1) as f64;
        let earlier = |c: usize| last.0.get(c).map_or(DVec3::ZERO, |m| *m * last.1 as f64);
        let means: Vec<DVec3> = (0..cumulative.len())
            .map(|c| (cumulative[c] * passes as f64 - earlier(c)) / n)
            .collect();
        self.push(&means);
        *last = (cumulative.to_vec(), passes);
    }

    /// The overall mean, per slot (the mean of the batch means: batches of equal size).
    pub fn means(&self) -> Vec<DVec3> {
        let k = self.batches.len() as f64;
        (0..self.slots())
            .map(|c| self.batches.iter().map(|b| b[c]).sum::<DVec3>() / k)
            .collect()
    }

    pub fn standard_errors(&self) -> Vec<DVec3> {
        let k = self.batches.len() as f64;
        assert!(k >= 2.0, "need at least two batches");
        let means = self.means();
        (0..self.slots())
            .map(|c| {
                let var = self
                    .batches
                    .iter()
                    .map(|b| (b[c] - means[c]) * (b[c] - means[c]))
                    .sum::<DVec3>()
                    / (k - 1.0);
                (var / k).map(f64::sqrt)
            })
            .collect()
    }

    fn slots(&self) -> usize {
        self.batches.first().map_or(0, Vec::len)
    }
}

/// Per-component values (`BatchMeans` of the seven components) as the fixed array the
/// component checks take.
pub fn per_component(v: Vec<DVec3>) -> [DVec3; 7] {
    v.try_into().expect("one value per component")
}

/// A render's image means with standard errors from batch means over `batches` equal batches
/// of its passes (a pass budget divisible by `batches`): per component (when
/// `RenderOptions::components`) and for the whole image.
pub struct MeansWithErrors {
    pub result: beamlight_render::RenderResult,
    pub components: [DVec3; 7],
    pub component_errors: [DVec3; 7],
    pub image: DVec3,
    pub image_error: DVec3,
    /// The standard error of each [`TILE`]² tile's mean (row-major, as `Image::downsample`),
    /// from the same batches.
    pub tile_errors: Vec<DVec3>,
}

/// Side of the tiles whose means [`MeansWithErrors::tile_errors`] gives errors for.
pub const TILE: u32 = 4;

pub fn render_with_errors(ts: &TraceScene, opts: &RenderOptions, batches: u64) -> MeansWithErrors {
    let Budget::Passes(passes) = opts.budget else {
        panic!("batch means need a pass budget")
    };
    assert!(
        passes % batches == 0,
        "{passes} passes do not split into {batches} batches"
    );
    let batch = passes / batches;
    // Slot 0..7: the components; the image is tracked apart in the same way.
    let (mut parts, mut last_parts) = (BatchMeans::default(), (Vec::new(), 0u64));
    let (mut whole, mut last_whole) = (BatchMeans::default(), (Vec::new(), 0u64));
    let (mut tiles, mut last_tiles) = (BatchMeans::default(), (Vec::new(), 0u64));
    let result = render(ts, opts, |progress| {
        if progress.passes % batch == 0 {
            let means: [DVec3; 7] = std::array::from_fn(|c| {
                progress
                    .components
                    .get(c)
                    .map_or(DVec3::ZERO, |f| f.image().mean().as_dvec3())
            });
            parts.push_cumulative(&means, progress.passes, &mut last_parts);
            let image = progress.film.image();
            whole.push_cumulative(&[image.mean().as_dvec3()], progress.passes, &mut last_whole);
            let now: Vec<DVec3> = image.downsample(TILE).pixels.iter().map(|p| p.as_dvec3()).collect();
            tiles.push_cumulative(&now, progress.passes, &mut last_tiles);
        }
        true
    })
    .unwrap();
    let components = std::array::from_fn(|c| {
        result
            .components
            .get(c)
            .map_or(DVec3::ZERO, |f| f.image().mean().as_dvec3())
    });
    let image = result.film.image().mean().as_dvec3();
    MeansWithErrors {
        result,
        components,
        component_errors: per_component(parts.standard_errors()),
        image,
        image_error: whole.standard_errors()[0],
        tile_errors: tiles.standard_errors(),
    }
}

fn pt_component_sums(
    ts: &TraceScene,
    settings: &PathTracerSettings,
    passes: std::ops::Range<u32>,
    seed: u32,
    sum: &mut [DVec3; 7],
) {
    let (w, h) = (ts.scene.render.width, ts.scene.render.height);
    for pass in passes {
        for y in 0..h {
            for x in 0..w {
                let mut s = Sampler::new(seed, pass, y * w + x);
                let j = s.next_2d();
                let film = Vec2::new((x as f32 + j.x) / w as f32, (y as f32 + j.y) / h as f32);
                let d = ts.scene.camera.direction(film, w as f32 / h as f32);
                pt::radiance_split(
                    ts,
                    settings,
                    ts.scene.camera.position(),
                    d,
                    ts.camera_medium,
                    &mut s,
                    &mut |c, l| sum[c as usize] += l.as_dvec3(),
                );
            }
        }
    }
}

/// Compares per-component image means with the path tracer's, each with its standard error:
/// the worst channel's difference must be within `k` combined standard errors. What this can
/// catch is a bias larger than k standard errors (printed); what it cannot is one below that.
pub fn assert_components_within_errors(
    label: &str,
    (ours, ours_se): (&[DVec3; 7], &[DVec3; 7]),
    (reference, reference_se): (&[DVec3; 7], &[DVec3; 7]),
    components: &[Component],
    k: f64,
) {
    let mut failed = Vec::new();
    for &c in components {
        let i = c as usize;
        let (a, b) = (ours[i], reference[i]);
        let se = (ours_se[i] * ours_se[i] + reference_se[i] * reference_se[i]).map(f64::sqrt);
        let z = ((a - b) / se).abs().max_element();
        eprintln!(
            "{:>15}: {label} {a:.5} ± {:.5}, path tracer {b:.5} ± {:.5}: relative {:+.4}, z {z:.2}",
            c.name(),
            ours_se[i].max_element(),
            reference_se[i].max_element(),
            ((a - b) / b).x,
        );
        assert!(b.min_element() > 0.0, "{}: the scene must have some", c.name());
        if !(z < k) {
            failed.push(c.name());
        }
    }
    assert!(failed.is_empty(), "{label}: {failed:?} beyond {k} standard errors");
}

/// Compares per-component image means with the path tracer's (`Component::ALL` order): prints
/// each of `components`, and asserts that the reference has some of it and that the worst
/// channel's relative difference is below `tolerance(c)`.
pub fn assert_components_match(
    label: &str,
    ours: &[DVec3],
    reference: &[DVec3; 7],
    components: &[Component],
    tolerance: impl Fn(Component) -> f64,
) {
    for &c in components {
        let (a, b) = (ours[c as usize], reference[c as usize]);
        let rel = ((a - b) / b).abs().max_element();
        eprintln!(
            "{:>15}: {label} {a:.5}, path tracer {b:.5}, relative difference {rel:.4}",
            c.name()
        );
        assert!(b.min_element() > 0.0, "{}: the scene must have some", c.name());
        assert!(rel < tolerance(c), "{}: {label} {a} vs path tracer {b}", c.name());
    }
}

/// Writes a small scene with every transport component to `dir` (`glass.gltf` and
/// `glass.toml`, returned): a glass ball (IOR 1.5) above a Lambert floor under a point lamp, in
/// a global fog, with a back wall, so the caustics (through the ball onto the floor, and into the fog) have light
/// as well as direct light and the four virtual-light gathers.
pub fn write_glass_ball_scene(dir: &std::path::Path) -> std::path::PathBuf {
    use beamlight_testkit::gltf_writer::{GltfBuilder, MaterialDesc, shapes};
    let mut b = GltfBuilder::new();
    let glass = b.material(MaterialDesc::glass("Glass", 1.5));
    let (p, i) = shapes::uv_sphere(Vec3::ZERO, 0.5, 8, 16);
    b.mesh("Ball", &p, &i, None, Some(glass));
    let floor = b.material(MaterialDesc::lambert("Floor", [0.7; 3]));
    let (p, i) = shapes::quad(
        Vec3::new(-2.0, -0.6, 2.0),
        Vec3::new(4.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -4.0),
    );
    b.mesh("Floor", &p, &i, None, Some(floor));
    // A back wall, lit by light bounced off the floor (which a flat floor cannot give itself).
    let (p, i) = shapes::quad(
        Vec3::new(-2.0, -0.6, -1.5),
        Vec3::new(4.0, 0.0, 0.0),
        Vec3::new(0.0, 3.0, 0.0),
    );
    b.mesh("Wall", &p, &i, None, Some(floor));
    b.point_light("Lamp", Vec3::new(0.0, 2.0, 0.0), [1.0; 3], 10.0);
    b.camera_look_at("Camera", Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 0.8, None);
    b.write_gltf(&dir.join("glass.gltf")).unwrap();
    let toml = dir.join("glass.toml");
    std::fs::write(
        &toml,
        "gltf = \"glass.gltf\"\n[[media]]\nname = \"fog\"\nregion = \"global\"\nsigma_s = 0.2\nsigma_a = 0.01\n",
    )
    .unwrap();
    toml
}
