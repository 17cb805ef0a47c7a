//! beamlight-testkit: what tests, benches and `cargo xtask assets` need to author scenes, kept
//! out of the runtime crates (a dev-dependency only, and of xtask).
pub mod gltf_writer;
pub mod scenes;
