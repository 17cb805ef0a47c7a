//! glTF loading: arbitrary bytes as a `.gltf` (JSON) or, when they start with the GLB magic, a
//! `.glb` file.
#![no_main]
#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let name = if data.starts_with(b"glTF") { "scene.glb" } else { "scene.gltf" };
    common::load(name, data);
});
