//! Opening the GPU: a headless wgpu device on the Vulkan backend.
//!
//! `auto` prefers a discrete GPU, then an integrated one, then a virtual one, then a CPU
//! adapter (Mesa's lavapipe); without any, the caller falls back to the CPU estimators.
use std::fmt;

/// Which device runs the gathers (`--backend`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Backend {
    /// The best Vulkan adapter there is, else the CPU estimators.
    #[default]
    Auto,
    /// The CPU estimators only.
    Cpu,
    /// A Vulkan adapter, or an error.
    Gpu,
}

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no Vulkan adapter found (install one; on Debian `apt-get install mesa-vulkan-drivers` gives \
         the CPU adapter lavapipe)"
    )]
    NoAdapter,
    #[error("the Vulkan adapter {adapter} refused a device: {source}")]
    Device {
        adapter: String,
        source: wgpu::RequestDeviceError,
    },
    #[error("WGSL: {0}")]
    Shader(String),
    #[error("the gather inputs do not fit together: {0}")]
    Inputs(String),
    #[error("GPU buffer readback failed: {0}")]
    Readback(String),
    #[error("the GPU reported: {0}")]
    Reported(String),
    #[error(
        "the GPU driver cut the loops of {kernel} short in {records} gather records (lavapipe caps \
         the loop iterations of one invocation): their results would be wrong; draw fewer lights \
         per record (--light-samples) or use --backend cpu"
    )]
    LoopCap { kernel: &'static str, records: usize },
    #[error("{what} needs {needed} but the adapter allows {allowed}")]
    Limit {
        what: &'static str,
        needed: u64,
        allowed: u64,
    },
}

/// An adapter's name, kind and driver, as wgpu reports them.
pub use wgpu::AdapterInfo;

/// An open device with what the kernels need to know about it.
pub struct Gpu {
    /// The first error wgpu reported outside any call's return value (validation, device
    /// loss): [`Gpu::check`] turns it into a [`GpuError`] instead of wgpu's default panic.
    errors: std::sync::Arc<std::sync::Mutex<Option<String>>>,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    /// Timestamp queries inside compute passes (kernel times without wall-clock noise).
    pub timestamps: bool,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
}

fn instance() -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = wgpu::Backends::VULKAN;
    wgpu::Instance::new(desc)
}

/// Lower is better: the order `auto` tries adapters in.
fn rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    }
}

/// Every Vulkan adapter on this machine, best first.
pub fn adapters() -> Vec<wgpu::AdapterInfo> {
    let mut all: Vec<_> = pollster::block_on(instance().enumerate_adapters(wgpu::Backends::VULKAN))
        .iter()
        .map(|a| a.get_info())
        .collect();
    all.sort_by_key(|i| rank(i.device_type));
    all
}

impl Gpu {
    /// Opens the best Vulkan adapter (see the module docs).
    pub fn open() -> Result<Gpu, GpuError> {
        let mut candidates = pollster::block_on(instance().enumerate_adapters(wgpu::Backends::VULKAN));
        candidates.sort_by_key(|a| rank(a.get_info().device_type));
        let adapter = candidates.into_iter().next().ok_or(GpuError::NoAdapter)?;
        let info = adapter.get_info();
        let supported = adapter.limits();
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        // Ask for everything the adapter offers: big storage bindings and workgroup counts
        // matter for big scenes, and nothing here needs to run on weaker devices than this one.
        let required_features = if timestamps {
            wgpu::Features::TIMESTAMP_QUERY
        } else {
            wgpu::Features::empty()
        };
        let desc = wgpu::DeviceDescriptor {
            label: Some("beamlight"),
            required_features,
            required_limits: supported.clone(),
            ..Default::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&desc)).map_err(|source| GpuError::Device {
            adapter: info.name.clone(),
            source,
        })?;
        let errors = std::sync::Arc::new(std::sync::Mutex::new(None));
        let sink = errors.clone();
        device.on_uncaptured_error(std::sync::Arc::new(move |e: wgpu::Error| {
            let mut first = sink.lock().unwrap_or_else(|p| p.into_inner());
            if first.is_none() {
                *first = Some(e.to_string());
            }
        }));
        Ok(Gpu {
            errors,
            info,
            limits: supported,
            timestamps,
            device,
            queue,
        })
    }

    /// The first error wgpu reported since the device opened, if any.
    pub fn check(&self) -> Result<(), GpuError> {
        match self.errors.lock().unwrap_or_else(|p| p.into_inner()).clone() {
            Some(e) => Err(GpuError::Reported(e)),
            None => Ok(()),
        }
    }

    /// The adapter in one line: name, kind and driver.
    pub fn describe(&self) -> String {
        describe(&self.info)
    }
}

/// An adapter in one line.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    let kind = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => "discrete GPU",
        wgpu::DeviceType::IntegratedGpu => "integrated GPU",
        wgpu::DeviceType::VirtualGpu => "virtual GPU",
        wgpu::DeviceType::Cpu => "CPU adapter",
        wgpu::DeviceType::Other => "other adapter",
    };
    format!(
        "{} ({kind}, {:?}, {} {})",
        info.name, info.backend, info.driver, info.driver_info
    )
}

impl fmt::Debug for Gpu {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.describe())
    }
}

/// Whether GPU tests must fail rather than skip when there is no adapter (`CI=true`).
pub fn required_by_environment() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
}

/// Opens the GPU for a test: `None` (with a message saying how to get lavapipe) when there is
/// no adapter outside CI; a panic when there is none in CI.
pub fn for_tests() -> Option<Gpu> {
    match Gpu::open() {
        Ok(gpu) => Some(gpu),
        Err(e) if !required_by_environment() => {
            report_skipped_test(&e.to_string());
            None
        }
        Err(e) => panic!("CI=true and no GPU: {e}"),
    }
}

/// Whether a test's GPU half can run: true with an adapter; false without one outside CI (the
/// skip reported where the person running `cargo test` sees it); a panic without one in CI.
/// For tests that only need to know (they run the binary with `--backend gpu`); those that
/// open the GPU themselves use [`for_tests`].
pub fn adapter_for_tests() -> bool {
    if !adapters().is_empty() {
        return true;
    }
    assert!(!required_by_environment(), "CI=true and no Vulkan adapter");
    report_skipped_test(&format!("no Vulkan adapter; {LAVAPIPE}"));
    false
}

/// How to get a Vulkan adapter on a machine without a GPU.
const LAVAPIPE: &str = "install lavapipe (apt-get install mesa-vulkan-drivers) to run it";

/// Tells the person running `cargo test` that the current test, or part of it, did not run and
/// why (`reason`, with the remedy). Written to the process's stderr directly: the test harness
/// captures `eprintln!` and shows it only for failing tests, so a skipped test would read as a
/// passed one.
pub fn report_skipped_test(reason: &str) {
    use std::io::Write;
    let test = std::thread::current().name().unwrap_or("a test").to_string();
    let _ = writeln!(std::io::stderr(), "SKIPPED (all or part of) {test}: {reason}");
}

/// Whether an adapter runs on the CPU (lavapipe, SwiftShader): its kernels then share the
/// cores with the CPU estimators.
pub fn is_cpu_adapter(info: &wgpu::AdapterInfo) -> bool {
    info.device_type == wgpu::DeviceType::Cpu
}
