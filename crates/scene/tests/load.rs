//! Scene loading: round trips through the glTF writer, sidecar features, the bundled assets, and
//! the broken-scene corpus in `tests/bad_scenes/` (every case must fail with a clear message
//! naming the file, never panic).
use beamlight_scene::bsdf::Bsdf;
use beamlight_scene::light::PunctualLight;
use beamlight_scene::load::load_scene;
use beamlight_scene::medium::write_grid;
use beamlight_scene::scene::MediumInterface;
use beamlight_scene::texture::Wrap;
use beamlight_scene::{Scene, SceneError};
use beamlight_testkit::gltf_writer::{GltfBuilder, IndexWidth, MaterialDesc, NodeDesc, shapes};
use glam::{Quat, UVec3, Vec2, Vec3};
use std::path::{Path, PathBuf};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn approx(a: Vec3, b: Vec3, tol: f32) -> bool {
    (a - b).abs().max_element() <= tol
}

fn load_ok(path: &Path) -> Scene {
    match load_scene(path) {
        Ok(s) => s,
        Err(e) => panic!("{} should load: {e}", path.display()),
    }
}

fn load_err(path: &Path) -> String {
    match load_scene(path) {
        Ok(_) => panic!("{} should fail to load", path.display()),
        Err(e) => e.to_string(),
    }
}

/// A small scene with every feature the writer has.
fn feature_scene() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let white = b.material(MaterialDesc::lambert("White", [0.8, 0.7, 0.6]));
    let light = b.material(MaterialDesc::emitter("Lamp", [20.0, 10.0, 5.0]).with_double_sided(true));
    let glass = b.material(MaterialDesc::glass("Glass", 1.33));
    let (p, i) = shapes::quad(
        Vec3::new(-2.0, 0.0, 2.0),
        Vec3::new(4.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -4.0),
    );
    b.mesh("Floor", &p, &i, None, Some(white));
    let (p, i) = shapes::quad(
        Vec3::new(-0.5, 3.0, -0.5),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
    );
    b.mesh("Lamp", &p, &i, None, Some(light));
    let (p, i) = shapes::uv_sphere(Vec3::new(0.0, 1.0, 0.0), 0.5, 8, 12);
    let n: Vec<Vec3> = p.iter().map(|q| (*q - Vec3::new(0.0, 1.0, 0.0)).normalize()).collect();
    b.mesh("Ball", &p, &i, Some(&n), Some(glass));
    let (p, i) = shapes::cuboid(Vec3::splat(-0.25), Vec3::splat(0.25), true);
    b.mesh("Cube", &p, &i, None, None);
    b.camera_look_at(
        "Cam",
        Vec3::new(0.0, 1.5, 6.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::Y,
        0.6,
        Some(1.5),
    );
    b.point_light("Bulb", Vec3::new(1.0, 2.0, 3.0), [1.0, 0.5, 0.25], 40.0);
    b.spot_light(
        "Spot",
        Vec3::new(0.0, 4.0, 0.0),
        Vec3::NEG_Y,
        [1.0, 1.0, 1.0],
        100.0,
        0.2,
        0.5,
    );
    b
}

fn check_feature_scene(s: &Scene) {
    // Triangles: floor 2 + lamp 2 + ball 2*12 + 6*12*2... + cube 12.
    let ball = 12 * 2 + (8 - 2) * 12 * 2;
    assert_eq!(s.triangles.len(), 2 + 2 + ball + 12, "warnings: {:?}", s.warnings);
    assert_eq!(s.meshes, vec!["Floor", "Lamp", "Ball", "Cube"]);
    let mat = |name: &str| {
        s.materials
            .iter()
            .find(|m| m.name == name)
            .unwrap_or_else(|| panic!("material {name}"))
    };
    assert_eq!(
        mat("White").bsdf,
        Some(Bsdf::Lambert {
            albedo: Vec3::new(0.8, 0.7, 0.6)
        })
    );
    assert!(approx(mat("Lamp").emission, Vec3::new(20.0, 10.0, 5.0), 1e-4));
    assert!(mat("Lamp").double_sided && !mat("White").double_sided);
    assert_eq!(
        mat("Glass").bsdf,
        Some(Bsdf::Glass {
            ior: 1.33,
            tint: Vec3::ONE
        })
    );
    // The cube has no material: it gets glTF's default material (base colour 1) as Lambert.
    let cube = s
        .triangles
        .iter()
        .find(|t| s.meshes[t.mesh as usize] == "Cube")
        .unwrap();
    assert_eq!(
        s.materials[cube.material as usize].bsdf,
        Some(Bsdf::Lambert {
            albedo: Vec3::splat(1.0)
        })
    );
    // Flat floor facing +Y, no shading normals; ball has normals, pointing outward.
    for t in &s.triangles {
        match s.meshes[t.mesh as usize].as_str() {
            "Floor" => {
                assert!(t.n.is_none());
                assert!(approx(t.cross().normalize(), Vec3::Y, 1e-6));
            }
            "Lamp" => assert!(approx(t.cross().normalize(), Vec3::NEG_Y, 1e-6)),
            "Ball" => {
                let n = t.n.expect("ball has normals");
                let c = (t.p[0] + t.p[1] + t.p[2]) / 3.0 - Vec3::new(0.0, 1.0, 0.0);
                assert!(t.cross().dot(c) > 0.0, "sphere faces outward");
                for (nk, pk) in n.iter().zip(t.p) {
                    assert!((nk.length() - 1.0).abs() < 1e-5);
                    assert!(approx(*nk, (pk - Vec3::new(0.0, 1.0, 0.0)).normalize(), 1e-5));
                }
            }
            _ => {}
        }
        assert!(t.interface.is_none());
    }
    // Camera: at the eye, looking at the target, right-handed rigid frame.
    let c = &s.camera;
    assert_eq!(c.name.as_deref(), Some("Cam"));
    assert!(approx(c.position(), Vec3::new(0.0, 1.5, 6.0), 1e-5));
    assert!(approx(
        c.forward(),
        (Vec3::new(0.0, 1.0, 0.0) - Vec3::new(0.0, 1.5, 6.0)).normalize(),
        1e-5
    ));
    assert!((c.yfov - 0.6).abs() < 1e-6);
    let m = c.to_world;
    assert!((m.x_axis.truncate().cross(m.y_axis.truncate()) - m.z_axis.truncate()).length() < 1e-5);
    assert!(
        c.direction(glam::Vec2::new(0.5, 0.0), 1.0).y > c.forward().y,
        "image top is up"
    );
    // Lights.
    assert_eq!(s.lights.len(), 2);
    match &s.lights[0] {
        PunctualLight::Point { position, intensity } => {
            assert!(approx(*position, Vec3::new(1.0, 2.0, 3.0), 1e-6));
            assert!(approx(*intensity, Vec3::new(40.0, 20.0, 10.0), 1e-4));
        }
        other => panic!("expected a point light, got {other:?}"),
    }
    match &s.lights[1] {
        PunctualLight::Spot {
            position,
            direction,
            intensity,
            cos_inner,
            cos_outer,
        } => {
            assert!(approx(*position, Vec3::new(0.0, 4.0, 0.0), 1e-6));
            assert!(approx(*direction, Vec3::NEG_Y, 1e-6));
            assert!(approx(*intensity, Vec3::splat(100.0), 1e-4));
            assert!((cos_inner - 0.2f32.cos()).abs() < 1e-6 && (cos_outer - 0.5f32.cos()).abs() < 1e-6);
        }
        other => panic!("expected a spot light, got {other:?}"),
    }
    assert!(s.media.is_empty() && s.global_medium.is_none());
}

#[test]
fn gltf_round_trip_without_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("features.gltf");
    feature_scene().write_gltf(&path).unwrap();
    let s = load_ok(&path);
    check_feature_scene(&s);
    // glTF alone: 512 high, width from the camera's aspect ratio 1.5.
    assert_eq!((s.render.width, s.render.height), (768, 512));
    assert_eq!(s.source, path);
}

#[test]
fn glb_round_trip_matches_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("f.gltf"), dir.path().join("f.glb"));
    feature_scene().write_gltf(&a).unwrap();
    feature_scene().write_glb(&b).unwrap();
    let (sa, sb) = (load_ok(&a), load_ok(&b));
    check_feature_scene(&sb);
    assert_eq!(sa.triangles.len(), sb.triangles.len());
    for (x, y) in sa.triangles.iter().zip(&sb.triangles) {
        assert_eq!(x.p, y.p);
        assert_eq!(x.n, y.n);
        assert_eq!(x.material, y.material);
    }
}

#[test]
fn every_index_width_and_non_indexed_give_the_same_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let (p, i) = shapes::uv_sphere(Vec3::ZERO, 1.0, 6, 10);
    let mut reference: Option<Vec<[Vec3; 3]>> = None;
    for (k, width) in [IndexWidth::U8, IndexWidth::U16, IndexWidth::U32, IndexWidth::Auto]
        .into_iter()
        .enumerate()
    {
        let mut b = GltfBuilder::new();
        b.index_width(width);
        b.mesh("S", &p, &i, None, None);
        let path = dir.path().join(format!("w{k}.gltf"));
        b.write_gltf(&path).unwrap();
        let tris: Vec<[Vec3; 3]> = load_ok(&path).triangles.iter().map(|t| t.p).collect();
        match &reference {
            None => reference = Some(tris),
            Some(r) => assert_eq!(r, &tris),
        }
    }
    // Non-indexed: positions three at a time.
    let flat: Vec<Vec3> = i.iter().map(|&k| p[k as usize]).collect();
    let mut b = GltfBuilder::new();
    b.mesh("S", &flat, &[], None, None);
    let path = dir.path().join("flat.gltf");
    b.write_gltf(&path).unwrap();
    let tris: Vec<[Vec3; 3]> = load_ok(&path).triangles.iter().map(|t| t.p).collect();
    assert_eq!(reference.unwrap(), tris);
}

#[test]
fn node_hierarchy_transforms_accumulate_and_mirroring_keeps_orientation() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = GltfBuilder::new();
    // A unit quad in the XY plane facing +Z, with +Z shading normals.
    let (p, i) = shapes::quad(Vec3::ZERO, Vec3::X, Vec3::Y);
    let n = vec![Vec3::Z; 4];
    let quad = b.add_mesh("Quad", &p, &i, Some(&n), None);
    // child: scale (2, 1, 1); parent: rotate 90° about Y then translate (10, 0, 0).
    let child = b.node(
        NodeDesc::new("Child")
            .with_mesh(quad)
            .with_scale(Vec3::new(2.0, 1.0, 1.0)),
    );
    b.node(
        NodeDesc::new("Parent")
            .with_translation(Vec3::new(10.0, 0.0, 0.0))
            .with_rotation(Quat::from_rotation_y(std::f32::consts::FRAC_PI_2))
            .with_children(&[child]),
    );
    // Mirrored instances: x → −x (normal stays +Z) and z → −z (normal becomes −Z).
    b.node(
        NodeDesc::new("MirrorX")
            .with_mesh(quad)
            .with_scale(Vec3::new(-1.0, 1.0, 1.0)),
    );
    b.node(
        NodeDesc::new("MirrorZ")
            .with_mesh(quad)
            .with_scale(Vec3::new(1.0, 1.0, -1.0)),
    );
    // Non-uniform scale of a tilted quad: normals use the inverse transpose.
    let (p2, i2) = shapes::quad(Vec3::ZERO, Vec3::new(1.0, 0.0, -1.0), Vec3::Y);
    let n2 = vec![Vec3::new(1.0, 0.0, 1.0).normalize(); 4];
    let tilted = b.add_mesh("Tilted", &p2, &i2, Some(&n2), None);
    b.node(
        NodeDesc::new("Squash")
            .with_mesh(tilted)
            .with_scale(Vec3::new(3.0, 1.0, 1.0)),
    );
    b.camera_look_at("Cam", Vec3::new(0.0, 0.0, 20.0), Vec3::ZERO, Vec3::Y, 0.5, None);
    let path = dir.path().join("h.gltf");
    b.write_gltf(&path).unwrap();
    let s = load_ok(&path);
    assert_eq!(s.triangles.len(), 8);
    let [c0, c1, m0, _, z0, _, q0, _] = [0, 1, 2, 3, 4, 5, 6, 7].map(|k| &s.triangles[k]);
    // Child world = T(10,0,0) · R_y(90°) · S(2,1,1): (1,0,0) → (2,0,0) → (0,0,−2) → (10,0,−2).
    assert!(approx(c0.p[1], Vec3::new(10.0, 0.0, -2.0), 1e-5), "{:?}", c0.p);
    assert!(approx(c0.cross().normalize(), Vec3::X, 1e-5));
    assert!(approx(c1.n.unwrap()[0], Vec3::X, 1e-5));
    for (t, expect) in [(m0, Vec3::Z), (z0, Vec3::NEG_Z)] {
        assert!(approx(t.cross().normalize(), expect, 1e-6), "geometric {:?}", t.cross());
        assert!(approx(t.n.unwrap()[0], expect, 1e-6), "shading {:?}", t.n);
    }
    // Tilted plane x = −z scaled by 3 in x: plane 3z' ... normal ∝ (1/3, 0, 1).
    let want = Vec3::new(1.0 / 3.0, 0.0, 1.0).normalize();
    assert!(approx(q0.n.unwrap()[0], want, 1e-5));
    assert!(approx(q0.cross().normalize(), want, 1e-5));
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

#[test]
fn degenerate_triangles_are_skipped_with_one_warning_per_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = GltfBuilder::new();
    let p = vec![
        Vec3::ZERO,
        Vec3::X,
        Vec3::Y,
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(3.0, 0.0, 0.0),
    ];
    // one good, two zero-area (repeated vertex, collinear), one good
    let i = vec![0, 1, 2, 0, 0, 1, 0, 3, 4, 2, 1, 3];
    b.mesh("Sliver", &p, &i, None, None);
    b.camera_look_at("Cam", Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 0.5, None);
    let path = dir.path().join("d.gltf");
    b.write_gltf(&path).unwrap();
    let s = load_ok(&path);
    assert_eq!(s.triangles.len(), 2);
    let w: Vec<&String> = s.warnings.iter().filter(|w| w.contains("degenerate")).collect();
    assert_eq!(w.len(), 1, "{:?}", s.warnings);
    assert!(w[0].contains("'Sliver'") && w[0].contains("skipped 2"), "{}", w[0]);
}

#[test]
fn no_camera_gives_a_default_camera_and_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = GltfBuilder::new();
    let (p, i) = shapes::cuboid(Vec3::new(1.0, 1.0, 1.0), Vec3::new(3.0, 2.0, 5.0), true);
    b.mesh("Box", &p, &i, None, None);
    let path = dir.path().join("nocam.gltf");
    b.write_gltf(&path).unwrap();
    let s = load_ok(&path);
    assert!(s.warnings.iter().any(|w| w.contains("no camera")), "{:?}", s.warnings);
    let c = &s.camera;
    assert!(approx(c.forward(), Vec3::NEG_Z, 1e-6));
    assert!((c.yfov - 40f32.to_radians()).abs() < 1e-6);
    let centre = Vec3::new(2.0, 1.5, 3.0);
    assert!(approx(
        c.position() * Vec3::new(1.0, 1.0, 0.0),
        centre * Vec3::new(1.0, 1.0, 0.0),
        1e-5
    ));
    assert!(c.position().z > 5.0, "camera outside the bounds on the +Z side");
    // The whole bounding sphere is inside the field of view.
    let r = 0.5 * Vec3::new(2.0, 1.0, 4.0).length();
    assert!((r / (c.position().z - centre.z)) <= (0.5 * c.yfov).sin() + 1e-5);
    assert_eq!((s.render.width, s.render.height), (512, 512));
}

/// A scene with nested medium regions: global fog ⊃ box "Tank" ⊃ sphere "Bubble" (no
/// material: index-matched boundary), plus "Inverted" (an inward-facing cube, to be flipped).
fn media_scene(dir: &Path) -> PathBuf {
    let mut b = GltfBuilder::new();
    let white = b.material(MaterialDesc::lambert("White", [0.5, 0.5, 0.5]));
    let glass = b.material(MaterialDesc::glass("TankGlass", 1.5));
    b.material(MaterialDesc::lambert("Statue", [0.3, 0.3, 0.3]));
    let (p, i) = shapes::quad(
        Vec3::new(-5.0, 0.0, 5.0),
        Vec3::new(10.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -10.0),
    );
    b.mesh("Floor", &p, &i, None, Some(white));
    let (p, i) = shapes::cuboid(Vec3::new(-2.0, 0.5, -2.0), Vec3::new(2.0, 3.0, 2.0), true);
    b.mesh("Tank", &p, &i, None, Some(glass));
    let (p, i) = shapes::uv_sphere(Vec3::new(0.0, 1.5, 0.0), 0.7, 8, 12);
    b.mesh("Bubble", &p, &i, None, None);
    let (p, i) = shapes::cuboid(Vec3::new(3.0, 0.5, -1.0), Vec3::new(4.0, 1.5, 0.0), false);
    b.mesh("Inverted", &p, &i, None, None);
    b.camera_look_at(
        "Cam",
        Vec3::new(0.0, 2.0, 9.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::Y,
        0.7,
        None,
    );
    b.write_gltf(&dir.join("media.gltf")).unwrap();
    std::fs::write(dir.join("ramp.bgrid"), write_grid(UVec3::new(2, 1, 1), &[0.0, 1.0])).unwrap();
    write(
        dir,
        "media.toml",
        r#"
gltf = "media.gltf"

[render]
width = 320
camera = "Cam"

[[media]]
name = "air"
region = "global"
sigma_s = 0.01

[[media]]
name = "water"
region = "Tank"
sigma_s = [0.1, 0.2, 0.3]
sigma_a = [0.3, 0.2, 0.1]
g = -0.5

[[media]]
name = "milk"
region = "Bubble"
sigma_s = [5, 5, 5]
g = 0.9
density = { grid = "ramp.bgrid" }

[[media]]
name = "ink"
region = "Inverted"
sigma_s = [1.0, 1.0, 1.0]
density = { grid = "ramp.bgrid", bounds = [[0, 0, 0], [1, 2, 3]] }
"#,
    )
}

#[test]
fn media_regions_nest_and_get_interfaces() {
    let dir = tempfile::tempdir().unwrap();
    let s = load_ok(&media_scene(dir.path()));
    let names: Vec<&str> = s.media.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["air", "water", "milk", "ink"]);
    let (air, water, milk, ink) = (Some(0), Some(1), Some(2), Some(3));
    assert_eq!(s.global_medium, air);
    assert_eq!(s.media[0].sigma_s, Vec3::splat(0.01));
    assert_eq!(s.media[1].sigma_a, Vec3::new(0.3, 0.2, 0.1));
    assert_eq!(s.media[1].g, -0.5);
    assert!(s.media[0].density.is_none() && s.media[1].density.is_none());
    // Default bounds of a region's grid: the region mesh's box.
    let g = s.media[2].density.as_ref().expect("milk has a grid");
    assert!(approx(g.lo, Vec3::new(-0.7, 0.8, -0.7), 1e-5) && approx(g.hi, Vec3::new(0.7, 2.2, 0.7), 1e-5));
    let g = s.media[3].density.as_ref().expect("ink has a grid");
    assert_eq!((g.lo, g.hi), (Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0)));

    let iface = |mesh: &str| -> Vec<Option<MediumInterface>> {
        s.triangles
            .iter()
            .filter(|t| s.meshes[t.mesh as usize] == mesh)
            .map(|t| t.interface)
            .collect()
    };
    assert!(iface("Floor").iter().all(|i| i.is_none()));
    assert!(iface("Tank").iter().all(|i| *i
        == Some(MediumInterface {
            inside: water,
            outside: air
        })));
    assert!(iface("Bubble").iter().all(|i| *i
        == Some(MediumInterface {
            inside: milk,
            outside: water
        })));
    assert!(iface("Inverted").iter().all(|i| *i
        == Some(MediumInterface {
            inside: ink,
            outside: air
        })));
    // Region triangles face out of their medium after loading (the inverted cube was flipped).
    for t in &s.triangles {
        if t.interface.is_some() {
            let centre = match s.meshes[t.mesh as usize].as_str() {
                "Tank" => Vec3::new(0.0, 1.75, 0.0),
                "Bubble" => Vec3::new(0.0, 1.5, 0.0),
                _ => Vec3::new(3.5, 1.0, -0.5),
            };
            assert!(t.cross().dot((t.p[0] + t.p[1] + t.p[2]) / 3.0 - centre) > 0.0);
        }
    }
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("'Inverted'") && w.contains("inward")),
        "{:?}",
        s.warnings
    );
    // Region primitives without a material are index-matched boundaries; with one they keep it.
    let bubble = s
        .triangles
        .iter()
        .find(|t| s.meshes[t.mesh as usize] == "Bubble")
        .unwrap();
    assert!(s.materials[bubble.material as usize].bsdf.is_none());
    let tank = s
        .triangles
        .iter()
        .find(|t| s.meshes[t.mesh as usize] == "Tank")
        .unwrap();
    assert!(matches!(
        s.materials[tank.material as usize].bsdf,
        Some(Bsdf::Glass { .. })
    ));
    // Only the width is given: the height follows the (missing → square) aspect ratio.
    assert_eq!((s.render.width, s.render.height), (320, 320));
}

#[test]
fn material_overrides() {
    let dir = tempfile::tempdir().unwrap();
    media_scene(dir.path());
    let toml = write(
        dir.path(),
        "over.toml",
        r#"
gltf = "media.gltf"
[render]
width = 64
height = 48
[materials.White]
kind = "phong"
specular = [0.3, 0.4, 0.5]
exponent = 60
[materials.TankGlass]
kind = "mirror"
emission = [1, 2, 3]
double_sided = true
[materials.Statue]
kind = "lambert"
diffuse = 0.25
"#,
    );
    let s = load_ok(&toml);
    assert_eq!((s.render.width, s.render.height), (64, 48));
    let mat = |name: &str| s.materials.iter().find(|m| m.name == name).unwrap();
    // Phong's diffuse defaults to the glTF base colour.
    assert_eq!(
        mat("White").bsdf,
        Some(Bsdf::Phong {
            diffuse: Vec3::splat(0.5),
            specular: Vec3::new(0.3, 0.4, 0.5),
            exponent: 60.0
        })
    );
    assert_eq!(mat("TankGlass").bsdf, Some(Bsdf::Mirror { reflectance: Vec3::ONE }));
    assert_eq!(mat("TankGlass").emission, Vec3::new(1.0, 2.0, 3.0));
    assert!(mat("TankGlass").double_sided);
    assert_eq!(
        mat("Statue").bsdf,
        Some(Bsdf::Lambert {
            albedo: Vec3::splat(0.25)
        })
    );

    let glass = write(
        dir.path(),
        "g.toml",
        "gltf = \"media.gltf\"\n[materials.Statue]\nkind = \"glass\"\nior = 1.2\ntint = [0.9, 1, 1]\n",
    );
    let s = load_ok(&glass);
    let m = s.materials.iter().find(|m| m.name == "Statue").unwrap();
    assert_eq!(
        m.bsdf,
        Some(Bsdf::Glass {
            ior: 1.2,
            tint: Vec3::new(0.9, 1.0, 1.0)
        })
    );

    for (body, fragment) in [
        (
            "[materials.Statue]\nkind = \"mirror\"\nexponent = 3\n",
            "does not apply",
        ),
        ("[materials.Statue]\nalbedo = 0.5\n", "needs a 'kind'"),
        (
            "[materials.Statue]\nkind = \"phong\"\nspecular = 0.5\n",
            "needs 'exponent'",
        ),
        (
            "[materials.Statue]\nkind = \"lambert\"\nalbedo = 1.5\n",
            "must be in [0, 1]",
        ),
        ("[materials.Statue]\nkind = \"glass\"\nior = -1\n", "ior -1"),
        ("[materials.Statue]\nkind = \"lambert\"\nalbedo = [1, 2]\n", "3 numbers"),
        (
            "[materials.Nope]\nkind = \"lambert\"\n",
            "available: 'Statue', 'TankGlass', 'White'",
        ),
    ] {
        let p = write(dir.path(), "bad.toml", &format!("gltf = \"media.gltf\"\n{body}"));
        let e = load_err(&p);
        assert!(e.contains("bad.toml") && e.contains(fragment), "{body}: {e}");
    }
}

/// Procedural and OpenVDB densities load into density grids placed where the sidecar says.
#[test]
fn perlin_and_vdb_densities_load() {
    let dir = tempfile::tempdir().unwrap();
    media_scene(dir.path());
    let vdb = workspace().join("assets/volumes/blob.vdb");
    std::fs::copy(&vdb, dir.path().join("blob.vdb")).unwrap();
    let p = write(
        dir.path(),
        "ok.toml",
        "gltf = \"media.gltf\"\n[[media]]\nname = \"a\"\nregion = \"global\"\nsigma_s = 1\n\
         density = { perlin = { scale = 3, octaves = 2, height_falloff = 2, seed = 7 }, resolution = [16, 8, 4], bounds = [[0, 0, 0], [2, 1, 1]] }\n\
         [[media]]\nname = \"b\"\nregion = \"Tank\"\nsigma_s = 1\ndensity = { grid = \"blob.vdb\" }\n",
    );
    let scene = load_scene(&p).unwrap();
    let a = scene.media[0].density.as_ref().unwrap();
    assert_eq!(a.res, glam::UVec3::new(16, 8, 4));
    assert_eq!((a.lo, a.hi), (glam::Vec3::ZERO, glam::Vec3::new(2.0, 1.0, 1.0)));
    let params = beamlight_scene::noise::PerlinDensity {
        scale: 3.0,
        octaves: 2,
        height_falloff: 2.0,
        seed: 7,
        ..Default::default()
    };
    assert_eq!(a.values, params.bake_values(a.res));
    let b = scene.media[1].density.as_ref().unwrap();
    assert_eq!(b.res, glam::UVec3::new(32, 14, 14));
    assert!((b.lo - glam::Vec3::new(-0.55, -0.175, -0.74)).abs().max_element() < 1e-6);
    assert!((b.density(glam::Vec3::new(0.3, 0.15, -0.3)) - 1.2239).abs() < 1e-4);
}

#[test]
fn media_errors() {
    let dir = tempfile::tempdir().unwrap();
    media_scene(dir.path());
    for (body, fragment) in [
        (
            "name = \"a\"\nregion = \"Floor\"\nsigma_s = 1",
            "must be a closed mesh, but it has 4 open edge",
        ),
        ("name = \"a\"\nregion = \"global\"\nsigma_s = 1\ng = -1", "-1 < g < 1"),
        ("name = \"a\"\nregion = \"global\"\nsigma_s = 1\ng = nan", "-1 < g < 1"),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = inf",
            "finite and non-negative",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\nsigma_a = [0, -1, 0]",
            "sigma_a",
        ),
        (
            "name = \"a\"\nregion = \"Nowhere\"\nsigma_s = 1",
            "meshes: 'Bubble', 'Floor', 'Inverted', 'Tank'",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { grid = \"ramp.bgrid\", bounds = [[0, 0, 0], [0, 1, 1]] }",
            "min < max",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { perlin = 3 }",
            "invalid type: integer `3`",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { perlin = { octaves = 17 } }",
            "line 6, column 34: [[media]] 'a': density.perlin.octaves = 17 must be between 1 and 16",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { perlin = { scale = -1 } }",
            "density.perlin.scale = -1 must be",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { perlin = { gain = nan } }",
            "density.perlin.gain = NaN must be",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { perlin = { seed = -1 } }",
            "density.perlin.seed = -1 must be between 0 and 4294967295",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { perlin = { wiggle = 1 } }",
            "unknown field `wiggle`",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { perlin = {}, resolution = 0 }",
            "density resolution [0, 0, 0] must be 1 to 4096 per axis",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { perlin = {}, resolution = [512, 512, 512] }",
            "at most 16777216 voxels",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { perlin = {}, resolution = [8, 8] }",
            "exactly 3 integers",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { perlin = {}, grid = \"x.bgrid\" }",
            "both 'grid' and 'perlin'",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { bounds = [[0, 0, 0], [1, 1, 1]] }",
            "density needs 'grid",
        ),
        (
            "name = \"a\"\nregion = \"global\"\nsigma_s = 1\ndensity = { grid = \"x.bgrid\", name = \"density\" }",
            "'x.bgrid' is not one",
        ),
        ("region = \"global\"\nsigma_s = 1", "missing field `name`"),
    ] {
        let p = write(
            dir.path(),
            "bad.toml",
            &format!("gltf = \"media.gltf\"\n[[media]]\n{body}\n"),
        );
        let e = load_err(&p);
        assert!(e.contains("bad.toml") && e.contains(fragment), "{body}: {e}");
    }
    // The same mesh cannot bound two media.
    let p = write(
        dir.path(),
        "twice.toml",
        "gltf = \"media.gltf\"\n[[media]]\nname = \"a\"\nregion = \"Tank\"\nsigma_s = 1\n[[media]]\nname = \"b\"\nregion = \"Tank\"\nsigma_s = 1\n",
    );
    assert!(load_err(&p).contains("at most one medium"));
}

#[test]
fn render_size_and_camera_choice() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = GltfBuilder::new();
    let (p, i) = shapes::quad(Vec3::ZERO, Vec3::X, Vec3::Y);
    b.mesh("Q", &p, &i, None, None);
    b.camera_look_at("Front", Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 0.5, Some(2.0));
    b.camera_look_at("Side", Vec3::new(5.0, 0.0, 0.0), Vec3::ZERO, Vec3::Y, 0.7, Some(0.5));
    b.write_gltf(&dir.path().join("two.gltf")).unwrap();
    let case = |body: &str| {
        let p = write(dir.path(), "c.toml", &format!("gltf = \"two.gltf\"\n[render]\n{body}"));
        load_scene(&p)
    };
    let s = case("").unwrap();
    assert_eq!(s.camera.name.as_deref(), Some("Front"));
    assert_eq!((s.render.width, s.render.height), (1024, 512));
    let s = case("camera = \"Side\"").unwrap();
    assert!(approx(s.camera.position(), Vec3::new(5.0, 0.0, 0.0), 1e-6));
    assert_eq!((s.render.width, s.render.height), (256, 512));
    let s = case("camera = \"Side\"\nheight = 100").unwrap();
    assert_eq!((s.render.width, s.render.height), (50, 100));
    let s = case("width = 7\nheight = 16384").unwrap();
    assert_eq!((s.render.width, s.render.height), (7, 16384));
    let e = case("width = 0").unwrap_err().to_string();
    assert!(
        e.contains("c.toml") && e.contains("absurd resolution") && e.contains("line 3"),
        "{e}"
    );
    let e = case("height = -3").unwrap_err().to_string();
    assert!(e.contains("c.toml") && e.contains("invalid value"), "{e}");
    let e = case("camera = \"Top\"").unwrap_err().to_string();
    assert!(e.contains("'Front', 'Side'"), "{e}");
}

#[test]
fn unsupported_features_warn_once() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = GltfBuilder::new();
    b.material(MaterialDesc::lambert("M", [0.5; 3]));
    let (p, i) = shapes::quad(Vec3::ZERO, Vec3::X, Vec3::Y);
    b.mesh("Q", &p, &i, None, Some(0));
    b.point_light("L", Vec3::Z, [1.0; 3], 1.0);
    b.camera_look_at("C", Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 0.5, None);
    let mut v: serde_json::Value = serde_json::from_str(&b.to_json_string()).unwrap();
    // Only the textures we ignore warn; their images are never read (this one is missing).
    v["materials"][0]["emissiveTexture"] = serde_json::json!({ "index": 0 });
    v["materials"][0]["normalTexture"] = serde_json::json!({ "index": 0 });
    v["textures"] = serde_json::json!([{ "source": 0 }]);
    v["images"] = serde_json::json!([{ "uri": "missing.png" }]);
    v["extensionsUsed"] = serde_json::json!([
        "KHR_lights_punctual",
        "KHR_texture_transform",
        "KHR_materials_clearcoat"
    ]);
    v["extensions"]["KHR_lights_punctual"]["lights"][0]["range"] = serde_json::json!(10.0);
    v["animations"] = serde_json::json!([]);
    let path = dir.path().join("w.gltf");
    std::fs::write(&path, serde_json::to_string(&v).unwrap()).unwrap();
    let s = load_ok(&path);
    let count = |frag: &str| s.warnings.iter().filter(|w| w.contains(frag)).count();
    assert_eq!(
        count("textures ignored: normalTexture, emissiveTexture"),
        1,
        "{:?}",
        s.warnings
    );
    assert_eq!(count("KHR_texture_transform"), 1);
    assert_eq!(count("KHR_materials_clearcoat"), 1);
    assert_eq!(count("range ignored"), 1);
    assert!(s.warnings.iter().all(|w| w.starts_with("w.gltf: ")), "{:?}", s.warnings);
}

/// The broken-scene corpus: (file, expected fragment of the message).
const BAD_SCENES: &[(&str, &str)] = &[
    ("missing_gltf.toml", "does_not_exist.gltf"),
    ("malformed_json.gltf", "malformed glTF JSON"),
    ("truncated.glb", "truncated GLB"),
    ("short_buffer.gltf", "accessor 0: needs bytes 0..1200 of bufferView 0"),
    ("truncated_bin.gltf", "'truncated_bin.bin' holds only"),
    ("missing_bin.gltf", "no_such_buffer.bin"),
    ("bad_base64.gltf", "malformed base64"),
    (
        "index_out_of_range.gltf",
        "mesh 'Statue' primitive 0: index 8 out of range (8 vertices)",
    ),
    (
        "nan_position.gltf",
        "mesh 'Statue' primitive 0: vertex 5 has a non-finite position",
    ),
    (
        "required_extension.gltf",
        "required extension 'KHR_draco_mesh_compression' is not supported",
    ),
    (
        "position_accessor_out_of_range.gltf",
        "mesh 0 primitive 0 names accessor 7 (there are",
    ),
    ("orthographic.gltf", "orthographic cameras are unsupported"),
    ("node_cycle.gltf", "reached twice"),
    ("malformed.toml", "TOML parse error at line 4"),
    ("unknown_key.toml", "unknown field `heigth`"),
    ("wrong_type.toml", "invalid type: string \"wide\", expected u32"),
    (
        "unknown_material.toml",
        "no glTF material named 'Statue' (available: 'White')",
    ),
    ("unknown_kind.toml", "unknown kind 'metal'"),
    ("unknown_camera.toml", "camera = \"Overview\""),
    ("g_one.toml", "g = 1 must satisfy -1 < g < 1"),
    ("negative_sigma.toml", "must be finite and non-negative"),
    (
        "region_no_mesh.toml",
        "region 'Teapot' names no glTF mesh (meshes: 'Box', 'Plane')",
    ),
    ("open_region.toml", "must be a closed mesh"),
    ("absurd_resolution.toml", "absurd resolution"),
    ("missing_grid.toml", "no_such_grid.bgrid"),
    ("bad_grid.toml", "not_a_grid.bgrid: not a beamlight density grid"),
    ("vdb_missing_file.toml", "no_such_volume.vdb"),
    ("vdb_truncated.toml", "truncated.vdb: corrupt or truncated OpenVDB file"),
    (
        "vdb_unknown_grid.toml",
        "no grid named 'smoke' (grids: 'density', 'temperature', 'velocity')",
    ),
    ("vdb_not_float.toml", "a density must be a float grid"),
    (
        "perlin_bad_octaves.toml",
        "line 8, column 47: [[media]] 'smoke': density.perlin.octaves = 0 must be between 1 and 16",
    ),
    ("phong_energy.toml", "not energy conserving"),
    ("two_global.toml", "at most one medium may be global"),
];

/// Files in the corpus directory that are not cases themselves.
const HELPERS: &[&str] = &[
    "README.md",
    "_valid_box.gltf",
    "truncated_bin.bin",
    "not_a_grid.bgrid",
    "truncated.vdb",
];

#[test]
fn bad_scenes_fail_with_clear_messages() {
    let dir = workspace().join("tests/bad_scenes");
    let mut failures = Vec::new();
    for (file, fragment) in BAD_SCENES {
        let path = dir.join(file);
        assert!(path.exists(), "{} is missing", path.display());
        let result = std::panic::catch_unwind(|| load_scene(&path));
        let msg = match result {
            Err(_) => format!("{file}: PANICKED"),
            Ok(Ok(_)) => format!("{file}: loaded without error"),
            Ok(Err(e)) => {
                let m = e.to_string();
                if m.contains(file) && m.contains(fragment) {
                    continue;
                }
                format!("{file}: message lacks the file name or '{fragment}': {m}")
            }
        };
        failures.push(msg);
    }
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
    // Every file in the directory is a listed case or a known helper.
    for entry in std::fs::read_dir(&dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        assert!(
            BAD_SCENES.iter().any(|(f, _)| *f == name) || HELPERS.contains(&name.as_str()),
            "{name} in tests/bad_scenes is not in the test's table"
        );
    }
    // The helper scene itself is valid.
    load_ok(&dir.join("_valid_box.gltf"));
}

#[test]
fn missing_top_level_file_is_an_io_error_naming_it() {
    let e = load_scene(Path::new("/nonexistent/scene.toml")).unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }));
    assert!(e.to_string().contains("/nonexistent/scene.toml"));
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "scene.obj", "v 0 0 0\n");
    assert!(load_err(&p).contains("unknown scene file type"));
}

/// Cutting a valid GLB or glTF anywhere, or flipping bytes, gives errors, never panics.
#[test]
fn truncated_and_corrupted_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let glb = feature_scene().to_glb_bytes();
    let gltf = feature_scene().to_json_string().into_bytes();
    let path_glb = dir.path().join("cut.glb");
    let path_gltf = dir.path().join("cut.gltf");
    let step = (glb.len() / 200).max(1);
    for len in (0..glb.len()).step_by(step) {
        std::fs::write(&path_glb, &glb[..len]).unwrap();
        let r = std::panic::catch_unwind(|| load_scene(&path_glb));
        let r = r.unwrap_or_else(|_| panic!("panic on GLB cut at {len}"));
        let e = r.expect_err("a truncated GLB cannot load").to_string();
        assert!(e.contains("cut.glb"), "{e}");
    }
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut rand = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for round in 0..300 {
        let (src, path) = if round % 2 == 0 {
            (&glb, &path_glb)
        } else {
            (&gltf, &path_gltf)
        };
        let mut bytes = src.clone();
        for _ in 0..1 + rand() % 4 {
            let at = (rand() % bytes.len() as u64) as usize;
            bytes[at] = (rand() & 0xff) as u8;
        }
        std::fs::write(path, &bytes).unwrap();
        let r = std::panic::catch_unwind(|| load_scene(path));
        assert!(r.is_ok(), "panic on corrupted file (round {round})");
    }
}

#[test]
fn bundled_assets_load() {
    let scenes = workspace().join("assets/scenes");
    let cornell = load_ok(&scenes.join("cornell.toml"));
    assert_eq!((cornell.render.width, cornell.render.height), (256, 256));
    assert!(cornell.media.is_empty());
    assert!(cornell.warnings.is_empty(), "{:?}", cornell.warnings);
    let lights: Vec<_> = cornell.materials.iter().filter(|m| m.is_emissive()).collect();
    assert_eq!(lights.len(), 1);
    assert!(lights[0].emission.min_element() >= 10.0 && lights[0].emission.max_element() <= 20.0);
    // The light faces down, and the camera is inside the closed room.
    for t in cornell
        .triangles
        .iter()
        .filter(|t| cornell.materials[t.material as usize].is_emissive())
    {
        assert!(approx(t.cross().normalize(), Vec3::NEG_Y, 1e-6));
    }
    let (lo, hi) = cornell.bounds();
    let cam = cornell.camera.position();
    assert!(cam.cmpgt(lo).all() && cam.cmplt(hi).all());

    let fog = load_ok(&scenes.join("cornell_fog.toml"));
    assert_eq!(fog.triangles.len(), cornell.triangles.len());
    assert_eq!(fog.global_medium, Some(0));
    let m = &fog.media[0];
    assert!(m.sigma_s.min_element() > 0.0 && m.sigma_a.min_element() >= 0.0 && m.g.abs() < 1.0);
    let sphere = fog.materials.iter().find(|m| m.name == "Sphere").unwrap();
    assert!(matches!(sphere.bsdf, Some(Bsdf::Phong { exponent: 80.0, .. })));

    let furnace = load_ok(&scenes.join("furnace.toml"));
    assert_eq!(furnace.global_medium, Some(0));
    assert_eq!(furnace.media[0].sigma_a, Vec3::ZERO);
    assert!(furnace.warnings.is_empty(), "{:?}", furnace.warnings);
    for t in &furnace.triangles {
        let m = &furnace.materials[t.material as usize];
        assert_eq!(m.emission, Vec3::ONE);
        assert_eq!(
            m.bsdf,
            Some(Bsdf::Lambert {
                albedo: Vec3::splat(0.5)
            })
        );
        // Emitting faces point into the box (towards its centre, where the camera is).
        let c = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        assert!(t.cross().dot(-c) > 0.0);
    }
    assert!(approx(furnace.camera.position(), Vec3::ZERO, 1e-6));
}

/// A quad "Q" written by the builder, as JSON to patch.
fn quad_json() -> serde_json::Value {
    let mut b = GltfBuilder::new();
    let (p, i) = shapes::quad(Vec3::ZERO, Vec3::X, Vec3::Y);
    b.mesh("Q", &p, &i, None, None);
    b.camera_look_at("C", Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 0.5, None);
    serde_json::from_str(&b.to_json_string()).unwrap()
}

#[test]
fn strips_fans_and_skipped_modes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.gltf");
    let tris_for = |mode: u32, drop_indices: bool| {
        let mut v = quad_json();
        v["meshes"][0]["primitives"][0]["mode"] = serde_json::json!(mode);
        if drop_indices {
            v["meshes"][0]["primitives"][0]
                .as_object_mut()
                .unwrap()
                .remove("indices");
        }
        std::fs::write(&path, serde_json::to_string(&v).unwrap()).unwrap();
        load_ok(&path)
    };
    // Vertices 0,1,2,3 = (0,0),(1,0),(1,1),(0,1): as a fan both triangles face +Z.
    let s = tris_for(6, true);
    assert_eq!(s.triangles.len(), 2);
    assert!(s.triangles.iter().all(|t| approx(t.cross().normalize(), Vec3::Z, 1e-6)));
    // A strip over (0,0),(1,0),(0,1),(1,1): triangles {0,1,2} and {1,3,2} (the spec's order
    // for odd triangles), both facing +Z.
    let mut b = GltfBuilder::new();
    let strip = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
    b.mesh("Strip", &strip, &[], None, None);
    let mut v: serde_json::Value = serde_json::from_str(&b.to_json_string()).unwrap();
    v["meshes"][0]["primitives"][0]["mode"] = serde_json::json!(5);
    std::fs::write(&path, serde_json::to_string(&v).unwrap()).unwrap();
    let s = load_ok(&path);
    assert_eq!(s.triangles.len(), 2);
    assert_eq!(s.triangles[1].p, [strip[1], strip[3], strip[2]]);
    assert!(s.triangles.iter().all(|t| approx(t.cross().normalize(), Vec3::Z, 1e-6)));
    // Lines and points are skipped with a warning.
    for mode in [0, 1, 3] {
        let s = tris_for(mode, false);
        assert!(s.triangles.is_empty());
        assert!(
            s.warnings.iter().any(|w| w.contains("not triangles")),
            "{:?}",
            s.warnings
        );
    }
}

#[test]
fn sparse_accessors_and_external_buffers() {
    use base64::Engine as _;
    let dir = tempfile::tempdir().unwrap();
    let mut v = quad_json();
    // Sparse: vertex 2 moves to (1, 1, 1).
    let mut extra = vec![2u8, 0, 0, 0];
    for c in [1.0f32, 1.0, 1.0] {
        extra.extend_from_slice(&c.to_le_bytes());
    }
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&extra)
    );
    v["buffers"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({ "byteLength": 16, "uri": uri }));
    let views = v["bufferViews"].as_array_mut().unwrap();
    views.push(serde_json::json!({ "buffer": 1, "byteOffset": 0, "byteLength": 1 }));
    views.push(serde_json::json!({ "buffer": 1, "byteOffset": 4, "byteLength": 12 }));
    let (iv, vv) = (views.len() - 2, views.len() - 1);
    v["accessors"][0]["sparse"] = serde_json::json!({
        "count": 1,
        "indices": { "bufferView": iv, "componentType": 5121 },
        "values": { "bufferView": vv }
    });
    v["accessors"][0]["max"] = serde_json::json!([1.0, 1.0, 1.0]);
    // Buffer 0 moves to an external file whose name needs escaping.
    let b0 = v["buffers"][0]["uri"].as_str().unwrap().to_string();
    let bytes = base64::engine::general_purpose::STANDARD
        .decode(&b0[b0.find(',').unwrap() + 1..])
        .unwrap();
    std::fs::write(dir.path().join("my buffer.bin"), &bytes).unwrap();
    v["buffers"][0]["uri"] = serde_json::json!("my%20buffer.bin");
    let path = dir.path().join("sparse.gltf");
    std::fs::write(&path, serde_json::to_string(&v).unwrap()).unwrap();
    let s = load_ok(&path);
    assert_eq!(s.triangles[0].p[2], Vec3::new(1.0, 1.0, 1.0));
    assert_eq!(s.triangles[1].p[1], Vec3::new(1.0, 1.0, 1.0));
    // An out-of-range sparse index is an error naming the accessor.
    v["accessors"][0]["sparse"]["count"] = serde_json::json!(1);
    let mut extra_bad = extra.clone();
    extra_bad[0] = 9;
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&extra_bad)
    );
    v["buffers"][1]["uri"] = serde_json::json!(uri);
    std::fs::write(&path, serde_json::to_string(&v).unwrap()).unwrap();
    let e = load_err(&path);
    assert!(
        e.contains("sparse.gltf") && e.contains("accessor 0: sparse index 9 out of range (4 elements)"),
        "{e}"
    );
}

#[test]
fn camera_by_camera_name_and_instanced_region_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = GltfBuilder::new();
    let (p, i) = shapes::cuboid(Vec3::splat(-0.5), Vec3::splat(0.5), true);
    let cube = b.add_mesh("Puff", &p, &i, None, None);
    b.node(
        NodeDesc::new("PuffA")
            .with_mesh(cube)
            .with_translation(Vec3::new(-2.0, 0.0, 0.0)),
    );
    b.node(
        NodeDesc::new("PuffB")
            .with_mesh(cube)
            .with_translation(Vec3::new(2.0, 0.0, 0.0)),
    );
    b.camera_look_at("CamNode", Vec3::new(0.0, 0.0, 8.0), Vec3::ZERO, Vec3::Y, 0.5, None);
    let mut v: serde_json::Value = serde_json::from_str(&b.to_json_string()).unwrap();
    v["cameras"][0]["name"] = serde_json::json!("Lens");
    std::fs::write(dir.path().join("i.gltf"), serde_json::to_string(&v).unwrap()).unwrap();
    let toml = write(
        dir.path(),
        "i.toml",
        "gltf = \"i.gltf\"\n[render]\ncamera = \"Lens\"\n[[media]]\nname = \"smoke\"\nregion = \"PuffB\"\nsigma_s = 2\n",
    );
    let s = load_ok(&toml);
    assert_eq!(s.camera.name.as_deref(), Some("CamNode"));
    // The region was named by a node; every instance of its mesh bounds the medium.
    assert_eq!(s.triangles.len(), 24);
    assert!(s.triangles.iter().all(|t| t.interface
        == Some(MediumInterface {
            inside: Some(0),
            outside: None
        })));
    assert_eq!(s.global_medium, None);
}

// ---------------------------------------------------------------------------------------------
// Base-colour textures
// ---------------------------------------------------------------------------------------------

/// The exact sRGB EOTF, written out independently of the loader.
fn srgb8(c: u8) -> f32 {
    let c = c as f64 / 255.0;
    (if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }) as f32
}

fn srgb_rgb(c: [u8; 3]) -> Vec3 {
    Vec3::new(srgb8(c[0]), srgb8(c[1]), srgb8(c[2]))
}

fn encode_png(w: u32, h: u32, bytes: &[u8], color: image::ExtendedColorType) -> Vec<u8> {
    let mut png = Vec::new();
    image::ImageEncoder::write_image(image::codecs::png::PngEncoder::new(&mut png), bytes, w, h, color).unwrap();
    png
}

fn data_uri(mime: &str, bytes: &[u8]) -> String {
    use base64::Engine as _;
    format!(
        "data:{mime};base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// 4×2 texels, row 0 first (v = 0 is the top row).
const TEXELS: [[u8; 3]; 8] = [
    [0, 0, 0],
    [255, 255, 255],
    [10, 20, 30],
    [128, 64, 200],
    [1, 2, 3],
    [250, 100, 40],
    [77, 77, 77],
    [200, 0, 255],
];
const FACTOR: [f32; 3] = [1.0, 0.5, 0.25];
/// uv of the floor quad's corners (p0 = (−1, 0, 1), p1 = (1, 0, 1), p2 = (1, 0, −1), p3 = (−1, 0, −1)).
const QUAD_UV: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];

/// A floor quad with material "Checker" = `FACTOR` × the 4×2 texture `TEXELS` (clamped).
fn textured_scene() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let t = b.texture_png("checker", 4, 2, &TEXELS, Wrap::ClampToEdge, Wrap::ClampToEdge);
    let m = b.material(MaterialDesc::lambert("Checker", FACTOR).with_base_color_texture(t));
    let (p, i) = shapes::quad(Vec3::new(-1.0, 0.0, 1.0), Vec3::X * 2.0, Vec3::NEG_Z * 2.0);
    let mesh = b.mesh("Floor", &p, &i, None, Some(m));
    b.texcoords(mesh, &QUAD_UV.map(Vec2::from));
    b.camera_look_at("Cam", Vec3::new(0.0, 3.0, 0.1), Vec3::ZERO, Vec3::Y, 0.8, None);
    b
}

fn textured_json() -> serde_json::Value {
    serde_json::from_str(&textured_scene().to_json_string()).unwrap()
}

fn write_json(dir: &Path, name: &str, v: &serde_json::Value) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, serde_json::to_string(v).unwrap()).unwrap();
    p
}

fn material_index(s: &Scene, name: &str) -> u32 {
    s.materials.iter().position(|m| m.name == name).unwrap() as u32
}

/// Everything a correctly loaded `textured_scene` (or a variant) must show.
fn check_textured(s: &Scene) {
    assert!(
        s.warnings.iter().all(|w| !w.contains("textur") && !w.contains("image")),
        "{:?}",
        s.warnings
    );
    assert_eq!(s.textures.len(), 1);
    let tex = &s.textures[0];
    assert_eq!((tex.width(), tex.height()), (4, 2));
    assert_eq!((tex.wrap_s(), tex.wrap_t()), (Wrap::ClampToEdge, Wrap::ClampToEdge));
    for y in 0..2 {
        for x in 0..4 {
            // Exactly the sRGB EOTF of the stored bytes, first texel in memory at (0, 0).
            assert_eq!(
                tex.texel(x, y),
                srgb_rgb(TEXELS[(y * 4 + x) as usize]),
                "texel ({x}, {y})"
            );
        }
    }
    let m = material_index(s, "Checker");
    let mat = &s.materials[m as usize];
    assert_eq!(mat.base_color_texture, Some(0));
    assert_eq!(
        mat.bsdf,
        Some(Bsdf::Lambert {
            albedo: Vec3::from(FACTOR)
        })
    );
    for t in &s.triangles {
        let uv = t.uv.expect("textured triangles have uvs");
        for k in 0..3 {
            // Recover which quad corner this vertex is.
            let corner = (0..4)
                .find(|&c| {
                    let q = [
                        Vec3::new(-1.0, 0.0, 1.0),
                        Vec3::new(1.0, 0.0, 1.0),
                        Vec3::new(1.0, 0.0, -1.0),
                        Vec3::new(-1.0, 0.0, -1.0),
                    ];
                    q[c] == t.p[k]
                })
                .unwrap();
            assert_eq!(uv[k], Vec2::from(QUAD_UV[corner]));
        }
    }
    // At a texel centre the BSDF's albedo is factor × that texel.
    for (x, y) in [(0u32, 0u32), (3, 0), (1, 1), (2, 1)] {
        let uv = Vec2::new((x as f32 + 0.5) / 4.0, (y as f32 + 0.5) / 2.0);
        let want = Vec3::from(FACTOR) * srgb_rgb(TEXELS[(y * 4 + x) as usize]);
        assert_eq!(s.bsdf_at(m, Some(uv)), Some(Bsdf::Lambert { albedo: want }));
    }
    // No uv: the factor alone.
    assert_eq!(s.bsdf_at(m, None), mat.bsdf);
}

#[test]
fn base_color_texture_from_buffer_view_glb_data_uri_and_file() {
    let dir = tempfile::tempdir().unwrap();
    // bufferView in a .gltf (embedded buffer) and in a .glb (BIN chunk).
    let gltf = dir.path().join("t.gltf");
    textured_scene().write_gltf(&gltf).unwrap();
    check_textured(&load_ok(&gltf));
    let glb = dir.path().join("t.glb");
    textured_scene().write_glb(&glb).unwrap();
    check_textured(&load_ok(&glb));

    let bytes: Vec<u8> = TEXELS.iter().flatten().copied().collect();
    let png = encode_png(4, 2, &bytes, image::ExtendedColorType::Rgb8);
    // A data URI (no mimeType: the data URI's type is used).
    let mut v = textured_json();
    v["images"][0] = serde_json::json!({ "uri": data_uri("image/png", &png) });
    check_textured(&load_ok(&write_json(dir.path(), "d.gltf", &v)));
    // A file relative to the glTF, %-escaped.
    std::fs::create_dir(dir.path().join("tex dir")).unwrap();
    std::fs::write(dir.path().join("tex dir/wood 1.png"), &png).unwrap();
    v["images"][0] = serde_json::json!({ "uri": "tex%20dir/wood%201.png" });
    let s = load_ok(&write_json(dir.path(), "f.gltf", &v));
    check_textured(&s);
    assert_eq!(s.textures[0].name(), "image 0 'tex%20dir/wood%201.png'");

    // A few sRGB values against published numbers, too.
    let t = &s.textures[0];
    assert_eq!(t.texel(0, 0), Vec3::ZERO);
    assert_eq!(t.texel(1, 0), Vec3::ONE);
    assert_eq!(t.texel(2, 0).x, (10.0f64 / 255.0 / 12.92) as f32); // linear segment
    assert!((t.texel(3, 0).x - 0.215_860_5).abs() < 1e-7, "{}", t.texel(3, 0).x); // sRGB 128
}

#[test]
fn textures_are_shared_and_wrap_modes_come_from_the_sampler() {
    let dir = tempfile::tempdir().unwrap();
    let mut v = textured_json();
    // Three more materials: one on the same texture, one on the same image with another
    // sampler, one on the same image without a sampler (REPEAT).
    let base = v["materials"][0].clone();
    for (name, tex) in [("Same", 0), ("Mirrored", 1), ("NoSampler", 2)] {
        let mut m = base.clone();
        m["name"] = serde_json::json!(name);
        m["pbrMetallicRoughness"]["baseColorTexture"]["index"] = serde_json::json!(tex);
        v["materials"].as_array_mut().unwrap().push(m);
    }
    v["samplers"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({ "wrapS": 33648, "wrapT": 10497 }));
    let textures = v["textures"].as_array_mut().unwrap();
    textures.push(serde_json::json!({ "sampler": 1, "source": 0 }));
    textures.push(serde_json::json!({ "source": 0 }));
    // Give every material a floor of its own.
    let prim = v["meshes"][0]["primitives"][0].clone();
    for m in 1..4 {
        let mut p = prim.clone();
        p["material"] = serde_json::json!(m);
        v["meshes"][0]["primitives"].as_array_mut().unwrap().push(p);
    }
    let s = load_ok(&write_json(dir.path(), "w.gltf", &v));
    assert_eq!(s.textures.len(), 3, "{:?}", s.textures);
    let tex_of = |name: &str| {
        s.materials[material_index(&s, name) as usize]
            .base_color_texture
            .unwrap()
    };
    assert_eq!(tex_of("Checker"), tex_of("Same"));
    let wraps = |t: u32| (s.textures[t as usize].wrap_s(), s.textures[t as usize].wrap_t());
    assert_eq!(wraps(tex_of("Checker")), (Wrap::ClampToEdge, Wrap::ClampToEdge));
    assert_eq!(wraps(tex_of("Mirrored")), (Wrap::MirroredRepeat, Wrap::Repeat));
    assert_eq!(wraps(tex_of("NoSampler")), (Wrap::Repeat, Wrap::Repeat));
    assert_eq!(s.triangles.len(), 8);
    assert!(s.triangles.iter().all(|t| t.uv.is_some()));

    // The wrap modes at work, through bsdf_at.
    let albedo = |name: &str, u: f32, v: f32| match s.bsdf_at(material_index(&s, name), Some(Vec2::new(u, v))) {
        Some(Bsdf::Lambert { albedo }) => albedo,
        other => panic!("{other:?}"),
    };
    let f = Vec3::from(FACTOR);
    let texel = |x: usize, y: usize| f * srgb_rgb(TEXELS[y * 4 + x]);
    // Clamp: far outside gives the edge texels.
    assert_eq!(albedo("Checker", -3.0, 0.1), texel(0, 0));
    assert_eq!(albedo("Checker", 7.0, 9.0), texel(3, 1));
    // Repeat: shifted by whole periods.
    assert_eq!(albedo("NoSampler", 2.375, -0.75), texel(1, 0));
    // Mirrored in u: u and −u and 2 − u agree; repeat in v.
    assert_eq!(albedo("Mirrored", -0.375, 0.25), texel(1, 0));
    assert_eq!(albedo("Mirrored", 1.625, 1.25), texel(1, 0));
    // Bilinear halfway between two texel centres.
    let mid = albedo("Checker", 0.25, 0.25);
    assert!(approx(mid, 0.5 * (texel(0, 0) + texel(1, 0)), 1e-6), "{mid}");
}

/// Replaces the quad's TEXCOORD_0 with `bytes` (in a new buffer) read as `component`.
fn with_integer_texcoords(component: u32, bytes: &[u8], stride: Option<usize>, normalized: bool) -> serde_json::Value {
    let mut v = textured_json();
    v["buffers"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({ "byteLength": bytes.len(), "uri": data_uri("application/octet-stream", bytes) }));
    let nb = v["buffers"].as_array().unwrap().len() - 1;
    let mut view = serde_json::json!({ "buffer": nb, "byteLength": bytes.len() });
    if let Some(s) = stride {
        view["byteStride"] = serde_json::json!(s);
    }
    v["bufferViews"].as_array_mut().unwrap().push(view);
    let nv = v["bufferViews"].as_array().unwrap().len() - 1;
    v["accessors"].as_array_mut().unwrap().push(serde_json::json!({
        "bufferView": nv, "componentType": component, "normalized": normalized, "count": 4, "type": "VEC2"
    }));
    let na = v["accessors"].as_array().unwrap().len() - 1;
    v["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = serde_json::json!(na);
    v
}

#[test]
fn normalized_integer_texcoords_and_texcoord_sets() {
    let dir = tempfile::tempdir().unwrap();
    let corner_uv = |s: &Scene, corner: Vec3| {
        let t = s.triangles.iter().find(|t| t.p.contains(&corner)).unwrap();
        t.uv.unwrap()[t.p.iter().position(|p| *p == corner).unwrap()]
    };
    let p0 = Vec3::new(-1.0, 0.0, 1.0);
    let p2 = Vec3::new(1.0, 0.0, -1.0);
    // UNSIGNED_BYTE, padded to a 4-byte stride.
    let u8s = [0u8, 255, 0, 0, 255, 255, 0, 0, 51, 204, 0, 0, 7, 0, 0, 0];
    let s = load_ok(&write_json(
        dir.path(),
        "u8.gltf",
        &with_integer_texcoords(5121, &u8s, Some(4), true),
    ));
    assert_eq!(corner_uv(&s, p0), Vec2::new(0.0, 1.0));
    assert_eq!(corner_uv(&s, p2), Vec2::new(51.0 / 255.0, 204.0 / 255.0));
    // UNSIGNED_SHORT, tightly packed.
    let u16s: Vec<u8> = [0u16, 65535, 65535, 65535, 13107, 52428, 1, 0]
        .iter()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    let s = load_ok(&write_json(
        dir.path(),
        "u16.gltf",
        &with_integer_texcoords(5123, &u16s, None, true),
    ));
    assert_eq!(corner_uv(&s, p0), Vec2::new(0.0, 1.0));
    assert_eq!(corner_uv(&s, p2), Vec2::new(13107.0 / 65535.0, 52428.0 / 65535.0));
    // Not normalized: KHR_mesh_quantization territory.
    let p = write_json(
        dir.path(),
        "raw.gltf",
        &with_integer_texcoords(5121, &u8s, Some(4), false),
    );
    let e = load_err(&p);
    assert!(
        e.contains("raw.gltf") && e.contains("TEXCOORD_0: accessor 3 is UNSIGNED_BYTE VEC2 but not normalized"),
        "{e}"
    );
    // A FLOAT VEC3 accessor is not texture coordinates.
    let mut v = textured_json();
    v["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = serde_json::json!(0);
    let e = load_err(&write_json(dir.path(), "vec3.gltf", &v));
    assert!(e.contains("TEXCOORD_0: accessor 0 is FLOAT VEC3, expected VEC2"), "{e}");

    // texCoord = 1 reads TEXCOORD_1.
    let mut v = textured_json();
    let attrs = &mut v["meshes"][0]["primitives"][0]["attributes"];
    attrs["TEXCOORD_1"] = attrs["TEXCOORD_0"].clone();
    attrs["TEXCOORD_0"] = serde_json::json!(0); // would be an error if it were read
    v["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = serde_json::json!(1);
    let s = load_ok(&write_json(dir.path(), "set1.gltf", &v));
    assert_eq!(corner_uv(&s, p0), Vec2::new(0.0, 1.0));
    // ...and without TEXCOORD_1, uv (0, 0) with a warning.
    v["meshes"][0]["primitives"][0]["attributes"]
        .as_object_mut()
        .unwrap()
        .remove("TEXCOORD_1");
    let s = load_ok(&write_json(dir.path(), "noset.gltf", &v));
    assert!(s.triangles.iter().all(|t| t.uv == Some([Vec2::ZERO; 3])));
    assert_eq!(
        s.warnings.iter().filter(|w| w.contains("no TEXCOORD_1")).count(),
        1,
        "{:?}",
        s.warnings
    );
    // A NaN texture coordinate is an error naming the vertex.
    let nan: Vec<u8> = [0.0f32, 0.0, 1.0, f32::NAN, 1.0, 1.0, 0.0, 1.0]
        .iter()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    let mut v = with_integer_texcoords(5126, &nan, None, false);
    v["bufferViews"].as_array_mut().unwrap().last_mut().unwrap()["byteLength"] = serde_json::json!(32);
    let e = load_err(&write_json(dir.path(), "nan.gltf", &v));
    assert!(e.contains("vertex 1 has a non-finite TEXCOORD_0"), "{e}");
}

#[test]
fn broken_images_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let bytes: Vec<u8> = TEXELS.iter().flatten().copied().collect();
    let png = encode_png(4, 2, &bytes, image::ExtendedColorType::Rgb8);
    let mut garbage = png[..16].to_vec();
    garbage.extend_from_slice(&[0x5a; 64]);
    let cases: Vec<(&str, serde_json::Value, &str)> = vec![
        (
            "missing.gltf",
            serde_json::json!({ "uri": "no_such_wood.png" }),
            "image 0 'no_such_wood.png': cannot read '",
        ),
        (
            "corrupt.gltf",
            serde_json::json!({ "name": "wood", "uri": data_uri("image/png", &garbage) }),
            "image 0 'wood': cannot decode: ",
        ),
        (
            "truncated.gltf",
            serde_json::json!({ "uri": data_uri("image/png", &png[..png.len() / 2]) }),
            "image 0: cannot decode: ",
        ),
        (
            "notimage.gltf",
            serde_json::json!({ "uri": data_uri("image/png", b"hello, world") }),
            "image 0: cannot decode: not a PNG or JPEG image",
        ),
        (
            "remote.gltf",
            serde_json::json!({ "uri": "https://example.com/wood.png" }),
            "remote uri 'https://example.com/wood.png' is not supported",
        ),
        (
            "nothing.gltf",
            serde_json::json!({}),
            "has neither a uri nor a bufferView",
        ),
        (
            "badview.gltf",
            serde_json::json!({ "bufferView": 0, "mimeType": "image/png" }),
            "cannot decode",
        ),
    ];
    for (file, image, fragment) in cases {
        let mut v = textured_json();
        v["images"][0] = image;
        let e = load_err(&write_json(dir.path(), file, &v));
        assert!(
            e.contains(file) && e.contains("material 'Checker' baseColorTexture: ") && e.contains(fragment),
            "{file}: {e}"
        );
        if file == "missing.gltf" {
            assert!(e.contains("no_such_wood.png"), "{e}");
        }
    }
    // A sampler with an invalid wrap mode fails validation with a message naming it.
    let mut v = textured_json();
    v["samplers"][0]["wrapS"] = serde_json::json!(12345);
    let e = load_err(&write_json(dir.path(), "wrap.gltf", &v));
    assert!(e.contains("wrap.gltf") && e.contains("wrapS"), "{e}");
}

#[test]
fn unsupported_image_types_fall_back_to_the_factor() {
    let dir = tempfile::tempdir().unwrap();
    let webp = b"RIFF\x10\0\0\0WEBPVP8 \x04\0\0\0\0\0\0\0";
    for (file, image, fragment) in [
        (
            "ktx.gltf",
            serde_json::json!({ "bufferView": 0, "mimeType": "image/ktx2" }),
            "'image/ktx2' images are not supported",
        ),
        (
            "webp_uri.gltf",
            serde_json::json!({ "uri": data_uri("image/webp", webp) }),
            "'image/webp' images are not supported",
        ),
        (
            "webp_file.gltf",
            serde_json::json!({ "uri": "wood.webp" }),
            "WebP images are not supported",
        ),
    ] {
        std::fs::write(dir.path().join("wood.webp"), webp).unwrap();
        let mut v = textured_json();
        v["images"][0] = image;
        let s = load_ok(&write_json(dir.path(), file, &v));
        let m = &s.materials[material_index(&s, "Checker") as usize];
        assert_eq!(m.base_color_texture, None);
        assert_eq!(
            m.bsdf,
            Some(Bsdf::Lambert {
                albedo: Vec3::from(FACTOR)
            })
        );
        assert!(s.textures.is_empty() && s.triangles.iter().all(|t| t.uv.is_none()));
        let warned: Vec<_> = s.warnings.iter().filter(|w| w.contains(fragment)).collect();
        assert_eq!(warned.len(), 1, "{file}: {:?}", s.warnings);
        assert!(
            warned[0].starts_with(&format!("{file}: material 'Checker' baseColorTexture: image 0")),
            "{}",
            warned[0]
        );
    }
}

#[test]
fn jpeg_sixteen_bit_grey_and_alpha_images() {
    let dir = tempfile::tempdir().unwrap();
    let load_image = |name: &str, uri: String| {
        let mut v = textured_json();
        v["images"][0] = serde_json::json!({ "uri": uri });
        let s = load_ok(&write_json(dir.path(), name, &v));
        s.textures[0].clone()
    };
    // JPEG (lossy: within 2 code values of a flat colour).
    let mut jpg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpg, 100)
        .encode(&[200u8, 100, 50].repeat(64), 8, 8, image::ExtendedColorType::Rgb8)
        .unwrap();
    let t = load_image("jpg.gltf", data_uri("image/jpeg", &jpg));
    assert_eq!((t.width(), t.height()), (8, 8));
    for (c, want) in [200u8, 100, 50].into_iter().enumerate() {
        let got = t.texel(3, 5)[c];
        assert!(got >= srgb8(want - 2) && got <= srgb8(want + 2), "channel {c}: {got}");
    }
    // 16-bit PNG: full precision through the EOTF.
    let v16 = [0u16, 32768, 65535, 1000, 3000, 60000];
    let bytes: Vec<u8> = v16.iter().flat_map(|c| c.to_ne_bytes()).collect(); // the encoder takes native order
    let png16 = encode_png(2, 1, &bytes, image::ExtendedColorType::Rgb16);
    let t = load_image("png16.gltf", data_uri("image/png", &png16));
    let eotf16 = |c: u16| {
        let c = c as f64 / 65535.0;
        (if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }) as f32
    };
    for x in 0..2 {
        for c in 0..3 {
            assert_eq!(
                t.texel(x, 0)[c],
                eotf16(v16[3 * x as usize + c]),
                "texel {x} channel {c}"
            );
        }
    }
    // RGBA: alpha ignored (not premultiplied).
    let rgba = encode_png(1, 1, &[90, 180, 250, 0], image::ExtendedColorType::Rgba8);
    let t = load_image("rgba.gltf", data_uri("image/png", &rgba));
    assert_eq!(t.texel(0, 0), srgb_rgb([90, 180, 250]));
    // Grey: replicated to RGB.
    let grey = encode_png(2, 1, &[33, 222], image::ExtendedColorType::L8);
    let t = load_image("grey.gltf", data_uri("image/png", &grey));
    assert_eq!(t.texel(1, 0), srgb_rgb([222; 3]));
}

#[test]
fn textures_with_material_overrides() {
    let dir = tempfile::tempdir().unwrap();
    // Every texel ≤ sRGB 188 (linear ≈ 0.503).
    let texels = [[188u8, 100, 50], [20, 188, 0], [0, 0, 188], [188, 188, 188]];
    let max = srgb8(188);
    let mut b = GltfBuilder::new();
    let t = b.texture_png("dim", 2, 2, &texels, Wrap::Repeat, Wrap::Repeat);
    let (p, i) = shapes::quad(Vec3::new(-1.0, 0.0, 1.0), Vec3::X * 2.0, Vec3::NEG_Z * 2.0);
    for (k, name) in ["Lam", "LamAlbedo", "Pho", "PhoDiffuse", "Glassy", "Mirror"]
        .iter()
        .enumerate()
    {
        let mut m = MaterialDesc::lambert(name, [1.0; 3]).with_base_color_texture(t);
        if *name == "Glassy" {
            m.transmission = 1.0;
        }
        let m = b.material(m);
        let mesh = b.add_mesh(name, &p, &i, None, Some(m));
        b.node(
            NodeDesc::new(name)
                .with_mesh(mesh)
                .with_translation(Vec3::new(0.0, k as f32, 0.0)),
        );
        b.texcoords(mesh, &QUAD_UV.map(Vec2::from));
    }
    b.camera_look_at("Cam", Vec3::new(0.0, 3.0, 9.0), Vec3::ZERO, Vec3::Y, 0.8, None);
    b.write_gltf(&dir.path().join("o.gltf")).unwrap();
    let sections = |phong_specular: f32| {
        format!(
            r#"gltf = "o.gltf"
[materials.Lam]
kind = "lambert"
[materials.LamAlbedo]
kind = "lambert"
albedo = 0.3
[materials.Pho]
kind = "phong"
specular = {phong_specular}
exponent = 10
[materials.PhoDiffuse]
kind = "phong"
diffuse = 0.2
specular = 0.3
exponent = 10
[materials.Mirror]
kind = "mirror"
"#
        )
    };
    // 1 × 0.503 + 0.45 ≤ 1: energy conserving although the factor alone (1) would not be.
    let s = load_ok(&write(dir.path(), "o.toml", &sections(0.45)));
    let tex = |name: &str| s.materials[material_index(&s, name) as usize].base_color_texture;
    assert_eq!(tex("Lam"), Some(0));
    assert_eq!(tex("Pho"), Some(0));
    assert_eq!(s.textures.len(), 1, "one texture shared by every material");
    assert_eq!(s.textures[0].max_texel(), Vec3::splat(max));
    for name in ["LamAlbedo", "PhoDiffuse", "Glassy", "Mirror"] {
        assert_eq!(tex(name), None, "{name}");
    }
    let warned: Vec<_> = s
        .warnings
        .iter()
        .filter(|w| w.contains("baseColorTexture ignored"))
        .collect();
    assert_eq!(warned.len(), 1, "{:?}", s.warnings);
    assert!(warned[0].contains("material 'Glassy'"), "{}", warned[0]);
    // Triangles get uvs exactly when their material uses the texture.
    for t in &s.triangles {
        let m = &s.materials[t.material as usize];
        assert_eq!(t.uv.is_some(), m.base_color_texture.is_some(), "{}", m.name);
    }
    let centre = Some(Vec2::new(0.25, 0.25)); // texel (0, 0)
    let t00 = srgb_rgb(texels[0]);
    assert_eq!(
        s.bsdf_at(material_index(&s, "Lam"), centre),
        Some(Bsdf::Lambert { albedo: t00 })
    );
    assert_eq!(
        s.bsdf_at(material_index(&s, "Pho"), centre),
        Some(Bsdf::Phong {
            diffuse: t00,
            specular: Vec3::splat(0.45),
            exponent: 10.0
        })
    );
    assert_eq!(
        s.bsdf_at(material_index(&s, "LamAlbedo"), centre),
        Some(Bsdf::Lambert {
            albedo: Vec3::splat(0.3)
        })
    );
    assert_eq!(
        s.bsdf_at(material_index(&s, "Glassy"), centre),
        Some(Bsdf::Glass {
            ior: 1.5,
            tint: Vec3::ONE
        })
    );
    // 0.503 + 0.55 > 1.
    let e = load_err(&write(dir.path(), "o.toml", &sections(0.55)));
    assert!(
        e.contains("o.toml")
            && e.contains("[materials.Pho]: diffuse × brightest base colour texel + specular")
            && e.contains("not energy conserving"),
        "{e}"
    );
}

/// Flipping bytes inside an embedded PNG gives an error or a scene, never a panic.
#[test]
fn corrupted_images_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let glb = textured_scene().to_glb_bytes();
    let at = glb.windows(8).position(|w| w == b"\x89PNG\r\n\x1a\n").unwrap();
    let png_len = 120.min(glb.len() - at);
    let path = dir.path().join("img.glb");
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rand = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for round in 0..300 {
        let mut bytes = glb.clone();
        for _ in 0..1 + rand() % 3 {
            let k = at + (rand() % png_len as u64) as usize;
            bytes[k] = (rand() & 0xff) as u8;
        }
        std::fs::write(&path, &bytes).unwrap();
        let r = std::panic::catch_unwind(|| load_scene(&path));
        match r {
            Err(_) => panic!("panic on corrupted image (round {round})"),
            Ok(Ok(s)) => assert!(s.textures.iter().all(|t| t.max_texel().cmple(Vec3::ONE).all())),
            Ok(Err(e)) => assert!(e.to_string().contains("img.glb"), "{e}"),
        }
    }
}
