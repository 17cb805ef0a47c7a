//! What a render is asked for: the method, the image, the budget and each estimator's
//! settings.
use crate::{many_lights::ManyLightSettings, method::Method};
use beamlight_gpu::GpuBackend;
use beamlight_trace::pt::PathTracerSettings;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// When to stop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// Exactly this many passes (for `pt` one pass is one sample per pixel).
    Passes(u64),
    /// Stop before the wall-clock time since `RenderOptions::start` would exceed this; at
    /// least one pass is always rendered.
    Time(Duration),
}

impl std::fmt::Display for Budget {
    /// As the EXR header and `--stats-json` record it: `passes N` or `time T s` (start-up
    /// included).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Budget::Passes(n) => write!(f, "passes {n}"),
            Budget::Time(t) => write!(f, "time {:.3} s", t.as_secs_f64()),
        }
    }
}

#[derive(Clone, Debug)]
pub struct RenderOptions {
    pub method: Method,
    pub width: u32,
    pub height: u32,
    pub budget: Budget,
    pub seed: u32,
    /// First pass index (ranges of passes can be rendered separately and averaged).
    pub first_pass: u64,
    pub path_tracer: PathTracerSettings,
    /// The moment the time budget counts from (process start, so start-up is included).
    pub start: Instant,
    /// Also accumulate each transport component separately (`RenderResult::components`).
    pub components: bool,
    pub many_lights: ManyLightSettings,
    /// The GPU that runs the gathers it has kernels for; `None` renders on the CPU alone.
    pub gpu: Option<Arc<GpuBackend>>,
}
