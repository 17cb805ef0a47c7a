//! The `beamlight` command line: `render`, `compare`, `info`, `merge`, `export-mitsuba`.
pub mod mitsuba;
mod runs;

use anyhow::{Context, Result, bail};
use beamlight_gpu::{Gpu, GpuBackend, gather::GatherKernel};
use beamlight_render::{
    Budget, Film, Method, RenderOptions,
    auto::{AutoReport, AutoSums},
    compare,
    components::{Component, SceneFeatures},
    many_lights::{self, Discards, ManyLightSettings, PassTimes, VirtualLights},
    output,
};
use beamlight_scene::{bsdf::Bsdf, load::load_scene};
use beamlight_trace::{
    TraceScene,
    pt::PathTracerSettings,
    vbl::{self, VblSettings},
};
use clap::{Parser, Subcommand, ValueEnum};
use std::{
    io::IsTerminal,
    path::{Path, PathBuf},
    process::ExitCode,
    sync::Arc,
    time::{Duration, Instant},
};

#[derive(Parser)]
#[command(
    name = "beamlight",
    version,
    about = "Progressive virtual beam lights: a renderer for participating media"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene (TOML sidecar, or a .gltf/.glb alone) to a linear-RGB OpenEXR image.
    Render(Box<RenderArgs>),
    /// Compare two EXR images: RMSE, relMSE, MAE and maximum absolute error (B is the reference).
    Compare {
        a: PathBuf,
        b: PathBuf,
        /// Also compare every component layer the two files share (one line each).
        #[arg(long)]
        layers: bool,
    },
    /// Describe a scene: geometry, materials, media, emitters, backend.
    Info { scene: PathBuf },
    /// Write the scene for Mitsuba 3 (XML, PLY meshes and .vol grids beside it), saying what
    /// could not be exported exactly.
    ExportMitsuba {
        scene: PathBuf,
        output: PathBuf,
        /// Override the scene's image width.
        #[arg(long)]
        width: Option<u32>,
        /// Override the scene's image height.
        #[arg(long)]
        height: Option<u32>,
    },
    /// A labelled contact sheet (PNG). With one EXR: every layer of it, the beauty image and each
    /// transport component (paper Fig. 9). With several: the beauty image of each, side by side
    /// (equal-time comparisons). Each tile is tonemapped on its own unless --exposure is given.
    Sheet {
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Tile labels for several inputs, comma-separated (default: the file names).
        #[arg(long, value_delimiter = ',')]
        labels: Vec<String>,
        #[arg(short, long)]
        output: PathBuf,
        /// Tiles per row.
        #[arg(long, default_value_t = 4)]
        columns: u32,
        /// Each tile's luminance percentile (0–1) that maps to white.
        #[arg(long, default_value_t = 0.995)]
        percentile: f32,
        /// One exposure in stops for every tile instead (keeps brightness comparable).
        #[arg(long, allow_negative_numbers = true)]
        exposure: Option<f32>,
        /// Average N×N pixel blocks of every image first (smaller sheets of large renders).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
        downsample: u32,
    },
    /// Merge the accumulators of adjacent pass ranges (`render --passes A..B`) into one image.
    Merge {
        /// Accumulator files (`.accum`), in any order.
        parts: Vec<PathBuf>,
        /// The whole range the parts must cover, `A..B` (or `N` for `0..N`); without it, from
        /// the first part's start to the last part's end.
        #[arg(long)]
        passes: Option<runs::PassRange>,
        /// Output OpenEXR file; its accumulators are written beside it (`.accum`).
        #[arg(short, long)]
        output: PathBuf,
        /// Also write a tonemapped sRGB PNG preview.
        #[arg(long)]
        preview: Option<PathBuf>,
        /// Exposure of the preview in stops.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        exposure: f32,
    },
}

#[derive(Clone, Copy, ValueEnum)]
enum MethodArg {
    Vbl,
    Vrl,
    VrlClamped,
    Pt,
    /// Each component from `pt` and `vbl`, combined by their measured errors.
    Auto,
}

#[derive(Clone, Copy, ValueEnum, PartialEq)]
enum BackendArg {
    Auto,
    Gpu,
    Cpu,
}

#[derive(clap::Args)]
struct RenderArgs {
    scene: PathBuf,
    /// Output OpenEXR file (float32 linear RGB).
    #[arg(short, long)]
    output: PathBuf,
    #[arg(long, value_enum, default_value = "vbl")]
    method: MethodArg,
    /// Number of progressive passes, or a range `A..B` of the global pass sequence (one part
    /// of a render split across machines: its accumulators are written for `beamlight merge`).
    #[arg(long, conflicts_with_all = ["spp", "time"])]
    passes: Option<runs::PassRange>,
    /// Samples per pixel (for `pt`, the same as passes).
    #[arg(long, conflicts_with = "time")]
    spp: Option<u64>,
    /// Wall-clock budget in seconds, start-up included.
    #[arg(long)]
    time: Option<f64>,
    #[arg(long, default_value_t = 0)]
    seed: u32,
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
    /// Override the scene's image width.
    #[arg(long)]
    width: Option<u32>,
    /// Override the scene's image height.
    #[arg(long)]
    height: Option<u32>,
    /// Also write a tonemapped sRGB PNG preview.
    #[arg(long)]
    preview: Option<PathBuf>,
    /// Exposure of the preview in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    exposure: f32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Maximum scattering events per path (`pt`); 1 = direct light / single scattering only.
    #[arg(long)]
    max_depth: Option<u32>,
    /// Also write each transport component (direct, Lsm, Lmm, Lms, Lss, caustic_surface,
    /// caustic_volume) as its own EXR layer; `pt` classifies its paths the same way.
    #[arg(long)]
    components: bool,
    /// `pt`: estimate only these components (comma-separated layer names, e.g. `Lmm,Lms`);
    /// the others stay black. Paths that can reach none of them end early, and in homogeneous
    /// media a ray whose next surface could feed only the others collides for sure, so a
    /// component alone converges 1.7-3.9x faster than within the whole image. Implies
    /// `--components`.
    #[arg(long, value_name = "LIST", value_parser = parse_component_list)]
    only: Option<ComponentList>,
    /// Light paths traced per pass by the many-light methods (each leaves several VPLs/VRLs;
    /// at most 1 048 576).
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=many_lights::MAX_LIGHT_PATHS as i64))]
    light_paths: u32,
    /// `vbl`: virtual lights each gather record draws per component from the pass's light
    /// tree (1–1024), or `all` to gather every light of the pass (the all-pairs estimator).
    #[arg(long, default_value_t = LightSamples(Some(many_lights::DEFAULT_LIGHT_SAMPLES)), value_name = "N|all", value_parser = parse_light_samples)]
    light_samples: LightSamples,
    /// `vbl`: virtual beam lights each camera media segment draws for `Lmm` (1–1024; default:
    /// as `--light-samples`). More can pay in homogeneous glossy fog, where `Lmm`'s draws are
    /// the noisiest (see docs/rendering.md)
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
    media_light_samples: Option<u32>,
    /// Many-light methods: camera samples per pixel per pass for direct light (its own pixel
    /// jitter and next-event estimate each; the gathers use one).
    #[arg(long, default_value_t = many_lights::DEFAULT_DIRECT_SAMPLES, value_parser = clap::value_parser!(u32).range(1..=4096))]
    direct_samples: u32,
    /// Many-light methods: light paths traced per pass for the surface caustics (photon
    /// mapping), apart from the gathers' `--light-paths` (default: 4 per pixel, at least
    /// 32 768 and at most 4 194 304; at most 16 777 216 given).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=many_lights::MAX_CAUSTIC_PATHS as i64))]
    caustic_paths: Option<u32>,
    /// Many-light methods: light paths traced per pass for the volume caustics (photon
    /// beams; each costs a lookup per camera media segment it crosses; at most 4 194 304).
    #[arg(long, default_value_t = many_lights::DEFAULT_BEAM_PATHS, value_parser = clap::value_parser!(u32).range(1..=many_lights::MAX_BEAM_PATHS as i64))]
    beam_paths: u32,
    /// `vrl-clamped`: minimum distance in the 1/d² falloff (default: 5 % of the scene's diagonal).
    #[arg(long)]
    clamp_distance: Option<f32>,
    /// `vbl`: initial radius R0 of the virtual beam and spherical lights, in scene units
    /// (default: 10 % of the scene's diagonal).
    #[arg(long)]
    radius: Option<f32>,
    /// Initial radius of the caustics' photon mapping and photon beams, in scene units
    /// (default: 2.5 % of the scene's diagonal).
    #[arg(long)]
    photon_radius: Option<f32>,
    /// Also write the image (EXR and preview) every SECONDS while rendering, atomically, so
    /// an interrupted render leaves its latest state readable.
    #[arg(long, value_name = "SECONDS")]
    write_every: Option<f64>,
    /// `vbl`: directions integrating each virtual spherical light's solid angle (paper eq. 9;
    /// the paper uses up to 100).
    #[arg(long, default_value_t = vbl::DEFAULT_DIRECTIONS, value_parser = clap::value_parser!(u32).range(1..=1024))]
    vsl_directions: u32,
    /// `vbl`: most vertices of the piecewise-linear angular PDFs (fewer for segments that
    /// subtend small angles).
    #[arg(long, default_value_t = vbl::DEFAULT_PDF_VERTICES, value_parser = clap::value_parser!(u32).range(2..=64))]
    pdf_vertices: u32,
    /// Radius reduction α of the paper's eq. 11, in (0, 1); smaller shrinks faster.
    #[arg(long, default_value_t = 0.7)]
    alpha: f32,
    /// Testing only (hidden): the many-light methods poison the first record of each gather
    /// of every pass with a NaN, on the CPU and the GPU, and the first path of each light set,
    /// so that a test can read the counts back through `--stats`, `--stats-json` and the EXR
    /// header.
    #[arg(long, hide = true)]
    inject_nan: bool,
    /// Save the accumulators (running sums, pass count, settings) to FILE every
    /// `--write-every` seconds (default 60) and at the end, atomically.
    #[arg(long, value_name = "FILE")]
    checkpoint: Option<PathBuf>,
    /// Continue the render saved in FILE (same scene and settings): `--passes N` then counts
    /// all passes, the saved ones included.
    #[arg(long, value_name = "FILE", conflicts_with = "spp")]
    resume: Option<PathBuf>,
    /// Print where the passes' time went: CPU tracing, CPU estimates, waiting for the GPU,
    /// and each GPU kernel's time (from timestamp queries).
    #[arg(long)]
    stats: bool,
    /// Write the run's timings as JSON to FILE (for `cargo xtask bench`): process time with
    /// and without start-up, passes, and the CPU and GPU seconds of each transport component.
    #[arg(long, value_name = "FILE")]
    stats_json: Option<PathBuf>,
}

/// `--only`: which components, by `Component::ALL` index.
#[derive(Clone, Copy, Debug)]
struct ComponentList([bool; Component::ALL.len()]);

fn parse_component_list(s: &str) -> Result<ComponentList, String> {
    let mut list = [false; Component::ALL.len()];
    for name in s.split(',').map(str::trim) {
        let Some(k) = Component::ALL.iter().position(|c| c.name() == name) else {
            let names: Vec<&str> = Component::ALL.iter().map(|c| c.name()).collect();
            return Err(format!("'{name}' is not a component (one of {})", names.join(", ")));
        };
        list[k] = true;
    }
    Ok(ComponentList(list))
}

/// `--light-samples`: a count, or `None` for all pairs.
#[derive(Clone, Copy, Debug)]
struct LightSamples(Option<u32>);

impl std::fmt::Display for LightSamples {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self.0 {
            Some(n) => write!(f, "{n}"),
            None => write!(f, "all"),
        }
    }
}

fn parse_light_samples(s: &str) -> Result<LightSamples, String> {
    if s == "all" {
        return Ok(LightSamples(None));
    }
    match s.parse::<u32>() {
        Ok(n) if (1..=1024).contains(&n) => Ok(LightSamples(Some(n))),
        _ => Err(format!("'{s}' is neither a number of lights in 1..=1024 nor 'all'")),
    }
}

/// Runs the command line; errors are printed as one clear message and give exit code 1.
pub fn main() -> ExitCode {
    let start = Instant::now();
    let runtime_dir = quiet_vulkan_loader();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => render(*args, start),
        Command::Compare { a, b, layers } => compare_cmd(&a, &b, layers),
        Command::Info { scene } => info(&scene),
        Command::ExportMitsuba {
            scene,
            output,
            width,
            height,
        } => export_mitsuba(&scene, &output, width, height),
        Command::Sheet {
            inputs,
            labels,
            output,
            columns,
            percentile,
            exposure,
            downsample,
        } => sheet_cmd(&inputs, &labels, &output, columns, percentile, exposure, downsample),
        Command::Merge {
            parts,
            passes,
            output,
            preview,
            exposure,
        } => check_output_path(&output, "exr")
            .and_then(|()| runs::merge(&parts, passes, &output, preview.as_deref(), exposure)),
    };
    if let Some(dir) = runtime_dir {
        let _ = std::fs::remove_dir_all(dir);
    }
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // The image is written; the exit code still tells a script the render did not finish.
        Err(e) if e.is::<runs::Interrupted>() => ExitCode::from(130),
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

const DEFAULT_PASSES: u64 = 64;

/// The shortest time between two progress lines when standard error is not a terminal.
const PROGRESS_EVERY: Duration = Duration::from_secs(10);

fn render(args: RenderArgs, start: Instant) -> Result<()> {
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
            .context("cannot set up the thread pool")?;
    }
    let method = match args.method {
        MethodArg::Pt => Method::Pt,
        MethodArg::Vrl => Method::Vrl,
        MethodArg::VrlClamped => Method::VrlClamped,
        MethodArg::Vbl => Method::Vbl,
        MethodArg::Auto => Method::Auto,
    };
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
    let pass_count = args.passes.map(|r| r.end - r.start.unwrap_or(0)).or(args.spp);
    if range_start.is_some() && args.resume.is_some() {
        bail!("--resume continues a whole render; a pass range (--passes A..B) starts at A");
    }
    let budget = match (pass_count, args.time) {
        (Some(0), _) => bail!("--passes/--spp must be at least 1"),
        (Some(n), _) => Budget::Passes(n),
        (None, Some(t)) if t.is_finite() && t > 0.0 => Budget::Time(Duration::from_secs_f64(t)),
        (None, Some(t)) => bail!("--time must be a positive number of seconds, got {t}"),
        (None, None) if args.resume.is_some() => bail!("--resume needs the total --passes N or a --time budget"),
        (None, None) => Budget::Passes(DEFAULT_PASSES),
    };
    for (flag, v) in [("--width", args.width), ("--height", args.height)] {
        if let Some(v) = v
            && (v == 0 || v > 16384)
        {
            bail!("{flag} {v} is out of range (1..=16384)");
        }
    }
    if args.only.is_some() && method != Method::Pt {
        bail!(
            "--only restricts the path tracer; with --method {} every component is computed (auto restricts its path tracer by itself)",
            method.name()
        );
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
    let opening = Instant::now();
    let (gpu, backend) = choose_backend(args.backend, method, &ts)?;
    let gpu_time = opening.elapsed();
    if args.stats {
        eprintln!(
            "start-up: scene loaded in {:.2} s, CPU BVH and light tables built in {:.2} s, GPU opened and scene uploaded in {:.2} s",
            load_time.as_secs_f64(),
            bvh_time.as_secs_f64(),
            gpu_time.as_secs_f64()
        );
    }
    eprintln!(
        "beamlight: {} ({} triangles), {width}x{height}, method {}, backend {backend}",
        args.scene.display(),
        ts.scene.triangles.len(),
        method.name()
    );

    let opts = RenderOptions {
        method,
        width,
        height,
        budget,
        seed: args.seed,
        first_pass: range_start.unwrap_or(0),
        path_tracer: PathTracerSettings {
            max_depth: args.max_depth,
            components: args.only.map_or([true; Component::ALL.len()], |l| l.0),
            ..Default::default()
        },
        start,
        // The many-light methods always keep their components apart (and write them).
        components: args.components || args.only.is_some() || method != Method::Pt,
        many_lights: ManyLightSettings {
            light_paths_per_pass: args.light_paths,
            light_samples: args.light_samples.0,
            media_light_samples: args.media_light_samples,
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
            components: [true; Component::ALL.len()],
            inject_nan: args.inject_nan,
        },
        gpu,
    };
    // Checkpoints and pass ranges: what identifies this render, and where it resumes.
    let fingerprint = runs::fingerprint(&ts.scene, &opts);
    let resumed = match &args.resume {
        Some(path) => Some(runs::read_checkpoint(path, &fingerprint)?),
        None => None,
    };
    let mut opts = opts;
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
    eprintln!(
        "done: {} in {secs:.2} s, {} spp, {:.3} Msamples/s -> {}",
        method.name(),
        result.passes,
        (result.passes * width as u64 * height as u64) as f64 / secs.max(1e-9) / 1e6,
        args.output.display()
    );
    Ok(())
}

/// Mesa's Vulkan drivers print "error: XDG_RUNTIME_DIR is invalid or not set" on every device
/// open without that variable (containers, CI), which reads like one of ours: give the process
/// a private runtime directory when it has none (returned, to be removed at exit).
fn sheet_cmd(
    inputs: &[PathBuf],
    labels: &[String],
    output: &Path,
    columns: u32,
    percentile: f32,
    exposure: Option<f32>,
    downsample: u32,
) -> Result<()> {
    use beamlight_render::sheet::{Exposure, contact_sheet};
    check_output_path(output, "png")?;
    if !(0.0..=1.0).contains(&percentile) {
        bail!("--percentile {percentile}: must lie in [0, 1]");
    }
    if !labels.is_empty() && labels.len() != inputs.len() {
        bail!(
            "--labels names {} tiles but {} images were given",
            labels.len(),
            inputs.len()
        );
    }
    let tiles: Vec<(String, beamlight_render::Image)> = if let [input] = inputs {
        beamlight_render::output::read_exr_layers(input)?
            .into_iter()
            .map(|(name, img)| (if name.is_empty() { "beauty".into() } else { name }, img))
            .collect()
    } else {
        let mut tiles = Vec::new();
        for (k, input) in inputs.iter().enumerate() {
            let (img, _) = beamlight_render::output::read_exr(input)?;
            let label = labels.get(k).cloned().unwrap_or_else(|| {
                input
                    .file_stem()
                    .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
            });
            tiles.push((label, img));
        }
        tiles
    };
    let tiles: Vec<(String, beamlight_render::Image)> = tiles
        .into_iter()
        .map(|(label, img)| (label, img.downsample(downsample)))
        .collect();
    let exposure = match exposure {
        Some(stops) => Exposure::Shared { stops },
        None => Exposure::PerTile { percentile },
    };
    let refs: Vec<(&str, &beamlight_render::Image)> = tiles.iter().map(|(l, i)| (l.as_str(), i)).collect();
    let (w, h, rgb) = contact_sheet(&refs, columns, exposure);
    beamlight_render::output::write_png_rgb8(output, w, h, rgb)?;
    eprintln!("wrote {} ({} tiles)", output.display(), tiles.len());
    Ok(())
}

fn quiet_vulkan_loader() -> Option<PathBuf> {
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
fn choose_backend(arg: BackendArg, method: Method, ts: &TraceScene) -> Result<(Option<Arc<GpuBackend>>, String)> {
    let has_kernels = match method {
        Method::Pt => false,
        Method::Vbl | Method::Auto => many_lights::gpu_has_kernels(VirtualLights::Beams),
        Method::Vrl | Method::VrlClamped => many_lights::gpu_has_kernels(VirtualLights::Rays),
    };
    let beams = matches!(method, Method::Vbl | Method::Auto);
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

/// The `--stats` timeline summary: per pass, how long the CPU and the GPU were busy and how
/// long the CPU waited. With a GPU, one pass is in flight: the CPU traces and estimates pass
/// i + 1 while the GPU gathers pass i, so busy times can add up to more than the wall time.
fn print_stats(times: &[PassTimes], discarded: &Discards) {
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
fn stats_json(
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
    let kernels = many_lights::gpu_kernels(match opts.method {
        Method::Vbl | Method::Auto => VirtualLights::Beams,
        _ => VirtualLights::Rays,
    });
    let gpu_component = [Component::Lss, Component::Lsm, Component::Lms, Component::Lmm];
    let discarded = result.discarded;
    let mut components = serde_json::Map::new();
    for (k, c) in Component::ALL.iter().enumerate() {
        let gpu: f64 = kernels
            .iter()
            .zip(gpu_component)
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

/// Where and how the render's images are written (at the end, and with `--write-every`).
struct Outputs<'a> {
    args: &'a RenderArgs,
    method: Method,
    backend: &'a str,
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
        let passes = film.samples;
        let image = film.image();
        let mut metadata = vec![
            ("beamlight.method", self.method.name().to_string()),
            ("beamlight.passes", passes.to_string()),
            ("beamlight.spp", passes.to_string()),
            ("beamlight.seed", args.seed.to_string()),
            ("beamlight.render_seconds", format!("{:.3}", elapsed.as_secs_f64())),
            ("beamlight.scene", args.scene.display().to_string()),
            ("beamlight.backend", self.backend.to_string()),
            ("beamlight.rejected_samples", film.rejected.to_string()),
            ("beamlight.discarded_estimates", discarded.to_string()),
        ];
        if let Some(report) = auto {
            metadata.push(("beamlight.auto", report.lines().join("; ")));
        }
        let layers: Vec<(Component, beamlight_render::Image)> = Component::ALL
            .iter()
            .zip(components)
            .map(|(c, f)| (*c, f.image()))
            .collect();
        let named: Vec<(&str, &beamlight_render::Image)> = layers.iter().map(|(c, i)| (c.name(), i)).collect();
        output::write_exr_layers(&args.output, &image, &named, &metadata)?;
        if let Some(p) = &args.preview {
            output::write_png(p, &image, args.exposure)?;
        }
        Ok(())
    }
}

fn check_output_path(p: &Path, ext: &str) -> Result<()> {
    match p.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case(ext) => Ok(()),
        _ => bail!("{}: output file must end in .{ext}", p.display()),
    }
}

fn progress_bar(budget: &Budget) -> indicatif::ProgressBar {
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

/// `writeln!` into a report string (formatting into a `String` cannot fail).
macro_rules! outln {
    ($out:expr, $($arg:tt)*) => {{
        use std::fmt::Write as _;
        let _ = writeln!($out, $($arg)*);
    }};
}

/// Prints a finished report; a closed pipe (`beamlight info … | head`) is not an error.
fn print_stdout(text: &str) -> Result<()> {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    match stdout.write_all(text.as_bytes()).and_then(|()| stdout.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e).context("cannot write to standard output"),
        _ => Ok(()),
    }
}

fn export_mitsuba(scene_path: &Path, output: &Path, width: Option<u32>, height: Option<u32>) -> Result<()> {
    check_output_path(output, "xml")?;
    let mut scene = load_scene(scene_path)?;
    for v in [width, height].into_iter().flatten() {
        if v == 0 || v > 16384 {
            bail!("image size {v} is out of range (1..=16384)");
        }
    }
    scene.render.width = width.unwrap_or(scene.render.width);
    scene.render.height = height.unwrap_or(scene.render.height);
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let ts = TraceScene::new(scene);
    let report = mitsuba::export(&ts.scene, ts.camera_medium, output)?;
    eprintln!(
        "wrote {}: {} shapes ({} triangles), {} area and {} punctual emitters, {} media",
        output.display(),
        report.shapes,
        report.triangles,
        report.area_emitters,
        report.punctual_emitters,
        report.media
    );
    for w in &report.not_exported {
        eprintln!("not exported exactly: {w}");
    }
    Ok(())
}

fn compare_cmd(a: &Path, b: &Path, layers: bool) -> Result<()> {
    let mut out = String::new();
    let (ia, _) = output::read_exr(a)?;
    let (ib, _) = output::read_exr(b)?;
    let m = compare::compare(&ia, &ib).map_err(|e| anyhow::anyhow!("{} vs {}: {e}", a.display(), b.display()))?;
    outln!(out, "RMSE    {:.6e}", m.rmse);
    outln!(out, "relMSE  {:.6e}", m.rel_mse);
    outln!(out, "MAE     {:.6e}", m.mae);
    outln!(out, "max     {:.6e}", m.max_abs);
    outln!(out, "mean    {:?} vs {:?}", ia.mean(), ib.mean());
    if layers {
        let (la, lb) = (output::read_exr_layers(a)?, output::read_exr_layers(b)?);
        for (name, image) in la.iter().filter(|(n, _)| !n.is_empty()) {
            let Some((_, reference)) = lb.iter().find(|(n, _)| n == name) else {
                continue;
            };
            let m = compare::compare(image, reference)
                .map_err(|e| anyhow::anyhow!("layer {name} of {} vs {}: {e}", a.display(), b.display()))?;
            outln!(
                out,
                "{name:<16} RMSE {:.6e}  relMSE {:.6e}  mean {:?} vs {:?}",
                m.rmse,
                m.rel_mse,
                image.mean(),
                reference.mean()
            );
        }
    }
    print_stdout(&out)
}

fn info(path: &Path) -> Result<()> {
    let mut out = String::new();
    let scene = load_scene(path)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let ts = TraceScene::new(scene);
    let s = &ts.scene;
    outln!(out, "scene       {}", path.display());
    outln!(out, "image       {}x{}", s.render.width, s.render.height);
    let cam = &s.camera;
    outln!(
        out,
        "camera      {} at {:?}, yfov {:.1}°",
        cam.name.as_deref().unwrap_or("(default)"),
        cam.position(),
        cam.yfov.to_degrees()
    );
    let (lo, hi) = s.bounds();
    outln!(out, "bounds      {lo:?} .. {hi:?}");
    outln!(out, "triangles   {}", s.triangles.len());
    let emissive = s
        .triangles
        .iter()
        .filter(|t| s.materials[t.material as usize].is_emissive())
        .count();
    outln!(
        out,
        "emitters    {emissive} emissive triangles, {} punctual lights",
        s.lights.len()
    );
    outln!(out, "materials");
    for m in &s.materials {
        let kind = match &m.bsdf {
            None => "medium boundary (index-matched)".to_string(),
            Some(Bsdf::Lambert { albedo }) => format!("lambert albedo {albedo:?}"),
            Some(Bsdf::Phong {
                diffuse,
                specular,
                exponent,
            }) => {
                format!("phong diffuse {diffuse:?} specular {specular:?} exponent {exponent}")
            }
            Some(Bsdf::Mirror { reflectance }) => format!("mirror {reflectance:?}"),
            Some(Bsdf::Glass { ior, .. }) => format!("glass ior {ior}"),
        };
        let emit = if m.is_emissive() {
            format!(", emits {:?}", m.emission)
        } else {
            String::new()
        };
        outln!(out, "  {:<20} {kind}{emit}", m.name);
    }
    outln!(out, "media");
    for (i, m) in s.media.iter().enumerate() {
        let region = if s.global_medium == Some(i as u32) {
            "global"
        } else {
            "bounded"
        };
        let kind = match &m.density {
            None => "homogeneous".to_string(),
            Some(g) => format!("grid {}x{}x{}", g.res.x, g.res.y, g.res.z),
        };
        outln!(
            out,
            "  {:<20} {region}, {kind}, sigma_s {:?}, sigma_a {:?}, g {}",
            m.name,
            m.sigma_s,
            m.sigma_a,
            m.g
        );
    }
    let needed = SceneFeatures::of(s).needed();
    let names: Vec<&str> = needed.iter().map(|c| c.name()).collect();
    outln!(
        out,
        "components  {} (of the many-light methods; `pt` renders the whole image)",
        if names.is_empty() {
            "none: the scene has no emitters".to_string()
        } else {
            names.join(", ")
        }
    );
    if !needed.is_empty() {
        let only = beamlight_render::auto::vbl_only(&ts);
        let (solo, both): (Vec<Component>, Vec<Component>) = needed.iter().partition(|c| only[**c as usize]);
        let list = |v: &[Component]| v.iter().map(|c| c.name()).collect::<Vec<_>>().join(", ");
        let (caustics, blind): (Vec<Component>, Vec<Component>) = solo
            .into_iter()
            .partition(|c| matches!(c, Component::CausticSurface | Component::CausticVolume));
        let mut plan = Vec::new();
        if !both.is_empty() {
            plan.push(format!(
                "{}: pt and vbl, one weight per component from their measured errors; vbl runs a component only while its passes lower the error faster per second than path tracing",
                list(&both)
            ));
        }
        if !caustics.is_empty() {
            plan.push(format!(
                "{}: vbl's photon maps and beams alone (the path tracer finds caustic light only by hitting an emitter through the mirror or glass: rare, heavy-tailed samples)",
                list(&caustics)
            ));
        }
        if !blind.is_empty() {
            plan.push(format!(
                "{}: vbl alone (the path tracer cannot follow light from point, spot or directional lights through mirrors or glass, which reaches these)",
                list(&blind)
            ));
        }
        let plan = plan.join("; ");
        outln!(out, "auto        {plan}");
    }
    let cam_medium = ts
        .camera_medium
        .map_or("vacuum".to_string(), |i| s.media[i as usize].name.clone());
    outln!(out, "camera in   {cam_medium}");
    let adapters = beamlight_gpu::device::adapters();
    outln!(
        out,
        "backend     {}",
        match adapters.first() {
            None => "cpu: no Vulkan adapter".to_string(),
            Some(a) if beamlight_gpu::device::is_cpu_adapter(a) => format!(
                "`auto` runs the gathers of `vbl` on {} (a CPU adapter, faster for them than the CPU estimators) and keeps those of `vrl` on the CPU",
                a.name
            ),
            Some(a) => format!("`auto` runs the virtual-light gathers on {}", a.name),
        }
    );
    if adapters.is_empty() {
        outln!(out, "gpu         none (no Vulkan adapter: the gathers run on the CPU)");
    }
    for (i, a) in adapters.iter().enumerate() {
        outln!(out, "gpu {i}       {}", beamlight_gpu::device::describe(a));
    }
    if !adapters.is_empty() {
        match Gpu::open() {
            Ok(g) => {
                let l = &g.limits;
                outln!(
                    out,
                    "gpu limits  storage binding {} MiB, buffer {} MiB, {} workgroups per dimension, {} storage buffers per stage, timestamps {}",
                    l.max_storage_buffer_binding_size >> 20,
                    l.max_buffer_size >> 20,
                    l.max_compute_workgroups_per_dimension,
                    l.max_storage_buffers_per_shader_stage,
                    if g.timestamps { "yes" } else { "no" }
                );
            }
            Err(e) => outln!(out, "gpu limits  unavailable: {e}"),
        }
    }
    print_stdout(&out)
}
