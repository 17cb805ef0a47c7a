//! What a render reports about its time and its discards: `--stats` and `--stats-json`.
use beamlight_render::{
    Method, RenderOptions,
    components::{Component, SceneFeatures},
    many_lights::{self, Discards, PassTimes},
};
use beamlight_render::{TraceScene, many_lights::GatherKernel};
use std::time::Duration;

/// The `--stats` timeline summary: per pass, how long the CPU and the GPU were busy and how
/// long the CPU waited. With a GPU, one pass is in flight: the CPU traces and estimates pass
/// i + 1 while the GPU gathers pass i, so busy times can add up to more than the wall time.
pub(crate) fn print_stats(times: &[PassTimes], discarded: &Discards) {
    if times.is_empty() {
        eprintln!("stats: no many-light passes");
        return;
    }
    let n = times.len() as f64;
    let mean = |f: &dyn Fn(&PassTimes) -> f64| times.iter().map(f).sum::<f64>() / n * 1e3;
    let wall = mean(&|t| t.wall.as_secs_f64());
    let cpu = mean(&|t| (t.trace + t.cpu_estimates).as_secs_f64());
    let gpu = mean(&|t| t.kernels.iter().sum());
    eprintln!("stats over {} passes (mean ms per pass):", times.len());
    eprintln!("  wall time                              {wall:>9.2}");
    eprintln!(
        "  cpu trace (camera + light paths, maps) {:>9.2}",
        mean(&|t| t.trace.as_secs_f64())
    );
    eprintln!(
        "  cpu estimates                          {:>9.2}",
        mean(&|t| t.cpu_estimates.as_secs_f64())
    );
    eprintln!(
        "  cpu waiting for the gpu                {:>9.2}",
        mean(&|t| t.gpu_wait.as_secs_f64())
    );
    for k in GatherKernel::ALL {
        let ms = mean(&|t| t.kernels[k as usize]);
        if ms > 0.0 {
            eprintln!("  gpu kernel {:<28}{:>9.2}", k.name(), ms);
        }
    }
    if gpu > 0.0 {
        eprintln!(
            "  busy: cpu {:.0} %, gpu {:.0} % of the wall time",
            100.0 * cpu / wall.max(1e-9),
            100.0 * gpu / wall.max(1e-9)
        );
    }
    let records =
        |f: &dyn Fn(&many_lights::Records) -> u64| times.iter().map(|t| f(&t.records)).sum::<u64>() as f64 / n;
    eprintln!(
        "  gather records per pass: {:.0} shading points, {:.0} media segments",
        records(&|r| r.shading_points),
        records(&|r| r.media_segments)
    );
    let (walk_points, walk_segments) = (records(&|r| r.walk_points), records(&|r| r.walk_segments));
    if walk_points + walk_segments > 0.0 {
        eprintln!("  walks through sharp media per pass: {walk_points:.0} points, {walk_segments:.0} segments");
    }
    // The whole render's, a continued checkpoint's passes included (the rest is this run's).
    eprintln!("  discarded estimates (NaN, ∞ or < 0): {discarded}");
}

/// The `--stats-json` record: what a benchmark needs to know about a run's time. Component
/// CPU seconds are summed over threads; GPU seconds come from timestamp queries of each
/// gather kernel (assigned to the component it computes). `pt` renders the whole image in one
/// estimator, reported as `path_tracing`.
pub(crate) fn stats_json(
    ts: &TraceScene,
    opts: &RenderOptions,
    backend: &str,
    result: &beamlight_render::RenderResult,
    startup: Duration,
    process: Duration,
) -> String {
    use serde_json::json;
    let times = &result.pass_times;
    let total = |f: &dyn Fn(&PassTimes) -> f64| times.iter().map(f).sum::<f64>() + 0.0;
    let needed = SceneFeatures::of(&ts.scene).needed();
    // A method without virtual lights (`pt`) has no kernel times: any kernel list will do.
    let kernels = many_lights::gpu_kernels(opts.method.virtual_lights().unwrap_or_default());
    let discarded = result.discarded;
    let mut components = serde_json::Map::new();
    for (k, c) in Component::ALL.iter().enumerate() {
        let gpu: f64 = kernels
            .iter()
            .zip(many_lights::KERNEL_COMPONENTS)
            .filter(|(_, gc)| gc == c)
            .map(|(kernel, _)| total(&|t| t.kernels[*kernel as usize]))
            .sum();
        components.insert(
            c.name().to_string(),
            json!({
                "needed": needed.contains(c),
                "cpu_seconds": total(&|t| t.component_cpu[k]),
                "gpu_seconds": gpu,
                "discarded": discarded.estimates[k],
            }),
        );
    }
    let value = json!({
        "method": opts.method.name(),
        "backend": backend,
        "width": opts.width,
        "height": opts.height,
        "seed": opts.seed,
        "passes": result.passes,
        "budget": opts.budget.to_string(),
        "process_seconds": process.as_secs_f64(),
        "startup_seconds": startup.as_secs_f64(),
        "render_seconds": result.elapsed.as_secs_f64(),
        // Path tracing keeps every worker busy: its CPU seconds are about these wall seconds
        // times the threads (the per-component figures below are CPU seconds already).
        "threads": rayon::current_num_threads(),
        "path_tracing_seconds": match (&result.auto, opts.method) {
            (Some(report), _) => report.pt_seconds,
            (None, Method::Pt) => result.elapsed.as_secs_f64(),
            _ => 0.0,
        },
        "trace_seconds": total(&|t| t.trace.as_secs_f64()),
        "cpu_estimates_seconds": total(&|t| t.cpu_estimates.as_secs_f64()),
        "gpu_wait_seconds": total(&|t| t.gpu_wait.as_secs_f64()),
        "components": components,
        "dropped_light_paths": discarded.light_paths,
        "auto": result.auto.as_ref().map(|r| {
            let per_component: serde_json::Map<String, serde_json::Value> = Component::ALL
                .iter()
                .enumerate()
                .filter(|(k, _)| r.needed[*k])
                .map(|(k, c)| {
                    (
                        c.name().to_string(),
                        json!({
                            "pt_spp": r.pt_spp[k],
                            "vbl_passes": r.vbl_passes[k],
                            "vbl_seconds": r.vbl_component_seconds[k],
                            "vbl_weight": r.vbl_weight[k],
                            "vbl_only": r.vbl_only[k],
                        }),
                    )
                })
                .collect();
            json!({
                "pt_seconds": r.pt_seconds,
                "vbl_seconds": r.vbl_seconds,
                "components": per_component,
            })
        }),
    });
    serde_json::to_string_pretty(&value).expect("JSON of numbers and strings")
}
