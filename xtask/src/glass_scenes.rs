//! The bench scenes where light reaches the fog through glass: the regime the photon maps,
//! photon beams and virtual beam lights exist for, and where a path tracer with next-event
//! estimation cannot connect to the light (a smooth dielectric is a delta surface, so every
//! path must find the emitter by BSDF sampling through the glass).
//!
//! * `caustic_sphere`: a small ceiling light above a glass ball hanging in thin fog; the ball
//!   focuses a cone of light into the fog and a bright caustic onto the floor. Its twin
//!   `caustic_sphere_wide` has the Cornell box's large light at equal power: there the path
//!   tracer finds the caustic easily (the control case).
//! * `lamp_in_glass`: a bulb of radius 0.03 inside a hollow glass globe, the only light in a
//!   fog-filled room with a glossy floor and a glossy ball: all light outside the globe has
//!   passed through glass.
//! * `cars_small`: the CARS analogue's geometry and materials with coarse car bodies, so that a
//!   reference and a bench fit in minutes (its bulbs have a real radius, 0.08, inside solid glass
//!   globes: all direct light is caustic).
use beamlight_testkit::gltf_writer::{GltfBuilder, MaterialDesc, NodeDesc, shapes};
use glam::Vec3;

/// (path relative to the workspace root, contents) of the glass scenes.
pub fn files() -> Vec<(String, Vec<u8>)> {
    vec![
        (
            "assets/scenes/caustic_sphere.gltf".into(),
            caustic_sphere_gltf(0.1).into_bytes(),
        ),
        (
            "assets/scenes/caustic_sphere.toml".into(),
            caustic_sphere_toml("caustic_sphere.gltf", CAUSTIC_SPHERE_HEAD).into_bytes(),
        ),
        (
            "assets/scenes/caustic_sphere_wide.gltf".into(),
            caustic_sphere_gltf(0.5).into_bytes(),
        ),
        (
            "assets/scenes/caustic_sphere_wide.toml".into(),
            caustic_sphere_toml("caustic_sphere_wide.gltf", CAUSTIC_SPHERE_WIDE_HEAD).into_bytes(),
        ),
        ("assets/scenes/lamp_in_glass.glb".into(), lamp_in_glass_glb()),
        (
            "assets/scenes/lamp_in_glass.toml".into(),
            LAMP_IN_GLASS_TOML.as_bytes().to_vec(),
        ),
        (
            "assets/scenes/cars_small.glb".into(),
            crate::showcase::cars_glb(CARS_SMALL_SEGMENTS, CARS_SMALL_RINGS),
        ),
        (
            "assets/scenes/cars_small.toml".into(),
            crate::showcase::cars_toml(CARS_SMALL_HEAD, "cars_small.glb", (480, 270)).into_bytes(),
        ),
    ]
}

/// A sphere mesh with smooth normals, outward (`inward = false`) or turned inside out.
fn sphere(centre: Vec3, radius: f32, rings: u32, segments: u32, inward: bool) -> (Vec<Vec3>, Vec<u32>, Vec<Vec3>) {
    let (p, mut i) = shapes::uv_sphere(centre, radius, rings, segments);
    let sign = if inward { -1.0 } else { 1.0 };
    let n = p.iter().map(|q| (*q - centre).normalize() * sign).collect();
    if inward {
        for t in i.chunks_exact_mut(3) {
            t.swap(1, 2);
        }
    }
    (p, i, n)
}

// ---------------------------------------------------------------------------------------------
// caustic_sphere

/// Radiance of the Cornell box's 0.5 × 0.5 light; a light of side `s` gets this × (0.5 / s)²,
/// so both variants emit the same power.
const CORNELL_LIGHT_RADIANCE: f32 = 15.0;

/// The glass ball: radius and centre. A ball lens of index n and radius r has its focus
/// n r / (2 (n − 1)) = 0.45 from its centre; with the light 0.99 above the centre the light's
/// image lies 0.83 below it (thin-lens estimate), just above the floor, so a converging cone
/// of light crosses the fog under the ball and a bright spot lands on the floor.
const BALL_RADIUS: f32 = 0.3;
const BALL_CENTRE: Vec3 = Vec3::new(0.0, 1.0, -0.1);

/// The Cornell room (x ∈ [−1, 1], y ∈ [0, 2], closed from z = −1 to z = 4 behind the camera)
/// with white, red and green Lambert walls, a square ceiling light of side `light`, and a
/// glass ball (IOR 1.5) hanging under it; the Cornell camera.
fn caustic_sphere_gltf(light: f32) -> String {
    let mut b = GltfBuilder::new();
    let white = b.material(MaterialDesc::lambert("White", [0.75, 0.75, 0.75]));
    let red = b.material(MaterialDesc::lambert("Red", [0.63, 0.065, 0.05]));
    let green = b.material(MaterialDesc::lambert("Green", [0.14, 0.45, 0.091]));
    let radiance = CORNELL_LIGHT_RADIANCE * (0.5 / light).powi(2);
    let emitter = b.material(MaterialDesc::emitter("Light", [radiance; 3]));
    let glass = b.material(MaterialDesc::glass("Glass", 1.5));
    for (name, (p, i)) in crate::showcase::room_walls(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 4.0)) {
        let mat = match name {
            "LeftWall" => red,
            "RightWall" => green,
            _ => white,
        };
        b.mesh(name, &p, &i, None, Some(mat));
    }
    let h = light / 2.0;
    let (p, i) = shapes::quad(
        Vec3::new(-h, 1.99, -h - 0.1),
        Vec3::new(light, 0.0, 0.0),
        Vec3::new(0.0, 0.0, light),
    );
    b.mesh("Light", &p, &i, None, Some(emitter));
    let (p, i, n) = sphere(BALL_CENTRE, BALL_RADIUS, 48, 96, false);
    let ball = b.add_mesh("Ball", &p, &i, Some(&n), Some(glass));
    b.node(NodeDesc::new("Ball").with_mesh(ball));
    b.camera_look_at(
        "Camera",
        Vec3::new(0.0, 1.0, 3.9),
        Vec3::new(0.0, 1.0, -1.0),
        Vec3::Y,
        39.3f32.to_radians(),
        Some(1.0),
    );
    b.to_json_string()
}

const CAUSTIC_SPHERE_HEAD: &str =
    "# The classic volumetric caustic: a small (0.1 × 0.1) ceiling light above a glass ball (IOR 1.5,
# radius 0.3) hanging in thin fog in the Cornell room. The ball focuses a cone of light into the
# fog and a bright spot onto the floor. What makes it hard: that light reaches the fog and the
# floor only through the glass, a delta surface, so a path tracer cannot connect to the light and
# must hit a 0.1-wide emitter by sampling through the ball: rare, bright paths (fireflies).
# Photon beams and photon maps trace the light from the light's side and find the caustic at once.
# The same light as the Cornell box's at equal power (radiance 15 × 25).
";

const CAUSTIC_SPHERE_WIDE_HEAD: &str =
    "# The control case of `caustic_sphere`: the same room, fog and glass ball under the Cornell
# box's large 0.5 × 0.5 light (radiance 15, the same power). Path tracing finds the caustic
# easily here (the light subtends 25 times the solid angle), so beams and photons should only
# match it.
";

fn caustic_sphere_toml(gltf: &str, head: &str) -> String {
    format!(
        r#"{head}# Generated by `cargo xtask assets`; see assets/README.md.
gltf = "{gltf}"

[render]
width = 256
height = 256
camera = "Camera"

[[media]]
name = "fog"
region = "global"
sigma_s = [0.25, 0.25, 0.25]
sigma_a = [0.02, 0.02, 0.02]
g = 0.5
"#
    )
}

// ---------------------------------------------------------------------------------------------
// lamp_in_glass

/// The globe: centre, outer and inner radius (a 1.5 cm shell), and the bulb's radius.
const GLOBE_CENTRE: Vec3 = Vec3::new(0.0, 1.65, -0.4);
const GLOBE_OUTER: f32 = 0.25;
const GLOBE_INNER: f32 = 0.235;
const BULB_RADIUS: f32 = 0.03;

/// Room x ∈ [−2, 2], y ∈ [0, 2.5], z ∈ [−2, 3]; a hollow glass globe hanging from the ceiling
/// on a cord, a bulb at its centre; a glossy floor, a glossy ball and a block on it.
fn lamp_in_glass_glb() -> Vec<u8> {
    let mut b = GltfBuilder::new();
    let wall = b.material(MaterialDesc::lambert("Wall", [0.7, 0.68, 0.64]));
    let blue = b.material(MaterialDesc::lambert("BlueWall", [0.12, 0.2, 0.45]));
    let floor = b.material(MaterialDesc::lambert("Floor", [0.3, 0.3, 0.3]));
    let ball_mat = b.material(MaterialDesc::lambert("Ball", [0.5, 0.2, 0.08]));
    let block_mat = b.material(MaterialDesc::lambert("Block", [0.6, 0.6, 0.6]));
    let cord_mat = b.material(MaterialDesc::lambert("Cord", [0.05, 0.05, 0.05]));
    let glass = b.material(MaterialDesc::glass("Globe", 1.5));
    // Buddha's bulb (radius 0.06, radiance 700/665/595) at half the radius and equal power.
    let bulb = b.material(MaterialDesc::emitter("Bulb", [2800.0, 2660.0, 2380.0]));
    for (name, (p, i)) in crate::showcase::room_walls(Vec3::new(-2.0, 0.0, -2.0), Vec3::new(2.0, 2.5, 3.0)) {
        let mat = match name {
            "Floor" => floor,
            "RightWall" => blue,
            _ => wall,
        };
        b.mesh(name, &p, &i, None, Some(mat));
    }
    // The globe: an outer sphere with normals out of the glass and an inner one turned inside
    // out (its normals point into the air inside, also out of the glass), so the shell between
    // them is the dielectric.
    let (p, i, mut n) = sphere(GLOBE_CENTRE, GLOBE_OUTER, 32, 64, false);
    let (pi, ii, ni) = sphere(GLOBE_CENTRE, GLOBE_INNER, 32, 64, true);
    let mut shell = (p, i);
    shapes::merge(&mut shell, (pi, ii));
    n.extend(ni);
    let globe = b.add_mesh("Globe", &shell.0, &shell.1, Some(&n), Some(glass));
    b.node(NodeDesc::new("Globe").with_mesh(globe));
    let (p, i, n) = sphere(GLOBE_CENTRE, BULB_RADIUS, 12, 24, false);
    let bulb_mesh = b.add_mesh("Bulb", &p, &i, Some(&n), Some(bulb));
    b.node(NodeDesc::new("Bulb").with_mesh(bulb_mesh));
    // The cord from the ceiling to the top of the globe.
    let top = GLOBE_CENTRE + Vec3::Y * GLOBE_OUTER;
    let (p, i) = shapes::cuboid(
        top + Vec3::new(-0.008, 0.0, -0.008),
        Vec3::new(0.008, 2.5, top.z + 0.008),
        true,
    );
    b.mesh("Cord", &p, &i, None, Some(cord_mat));
    // A glossy ball and a block on the floor.
    let (p, i, n) = sphere(Vec3::new(0.75, 0.35, -0.9), 0.35, 32, 64, false);
    let ball = b.add_mesh("Ball", &p, &i, Some(&n), Some(ball_mat));
    b.node(NodeDesc::new("Ball").with_mesh(ball));
    let (p, i) = shapes::cuboid(Vec3::new(-1.2, 0.0, -1.3), Vec3::new(-0.6, 0.7, -0.7), true);
    b.mesh("Block", &p, &i, None, Some(block_mat));
    b.camera_look_at(
        "Camera",
        Vec3::new(0.0, 1.2, 2.8),
        Vec3::new(0.0, 0.9, -1.0),
        Vec3::Y,
        50f32.to_radians(),
        Some(1.0),
    );
    b.to_glb_bytes()
}

const LAMP_IN_GLASS_TOML: &str = r#"# A lamp in glass: a bulb of radius 0.03 inside a hollow glass globe (IOR 1.5, 1.5 cm shell)
# hanging in a fog-filled room (σs 0.15, σa 0.01, HG g = 0.4), a glossy floor and a glossy ball,
# no other light. What makes it hard: every path from the bulb to the room passes through two
# glass interfaces, delta surfaces that next-event estimation cannot cross, so a path tracer
# reaches the bulb only when a BSDF- or phase-sampled direction happens to hit a 3-cm sphere
# through the globe (a solid angle of about 1e-3 sr from the floor). All light on the room's
# surfaces is a surface caustic and all single scattering outside the globe a volume caustic:
# the light-tracing estimators (photon maps, photon beams, and the virtual lights behind them)
# carry it at the cost of direct light.
# Generated by `cargo xtask assets`; see assets/README.md.
gltf = "lamp_in_glass.glb"

[render]
width = 256
height = 256
camera = "Camera"

[[media]]
name = "fog"
region = "global"
sigma_s = [0.15, 0.15, 0.15]
sigma_a = [0.01, 0.01, 0.01]
g = 0.4

[materials.Floor]
kind = "phong"
diffuse = [0.2, 0.2, 0.2]
specular = [0.4, 0.4, 0.4]
exponent = 40

[materials.Ball]
kind = "phong"
diffuse = [0.4, 0.12, 0.04]
specular = [0.5, 0.5, 0.5]
exponent = 80
"#;

// ---------------------------------------------------------------------------------------------
// cars_small

/// The reduced car bodies: 96 × 48 instead of 1000 × 561 (about 9 k triangles each instead of
/// 1.12 M), so the scene loads at once and the ripple of the paint is lost; the lamps and the
/// room are unchanged.
const CARS_SMALL_SEGMENTS: u32 = 96;
const CARS_SMALL_RINGS: u32 = 48;

const CARS_SMALL_HEAD: &str =
    "# The reduced CARS (bench stand-in for `cars`): the same room, lamps, fog and Phong materials,
# coarse car bodies (about 9 k triangles each instead of 1.12 M) and 480 × 270 pixels. The only
# lights are bulbs of radius 0.08 inside solid glass globes, so all direct illumination is caustic
# and a path tracer reaches a bulb only by sampling through a globe: it converges, slowly.
";
