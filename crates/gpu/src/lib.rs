//! The GPU half of beamlight: wgpu compute kernels, written in WGSL under `shaders/`, that
//! shoot visibility rays through the scene's BVH and evaluate the virtual-light gathers, each
//! kernel a twin of a CPU estimator in `beamlight-trace` (the oracle it is tested against).
pub mod compute;
pub mod device;
pub mod layout;
pub mod rays;
pub mod scene;
pub mod shaders;

pub use device::{Backend, Gpu, GpuError};
pub use scene::GpuScene;
