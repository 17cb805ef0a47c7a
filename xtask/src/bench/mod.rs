//! `cargo xtask bench`: run time against error, per scene, for every method and backend of
//! beamlight and for Mitsuba 3's `volpath`, against a cached path-traced reference.
//! See `docs/benchmarks.md` for what it measures and how to read the results.
mod metrics;
mod mitsuba;
mod plot;
mod reference;
mod runs;
mod sheet;
mod summary;

use anyhow::{Context, Result, bail};
use metrics::Image;
use runs::{BeamlightRun, Budget, Timing, median};
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
  --ref-methods M,...   the reference's estimators: pt, or pt and a second independent one
                        (e.g. pt,vrl), checked against each other per component and combined;
                        'auto' (default): pt, plus vrl where the scene has caustics
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
    /// `None`: per scene, pt plus vrl where it has caustics.
    ref_methods: Option<Vec<String>>,
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
        ref_methods: None,
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
            "--ref-methods" => o.ref_methods = (v != "auto").then(|| list(v)),
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
        renderer: renderer_id(root),
    };
    let budgets: Vec<f64> = o.budgets.iter().map(|b| b * o.scale).collect();
    let mut summary = String::new();
    let mut headline = Vec::new();
    let _ = writeln!(summary, "# Benchmark: run time against error\n");
    let _ = writeln!(
        summary,
        "Command: `cargo xtask bench {}`. Machine: {} cores, {}. Image {}², budgets {} s (start-up included), {} repeat(s) per budget (medians). Reference: `pt` (and, where the scene has caustics, `vrl`) for 2 × {:.0} s per estimator and scene. Mitsuba 3: {}.\n",
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
        mitsuba
            .as_deref()
            .map_or(format!("not run ({})", mitsuba::INSTALL_HINT), |v| format!(
                "{v}, `volpath`, via `bench/mitsuba_render.py`"
            ))
    );
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
        let ref_methods = match &o.ref_methods {
            Some(m) => m.clone(),
            None if has_caustics(&bin, &scene)? => vec!["pt".into(), "vrl".into()],
            None => vec!["pt".into()],
        };
        let scene_ref = reference::RefSettings {
            methods: ref_methods,
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
        if mitsuba.is_some() {
            std::fs::create_dir_all(xml.parent().expect("a parent"))?;
            not_exported = mitsuba::export(&bin, &scene, &xml, o.size)?;
            series.push(SeriesKey {
                renderer: "mitsuba".into(),
                method: "volpath".into(),
                backend: "llvm".into(),
            });
        }
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
                            extra_args: &[],
                        }
                        .run()?
                    };
                    let (beauty, layers) = metrics::read_beauty_and_layers(&image)?;
                    let rel_mse = metrics::rel_mse(&beauty, &reference.beauty)?;
                    let rmse = metrics::rmse(&beauty, &reference.beauty)?;
                    let mut components = Vec::new();
                    for (lname, layer) in &layers {
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

/// The median point of a series at one budget.
#[derive(Clone, Debug)]
struct Point {
    wall: f64,
    render: f64,
    passes: f64,
    rel_mse: f64,
}

fn curves(series: &[SeriesKey], budgets: &[f64], rows: &[Row]) -> Vec<(SeriesKey, Vec<Point>)> {
    series
        .iter()
        .map(|k| {
            let pts = budgets
                .iter()
                .filter_map(|&b| {
                    let rs: Vec<&Row> = rows.iter().filter(|r| &r.key == k && r.budget == b).collect();
                    if rs.is_empty() {
                        return None;
                    }
                    let m = |f: &dyn Fn(&Row) -> f64| median(&rs.iter().map(|r| f(r)).collect::<Vec<_>>());
                    Some(Point {
                        wall: m(&|r| r.timing.wall),
                        render: m(&|r| r.timing.render),
                        passes: m(&|r| r.timing.passes as f64),
                        rel_mse: m(&|r| r.rel_mse),
                    })
                })
                .collect();
            (k.clone(), pts)
        })
        .collect()
}

/// The transport components' layer names, in the renderer's order.
fn component_names() -> impl Iterator<Item = &'static str> {
    beamlight_render::components::Component::ALL.iter().map(|c| c.name())
}

fn write_csv(path: &Path, rows: &[Row], reference: &reference::Reference) -> Result<()> {
    let mut s = String::from(
        "renderer,method,backend,budget_s,repeat,seed,wall_s,render_s,startup_s,passes,relmse,rmse,ref_relmse_est",
    );
    for c in component_names() {
        let _ = write!(s, ",relmse_{c},rmse_{c}");
    }
    s.push('\n');
    for r in rows {
        let _ = write!(
            s,
            "{},{},{},{:.4},{},{},{:.4},{:.4},{:.4},{},{:.6e},{:.6e},{:.3e}",
            r.key.renderer,
            r.key.method,
            r.key.backend,
            r.budget,
            r.repeat,
            r.seed,
            r.timing.wall,
            r.timing.render,
            r.timing.wall - r.timing.render,
            r.timing.passes,
            r.rel_mse,
            r.rmse,
            reference.est_rel_mse
        );
        for c in component_names() {
            match r.components.iter().find(|x| x.0 == c) {
                Some((_, rel, rm)) => {
                    let _ = write!(s, ",{rel:.6e},{rm:.6e}");
                }
                None => s.push_str(",,"),
            }
        }
        s.push('\n');
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

fn scene_summary(
    out: &mut String,
    headline: &mut Vec<String>,
    sname: &str,
    scene: &Path,
    reference: &reference::Reference,
    series: &[SeriesKey],
    budgets: &[f64],
    curves: &[(SeriesKey, Vec<Point>)],
    rows: &[Row],
    target: Option<f64>,
    not_exported: &[String],
) {
    let _ = writeln!(out, "## {sname}\n");
    let _ = writeln!(
        out,
        "Scene `{}`. Plot: [{sname}.svg]({sname}.svg); data: [{sname}.csv]({sname}.csv); equal-time images at {:.2} s: [{sname}_sheet.png]({sname}_sheet.png) (tiles left to right, top to bottom: reference, {}; all tonemapped alike).\n",
        scene.strip_prefix(crate::root()).unwrap_or(scene).display(),
        budgets[budgets.len() - 1],
        series.iter().map(|k| k.label()).collect::<Vec<_>>().join(", ")
    );
    let per_layer = reference
        .layer_est_rel_mse
        .iter()
        .filter(|(_, e)| *e > 0.0)
        .map(|(n, e)| format!("{n} {e:.1e}"))
        .collect::<Vec<_>>()
        .join(", ");
    let _ = writeln!(
        out,
        "Reference: {} in {:.0} s ({}); relMSE between its halves {:.2e}, so its own relMSE ≈ {:.2e}.{}\n",
        reference
            .estimators
            .iter()
            .map(|e| format!(
                "`{}` ({} {} in {} parts, own relMSE ≈ {:.2e})",
                e.method,
                e.spp(),
                if e.method == "pt" { "spp" } else { "passes" },
                reference::PARTS,
                e.est_rel_mse
            ))
            .collect::<Vec<_>>()
            .join(" + "),
        reference.seconds,
        if reference.reused { "cached" } else { "made in this run" },
        reference.halves_rel_mse,
        reference.est_rel_mse,
        if per_layer.is_empty() {
            String::new()
        } else {
            format!(" Per component: {per_layer}.")
        }
    );
    if let [e0, e1] = &reference.estimators[..] {
        let _ = writeln!(
            out,
            "Cross-check of the reference's estimators per component (means of RGB / 3 over the image ± standard errors from the spread of {} parts each; z = difference / combined SE; tile Σz²: the same over 4 × 4 tiles, about 1.4 × the tile count (7-dof errors) when they agree everywhere; weight: `{}`'s share in the combination):\n",
            reference::PARTS,
            e0.method
        );
        let _ = writeln!(
            out,
            "| component | `{}` | `{}` | z | tile Σz² / tiles | weight `{}` | agree |",
            e0.method, e1.method, e0.method
        );
        let _ = writeln!(out, "|---|---|---|---|---|---|---|");
        for c in &reference.cross_check {
            if c.mean == [0.0, 0.0] {
                continue;
            }
            let _ = writeln!(
                out,
                "| {} | {:.4e} ± {:.1e} | {:.4e} ± {:.1e} | {:+.2} | {:.1} / {} | {:.2} | {} |",
                c.layer,
                c.mean[0],
                c.se[0],
                c.mean[1],
                c.se[1],
                c.z,
                c.tile_chi2,
                c.tiles,
                c.weight0,
                if c.agrees() { "yes" } else { "**no**" }
            );
        }
        out.push('\n');
    }
    // Error table: series × budget.
    let _ = write!(out, "| relMSE (wall s, passes/spp) |");
    for b in budgets {
        let _ = write!(out, " {b:.2} s |");
    }
    out.push('\n');
    out.push_str(&"|---".repeat(budgets.len() + 1));
    out.push_str("|\n");
    for (k, pts) in curves {
        let _ = write!(out, "| {} |", k.label());
        for p in pts {
            let _ = write!(out, " {:.2e} ({:.1} s, {:.0}) |", p.rel_mse, p.wall, p.passes);
        }
        out.push('\n');
    }
    // Time to target.
    let pt = curves
        .iter()
        .find(|(k, _)| k.renderer == "beamlight" && k.method == "pt");
    let target = target.or_else(|| pt.and_then(|(_, pts)| pts.get(pts.len() / 2)).map(|p| p.rel_mse));
    if let Some(target) = target {
        // Time to the target, measured, or for the unbiased path tracers (whose error falls as
        // 1/t) extrapolated from their last budget, marked `~`.
        let floor = reference.est_rel_mse;
        let time_to = |k: &SeriesKey, pts: &[Point], render: bool| -> (Option<f64>, bool) {
            let curve: Vec<(f64, f64)> = pts
                .iter()
                .map(|p| (if render { p.render } else { p.wall }, p.rel_mse))
                .collect();
            match summary::time_to_target(&curve, target) {
                Some(t) => (Some(t), false),
                None if k.method == "pt" || k.renderer == "mitsuba" => {
                    let t = summary::extrapolated_time(&curve, target, floor);
                    (t, t.is_some())
                }
                None => (None, false),
            }
        };
        let pt_wall = pt.map_or((None, false), |(k, pts)| time_to(k, pts, false));
        let pt_render = pt.map_or((None, false), |(k, pts)| time_to(k, pts, true));
        let _ = writeln!(
            out,
            "\nTime to reach relMSE {target:.2e} (log–log interpolation between budgets; `-`: not reached within the largest budget; `~`: not reached, extrapolated for an unbiased path tracer as relMSE − floor ∝ 1/t from its last budget, with the reference's own relMSE {floor:.1e} as the floor). Ratio = `pt`'s time / this one's (above 1: faster than `pt`).\n"
        );
        let _ = writeln!(
            out,
            "| series | wall s (start-up incl.) | ratio vs pt | render s (no start-up) | ratio vs pt |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|");
        let mut best: Option<(String, f64)> = None;
        for (k, pts) in curves {
            let (tw, tw_x) = time_to(k, pts, false);
            let (tr, tr_x) = time_to(k, pts, true);
            let mark = |x: bool| if x { "~" } else { "" };
            let ratio = |a: (Option<f64>, bool), b: (Option<f64>, bool)| match (a.0, b.0) {
                (Some(x), Some(y)) if y > 0.0 => format!("{}{:.2}", mark(a.1 || b.1), x / y),
                _ => "-".into(),
            };
            let _ = writeln!(
                out,
                "| {} | {}{} | {} | {}{} | {} |",
                k.label(),
                mark(tw_x),
                summary::secs(tw),
                ratio(pt_wall, (tw, tw_x)),
                mark(tr_x),
                summary::secs(tr),
                ratio(pt_render, (tr, tr_x))
            );
            if let Some(t) = tw.filter(|_| !tw_x)
                && best.as_ref().is_none_or(|b| t < b.1)
            {
                best = Some((k.label(), t));
            }
        }
        // Headline: vbl against pt and Mitsuba on this scene, at the largest budget.
        let at_last = |pred: &dyn Fn(&SeriesKey) -> bool| {
            curves
                .iter()
                .filter(|(k, _)| pred(k))
                .filter_map(|(k, p)| p.last().map(|p| (k.label(), p.rel_mse)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
        };
        // `auto` against the better of `pt` and `vbl` at every budget (issue 16's measure).
        let best_at = |pred: &dyn Fn(&SeriesKey) -> bool, i: usize| {
            curves
                .iter()
                .filter(|(k, _)| k.renderer == "beamlight" && pred(k))
                .filter_map(|(_, p)| p.get(i).map(|p| p.rel_mse))
                .min_by(|a, b| a.total_cmp(b))
        };
        let ratios: Vec<String> = (0..budgets.len())
            .filter_map(|i| {
                let auto = best_at(&|k| k.method == "auto", i)?;
                let others = best_at(&|k| k.method == "pt" || k.method == "vbl", i)?;
                Some(format!("{:.0} s {:.2}", budgets[i], auto / others))
            })
            .collect();
        if !ratios.is_empty() {
            headline.push(format!(
                "{sname}: auto's relMSE / min(pt, vbl) at each budget: {}",
                ratios.join(", ")
            ));
        }
        let vbl = at_last(&|k| k.method == "vbl");
        let pt_last = at_last(&|k| k.method == "pt" && k.renderer == "beamlight");
        let mi = at_last(&|k| k.renderer == "mitsuba");
        if let Some((vl, ve)) = vbl {
            let mut h = format!(
                "{sname}: at {:.1} s, best vbl ({vl}) relMSE {ve:.2e}",
                budgets[budgets.len() - 1]
            );
            if let Some((_, pe)) = pt_last {
                let _ = write!(h, "; pt {pe:.2e} (vbl/pt error ratio {:.2})", ve / pe);
            }
            if let Some((_, me)) = mi {
                let _ = write!(h, "; Mitsuba volpath {me:.2e} (vbl/Mitsuba error ratio {:.2})", ve / me);
            }
            if let Some((bl, bt)) = &best {
                let _ = write!(h, "; first to relMSE {target:.1e}: {bl} ({bt:.2} s)");
            }
            headline.push(h);
        }
    }
    // Where the time went, per series at the largest budget.
    let last = budgets[budgets.len() - 1];
    let _ = writeln!(
        out,
        "\nWhere the time went at the {last:.2} s budget (first repeat): start-up, then each component that ran, as CPU seconds (summed over threads; path tracing's as its wall seconds times the threads, all of which it keeps busy) + GPU kernel seconds; a component not listed did not run (took 0 s).\n"
    );
    let _ = writeln!(
        out,
        "| series | wall s | start-up s | tracing s | components that ran (cpu + gpu s) | largest cost |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|");
    for k in series {
        let Some(r) = rows.iter().find(|r| &r.key == k && r.budget == last && r.repeat == 0) else {
            continue;
        };
        let st = &r.timing.stats;
        let startup = r.timing.wall - r.timing.render;
        // (label, name, seconds)
        let mut parts: Vec<(String, String, f64)> = Vec::new();
        let trace = st["trace_seconds"].as_f64().unwrap_or(0.0);
        if k.renderer == "mitsuba" {
            let v = st["variant"].as_str().unwrap_or("");
            let t = r.timing.render;
            parts.push((format!("volpath ({v}) {t:.2}"), "volpath".into(), t));
        } else if k.method == "pt" {
            let t = path_tracing_cpu(st);
            parts.push((
                format!("path tracing (all components) {t:.2}"),
                "path tracing".into(),
                t,
            ));
        } else if let Some(obj) = st["components"].as_object() {
            // `auto` path traces too, besides its `vbl` passes' components.
            let t = path_tracing_cpu(st);
            if t > 0.0 {
                parts.push((format!("path tracing {t:.2}"), "path tracing".into(), t));
            }
            for c in component_names() {
                if let Some(v) = obj.get(c) {
                    let secs = |f: &str| v[f].as_f64().unwrap_or(0.0).max(0.0);
                    let (cpu, gpu) = (secs("cpu_seconds"), secs("gpu_seconds"));
                    if cpu + gpu > 0.0 {
                        parts.push((format!("{c} {cpu:.2} + {gpu:.2}"), c.to_string(), cpu + gpu));
                    }
                }
            }
        }
        let mut all = parts.clone();
        if trace > 0.0 {
            all.push((String::new(), "tracing (camera and light paths)".into(), trace));
        }
        let largest = all
            .iter()
            .max_by(|a, b| a.2.total_cmp(&b.2))
            .map_or("-".into(), |(_, n, _)| n.clone());
        let _ = writeln!(
            out,
            "| {} | {:.2} | {startup:.2} | {trace:.2} | {} | {largest} |",
            k.label(),
            r.timing.wall,
            if parts.is_empty() {
                "-".into()
            } else {
                parts.iter().map(|p| p.0.clone()).collect::<Vec<_>>().join(", ")
            }
        );
    }
    // Component errors of the many-light methods at the largest budget.
    let _ = writeln!(
        out,
        "\nPer-component relMSE at the {last:.2} s budget against the component-split reference (many-light methods; blank: the component is not in the scene):\n"
    );
    let _ = write!(out, "| series |");
    for c in component_names() {
        let _ = write!(out, " {c} |");
    }
    out.push('\n');
    out.push_str(&"|---".repeat(beamlight_render::components::Component::ALL.len() + 1));
    out.push_str("|\n");
    for k in series.iter().filter(|k| k.renderer == "beamlight" && k.method != "pt") {
        let Some(r) = rows.iter().find(|r| &r.key == k && r.budget == last && r.repeat == 0) else {
            continue;
        };
        let _ = write!(out, "| {} |", k.label());
        for c in component_names() {
            let needed = r.timing.stats["components"][c]["needed"].as_bool().unwrap_or(true);
            match r.components.iter().find(|x| x.0 == c) {
                Some((_, rel, _)) if needed => {
                    let _ = write!(out, " {rel:.2e} |");
                }
                _ => out.push_str(" |"),
            }
        }
        out.push('\n');
    }
    if !not_exported.is_empty() {
        let _ = writeln!(out, "\nMitsuba export of this scene, not exact:\n");
        for n in not_exported {
            let _ = writeln!(out, "* {n}");
        }
    }
    out.push('\n');
}

/// Lambert-only scene: beamlight's `pt` reference against a long Mitsuba render (two halves,
/// so Mitsuba's own noise is known too). If both converge to the same image, relMSE(Mitsuba,
/// reference) ≈ Mitsuba's own error + the reference's.
fn convention_check(
    out: &mut String,
    _root: &Path,
    bin: &Path,
    cache: &Path,
    work: &Path,
    o: &Options,
    script: &Path,
    scene: &Path,
    settings: &reference::RefSettings,
) -> Result<()> {
    let sname = scene_name(scene);
    let reference = reference::make_or_reuse(bin, cache, scene, settings)?;
    let dir = work.join(format!("check_{sname}"));
    std::fs::create_dir_all(&dir)?;
    let xml = dir.join("scene.xml");
    let not_exported = mitsuba::export(bin, scene, &xml, o.size)?;
    let seconds = o.check_time * o.scale;
    let mut halves = Vec::new();
    let mut spp = 0;
    for (i, seed) in [7u32, 8].iter().enumerate() {
        eprintln!(
            "bench: convention check {sname}: Mitsuba half {} for {seconds:.0} s",
            i + 1
        );
        let img = dir.join(format!("mitsuba_{i}.exr"));
        let t = mitsuba::render(&o.python, script, &xml, &img, Budget::Seconds(seconds), *seed)?;
        spp += t.passes;
        halves.push(metrics::read_beauty_and_layers(&img)?.0);
    }
    let m = metrics::blend(&halves[0], 0.5, &halves[1], 0.5)?;
    let m_est = metrics::rel_mse(&halves[0], &halves[1])? / 4.0;
    let rel = metrics::rel_mse(&m, &reference.beauty)?;
    let (mm, rm) = (m.mean(), reference.beauty.mean());
    let _ = writeln!(
        out,
        "## Convention check: beamlight `pt` against Mitsuba 3 on `{sname}`\n"
    );
    let _ = writeln!(
        out,
        "Mitsuba `volpath`, {spp} spp in 2 × {seconds:.0} s (own relMSE ≈ {m_est:.2e} from its halves), against beamlight's reference ({} spp, own relMSE ≈ {:.2e}): **relMSE {rel:.2e}** (RMSE {:.2e}); if both converge to the same image this is about the sum of the two own errors, {:.2e}, so the ratio {:.2} is what to look at (about 1: agreement). Mean radiance per channel: Mitsuba ({:.5}, {:.5}, {:.5}), beamlight ({:.5}, {:.5}, {:.5}), ratio ({:.4}, {:.4}, {:.4}).{}\n",
        reference.spp,
        reference.est_rel_mse,
        metrics::rmse(&m, &reference.beauty)?,
        m_est + reference.est_rel_mse,
        rel / (m_est + reference.est_rel_mse).max(1e-30),
        mm[0],
        mm[1],
        mm[2],
        rm[0],
        rm[1],
        rm[2],
        mm[0] / rm[0],
        mm[1] / rm[1],
        mm[2] / rm[2],
        if not_exported.is_empty() {
            " The export is exact for this scene.".to_string()
        } else {
            format!(" Not exact in the export: {}.", not_exported.join("; "))
        }
    );
    Ok(())
}

/// A render's path-tracing CPU seconds from its `--stats-json`: wall seconds times the threads
/// (path tracing keeps every worker busy); files from before the `threads` field count one.
fn path_tracing_cpu(stats: &serde_json::Value) -> f64 {
    let wall = stats["path_tracing_seconds"].as_f64().unwrap_or(0.0);
    wall * stats["threads"].as_f64().unwrap_or(1.0)
}
