//! The generated part of the broken-scene corpus in `tests/bad_scenes/` (glTF, GLB and buffer
//! files; the `.toml` cases and the README there are written by hand).
use beamlight_testkit::gltf_writer::{GltfBuilder, MaterialDesc, shapes};
use glam::Vec3;
use serde_json::{Value, json};

const DIR: &str = "tests/bad_scenes";

/// A valid scene the TOML cases point at: a closed cube "Box", an open quad "Plane", material
/// "White", camera "Camera".
fn base() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let white = b.material(MaterialDesc::lambert("White", [0.8, 0.8, 0.8]));
    let (p, i) = shapes::cuboid(Vec3::splat(-1.0), Vec3::splat(1.0), true);
    b.mesh("Box", &p, &i, None, Some(white));
    let (p, i) = shapes::quad(
        Vec3::new(-3.0, -1.0, 3.0),
        Vec3::new(6.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -6.0),
    );
    b.mesh("Plane", &p, &i, None, Some(white));
    b.camera_look_at("Camera", Vec3::new(0.0, 0.5, 5.0), Vec3::ZERO, Vec3::Y, 0.8, None);
    b
}

fn patched(f: impl FnOnce(&mut Value)) -> Vec<u8> {
    let mut v: Value = serde_json::from_str(&base().to_json_string()).expect("builder writes JSON");
    f(&mut v);
    let mut s = serde_json::to_string_pretty(&v).expect("serializes");
    s.push('\n');
    s.into_bytes()
}

/// (path relative to the workspace root, contents).
pub fn files() -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(&str, Vec<u8>)> = Vec::new();
    out.push(("_valid_box.gltf", base().to_json_string().into_bytes()));

    out.push((
        "malformed_json.gltf",
        b"{\n  \"asset\": { \"version\": \"2.0\" },\n  \"nodes\": [ { \"name\": \"Box\" ]\n}\n".to_vec(),
    ));

    let glb = base().to_glb_bytes();
    out.push(("truncated.glb", glb[..glb.len() * 3 / 5].to_vec()));

    // The OpenVDB test volume cut to 3/5 of its length (vdb_truncated.toml).
    let vdb = include_bytes!("../../assets/volumes/blob.vdb");
    out.push(("truncated.vdb", vdb[..vdb.len() * 3 / 5].to_vec()));

    // Accessor 0 (the cube's positions) claims 100 vertices; its buffer view holds 8.
    out.push((
        "short_buffer.gltf",
        patched(|v| v["accessors"][0]["count"] = json!(100)),
    ));

    // The external buffer file is shorter than the buffer's byteLength.
    let bin_len = {
        let v: Value = serde_json::from_str(&base().to_json_string()).unwrap();
        v["buffers"][0]["byteLength"].as_u64().unwrap() as usize
    };
    out.push((
        "truncated_bin.gltf",
        patched(|v| v["buffers"][0]["uri"] = json!("truncated_bin.bin")),
    ));
    out.push(("truncated_bin.bin", vec![0u8; bin_len / 2]));

    out.push((
        "missing_bin.gltf",
        patched(|v| v["buffers"][0]["uri"] = json!("no_such_buffer.bin")),
    ));
    out.push((
        "bad_base64.gltf",
        patched(|v| v["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@not base64@@")),
    ));

    // Index 8 into a mesh with 8 vertices.
    {
        let mut b = GltfBuilder::new();
        let (p, mut i) = shapes::cuboid(Vec3::splat(-1.0), Vec3::splat(1.0), true);
        i[17] = 8;
        b.mesh("Statue", &p, &i, None, None);
        out.push(("index_out_of_range.gltf", b.to_json_string().into_bytes()));
    }
    // A NaN vertex position.
    {
        let mut b = GltfBuilder::new();
        let (mut p, i) = shapes::cuboid(Vec3::splat(-1.0), Vec3::splat(1.0), true);
        p[5].y = f32::NAN;
        b.mesh("Statue", &p, &i, None, None);
        out.push(("nan_position.gltf", b.to_json_string().into_bytes()));
    }
    // A primitive's POSITION names an accessor that does not exist (found by `cargo xtask
    // fuzz`: the gltf crate's validator panicked on it).
    out.push((
        "position_accessor_out_of_range.gltf",
        patched(|v| v["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(7)),
    ));
    out.push((
        "required_extension.gltf",
        patched(|v| {
            v["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
            v["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
        }),
    ));
    out.push((
        "orthographic.gltf",
        patched(|v| {
            v["cameras"][0] = json!({
                "name": "Camera", "type": "orthographic",
                "orthographic": { "xmag": 1.0, "ymag": 1.0, "znear": 0.01, "zfar": 100.0 }
            })
        }),
    ));
    out.push((
        "node_cycle.gltf",
        patched(|v| {
            v["nodes"][0]["children"] = json!([1]);
            v["nodes"][1]["children"] = json!([0]);
            v["scenes"][0]["nodes"] = json!([0, 2]);
        }),
    ));
    // Not a density grid (wrong magic).
    out.push(("not_a_grid.bgrid", b"this is not a grid file\n".to_vec()));

    out.into_iter()
        .map(|(name, bytes)| (format!("{DIR}/{name}"), bytes))
        .collect()
}
