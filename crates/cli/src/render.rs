//! `beamlight render`: options checked and turned into a render, progress, outputs,
//! checkpoints and warnings.
use crate::{check_output_path, runs};
use anyhow::{Context, Result, bail};
use beamlight_render::{
    Budget, Film, Method, RenderOptions,
    auto::{AutoReport, AutoSums, PT_SPP_PER_ROUND},
    components::Component,
    many_lights::{Discards, ManyLightSettings},
    output,
};
use beamlight_render::{PathTracerSettings, TraceScene, VblSettings};
use beamlight_scene::load::load_scene;
use std::{
    io::IsTerminal,
    time::{Duration, Instant},
};

use crate::args::*;
use crate::report::{print_stats, stats_json};

pub(crate) const DEFAULT_PASSES: u64 = 64;
/// `auto`'s rounds when no budget is given: each one `vbl` pass and
/// [`PT_SPP_PER_ROUND`] path-traced samples, so 16 rounds cost about what 64 `vbl` passes
/// alone would.
pub(crate) const DEFAULT_AUTO_ROUNDS: u64 = 16;

/// The shortest time between two progress lines when standard error is not a terminal.
pub(crate) const PROGRESS_EVERY: Duration = Duration::from_secs(10);

pub(crate) fn render(args: RenderArgs, start: Instant) -> Result<()> {
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
            .context("cannot set up the thread pool")?;
    }
    let method = args.method.0;
    if let Some(c) = args.clamp_distance
        && !(c.is_finite() && c >= 0.0)
    {
        bail!("--clamp-distance must be a finite distance >= 0, got {c}");
    }
    for (flag, value) in [("--radius", args.radius), ("--photon-radius", args.photon_radius)] {
        if let Some(r) = value
            && !(r.is_finite() && r > 0.0)
        {
            bail!("{flag} must be a finite distance > 0, got {r}");
        }
    }
    if let Some(t) = args.write_every
        && !(t.is_finite() && t > 0.0)
    {
        bail!("--write-every must be a positive number of seconds, got {t}");
    }
    if !(args.alpha > 0.0 && args.alpha < 1.0) {
        bail!("--alpha must lie strictly between 0 and 1, got {}", args.alpha);
    }
    let range_start = args.passes.and_then(|r| r.start);
    // `--spp N`: N camera samples per pixel. A pass of every method but `auto` is one; an
    // `auto` round is `PT_SPP_PER_ROUND` path-traced ones (and one `vbl` pass).
    let spp_passes = args.spp.map(|n| match method {
        Method::Auto => n.div_ceil(PT_SPP_PER_ROUND as u64),
        _ => n,
    });
    let pass_count = args.passes.map(|r| r.end - r.start.unwrap_or(0)).or(spp_passes);
    if range_start.is_some() && args.resume.is_some() {
        bail!("--resume continues a whole render; a pass range (--passes A..B) starts at A");
    }
    let budget = match (pass_count, args.time) {
        (Some(0), _) => bail!("--passes/--spp must be at least 1"),
        (Some(n), _) => Budget::Passes(n),
        (None, Some(t)) if t.is_finite() && t > 0.0 => Budget::Time(Duration::from_secs_f64(t)),
        (None, Some(t)) => bail!("--time must be a positive number of seconds, got {t}"),
        (None, None) if args.resume.is_some() => bail!("--resume needs the total --passes N or a --time budget"),
        (None, None) if method == Method::Auto => Budget::Passes(DEFAULT_AUTO_ROUNDS),
        (None, None) => Budget::Passes(DEFAULT_PASSES),
    };
    for (flag, v) in [("--width", args.width), ("--height", args.height)] {
        if let Some(v) = v
            && (v == 0 || v > 16384)
        {
            bail!("{flag} {v} is out of range (1..=16384)");
        }
    }
    if args.only.is_some() && method == Method::Auto {
        bail!("--only restricts one estimator; --method auto picks its components by itself");
    }
    check_output_path(&args.output, "exr")?;
    if let Some(p) = &args.preview {
        check_output_path(p, "png")?;
    }

    let loading = Instant::now();
    let scene = load_scene(&args.scene)?;
    let load_time = loading.elapsed();
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let width = args.width.unwrap_or(scene.render.width);
    let height = args.height.unwrap_or(scene.render.height);
    let building = Instant::now();
    let ts = TraceScene::new(scene);
    let bvh_time = building.elapsed();
    if ts.lights.is_empty() {
        eprintln!(
            "warning: {}: the scene has no light sources (no emissive material, no KHR_lights_punctual light): the image will be black",
            args.scene.display()
        );
    }
    if ts.lights.unusable > 0 {
        eprintln!(
            "warning: {}: {} light(s) with a power that is not finite (an emission too large for f32?) are never sampled",
            args.scene.display(),
            ts.lights.unusable
        );
    }
    // `vrl` connects each VRL to surface points through the VRL's own phase function; where
    // that is a near-delta, the light sits in spikes that position sampling rarely draws, so
    // the image stays low for thousands of passes (unbiased, heavy-tailed; README, Status).
    if matches!(method, Method::Vrl | Method::VrlClamped)
        && let Some(m) = ts
            .scene
            .media
            .iter()
            .find(|m| beamlight_render::components::is_sharp(m.g))
    {
        eprintln!(
            "warning: {}: medium '{}' has a near-delta phase function (g = {}): `{}`'s connections through it converge very slowly (in the g = 0.999 furnace 15 of 16 seeds read 1.34-1.61 instead of 2 after 256 passes); `--method vbl` or `pt` handle such media",
            args.scene.display(),
            m.name,
            m.g,
            method.name()
        );
    }
    let opening = Instant::now();
    let seconds = match budget {
        Budget::Time(t) => Some(t.as_secs_f64()),
        Budget::Passes(_) => None,
    };
    let device = beamlight_render::backend::open(args.backend.0, method, &ts, seconds).map_err(anyhow::Error::msg)?;
    let gpu_time = opening.elapsed();
    if args.stats {
        eprintln!(
            "start-up: scene loaded in {:.2} s, CPU BVH and light tables built in {:.2} s, GPU opened and scene uploaded in {:.2} s",
            load_time.as_secs_f64(),
            bvh_time.as_secs_f64(),
            gpu_time.as_secs_f64()
        );
    }

    // `--only`: the components every estimator of the render computes.
    let only = args.only.map_or([true; Component::ALL.len()], |l| l.0);
    let mut opts = RenderOptions {
        method,
        width,
        height,
        budget,
        seed: args.seed,
        first_pass: range_start.unwrap_or(0),
        path_tracer: PathTracerSettings {
            max_depth: args.max_depth,
            components: only,
            ..Default::default()
        },
        start,
        // The many-light methods always keep their components apart (and write them).
        components: args.components || args.only.is_some() || method != Method::Pt,
        many_lights: ManyLightSettings {
            light_paths_per_pass: args.light_paths,
            light_samples: args.light_samples.0,
            media_light_samples: args.media_light_samples,
            media_drawing: args.media_light_draw.0,
            vsl_drawing: args.vsl_draw.0,
            direct_samples: args.direct_samples,
            caustic_paths: args.caustic_paths,
            beam_paths: args.beam_paths,
            clamp: args.clamp_distance.unwrap_or(0.0),
            radius: args.radius.unwrap_or(0.0),
            photon_radius: args.photon_radius.unwrap_or(0.0),
            alpha: args.alpha,
            vbl: VblSettings {
                directions: args.vsl_directions,
                pdf_vertices: args.pdf_vertices,
                ..Default::default()
            },
            // The method decides between rays and beams; `auto` picks the components.
            lights: Default::default(),
            components: only,
            inject_nan: args.inject_nan,
        },
        gpu: device.gpu.clone(),
    };
    check_pass_memory(&ts, &opts, args.memory_limit, args.seed)?;
    // `--backend auto` with a device worth trying: one small pass on each side decides.
    let backend = match (&device.gpu, device.measure) {
        (Some(gpu), true) => {
            let trial = beamlight_render::backend::measure(&ts, &opts, gpu).map_err(anyhow::Error::msg)?;
            // What opening and trying cost, for the next render with a time budget to weigh.
            beamlight_render::backend::Opening::of(&gpu.gpu.info, method).record(opening.elapsed().as_secs_f64());
            let (w, h) = trial.size;
            let measured = format!(
                "measured: a {w}x{h} {} pass took {:.3} s on the CPU, {:.3} s on the GPU",
                method.name(),
                trial.cpu,
                trial.gpu,
            );
            if trial.gpu_wins() {
                format!("{} ({measured})", device.line)
            } else {
                opts.gpu = None;
                format!("cpu ({measured}, {})", gpu.gpu.describe())
            }
        }
        _ => device.line,
    };
    eprintln!(
        "beamlight: {} ({} triangles), {width}x{height}, method {}, backend {backend}",
        args.scene.display(),
        ts.scene.triangles.len(),
        method.name()
    );
    // Checkpoints and pass ranges: what identifies this render, and where it resumes.
    let fingerprint = runs::fingerprint(&ts.scene, &opts);
    let resumed = match &args.resume {
        Some(path) => Some(runs::read_checkpoint(path, &fingerprint)?),
        None => None,
    };
    let mut budget = budget;
    if let Some(acc) = &resumed {
        opts.first_pass = acc.end_pass();
        if let Budget::Passes(n) = budget {
            if n <= acc.passes() {
                bail!(
                    "{}: the checkpoint already holds {} passes (asked for {n} in all)",
                    args.resume.as_ref().expect("resumed").display(),
                    acc.passes()
                );
            }
            budget = Budget::Passes(n - acc.passes());
        }
        opts.budget = budget;
        eprintln!("resuming after {} passes", acc.passes());
    }
    let accum_path = args
        .checkpoint
        .clone()
        .or_else(|| range_start.map(|_| runs::default_accum_path(&args.output)));
    let accum_first = resumed.as_ref().map_or(opts.first_pass, |a| a.first_pass);
    let accumulators = |film: &Film, components: &[Film], auto: Option<&AutoSums>, discarded: &Discards| {
        beamlight_render::accum::Accumulators {
            fingerprint: fingerprint.clone(),
            first_pass: accum_first,
            film: film.clone(),
            components: components.to_vec(),
            auto: auto.cloned(),
            discarded: *discarded,
        }
    };
    runs::catch_interrupts();
    let startup = start.elapsed();
    let bar = progress_bar(&budget);
    // Without a terminal (a log file, a batch job, a test) the bar is hidden: a plain line after
    // the first pass (the render is under way, Ctrl-C is handled) and then at most one every
    // `PROGRESS_EVERY`.
    let log_progress = !std::io::stderr().is_terminal();
    let mut last_progress_line: Option<Instant> = None;
    let outputs = Outputs {
        args: &args,
        method,
        budget: opts.budget,
        backend: &backend,
    };
    let mut last_write = Instant::now();
    let mut last_checkpoint = Instant::now();
    let checkpoint_every = args.write_every.unwrap_or(60.0);
    let mut write_error = None;
    let result = beamlight_render::render_from(&ts, &opts, resumed.as_ref(), |p| {
        bar.set_position(p.passes);
        if log_progress && last_progress_line.is_none_or(|t| t.elapsed() >= PROGRESS_EVERY) {
            eprintln!(
                "pass {}{} done after {:.1} s",
                p.passes,
                p.total.map_or(String::new(), |n| format!("/{n}")),
                p.elapsed.as_secs_f64()
            );
            last_progress_line = Some(Instant::now());
        }
        if let Some(every) = args.write_every
            && last_write.elapsed().as_secs_f64() >= every
            && write_error.is_none()
        {
            write_error = outputs
                .write(p.film, p.components, &p.discarded, p.auto, p.elapsed)
                .err();
            last_write = Instant::now();
        }
        if let Some(path) = &args.checkpoint
            && last_checkpoint.elapsed().as_secs_f64() >= checkpoint_every
            && write_error.is_none()
        {
            write_error = accumulators(p.film, p.components, p.auto_sums, &p.discarded)
                .write(path)
                .err()
                .map(anyhow::Error::from);
            last_checkpoint = Instant::now();
        }
        // An image that cannot be written ends the render now, not hours later; so does Ctrl-C
        // (after this pass, whose image is written below).
        write_error.is_none() && !runs::interrupted()
    })
    .map_err(anyhow::Error::msg)?;
    bar.finish_and_clear();
    if let Some(e) = write_error {
        return Err(e.context("writing an intermediate image or checkpoint"));
    }
    outputs.write(
        &result.film,
        &result.components,
        &result.discarded,
        result.auto.as_ref(),
        result.elapsed,
    )?;
    if let Some(path) = &accum_path {
        let sums = result.auto.as_ref().and_then(|r| r.sums.as_ref());
        accumulators(&result.film, &result.components, sums, &result.discarded).write(path)?;
    }
    let secs = result.elapsed.as_secs_f64();
    if result.film.rejected > 0 {
        eprintln!(
            "warning: {} non-finite samples were dropped (please report this scene)",
            result.film.rejected
        );
    }
    if result.discarded.any() {
        eprintln!(
            "warning: estimates or light paths that were NaN, infinite or negative were discarded ({}; please report this scene)",
            result.discarded
        );
    }
    if args.stats {
        print_stats(&result.pass_times, &result.discarded);
        if let Some(report) = &result.auto {
            eprintln!("auto, per component (a path-traced sample may serve several):");
            for line in report.lines() {
                eprintln!("  {line}");
            }
        }
    }
    if let Some(path) = &args.stats_json {
        let json = stats_json(&ts, &opts, &backend, &result, startup, start.elapsed());
        output::write_atomic(path, json.as_bytes())?;
    }
    if runs::interrupted() {
        eprintln!(
            "interrupted: {} passes written to {}{}",
            result.film.samples,
            args.output.display(),
            accum_path
                .as_ref()
                .map_or(String::new(), |p| format!(" (accumulators: {})", p.display()))
        );
        return Err(runs::Interrupted.into());
    }
    // What the render amounts to: samples per pixel (`pt`), passes (the many-light methods),
    // or each of `auto`'s estimators' most (a component's samples and passes; the path
    // tracer's may serve several components at once).
    let amount = match (&result.auto, method) {
        (Some(r), _) => format!(
            "pt {} spp and vbl {} passes in {} units",
            r.pt_spp.iter().max().unwrap_or(&0),
            r.vbl_passes.iter().max().unwrap_or(&0),
            result.passes
        ),
        (None, Method::Pt) => format!("{} spp", result.passes),
        (None, _) => format!("{} passes", result.passes),
    };
    // The time budget's last passes, shortened to the time left, covered a share of the
    // pixels (those of a resumed checkpoint are not this run's).
    let before = resumed.as_ref().map_or(0, |a| a.film.partial_passes());
    let amount = match result.film.partial_passes() - before {
        0 => amount,
        n => {
            let counts = result.film.partial_counts();
            let covered = counts.iter().map(|&c| c as f64).sum::<f64>() / counts.len().max(1) as f64;
            format!(
                "{amount}, the last {n} shortened to {:.0} % of the pixels on average",
                100.0 * covered / result.film.partial_passes() as f64
            )
        }
    };
    eprintln!(
        "done: {} in {secs:.2} s, {amount} -> {}",
        method.name(),
        args.output.display()
    );
    Ok(())
}

/// Where and how the render's images are written (at the end, and with `--write-every`).
pub(crate) struct Outputs<'a> {
    pub(crate) args: &'a RenderArgs,
    pub(crate) method: Method,
    pub(crate) budget: Budget,
    pub(crate) backend: &'a str,
}

impl Outputs<'_> {
    /// Writes the EXR (beauty + component layers) and the preview, each atomically.
    fn write(
        &self,
        film: &Film,
        components: &[Film],
        discarded: &Discards,
        auto: Option<&AutoReport>,
        elapsed: Duration,
    ) -> Result<()> {
        let args = self.args;
        let mut metadata = vec![
            ("beamlight.method", self.method.name().to_string()),
            ("beamlight.seed", args.seed.to_string()),
            ("beamlight.render_seconds", format!("{:.3}", elapsed.as_secs_f64())),
            ("beamlight.budget", self.budget.to_string()),
            ("beamlight.scene", args.scene.display().to_string()),
            ("beamlight.backend", self.backend.to_string()),
        ];
        if let Some(report) = auto {
            metadata.push(("beamlight.auto", report.lines().join("; ")));
        }
        let image = output::write_films(&args.output, film, components, discarded, &metadata)?;
        if let Some(p) = &args.preview {
            output::write_png(p, &image, args.exposure)?;
        }
        Ok(())
    }
}

pub(crate) fn progress_bar(budget: &Budget) -> indicatif::ProgressBar {
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let style = "{elapsed_precise} [{bar:40}] {pos}/{len} passes ({per_sec}, eta {eta})";
    match budget {
        Budget::Passes(n) => indicatif::ProgressBar::new(*n).with_style(
            indicatif::ProgressStyle::with_template(style)
                .unwrap()
                .progress_chars("=> "),
        ),
        Budget::Time(_) => indicatif::ProgressBar::new_spinner().with_style(
            indicatif::ProgressStyle::with_template("{elapsed_precise} {spinner} {pos} passes ({per_sec})").unwrap(),
        ),
    }
}

/// Refuses a many-light render whose pass would not fit in memory (`--memory-limit`, by
/// default 80 % of the memory available), before anything is traced at full size.
fn check_pass_memory(ts: &TraceScene, opts: &RenderOptions, limit_gib: Option<f64>, seed: u32) -> Result<()> {
    if let Some(g) = limit_gib
        && !(g.is_finite() && g > 0.0)
    {
        bail!("--memory-limit must be a positive number of GiB, got {g}");
    }
    if opts.method == Method::Pt {
        return Ok(());
    }
    let (limit, source) = match limit_gib {
        Some(g) => (g * (1u64 << 30) as f64, "--memory-limit".to_string()),
        None => match beamlight_render::memory::available() {
            Some(bytes) => (
                0.8 * bytes as f64,
                format!("80 % of the {:.2} GiB available", bytes as f64 / (1u64 << 30) as f64),
            ),
            // Nothing to compare with: the fixed limits on the counts still hold.
            None => return Ok(()),
        },
    };
    let sets = beamlight_render::memory::estimate(ts, &opts.many_lights, opts.width, opts.height, seed);
    beamlight_render::memory::check(&sets, limit, &source).map_err(anyhow::Error::msg)
}
