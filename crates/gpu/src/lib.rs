//! The GPU half of beamlight: wgpu compute kernels, written in WGSL under `shaders/`, that
//! shoot visibility rays through the scene's BVH and evaluate the virtual-light gathers, each
//! kernel a twin of a CPU estimator in `beamlight-trace` (the oracle it is tested against).
pub mod compute;
pub mod device;
pub mod gather;
pub mod layout;
pub mod rays;
pub mod scene;
pub mod shaders;

pub use device::{Backend, Gpu, GpuError};
pub use scene::GpuScene;

/// Everything a render needs on the GPU: the device, the scene uploaded once, and the gather
/// kernels compiled once.
pub struct GpuBackend {
    pub gpu: Gpu,
    pub scene: GpuScene,
    pub gathers: gather::Gathers,
}

impl GpuBackend {
    /// Opens the best adapter (see [`device`]), uploads `ts`'s scene (with the planar patches
    /// it has built) and compiles every gather kernel.
    pub fn open(ts: &beamlight_trace::TraceScene) -> Result<GpuBackend, GpuError> {
        Self::open_for(ts, &gather::GatherKernel::ALL)
    }

    /// [`GpuBackend::open`] compiling only `kernels` (a method's: compiling one costs about a
    /// third of a second on lavapipe); running another is an error.
    pub fn open_for(
        ts: &beamlight_trace::TraceScene,
        kernels: &[gather::GatherKernel],
    ) -> Result<GpuBackend, GpuError> {
        let gpu = Gpu::open()?;
        let gpu_scene = GpuScene::upload_with(&gpu, &ts.scene, &ts.patches)?;
        let gathers = gather::Gathers::new(&gpu, &gpu_scene, kernels)?;
        Ok(GpuBackend {
            gpu,
            scene: gpu_scene,
            gathers,
        })
    }
}

impl std::fmt::Debug for GpuBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.gpu.describe())
    }
}
