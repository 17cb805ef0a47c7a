//! Which device runs a render's gathers (`--backend`), decided in one place for the render and
//! for `beamlight info`, which says what `--backend auto` would do.
use crate::method::Method;
use beamlight_gpu::GpuBackend;
use beamlight_trace::TraceScene;
use std::{path::PathBuf, sync::Arc};

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
    /// The device is opened and one small pass on each side, before the render, decides
    /// ([`measure`]).
    Measure(String),
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
    // `auto` spends most of its time path tracing on the CPU, and on a CPU adapter (lavapipe)
    // the kernels share the cores with it: opening the device (about 1 s with lavapipe, its
    // kernels compiled by LLVM) costs more than its share of gathers gains.
    if cpu_adapter && method == Method::Auto {
        return AutoChoice::Cpu(format!(
            "the only Vulkan adapter, {}, is a CPU adapter: `auto` path traces most of the time, and opening it costs more than its gathers gain",
            a.name
        ));
    }
    if method == Method::Auto {
        return AutoChoice::Gpu(a.name);
    }
    // Which side is faster depends on the adapter, the cores and the scene: measured with
    // `cargo bench -p beamlight-gpu`, lavapipe ran the `vbl` kernels 1.5-2.1x faster than
    // the CPU twins on both cores and the `vrl` ones 0.4-0.65x as fast, and the committed
    // bench had lavapipe's `vbl` behind the CPU on two scenes of three. So a trial decides.
    AutoChoice::Measure(a.name)
}

/// A render's device: the GPU its gathers run on (none: the CPU alone), a line saying what
/// runs where and why, and whether [`measure`] should still decide between the two.
pub struct Device {
    pub gpu: Option<Arc<GpuBackend>>,
    pub line: String,
    pub measure: bool,
}

/// What opening a device for a method's kernels and the trial ([`measure`]) cost together, as
/// last measured on this machine: the kernels are compiled then (on lavapipe by LLVM, on the
/// render's cores; the first dispatch of a kernel compiles more, 175 s for `vbl`'s on a fresh
/// Mesa shader cache, 2 s once cached). Kept in a small cache file
/// (`$XDG_CACHE_HOME/beamlight/opening.json`, else `~/.cache/…`), so that `--backend auto`
/// can tell before opening whether a time budget can afford it. Losing the file only costs
/// the prior ([`Opening::expected`]); a file that cannot be read or written is ignored.
pub struct Opening {
    key: String,
    file: Option<PathBuf>,
}

/// Seconds [`Opening::expected`] assumes before a measurement: on a CPU adapter, about what
/// opening lavapipe for `vbl`'s kernels and its trial took on 2 cores with Mesa's shader cache
/// warm (7.3–9.3 s, the opening alone 5.2–6.9 s; `vrl`'s 0.6–0.9 s with the trial); on
/// another, a guess that lets a first trial run.
const OPENING_PRIOR_CPU_ADAPTER: f64 = 8.0;
const OPENING_PRIOR_GPU: f64 = 1.0;

/// `--backend auto` opens a device only when a time budget is at least this many times its
/// opening (or there is no time budget): the trial pass then costs at most a quarter of the
/// budget, and a device that gathers about 2× faster (lavapipe's `vbl` kernels, measured) can
/// still gain it back.
pub const OPENING_BUDGET_RATIO: f64 = 4.0;

impl Opening {
    pub fn of(adapter: &beamlight_gpu::device::AdapterInfo, method: Method) -> Opening {
        let lights = match method.virtual_lights() {
            Some(crate::many_lights::VirtualLights::Beams) => "vbl",
            Some(crate::many_lights::VirtualLights::Rays) => "vrl",
            None => "none",
        };
        let key = format!("{} / {lights} kernels", beamlight_gpu::device::describe(adapter));
        Opening {
            key,
            file: Self::file(),
        }
    }

    fn file() -> Option<PathBuf> {
        let base = std::env::var_os("XDG_CACHE_HOME")
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
        Some(base.join("beamlight").join("opening.json"))
    }

    fn read_all(&self) -> serde_json::Map<String, serde_json::Value> {
        self.file
            .as_ref()
            .and_then(|f| std::fs::read(f).ok())
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or_default()
    }

    /// The last measured seconds, if any.
    pub fn measured(&self) -> Option<f64> {
        self.read_all().get(&self.key).and_then(|v| v.as_f64())
    }

    /// The seconds to expect: the measured ones, or the prior for this kind of adapter.
    pub fn expected(&self, cpu_adapter: bool) -> f64 {
        self.measured().unwrap_or(match cpu_adapter {
            true => OPENING_PRIOR_CPU_ADAPTER,
            false => OPENING_PRIOR_GPU,
        })
    }

    /// Records a measurement (best effort: a cache), keeping the other adapters' and kernel
    /// sets'.
    pub fn record(&self, seconds: f64) {
        let Some(file) = &self.file else { return };
        let mut all = self.read_all();
        all.insert(self.key.clone(), serde_json::json!(seconds));
        if let Some(dir) = file.parent()
            && std::fs::create_dir_all(dir).is_ok()
            && let Ok(bytes) = serde_json::to_vec_pretty(&all)
        {
            let _ = crate::output::write_atomic(file, &bytes);
        }
    }
}

/// Whether a time budget of `budget` seconds (`None`: a pass budget) affords opening a device
/// expected to take `opening` seconds with its trial.
fn affords(budget: Option<f64>, opening: f64) -> bool {
    budget.is_none_or(|b| b >= OPENING_BUDGET_RATIO * opening)
}

/// The seconds opening the first adapter for `method`'s kernels is expected to take, and
/// whether they were measured here (`None` without an adapter).
pub fn expected_opening(method: Method) -> Option<(f64, bool)> {
    let a = beamlight_gpu::device::adapters().into_iter().next()?;
    let o = Opening::of(&a, method);
    Some((
        o.expected(beamlight_gpu::device::is_cpu_adapter(&a)),
        o.measured().is_some(),
    ))
}

/// Why `--backend auto` leaves the device closed for a time budget of `budget` seconds when
/// opening it would take more than [`OPENING_BUDGET_RATIO`]'s share (`None`: open it).
pub fn budget_too_short(
    adapter: &beamlight_gpu::device::AdapterInfo,
    method: Method,
    budget: Option<f64>,
) -> Option<String> {
    let opening = Opening::of(adapter, method);
    let cpu_adapter = beamlight_gpu::device::is_cpu_adapter(adapter);
    let expected = opening.expected(cpu_adapter);
    let budget = budget.filter(|_| !affords(budget, expected))?;
    let source = match opening.measured() {
        Some(_) => "as last measured here",
        None if cpu_adapter => "expected of a CPU adapter, not yet measured here",
        None => "not yet measured here",
    };
    Some(format!(
        "opening {} for {}'s kernels and trying it takes about {expected:.1} s ({source}), more than 1/{OPENING_BUDGET_RATIO} of the {budget:.1} s budget",
        adapter.name,
        method.name()
    ))
}

/// Opens the device of a render; `budget`: its time budget in seconds, when it has one.
pub fn open(backend: Backend, method: Method, ts: &TraceScene, budget: Option<f64>) -> Result<Device, String> {
    let has_kernels = method.has_gpu_kernels();
    let gathers = match method.virtual_lights() {
        Some(crate::many_lights::VirtualLights::Beams) => "VBL/VSL gathers",
        _ => "VRL/VPL gathers",
    };
    // Only the method's kernels are compiled (a method without any opens none).
    let kernels = method.virtual_lights().map(crate::many_lights::gpu_kernels);
    let open = || GpuBackend::open_for(ts, kernels.as_ref().map_or(&[][..], |k| &k[..])).map(Arc::new);
    let fixed = |gpu, line| Device {
        gpu,
        line,
        measure: false,
    };
    Ok(match backend {
        Backend::Cpu => fixed(None, "cpu".to_string()),
        Backend::Gpu => {
            let g = open().map_err(|e| format!("--backend gpu: {e}"))?;
            let what = if has_kernels {
                format!("{gathers}; tracing, direct light and caustics on the CPU")
            } else {
                "idle: this method has no GPU kernels yet and runs on the CPU".to_string()
            };
            let name = format!("gpu ({}: {what})", g.gpu.describe());
            fixed(has_kernels.then_some(g), name)
        }
        Backend::Auto => {
            let choice = auto_choice(method);
            // A time budget too short to pay for opening the device leaves it closed.
            let short = match &choice {
                AutoChoice::Cpu(_) => None,
                _ => beamlight_gpu::device::adapters()
                    .first()
                    .and_then(|a| budget_too_short(a, method, budget)),
            };
            match (choice, short) {
                (AutoChoice::Cpu(why), _) | (_, Some(why)) => fixed(None, format!("cpu ({why})")),
                (choice, None) => match open() {
                    Ok(g) => {
                        let name = format!("gpu ({}: {gathers})", g.gpu.describe());
                        Device {
                            gpu: Some(g),
                            line: name,
                            measure: matches!(choice, AutoChoice::Measure(_)),
                        }
                    }
                    Err(e) => fixed(None, format!("cpu ({e})")),
                },
            }
        }
    })
}

/// A trial ([`measure`]): the seconds of a pass of `size` pixels on each side.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Trial {
    pub cpu: f64,
    pub gpu: f64,
    pub size: (u32, u32),
}

impl Trial {
    /// Keep the GPU when its pass was faster.
    pub fn gpu_wins(&self) -> bool {
        self.gpu < self.cpu
    }
}

/// The trial images' sides: the render's, at most these many pixels wide and high. A pass's
/// cost is mostly its gathers, in proportion to the pixels, so small passes show which side is
/// faster at a small price; the larger one only when the smaller was a close call (within
/// [`CLEAR`]), as a 32x32 pass of `vbl` on lavapipe is (fixed costs per pass weigh more
/// there): measured on the glossy fog box, 0.050 s on the CPU, 0.052 s on the GPU, while at
/// 96x96 the GPU's passes were 11 % faster (283 vs 317 ms) and at 256x256 21 %.
pub const TRIAL_SIZES: [u32; 2] = [32, 64];

/// A trial whose sides differ by more than this factor decides at once.
const CLEAR: f64 = 1.5;

/// [`AutoChoice::Measure`]: one pass of `opts`' method on each side, at most
/// [`TRIAL_SIZES`]`[0]`² pixels and otherwise the render's settings, and again at the larger
/// size when that was a close call. The GPU first runs an 8x8 pass: its first dispatches pay
/// for warming up (0.13 s with lavapipe, more than a 32x32 pass), which the render's passes
/// do not. The passes are thrown away: only the render's passes make the image, which is
/// therefore the one a render on the winning side alone gives.
pub fn measure(ts: &TraceScene, opts: &crate::RenderOptions, gpu: &GpuBackend) -> Result<Trial, String> {
    use crate::source::{ManyLights, N, PassOutput, PassSource};
    use beamlight_trace::camera_paths::PixelShare;
    let source = |gpu, (w, h): (u32, u32)| ManyLights {
        ts,
        settings: opts.method.many_light_settings(ts, &opts.many_lights),
        width: w,
        height: h,
        seed: opts.seed,
        gpu,
    };
    let pass = opts.first_pass as u32;
    let time = |s: &ManyLights| -> Result<f64, String> {
        let clock = std::time::Instant::now();
        s.start(
            pass,
            [true; N],
            PixelShare::ALL,
            PassOutput::new((s.width * s.height) as usize),
        )?
        .finish()?;
        Ok(clock.elapsed().as_secs_f64())
    };
    let size = |side: u32| (opts.width.min(side), opts.height.min(side));
    time(&source(Some(gpu), size(8)))?;
    let mut trial = Trial::default();
    for (i, side) in TRIAL_SIZES.into_iter().enumerate() {
        trial = Trial {
            cpu: time(&source(None, size(side)))?,
            gpu: time(&source(Some(gpu), size(side)))?,
            size: size(side),
        };
        let ratio = trial.cpu / trial.gpu.max(1e-9);
        if i + 1 == TRIAL_SIZES.len()
            || !(1.0 / CLEAR..=CLEAR).contains(&ratio)
            || size(side) == (opts.width, opts.height)
        {
            break;
        }
    }
    Ok(trial)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The opening cache keeps each adapter's and kernel set's last measurement, survives a
    /// corrupt file (read as empty, then rewritten) and a missing one; a budget affords the
    /// device from 4x its opening. Catches a record that drops the other keys, a corrupt
    /// cache that fails the render, and the comparison turned round.
    #[test]
    fn the_opening_cache_keeps_the_last_measurements() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("beamlight").join("opening.json");
        let at = |key: &str| Opening {
            key: key.into(),
            file: Some(file.clone()),
        };
        assert_eq!(at("a / vbl kernels").measured(), None);
        assert_eq!(at("a / vbl kernels").expected(true), OPENING_PRIOR_CPU_ADAPTER);
        at("a / vbl kernels").record(9.3);
        at("a / vrl kernels").record(0.7);
        at("a / vbl kernels").record(5.2);
        assert_eq!(at("a / vbl kernels").measured(), Some(5.2));
        assert_eq!(at("a / vrl kernels").expected(true), 0.7);
        std::fs::write(&file, b"{ not json").unwrap();
        assert_eq!(at("a / vrl kernels").measured(), None);
        at("a / vrl kernels").record(0.6);
        assert_eq!(at("a / vrl kernels").measured(), Some(0.6));
        let nowhere = Opening {
            key: "a".into(),
            file: None,
        };
        nowhere.record(1.0);
        assert_eq!(nowhere.measured(), None);
        assert!(affords(None, 100.0) && affords(Some(24.0), 6.0));
        assert!(!affords(Some(23.9), 6.0) && !affords(Some(2.0), 6.0));
    }
}
