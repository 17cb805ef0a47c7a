//! The showcase scenes: analogues of the paper's BUDDHA, CARS and SMOKYROOM (§5, Figs. 1, 7,
//! 9, 10), whose assets are not public. Each keeps the difficulty the paper shows with it:
//!
//! * `buddha`: a glossy statue (modified Phong, exponent 80) in a room of dense, strongly
//!   forward-scattering fog (HG g = 0.7), lit by a small bulb in a corner, so that much of the
//!   light reaching the statue is indirect. The statue is the Stanford bunny scan
//!   (`assets/sources/bunny.json`, from the npm package `bunny`).
//! * `cars`: two glossy car bodies (Phong exponents 100 and 60), 2.2 M triangles together, in a
//!   homogeneous fog with g = 0.25, lit only by lamps whose bulbs sit inside glass globes: all
//!   direct light is caustic. The mesh is ~54 MB, so it is generated, not committed.
//! * `smokyroom`: a room of isotropic smoke whose density is fractal Perlin noise thinning with
//!   height, lit through a window-like panel and by a ceiling lamp.
use beamlight_testkit::gltf_writer::{GltfBuilder, IndexWidth, MaterialDesc, NodeDesc, shapes};
use glam::{Quat, Vec3};

/// The committed showcase files (scene sidecars and the small meshes).
pub fn files() -> Vec<(String, Vec<u8>)> {
    vec![
        ("assets/scenes/buddha.glb".into(), buddha_glb()),
        ("assets/scenes/buddha.toml".into(), BUDDHA_TOML.as_bytes().to_vec()),
        (
            "assets/scenes/cars.toml".into(),
            cars_toml(CARS_HEAD, "cars.glb", (1280, 720)).into_bytes(),
        ),
        ("assets/scenes/smokyroom.glb".into(), smokyroom_glb()),
        (
            "assets/scenes/smokyroom.toml".into(),
            SMOKYROOM_TOML.as_bytes().to_vec(),
        ),
    ]
}

/// Generated files too large to commit (git-ignored); `cargo xtask assets` writes them and
/// `cargo xtask ci` makes sure they exist before the tests run.
pub fn large_files() -> Vec<(String, Vec<u8>)> {
    vec![("assets/scenes/cars.glb".into(), cars_glb(CAR_SEGMENTS, CAR_RINGS))]
}

/// Area-weighted vertex normals of an indexed triangle mesh (outward for outward winding).
fn vertex_normals(p: &[Vec3], idx: &[u32]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; p.len()];
    for t in idx.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
        // The cross product's length is twice the area: the weighting is built in.
        let face = (p[b] - p[a]).cross(p[c] - p[a]);
        n[a] += face;
        n[b] += face;
        n[c] += face;
    }
    n.into_iter().map(|v| v.try_normalize().unwrap_or(Vec3::Y)).collect()
}

/// An indexed triangle mesh: positions and triangle indices.
type Mesh = (Vec<Vec3>, Vec<u32>);

/// A box room `[lo, hi]` closed on all six sides, normals pointing in, one quad per wall so
/// each can take its own material: (name, mesh) per wall.
pub(crate) fn room_walls(lo: Vec3, hi: Vec3) -> Vec<(&'static str, Mesh)> {
    let d = hi - lo;
    vec![
        (
            "Floor",
            shapes::quad(Vec3::new(lo.x, lo.y, hi.z), Vec3::X * d.x, Vec3::NEG_Z * d.z),
        ),
        (
            "Ceiling",
            shapes::quad(Vec3::new(lo.x, hi.y, lo.z), Vec3::X * d.x, Vec3::Z * d.z),
        ),
        ("BackWall", shapes::quad(lo, Vec3::X * d.x, Vec3::Y * d.y)),
        (
            "FrontWall",
            shapes::quad(Vec3::new(hi.x, lo.y, hi.z), Vec3::NEG_X * d.x, Vec3::Y * d.y),
        ),
        (
            "LeftWall",
            shapes::quad(Vec3::new(lo.x, lo.y, hi.z), Vec3::NEG_Z * d.z, Vec3::Y * d.y),
        ),
        (
            "RightWall",
            shapes::quad(Vec3::new(hi.x, lo.y, lo.z), Vec3::Z * d.z, Vec3::Y * d.y),
        ),
    ]
}

// ---------------------------------------------------------------------------------------------
// buddha

/// The bunny scan as stored in `assets/sources/bunny.json`: y up, about 9.7 units tall.
fn bunny() -> Mesh {
    let text = include_str!("../../assets/sources/bunny.json");
    let json: serde_json::Value = serde_json::from_str(text).expect("bunny.json is JSON");
    let positions = json["positions"]
        .as_array()
        .expect("positions")
        .iter()
        .map(|p| {
            let c = |i: usize| p[i].as_f64().expect("a number") as f32;
            Vec3::new(c(0), c(1), c(2))
        })
        .collect();
    let cells = json["cells"]
        .as_array()
        .expect("cells")
        .iter()
        .flat_map(|t| (0..3).map(move |i| t[i].as_u64().expect("an index") as u32))
        .collect();
    (positions, cells)
}

/// Room x ∈ [−2, 2], y ∈ [0, 3], z ∈ [−2, 3] with an orange left wall, a pedestal in the
/// middle, the bunny on it, and a bulb (a sphere of radius 0.06) in the back right corner, out
/// of view.
fn buddha_glb() -> Vec<u8> {
    let mut b = GltfBuilder::new();
    let white = b.material(MaterialDesc::lambert("White", [0.7, 0.7, 0.7]));
    let orange = b.material(MaterialDesc::lambert("Orange", [0.8, 0.32, 0.06]));
    let stone = b.material(MaterialDesc::lambert("Pedestal", [0.45, 0.45, 0.5]));
    let statue_mat = b.material(MaterialDesc::lambert("Statue", [0.6, 0.5, 0.3]));
    for (name, (p, i)) in room_walls(Vec3::new(-2.0, 0.0, -2.0), Vec3::new(2.0, 3.0, 3.0)) {
        let mat = if name == "LeftWall" { orange } else { white };
        b.mesh(name, &p, &i, None, Some(mat));
    }
    let (p, i) = shapes::cuboid(Vec3::new(-0.45, 0.0, -0.95), Vec3::new(0.45, 0.5, -0.05), true);
    b.mesh("Pedestal", &p, &i, None, Some(stone));

    // The scan is 9.7 tall with its base at y ≈ 0: scale it to 1.1 and stand it on the
    // pedestal, turned 30° towards the lit wall.
    let (p, i) = bunny();
    let n = vertex_normals(&p, &i);
    let statue = b.add_mesh("Statue", &p, &i, Some(&n), Some(statue_mat));
    b.node(
        NodeDesc::new("Statue")
            .with_mesh(statue)
            .with_translation(Vec3::new(0.0, 0.5, -0.5))
            .with_rotation(Quat::from_rotation_y(-30f32.to_radians()))
            .with_scale(Vec3::splat(1.1 / 9.66)),
    );
    // The light: a bulb in the back right corner, an emissive sphere of radius 6 cm (not a
    // point: a point light in dense fog gives next-event estimation infinite variance, so no
    // path-traced reference would converge). Radiance 700 makes its power about that of the
    // spot light it replaces (4π²r²L ≈ 100 W). It used to sit in an open box that aimed a cone
    // at the wall; at the default radius the virtual lights' blur, wider than that box, let
    // about 8 % more light out than the path tracer finds (at 24², 256 passes), so the bulb is
    // bare.
    let bulb = b.material(MaterialDesc::emitter("Bulb", [700.0, 665.0, 595.0]));
    let (bulb_p, bulb_i) = shapes::uv_sphere(Vec3::new(1.55, 2.6, -1.45), 0.06, 8, 16);
    b.mesh("Bulb", &bulb_p, &bulb_i, None, Some(bulb));
    b.camera_look_at(
        "Camera",
        Vec3::new(0.3, 1.3, 2.7),
        Vec3::new(-0.05, 0.85, -0.5),
        Vec3::Y,
        40f32.to_radians(),
        Some(1.0),
    );
    b.to_glb_bytes()
}

const BUDDHA_TOML: &str = r#"# Analogue of the paper's BUDDHA scene (Fig. 7): a glossy statue (modified Phong, exponent 80;
# the Stanford bunny scan) on a pedestal in a room filled with dense, strongly forward-scattering
# fog (HG g = 0.7, optical thickness 1.1 across the 5-unit room), lit by a bulb of 6 cm radius
# in the back right corner, out of view: much of the light on the statue is indirect, from the
# walls and the fog.
# Generated by `cargo xtask assets`; see assets/README.md.
gltf = "buddha.glb"

[render]
width = 720
height = 720
camera = "Camera"

[[media]]
name = "fog"
region = "global"
sigma_s = [0.2, 0.2, 0.2]
sigma_a = [0.02, 0.02, 0.02]
g = 0.7

[materials.Statue]
kind = "phong"
diffuse = [0.12, 0.09, 0.05]
specular = [0.6, 0.5, 0.3]
exponent = 80
"#;

// ---------------------------------------------------------------------------------------------
// cars

/// Tessellation of one car body (longitude segments × latitude rings): 2 × 1000 × 560 ≈ 1.12 M
/// triangles per body, so the scene has 2.26 M triangles and 1.14 M vertices (the paper's CARS:
/// 2.2 M and 1.2 M).
const CAR_SEGMENTS: u32 = 1000;
const CAR_RINGS: u32 = 561;

/// `sign(x)·|x|^e`: the superellipse's rounded-box profile.
fn signed_pow(x: f32, e: f32) -> f32 {
    x.signum() * x.abs().powf(e)
}

/// A car-like body: a rounded box (superellipsoid) 4.2 long, 1.8 wide, with a cabin bulging
/// from its top and fine ripples over the paint, standing with its bottom at y = 0.3.
/// Made by displacing a UV sphere, so it is closed with outward normals.
fn car_body(segments: u32, rings: u32) -> Mesh {
    let (sphere, idx) = shapes::uv_sphere(Vec3::ZERO, 1.0, rings, segments);
    let (half_len, half_height, half_width) = (2.1, 0.35, 0.9);
    let e = 0.35;
    let p = sphere
        .into_iter()
        .map(|s| {
            let horizontal = (s.x * s.x + s.z * s.z).sqrt();
            let (cu, su) = if horizontal > 0.0 {
                (s.x / horizontal, s.z / horizontal)
            } else {
                (1.0, 0.0)
            };
            let r = signed_pow(horizontal, e);
            let mut x = half_len * r * signed_pow(cu, e);
            let mut y = half_height * signed_pow(s.y, e);
            let mut z = half_width * r * signed_pow(su, e);
            // Cabin: the upper surface rises over the middle of the car, slightly towards the
            // back, and narrows as it rises.
            if y > 0.0 {
                let t = ((x + 0.25) / 1.3).clamp(-1.0, 1.0);
                let bump = (1.0 - t * t).max(0.0).powf(0.7);
                let upper = y / half_height;
                y += 0.5 * bump * upper.powf(0.5);
                z *= 1.0 - 0.22 * bump * upper;
            }
            // Fine ripples: a gentle orange-peel on the paint, which the fine tessellation carries.
            let ripple = 0.003 * (37.0 * x).sin() * (41.0 * z + 13.0 * y).sin();
            let n = Vec3::new(x / half_len, y / half_height, z / half_width).normalize_or_zero();
            x += ripple * n.x;
            z += ripple * n.z;
            y += ripple * n.y;
            Vec3::new(x, y + half_height + 0.3, z)
        })
        .collect();
    (p, idx)
}

/// A wheel: a torus around the z axis through `center`.
fn wheel(center: Vec3, radius: f32, tube: f32) -> Mesh {
    let (m, n) = (48u32, 16u32);
    let mut p = Vec::with_capacity((m * n) as usize);
    for i in 0..m {
        let a = std::f32::consts::TAU * i as f32 / m as f32;
        for j in 0..n {
            let b = std::f32::consts::TAU * j as f32 / n as f32;
            let ring = radius + tube * b.cos();
            p.push(center + Vec3::new(ring * a.cos(), ring * a.sin(), tube * b.sin()));
        }
    }
    let at = |i: u32, j: u32| (i % m) * n + j % n;
    let mut idx = Vec::with_capacity((6 * m * n) as usize);
    for i in 0..m {
        for j in 0..n {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            idx.extend_from_slice(&[a, b, c, a, c, d]);
        }
    }
    (p, idx)
}

/// Room x ∈ [−6, 6], y ∈ [0, 4], z ∈ [−6, 6]; two cars; three lamps, each a bulb inside a
/// solid glass globe on a post.
pub(crate) fn cars_glb(segments: u32, rings: u32) -> Vec<u8> {
    let mut b = GltfBuilder::new();
    b.index_width(IndexWidth::U32);
    let floor = b.material(MaterialDesc::lambert("Floor", [0.35, 0.35, 0.35]));
    let wall = b.material(MaterialDesc::lambert("Wall", [0.5, 0.5, 0.5]));
    let red = b.material(MaterialDesc::lambert("RedCar", [0.5, 0.05, 0.04]));
    let blue = b.material(MaterialDesc::lambert("BlueCar", [0.05, 0.12, 0.45]));
    let tyre = b.material(MaterialDesc::lambert("Tyre", [0.04, 0.04, 0.04]));
    let metal = b.material(MaterialDesc::lambert("Post", [0.3, 0.3, 0.3]));
    let glass = b.material(MaterialDesc::glass("Globe", 1.5));
    let bulb = b.material(MaterialDesc::emitter("Bulb", [400.0, 330.0, 240.0]));
    for (name, (p, i)) in room_walls(Vec3::new(-6.0, 0.0, -6.0), Vec3::new(6.0, 4.0, 6.0)) {
        b.mesh(name, &p, &i, None, Some(if name == "Floor" { floor } else { wall }));
    }

    let body = car_body(segments, rings);
    let body_normals = vertex_normals(&body.0, &body.1);
    let mut tyres = (Vec::new(), Vec::new());
    for x in [-1.35, 1.35] {
        for z in [-0.85, 0.85] {
            shapes::merge(&mut tyres, wheel(Vec3::new(x, 0.36, z), 0.24, 0.12));
        }
    }
    let tyre_normals = vertex_normals(&tyres.0, &tyres.1);
    for (name, mat, at, angle) in [
        ("RedCar", red, Vec3::new(-1.6, 0.0, -1.2), 25f32),
        ("BlueCar", blue, Vec3::new(2.5, 0.0, -0.7), -35f32),
    ] {
        let m = b.add_mesh(name, &body.0, &body.1, Some(&body_normals), Some(mat));
        let t = b.add_mesh(
            &format!("{name}Tyres"),
            &tyres.0,
            &tyres.1,
            Some(&tyre_normals),
            Some(tyre),
        );
        let body_node = b.node(NodeDesc::new(&format!("{name}Body")).with_mesh(m));
        let tyre_node = b.node(NodeDesc::new(&format!("{name}Tyres")).with_mesh(t));
        b.node(
            NodeDesc::new(name)
                .with_translation(at)
                .with_rotation(Quat::from_rotation_y(angle.to_radians()))
                .with_children(&[body_node, tyre_node]),
        );
    }

    // Lamps: a post, a solid glass globe (radius 0.3) on it, a bulb (radius 0.08) inside.
    for (k, at) in [
        Vec3::new(-4.0, 0.0, 1.5),
        Vec3::new(0.5, 0.0, -3.5),
        Vec3::new(4.2, 0.0, 3.0),
    ]
    .into_iter()
    .enumerate()
    {
        let (p, i) = shapes::cuboid(at + Vec3::new(-0.05, 0.0, -0.05), at + Vec3::new(0.05, 2.2, 0.05), true);
        b.mesh(&format!("Post{k}"), &p, &i, None, Some(metal));
        let centre = at + Vec3::Y * 2.5;
        let (p, i) = shapes::uv_sphere(centre, 0.3, 24, 48);
        let n: Vec<Vec3> = p.iter().map(|q| (*q - centre).normalize()).collect();
        b.mesh(&format!("Globe{k}"), &p, &i, Some(&n), Some(glass));
        let (p, i) = shapes::uv_sphere(centre, 0.08, 12, 24);
        let n: Vec<Vec3> = p.iter().map(|q| (*q - centre).normalize()).collect();
        b.mesh(&format!("Bulb{k}"), &p, &i, Some(&n), Some(bulb));
    }
    b.camera_look_at(
        "Camera",
        Vec3::new(0.6, 2.2, 5.6),
        Vec3::new(0.2, 0.6, -0.2),
        Vec3::Y,
        45f32.to_radians(),
        Some(16.0 / 9.0),
    );
    b.to_glb_bytes()
}

const CARS_HEAD: &str =
    "# Analogue of the paper's CARS scene (Figs. 1, 9): two highly glossy car bodies (modified Phong,
# exponents 100 and 60; 2.26 M triangles in all) in a homogeneous fog with HG g = 0.25. The only
# lights are bulbs inside solid glass globes, so all direct illumination is caustic.
# `cars.glb` (54 MB) is generated by `cargo xtask assets`, not committed; see assets/README.md.
";

/// The CARS sidecar: `head` (comment lines), the glTF file name and the image size.
pub(crate) fn cars_toml(head: &str, glb: &str, (width, height): (u32, u32)) -> String {
    format!(
        r#"{head}gltf = "{glb}"

[render]
width = {width}
height = {height}
camera = "Camera"

[[media]]
name = "fog"
region = "global"
sigma_s = [0.06, 0.06, 0.06]
sigma_a = [0.005, 0.005, 0.005]
g = 0.25

# The globes are clear glass: each bounds a medium of its own that scatters and absorbs nothing,
# since the global fog would otherwise fill them too (a global medium fills every closed mesh
# that is not a region, glass included). Fog inside a solid globe would scatter the bulb's
# light into directions that total internal reflection keeps inside: such light leaves only
# when the fog scatters it again, after tens to hundreds of bounces, and its rare photons and
# beams carry up to hundreds of times the mean flux (isolated bright dots in a long render).
[[media]]
name = "globe0"
region = "Globe0"
sigma_s = [0, 0, 0]

[[media]]
name = "globe1"
region = "Globe1"
sigma_s = [0, 0, 0]

[[media]]
name = "globe2"
region = "Globe2"
sigma_s = [0, 0, 0]

[materials.RedCar]
kind = "phong"
diffuse = [0.35, 0.03, 0.02]
specular = [0.5, 0.5, 0.5]
exponent = 100

[materials.BlueCar]
kind = "phong"
diffuse = [0.03, 0.08, 0.3]
specular = [0.5, 0.5, 0.5]
exponent = 60
"#
    )
}

// ---------------------------------------------------------------------------------------------
// smokyroom

/// Room x ∈ [−2, 2], y ∈ [0, 2.5], z ∈ [−2, 3]: a warm "window" panel high on the left wall, a
/// small ceiling lamp, a table-like block, a box and a glossy sphere.
fn smokyroom_glb() -> Vec<u8> {
    let mut b = GltfBuilder::new();
    let white = b.material(MaterialDesc::lambert("White", [0.72, 0.72, 0.72]));
    let blue = b.material(MaterialDesc::lambert("Blue", [0.12, 0.2, 0.55]));
    let wood = b.material(MaterialDesc::lambert("Wood", [0.45, 0.28, 0.15]));
    let sphere_mat = b.material(MaterialDesc::lambert("Sphere", [0.7, 0.7, 0.7]));
    let window = b.material(MaterialDesc::emitter("Window", [9.0, 7.5, 5.5]));
    let lamp = b.material(MaterialDesc::emitter("Lamp", [12.0, 12.0, 12.0]));
    for (name, (p, i)) in room_walls(Vec3::new(-2.0, 0.0, -2.0), Vec3::new(2.0, 2.5, 3.0)) {
        let mat = if name == "RightWall" { blue } else { white };
        b.mesh(name, &p, &i, None, Some(mat));
    }
    // The window: 1.4 × 0.9 on the left wall, 0.01 in front of it, facing into the room (+x).
    let (p, i) = shapes::quad(
        Vec3::new(-1.99, 1.2, 0.3),
        Vec3::new(0.0, 0.0, -1.4),
        Vec3::new(0.0, 0.9, 0.0),
    );
    b.mesh("Window", &p, &i, None, Some(window));
    let (p, i) = shapes::quad(
        Vec3::new(0.6, 2.49, -0.6),
        Vec3::new(0.3, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.3),
    );
    b.mesh("Lamp", &p, &i, None, Some(lamp));
    let (p, i) = shapes::cuboid(Vec3::new(-0.2, 0.0, -1.5), Vec3::new(1.2, 0.7, -0.6), true);
    b.mesh("Table", &p, &i, None, Some(wood));
    let (p, i) = shapes::cuboid(Vec3::new(-1.5, 0.0, -1.2), Vec3::new(-0.9, 0.6, -0.6), true);
    let boxm = b.add_mesh("Box", &p, &i, None, Some(white));
    b.node(
        NodeDesc::new("Box")
            .with_mesh(boxm)
            .with_rotation(Quat::from_rotation_y(15f32.to_radians())),
    );
    let centre = Vec3::new(0.5, 1.0, -1.05);
    let (p, i) = shapes::uv_sphere(centre, 0.3, 32, 64);
    let n: Vec<Vec3> = p.iter().map(|q| (*q - centre).normalize()).collect();
    b.mesh("Sphere", &p, &i, Some(&n), Some(sphere_mat));
    b.camera_look_at(
        "Camera",
        Vec3::new(0.2, 1.3, 2.8),
        Vec3::new(0.0, 0.9, -1.0),
        Vec3::Y,
        50f32.to_radians(),
        Some(1.0),
    );
    b.to_glb_bytes()
}

const SMOKYROOM_TOML: &str = r#"# Analogue of the paper's SMOKYROOM scene (Fig. 9): a room filled with isotropic, heterogeneous
# smoke whose density is fractal Perlin noise thinning with height, baked at load into a 64³ grid
# (CPU and GPU sample the same grid). Light comes from a warm window panel high on the left wall
# and a small ceiling lamp; the sphere is glossy.
# Generated by `cargo xtask assets`; see assets/README.md.
gltf = "smokyroom.glb"

[render]
width = 512
height = 512
camera = "Camera"

[[media]]
name = "smoke"
region = "global"
sigma_s = [0.8, 0.8, 0.8]
sigma_a = [0.05, 0.05, 0.05]
g = 0.0
density = { perlin = { scale = 3.0, octaves = 5, gain = 0.5, lacunarity = 2.0, height_falloff = 1.5, bias = 0.1, amplitude = 3.0, seed = 7 }, resolution = 64, bounds = [[-2.0, 0.0, -2.0], [2.0, 2.5, 3.0]] }

[materials.Sphere]
kind = "phong"
diffuse = [0.15, 0.15, 0.15]
specular = [0.6, 0.6, 0.6]
exponent = 60
"#;
