//! What a bench run writes per scene: the measured curves, the CSV of every render, the
//! summary (time to the target errors, per-component errors, the references' cross-check)
//! and the convention check against Mitsuba.

use super::runs::{Budget, median};
use super::{Options, Row, SeriesKey, metrics, mitsuba, path_tracing_cpu, reference, scene_name, summary};
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::Path;

/// The median point of a series at one budget.
#[derive(Clone, Debug)]
pub(super) struct Point {
    pub(super) wall: f64,
    pub(super) render: f64,
    pub(super) passes: f64,
    pub(super) rel_mse: f64,
}

pub(super) fn curves(series: &[SeriesKey], budgets: &[f64], rows: &[Row]) -> Vec<(SeriesKey, Vec<Point>)> {
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
pub(super) fn component_names() -> impl Iterator<Item = &'static str> {
    beamlight_render::components::Component::ALL.iter().map(|c| c.name())
}

pub(super) fn write_csv(path: &Path, rows: &[Row], reference: &reference::Reference) -> Result<()> {
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

/// A render's relMSE below this many times the reference's own is marked as at the floor.
const FLOOR_MARGIN: f64 = 2.0;

pub(super) fn scene_summary(
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
                "`{}` ({} {} in {} parts{}, own relMSE ≈ {:.2e})",
                e.method,
                e.spp(),
                if e.method == "pt" { "spp" } else { "passes" },
                reference::PARTS,
                match e.rounds {
                    1 => String::new(),
                    r => format!(" of {r} rounds"),
                },
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
    // An error against a reference adds the reference's own: one within twice of it says
    // more about the reference than about the render.
    let at_floor = |e: f64| e < FLOOR_MARGIN * reference.est_rel_mse;
    let mut marked = false;
    for (k, pts) in curves {
        let _ = write!(out, "| {} |", k.label());
        for p in pts {
            let mark = if at_floor(p.rel_mse) { " ‡" } else { "" };
            marked |= at_floor(p.rel_mse);
            let _ = write!(out, " {:.2e}{mark} ({:.1} s, {:.0}) |", p.rel_mse, p.wall, p.passes);
        }
        out.push('\n');
    }
    if marked {
        let _ = writeln!(
            out,
            "\n‡ below {FLOOR_MARGIN} × the reference's own relMSE ({:.2e}): mostly the reference's error, so such a cell does not rank the methods.",
            reference.est_rel_mse
        );
    }
    // Time to target.
    let pt = curves
        .iter()
        .find(|(k, _)| k.renderer == "beamlight" && k.method == "pt");
    let asked = target.or_else(|| pt.and_then(|(_, pts)| pts.get(pts.len() / 2)).map(|p| p.rel_mse));
    // A target the reference cannot resolve is raised to the floor's margin: a time to reach
    // an error mostly made of the reference's own would rank nothing (issue 32's "1e-2, or 2x
    // the reference's own floor, whichever is larger").
    let floor_target = FLOOR_MARGIN * reference.est_rel_mse;
    if let Some(target) = asked.map(|t| t.max(floor_target)) {
        if asked.is_some_and(|t| t < floor_target) {
            let _ = writeln!(
                out,
                "\nThe target relMSE {:.2e} is below {FLOOR_MARGIN} × the reference's own ({:.2e}); the times below are to {target:.2e} instead.",
                asked.unwrap_or_default(),
                reference.est_rel_mse
            );
        }
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
                let mark = if at_floor(auto) || at_floor(others) { " ‡" } else { "" };
                Some(format!("{:.0} s {:.2}{mark}", budgets[i], auto / others))
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
pub(super) fn convention_check(
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
