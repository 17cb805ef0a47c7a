//! `cargo xtask bench`: run time against error, per scene, for every method and backend of
//! beamlight and for Mitsuba 3's `volpath`, against a cached path-traced reference.
//! See `docs/benchmarks.md` for what it measures and how to read the results.
mod metrics;
mod mitsuba;
mod plot;
mod reference;
mod report;
mod runs;
mod sheet;
mod summary;

use anyhow::{Context, Result, bail};
use metrics::Image;
use report::{convention_check, curves, scene_summary, write_csv};
use runs::{BeamlightRun, Budget, Timing};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

pub const USAGE: &str = "usage: cargo xtask bench [options]
  --scenes A,B,...      scene names in assets/scenes/ or paths to .toml files (default
                        cornell_glossy_fog,cornell_smoke,cornell, and the glass scenes
                        caustic_sphere,caustic_sphere_wide,lamp_in_glass,cars_small)
  --methods M,...       pt,vrl,vrl-clamped,vbl,auto (default all five)
  --backends B,...      cpu,gpu (default both; pt always runs on the cpu, and gpu is
                        skipped without a Vulkan adapter)
  --budgets S,...       wall-time budgets in seconds before scaling (default 1,2,4,8,16)
  --time-scale X        multiplies every budget and the reference time (default 1)
  --size N              image width and height (default 96)
  --ref-time S          seconds per reference half and estimator before scaling (default 60)
  --ref-goal R          the reference's own relMSE to reach: while it is above, more rounds
                        (each doubling one estimator's time) are rendered (default 2.5e-3, a
                        quarter of the glass scenes' 1e-2 target; 0: as many as the cap allows)
  --ref-cap X           the most time a reference takes, as a multiple of its first round's
                        (default 4)
  --ref-renderer ID     the renderer identity the reference cache is keyed by (default: the
                        last commit touching the renderer's sources, '+dirty' with changes);
                        an earlier build's, to compare two builds against one reference
  --ref-methods M,...   the reference's estimators: pt, or pt and a second independent one
                        (e.g. pt,vrl), checked against each other per component and combined;
                        'auto' (default): pt, plus vrl where the scene has caustics
  --only C,...          restrict every render and the reference to these components (e.g.
                        Lmm): each series is then that component alone (`render --only`), and
                        the reference's floor under it is far lower than a whole-image
                        reference's layer (not with the method auto, which picks its own)
  --repeats N           renders per budget (different seeds), medians reported (default 1)
  --target R            relMSE for the time-to-target table (default: what pt reaches at
                        the middle budget, per scene)
  --no-mitsuba          skip Mitsuba 3 even when it is installed
  --check-scene NAME    Lambert-only scene for the pt-vs-Mitsuba convention check
                        (default cornell; 'none' skips it)
  --check-time S        seconds per Mitsuba half of that check before scaling (default 45)
  --python P            Python interpreter with the mitsuba package (default python3)
  --out DIR             results directory (default bench/results)";

struct Options {
    scenes: Vec<String>,
    methods: Vec<String>,
    backends: Vec<String>,
    budgets: Vec<f64>,
    scale: f64,
    size: u32,
    ref_time: f64,
    ref_goal: f64,
    ref_cap: f64,
    /// `None`: per scene, pt plus vrl where it has caustics.
    ref_methods: Option<Vec<String>>,
    /// `None`: [`renderer_id`].
    ref_renderer: Option<String>,
    /// Components every render and the reference are restricted to (`render --only`).
    only: Option<String>,
    repeats: u32,
    target: Option<f64>,
    mitsuba: bool,
    check_scene: Option<String>,
    check_time: f64,
    python: String,
    out: Option<PathBuf>,
}

fn parse(args: &[String]) -> Result<Options> {
    let mut o = Options {
        scenes: [
            "cornell_glossy_fog",
            "cornell_smoke",
            "cornell",
            "caustic_sphere",
            "caustic_sphere_wide",
            "lamp_in_glass",
            "cars_small",
        ]
        .map(String::from)
        .to_vec(),
        methods: ["pt", "vrl", "vrl-clamped", "vbl", "auto"].map(String::from).to_vec(),
        backends: ["cpu", "gpu"].map(String::from).to_vec(),
        budgets: vec![1.0, 2.0, 4.0, 8.0, 16.0],
        scale: 1.0,
        size: 96,
        ref_time: 60.0,
        ref_goal: 2.5e-3,
        ref_cap: 4.0,
        ref_methods: None,
        ref_renderer: None,
        only: None,
        repeats: 1,
        target: None,
        mitsuba: true,
        check_scene: Some("cornell".into()),
        check_time: 45.0,
        python: "python3".into(),
        out: None,
    };
    let list = |v: &str| {
        v.split(',')
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect::<Vec<_>>()
    };
    let num = |flag: &str, v: &str| -> Result<f64> {
        let x: f64 = v.parse().with_context(|| format!("{flag}: '{v}' is not a number"))?;
        if !(x > 0.0 && x.is_finite()) {
            bail!("{flag} must be positive, got {v}");
        }
        Ok(x)
    };
    let mut it = args.iter();
    while let Some(flag) = it.next() {
        if flag == "--no-mitsuba" {
            o.mitsuba = false;
            continue;
        }
        if flag == "-h" || flag == "--help" {
            println!("{USAGE}");
            std::process::exit(0);
        }
        let Some(v) = it.next() else {
            bail!("{flag} needs a value\n\n{USAGE}");
        };
        match flag.as_str() {
            "--scenes" => o.scenes = list(v),
            "--methods" => o.methods = list(v),
            "--backends" => o.backends = list(v),
            "--budgets" => o.budgets = list(v).iter().map(|b| num(flag, b)).collect::<Result<_>>()?,
            "--time-scale" => o.scale = num(flag, v)?,
            "--size" => o.size = num(flag, v)? as u32,
            "--ref-time" => o.ref_time = num(flag, v)?,
            "--ref-goal" => {
                o.ref_goal = v.parse().with_context(|| format!("{flag}: '{v}' is not a number"))?;
                if !(o.ref_goal >= 0.0 && o.ref_goal.is_finite()) {
                    bail!("{flag} must be 0 or positive, got {v}");
                }
            }
            "--ref-cap" => o.ref_cap = num(flag, v)?.max(1.0),
            "--ref-renderer" => o.ref_renderer = Some(v.to_string()),
            "--ref-methods" => o.ref_methods = (v != "auto").then(|| list(v)),
            "--only" => o.only = Some(list(v).join(",")),
            "--repeats" => o.repeats = num(flag, v)? as u32,
            "--target" => o.target = Some(num(flag, v)?),
            "--check-scene" => o.check_scene = (v != "none").then(|| v.clone()),
            "--check-time" => o.check_time = num(flag, v)?,
            "--python" => o.python = v.clone(),
            "--out" => o.out = Some(PathBuf::from(v)),
            _ => bail!("unknown option '{flag}'\n\n{USAGE}"),
        }
    }
    for m in &o.methods {
        if !["pt", "vrl", "vrl-clamped", "vbl", "auto"].contains(&m.as_str()) {
            bail!("unknown method '{m}' (pt, vrl, vrl-clamped, vbl, auto)");
        }
    }
    for m in o.ref_methods.iter().flatten() {
        if !["pt", "vrl", "vrl-clamped", "vbl", "auto"].contains(&m.as_str()) {
            bail!("unknown reference method '{m}'");
        }
    }
    if let Some(only) = &o.only {
        if only.is_empty() {
            bail!("--only needs at least one component");
        }
        let known: Vec<&str> = report::component_names().collect();
        for c in only.split(',') {
            if !known.contains(&c) {
                bail!("--only: unknown component '{c}' ({})", known.join(", "));
            }
        }
        if o.methods
            .iter()
            .chain(o.ref_methods.iter().flatten())
            .any(|m| m == "auto")
        {
            bail!("--only restricts what a method estimates, which auto decides itself: drop auto from the methods");
        }
    }
    if o.ref_methods.as_ref().is_some_and(|m| m.is_empty() || m.len() > 2) {
        bail!("--ref-methods takes one or two methods");
    }
    for b in &o.backends {
        if !["cpu", "gpu"].contains(&b.as_str()) {
            bail!("unknown backend '{b}' (cpu, gpu)");
        }
    }
    if o.scenes.is_empty() || o.methods.is_empty() || o.budgets.is_empty() || o.size == 0 || o.repeats == 0 {
        bail!("nothing to run\n\n{USAGE}");
    }
    o.budgets.sort_by(|a, b| a.total_cmp(b));
    Ok(o)
}

/// A curve on the plot: one renderer, method and backend.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct SeriesKey {
    renderer: String,
    method: String,
    backend: String,
}

impl SeriesKey {
    fn label(&self) -> String {
        if self.renderer == "mitsuba" {
            format!("mitsuba {}", self.method)
        } else {
            format!("{} {}", self.method, self.backend)
        }
    }
}

/// One render's measurements.
#[derive(Clone, Debug)]
struct Row {
    key: SeriesKey,
    budget: f64,
    repeat: u32,
    seed: u32,
    timing: Timing,
    rel_mse: f64,
    rmse: f64,
    /// Per component layer (name, relMSE, RMSE) against the component-split reference.
    components: Vec<(String, f64, f64)>,
    image: PathBuf,
}

fn scene_path(root: &Path, name: &str) -> PathBuf {
    let p = PathBuf::from(name);
    if p.extension().is_some_and(|e| e == "toml") || p.is_file() {
        return p;
    }
    root.join("assets/scenes").join(format!("{name}.toml"))
}

fn scene_name(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default()
}

/// The renderer's identity for the reference cache: the last commit touching its sources,
/// "+dirty" when they have uncommitted changes.
fn renderer_id(root: &Path) -> String {
    let git = |args: &[&str]| {
        Command::new("git")
            .current_dir(root)
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    let paths = ["crates/scene", "crates/trace", "crates/render", "src"];
    let mut args = vec!["log", "-1", "--format=%H", "--"];
    args.extend(paths);
    let commit = git(&args).unwrap_or_else(|| "unknown".into());
    let mut diff = vec!["status", "--porcelain", "--"];
    diff.extend(paths);
    let dirty = git(&diff).is_some_and(|s| !s.is_empty());
    format!("{commit}{}", if dirty { "+dirty" } else { "" })
}

pub fn main(root: &Path, args: &[String]) -> Result<()> {
    let o = parse(args)?;
    let results = o.out.clone().unwrap_or_else(|| root.join("bench/results"));
    let work = root.join("bench/out");
    let cache = root.join("bench/cache");
    for d in [&results, &work, &cache] {
        std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
    }
    crate::build_release_binary(root)?;
    let bin = root.join("target/release/beamlight");
    let script = root.join("bench/mitsuba_render.py");
    let mitsuba = if o.mitsuba {
        match mitsuba::available(&o.python) {
            Ok(v) => {
                eprintln!("bench: Mitsuba {v} found: its volpath runs at the same budgets");
                Some(v)
            }
            Err(why) => {
                eprintln!("bench: skipping Mitsuba 3: {why}");
                None
            }
        }
    } else {
        None
    };
    let gpu = adapter_present(&bin);
    let ref_settings = reference::RefSettings {
        size: o.size,
        seconds_per_half: o.ref_time * o.scale,
        seed_base: 1_000_001,
        methods: vec!["pt".into()],
        renderer: o.ref_renderer.clone().unwrap_or_else(|| renderer_id(root)),
        goal: o.ref_goal,
        // One round for the convention check's `pt` reference (its ratio accounts for the
        // reference's own error); each bench scene's gets its cap below.
        max_seconds: 0.0,
        only: None,
    };
    let budgets: Vec<f64> = o.budgets.iter().map(|b| b * o.scale).collect();
    let mut summary = String::new();
    let mut headline = Vec::new();
    let _ = writeln!(summary, "# Benchmark: run time against error\n");
    let _ = writeln!(
        summary,
        "Command: `cargo xtask bench {}`. Machine: {} cores, {}. Image {}², budgets {} s (start-up included), {} repeat(s) per budget (medians). Reference: `pt` (and, where the scene has caustics, `vrl`) for 2 × {:.0} s per estimator and scene, then rounds doubling one estimator's time while its own relMSE is above {:.1e} (at most {}× the first round's time). Mitsuba 3: {}.\n",
        args.join(" "),
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        if gpu {
            "Vulkan adapter present (the `gpu` backend)"
        } else {
            "no Vulkan adapter"
        },
        o.size,
        budgets.iter().map(|b| format!("{b:.3}")).collect::<Vec<_>>().join(", "),
        o.repeats,
        ref_settings.seconds_per_half,
        o.ref_goal,
        o.ref_cap,
        match (&mitsuba, o.mitsuba) {
            (Some(v), _) => format!("{v}, `volpath`, via `bench/mitsuba_render.py`"),
            (None, false) => "not run (`--no-mitsuba`)".to_string(),
            (None, true) => format!("not run ({})", mitsuba::INSTALL_HINT),
        }
    );
    if let Some(only) = &o.only {
        let _ = writeln!(
            summary,
            "**Restricted to {only}**: every render and the reference estimate only these components (`--only {only}`), so each error below is theirs alone, against a reference of them alone; Mitsuba does not run.\n"
        );
    }
    let _ = writeln!(
        summary,
        "Columns and method: [docs/benchmarks.md](../../docs/benchmarks.md). Errors are relMSE against the reference; the reference's own estimated relMSE is a floor under every error.\n"
    );

    for name in &o.scenes {
        let scene = scene_path(root, name);
        if !scene.is_file() {
            bail!("{}: no such scene", scene.display());
        }
        let sname = scene_name(&scene);
        let swork = work.join(&sname);
        std::fs::create_dir_all(&swork)?;
        // A second estimator where the path tracer is slow: the caustics, unless the renders
        // are restricted to components without them.
        let caustics_wanted = o.only.as_ref().is_none_or(|c| c.contains("caustic_"));
        let ref_methods = match &o.ref_methods {
            Some(m) => m.clone(),
            None if caustics_wanted && has_caustics(&bin, &scene)? => vec!["pt".into(), "vrl".into()],
            None => vec!["pt".into()],
        };
        let scene_ref = reference::RefSettings {
            max_seconds: o.ref_cap * 2.0 * ref_settings.seconds_per_half * ref_methods.len() as f64,
            methods: ref_methods,
            only: o.only.clone(),
            ..ref_settings.clone()
        };
        let reference = reference::make_or_reuse(&bin, &cache, &scene, &scene_ref)?;
        eprintln!(
            "bench: {sname}: reference {} spp ({}, {}), estimated relMSE {:.2e}",
            reference.spp,
            reference.dir.display(),
            if reference.reused { "cached" } else { "new" },
            reference.est_rel_mse
        );
        let mut series: Vec<SeriesKey> = Vec::new();
        for m in &o.methods {
            for b in &o.backends {
                // `pt` has no GPU kernels; `auto` runs on the CPU next to a CPU adapter (its
                // own choice with `--backend auto`), and its `vbl` share is measured in `vbl`.
                if b == "gpu" && (m == "pt" || m == "auto" || !gpu) {
                    continue;
                }
                series.push(SeriesKey {
                    renderer: "beamlight".into(),
                    method: m.clone(),
                    backend: b.clone(),
                });
            }
        }
        let mut not_exported = Vec::new();
        let xml = swork.join("mitsuba/scene.xml");
        // Mitsuba renders the whole image: it has no place in a bench of some components.
        if mitsuba.is_some() && o.only.is_none() {
            std::fs::create_dir_all(xml.parent().expect("a parent"))?;
            not_exported = mitsuba::export(&bin, &scene, &xml, o.size)?;
            series.push(SeriesKey {
                renderer: "mitsuba".into(),
                method: "volpath".into(),
                backend: "llvm".into(),
            });
        }
        let only_args: Vec<&str> = match &o.only {
            Some(c) => vec!["--only", c],
            None => Vec::new(),
        };
        let mut rows: Vec<Row> = Vec::new();
        for (bi, &budget) in budgets.iter().enumerate() {
            for repeat in 0..o.repeats {
                for key in &series {
                    let seed = repeat;
                    let image = swork.join(format!(
                        "{}_{}_{}_b{bi}_r{repeat}.exr",
                        key.renderer, key.method, key.backend
                    ));
                    let timing = if key.renderer == "mitsuba" {
                        mitsuba::render(&o.python, &script, &xml, &image, Budget::Seconds(budget), seed)?
                    } else {
                        BeamlightRun {
                            bin: &bin,
                            scene: &scene,
                            output: image.clone(),
                            method: &key.method,
                            backend: &key.backend,
                            budget: Budget::Seconds(budget),
                            seed,
                            size: o.size,
                            components: false,
                            extra_args: &only_args,
                        }
                        .run()?
                    };
                    let (beauty, layers) = metrics::read_beauty_and_layers(&image)?;
                    let rel_mse = metrics::rel_mse(&beauty, &reference.beauty)?;
                    let rmse = metrics::rmse(&beauty, &reference.beauty)?;
                    let mut components = Vec::new();
                    // Restricted renders' other layers are black by request: not scored.
                    let scored = |l: &str| o.only.as_ref().is_none_or(|c| c.split(',').any(|c| c == l));
                    for (lname, layer) in layers.iter().filter(|(l, _)| scored(l)) {
                        if let Some((_, r)) = reference.layers.iter().find(|(n, _)| n == lname) {
                            components.push((lname.clone(), metrics::rel_mse(layer, r)?, metrics::rmse(layer, r)?));
                        }
                    }
                    eprintln!(
                        "bench: {sname} {:<22} budget {budget:>7.2} s: wall {:>6.2} s, {:>5} passes, relMSE {rel_mse:.3e}",
                        key.label(),
                        timing.wall,
                        timing.passes
                    );
                    rows.push(Row {
                        key: key.clone(),
                        budget,
                        repeat,
                        seed,
                        timing,
                        rel_mse,
                        rmse,
                        components,
                        image,
                    });
                }
            }
        }
        write_csv(&results.join(format!("{sname}.csv")), &rows, &reference)?;
        let curves = curves(&series, &budgets, &rows);
        let plot = plot::svg(
            &format!("{sname}: error against wall time ({}², start-up included)", o.size),
            "wall time per render, seconds (log)",
            &curves
                .iter()
                .map(|(k, pts)| plot::Series {
                    label: k.label(),
                    points: pts.iter().map(|p| (p.wall, p.rel_mse)).collect(),
                    dashed: k.renderer == "mitsuba",
                })
                .collect::<Vec<_>>(),
            &[(reference.est_rel_mse, "reference's own error (est.)".into())],
        );
        std::fs::write(results.join(format!("{sname}.svg")), plot)?;
        // Equal-time sheet at the largest budget, first repeat, plus the reference.
        let last = budgets.len() - 1;
        let mut tiles: Vec<(String, Image)> = vec![("reference".into(), reference.beauty.clone())];
        for k in &series {
            if let Some(r) = rows
                .iter()
                .find(|r| &r.key == k && r.repeat == 0 && (r.budget - budgets[last]).abs() < 1e-9)
            {
                tiles.push((k.label(), metrics::read_beauty_and_layers(&r.image)?.0));
            }
        }
        let tile_refs: Vec<(String, &Image)> = tiles.iter().map(|(l, i)| (l.clone(), i)).collect();
        sheet::write(&results.join(format!("{sname}_sheet.png")), &tile_refs, 4, 0.0)?;
        scene_summary(
            &mut summary,
            &mut headline,
            &sname,
            &scene,
            &reference,
            &series,
            &budgets,
            &curves,
            &rows,
            o.target,
            &not_exported,
        );
    }

    if let (Some(_), Some(check)) = (&mitsuba, &o.check_scene) {
        convention_check(
            &mut summary,
            root,
            &bin,
            &cache,
            &work,
            &o,
            &script,
            &scene_path(root, check),
            &ref_settings,
        )?;
    }
    let mut full = String::new();
    full.push_str(&summary);
    if !headline.is_empty() {
        let _ = writeln!(full, "\n## Headline\n");
        for h in &headline {
            let _ = writeln!(full, "* {h}");
        }
    }
    std::fs::write(results.join("summary.md"), full)?;
    eprintln!("bench: wrote {}", results.join("summary.md").display());
    Ok(())
}

/// Whether the scene needs a caustic component (`beamlight info`'s component list).
fn has_caustics(bin: &Path, scene: &Path) -> Result<bool> {
    let out = Command::new(bin)
        .arg("info")
        .arg(scene)
        .output()
        .with_context(|| format!("running {} info", bin.display()))?;
    if !out.status.success() {
        bail!(
            "beamlight info {}: {}",
            scene.display(),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    // The line `components  direct, Lsm, …, caustic_surface (of the many-light methods; …)`.
    let stdout = String::from_utf8_lossy(&out.stdout);
    let Some(line) = stdout.lines().find(|l| l.starts_with("components ")) else {
        bail!("beamlight info {}: no 'components' line in:\n{stdout}", scene.display());
    };
    Ok(line.split(" (").next().unwrap_or("").contains("caustic_"))
}

/// Whether `beamlight info` lists a Vulkan adapter (the `gpu` backend can run).
fn adapter_present(bin: &Path) -> bool {
    let scene = bin
        .parent()
        .and_then(|p| p.parent())
        .and_then(|p| p.parent())
        .map(|r| r.join("assets/scenes/cornell.toml"));
    let Some(scene) = scene else { return false };
    Command::new(bin).arg("info").arg(scene).output().is_ok_and(|o| {
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .any(|l| l.starts_with("gpu 0"))
    })
}

/// A render's path-tracing CPU seconds from its `--stats-json`: wall seconds times the threads
/// (path tracing keeps every worker busy); files from before the `threads` field count one.
fn path_tracing_cpu(stats: &serde_json::Value) -> f64 {
    let wall = stats["path_tracing_seconds"].as_f64().unwrap_or(0.0);
    wall * stats["threads"].as_f64().unwrap_or(1.0)
}
