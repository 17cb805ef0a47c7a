//! Shared by the fuzz targets: load a scene whose main file holds the fuzzer's bytes, in a
//! directory with a valid glTF beside it, and require an `Ok` or an error naming the file —
//! never a panic (libFuzzer reports those) or a message without the path.
use std::path::Path;

pub fn load(name: &str, data: &[u8]) {
    thread_local! {
        static DIR: tempfile::TempDir = {
            let dir = tempfile::tempdir().unwrap();
            let valid = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/bad_scenes/_valid_box.gltf");
            std::fs::copy(valid, dir.path().join("_valid_box.gltf")).unwrap();
            dir
        };
    }
    DIR.with(|dir| {
        let path = dir.path().join(name);
        std::fs::write(&path, data).unwrap();
        if let Err(e) = beamlight_scene::load::load_scene(&path) {
            let message = e.to_string();
            assert!(message.contains(name), "error without the file name: {message}");
        }
    });
}
