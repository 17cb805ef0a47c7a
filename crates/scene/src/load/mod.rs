//! Scene loading. (Stub: being implemented.)
use crate::{Scene, SceneError};
use std::path::Path;

/// Loads a scene from a TOML sidecar, or a `.gltf`/`.glb` file alone.
pub fn load_scene(path: &Path) -> Result<Scene, SceneError> {
    todo!("{path:?}")
}
