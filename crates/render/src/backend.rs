//! Which device runs a render's gathers (`--backend`), decided in one place for the render and
//! for `beamlight info`, which says what `--backend auto` would do.
use crate::method::Method;
use beamlight_gpu::GpuBackend;
use beamlight_scene::Scene;
use std::sync::Arc;

/// `--backend`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// The GPU when the method has kernels and one is worth using, else the CPU.
    Auto,
    /// The first Vulkan adapter (an error without one).
    Gpu,
    Cpu,
}

/// What [`Backend::Auto`] does for a method on this machine, decided without opening a device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AutoChoice {
    /// The gathers stay on the CPU, for this reason.
    Cpu(String),
    /// The gathers go to this adapter.
    Gpu(String),
}

/// [`Backend::Auto`]'s choice for `method` given the machine's Vulkan adapters.
pub fn auto_choice(method: Method) -> AutoChoice {
    if !method.has_gpu_kernels() {
        return AutoChoice::Cpu("this method has no GPU kernels".into());
    }
    let Some(a) = beamlight_gpu::device::adapters().into_iter().next() else {
        return AutoChoice::Cpu("no Vulkan adapter".into());
    };
    let cpu_adapter = beamlight_gpu::device::is_cpu_adapter(&a);
    // On a CPU adapter (lavapipe) the kernels share the cores with the CPU estimators: measured
    // with `cargo bench -p beamlight-gpu`, the vbl kernels (numerical integration over each
    // sphere, mostly arithmetic) run 1.5-2.1x faster than the CPU twins on both cores, the vrl
    // ones (mostly BVH traversal, which diverges across SIMD lanes) 0.4-0.65x as fast. `auto`
    // spends most of its time path tracing on the CPU: opening a CPU adapter (about 2 s with
    // lavapipe) costs more than its share of gathers gains.
    if cpu_adapter && method == Method::Auto {
        return AutoChoice::Cpu(format!(
            "the only Vulkan adapter, {}, is a CPU adapter: `auto` path traces most of the time, and opening it costs more than its gathers gain",
            a.name
        ));
    }
    if cpu_adapter && method.virtual_lights() != Some(crate::many_lights::VirtualLights::Beams) {
        return AutoChoice::Cpu(format!(
            "the only Vulkan adapter, {}, is a CPU adapter: the CPU estimators of this method are faster on the same cores",
            a.name
        ));
    }
    AutoChoice::Gpu(a.name)
}

/// The device of a render: the GPU its gathers run on (none: the CPU alone) and a line saying
/// what runs where and why.
pub fn open(backend: Backend, method: Method, scene: &Scene) -> Result<(Option<Arc<GpuBackend>>, String), String> {
    let has_kernels = method.has_gpu_kernels();
    let gathers = match method.virtual_lights() {
        Some(crate::many_lights::VirtualLights::Beams) => "VBL/VSL gathers",
        _ => "VRL/VPL gathers",
    };
    // Only the method's kernels are compiled (a method without any opens none).
    let kernels = method.virtual_lights().map(crate::many_lights::gpu_kernels);
    let open = || GpuBackend::open_for(scene, kernels.as_ref().map_or(&[][..], |k| &k[..])).map(Arc::new);
    Ok(match backend {
        Backend::Cpu => (None, "cpu".to_string()),
        Backend::Gpu => {
            let g = open().map_err(|e| format!("--backend gpu: {e}"))?;
            let what = if has_kernels {
                format!("{gathers}; tracing, direct light and caustics on the CPU")
            } else {
                "idle: this method has no GPU kernels yet and runs on the CPU".to_string()
            };
            let name = format!("gpu ({}: {what})", g.gpu.describe());
            (has_kernels.then_some(g), name)
        }
        Backend::Auto => match auto_choice(method) {
            AutoChoice::Cpu(why) => (None, format!("cpu ({why})")),
            AutoChoice::Gpu(_) => match open() {
                Ok(g) => {
                    let name = format!("gpu ({}: {gathers})", g.gpu.describe());
                    (Some(g), name)
                }
                Err(e) => (None, format!("cpu ({e})")),
            },
        },
    })
}

/// `beamlight info`'s lines about the machine's Vulkan adapters: each one, and the first one's
/// limits.
pub fn adapter_lines() -> Vec<String> {
    let adapters = beamlight_gpu::device::adapters();
    let mut lines = Vec::new();
    if adapters.is_empty() {
        lines.push("gpu         none (no Vulkan adapter: the gathers run on the CPU)".to_string());
    }
    for (i, a) in adapters.iter().enumerate() {
        lines.push(format!("gpu {i}       {}", beamlight_gpu::device::describe(a)));
    }
    if !adapters.is_empty() {
        lines.push(match beamlight_gpu::Gpu::open() {
            Ok(g) => {
                let l = &g.limits;
                format!(
                    "gpu limits  storage binding {} MiB, buffer {} MiB, {} workgroups per dimension, {} storage buffers per stage, timestamps {}",
                    l.max_storage_buffer_binding_size >> 20,
                    l.max_buffer_size >> 20,
                    l.max_compute_workgroups_per_dimension,
                    l.max_storage_buffers_per_shader_stage,
                    if g.timestamps { "yes" } else { "no" }
                )
            }
            Err(e) => format!("gpu limits  unavailable: {e}"),
        });
    }
    lines
}
