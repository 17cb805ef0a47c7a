//! The TOML sidecar: arbitrary bytes as `scene.toml` beside a valid glTF.
#![no_main]
#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    // Point the sidecar at the valid glTF unless the input names its own file.
    let mut text = String::from_utf8_lossy(data).into_owned();
    if !text.contains("gltf") {
        text.insert_str(0, "gltf = \"_valid_box.gltf\"\n");
    }
    common::load("scene.toml", text.as_bytes());
});
