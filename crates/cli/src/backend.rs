//! Which device runs the gathers (`--backend`), and a quiet Vulkan loader.
use crate::args::BackendArg;
use anyhow::Result;
use beamlight_gpu::GpuBackend;
use beamlight_render::{Method, many_lights::VirtualLights};
use beamlight_trace::TraceScene;
use std::{path::PathBuf, sync::Arc};

/// Mesa's Vulkan drivers print "error: XDG_RUNTIME_DIR is invalid or not set" on every device
/// open without that variable (containers, CI), which reads like one of ours: give the process
/// a private runtime directory when it has none (returned, to be removed at exit).
pub(crate) fn quiet_vulkan_loader() -> Option<PathBuf> {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return None;
    }
    let dir = std::env::temp_dir().join(format!("beamlight-runtime-{}", std::process::id()));
    #[cfg(unix)]
    let made = {
        use std::os::unix::fs::DirBuilderExt;
        std::fs::DirBuilder::new().mode(0o700).create(&dir).is_ok()
    };
    #[cfg(not(unix))]
    let made = std::fs::create_dir(&dir).is_ok();
    if !made {
        return None;
    }
    // SAFETY: called first thing in `main`, before any thread exists.
    unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
    Some(dir)
}

/// Picks the device for the gathers (`--backend`) and says what runs where. `gpu` needs a
/// Vulkan adapter; `auto` takes one when the method has GPU kernels and falls back to the CPU.
pub(crate) fn choose_backend(
    arg: BackendArg,
    method: Method,
    ts: &TraceScene,
) -> Result<(Option<Arc<GpuBackend>>, String)> {
    let has_kernels = method.has_gpu_kernels();
    let beams = method.virtual_lights() == Some(VirtualLights::Beams);
    let gathers = if beams { "VBL/VSL gathers" } else { "VRL/VPL gathers" };
    let open = || GpuBackend::open(&ts.scene).map(Arc::new);
    Ok(match arg {
        BackendArg::Cpu => (None, "cpu".to_string()),
        BackendArg::Gpu => {
            let g = open().map_err(|e| anyhow::anyhow!("--backend gpu: {e}"))?;
            let what = if has_kernels {
                format!("{gathers}; tracing, direct light and caustics on the CPU")
            } else {
                "idle: this method has no GPU kernels yet and runs on the CPU".to_string()
            };
            let name = format!("gpu ({}: {what})", g.gpu.describe());
            (has_kernels.then_some(g), name)
        }
        BackendArg::Auto if !has_kernels => (None, "cpu (this method has no GPU kernels yet)".to_string()),
        BackendArg::Auto => match beamlight_gpu::device::adapters().first() {
            None => (None, "cpu (no Vulkan adapter)".to_string()),
            // On a CPU adapter (lavapipe) the kernels share the cores with the CPU estimators:
            // measured with `cargo bench -p beamlight-gpu`, the vbl kernels (numerical
            // integration over each sphere, mostly arithmetic) run 1.5-2.1x faster than the CPU
            // twins on both cores, the vrl ones (mostly BVH traversal, which diverges across
            // SIMD lanes) 0.4-0.65x as fast.
            // `auto` spends most of its time path tracing on the CPU: opening a CPU adapter
            // (about 2 s with lavapipe) costs more than its share of gathers gains.
            Some(a) if beamlight_gpu::device::is_cpu_adapter(a) && method == Method::Auto => (
                None,
                format!(
                    "cpu (the only Vulkan adapter, {}, is a CPU adapter: `auto` path traces most of the time, and opening it costs more than its gathers gain)",
                    a.name
                ),
            ),
            Some(a) if beamlight_gpu::device::is_cpu_adapter(a) && !beams => (
                None,
                format!(
                    "cpu (the only Vulkan adapter, {}, is a CPU adapter: the CPU estimators of this method are faster on the same cores)",
                    a.name
                ),
            ),
            Some(_) => match open() {
                Ok(g) => {
                    let name = format!("gpu ({}: {gathers})", g.gpu.describe());
                    (Some(g), name)
                }
                Err(e) => (None, format!("cpu ({e})")),
            },
        },
    })
}
