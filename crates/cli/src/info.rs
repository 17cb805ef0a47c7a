//! `beamlight info`: what a scene holds and what each method would do with it.
use crate::print_stdout;
use anyhow::Result;
use beamlight_render::Method;
use beamlight_render::TraceScene;
use beamlight_render::components::{Component, SceneFeatures};
use beamlight_scene::{bsdf::Bsdf, load::load_scene};
use std::path::Path;

/// For glass material `material`: a note when some of its triangles bound no region while the
/// scene has a medium that scatters, since such glass is filled with the medium around it
/// (docs/rendering.md, "Media": clear glass needs a region of its own).
fn holds_medium(s: &beamlight_scene::Scene, material: usize) -> &'static str {
    let unbounded = s
        .triangles
        .iter()
        .any(|t| t.material as usize == material && t.interface.is_none());
    if unbounded && s.media.iter().any(|m| m.scatters()) {
        ", holds the medium around it where it bounds no region (clear glass needs one: docs/rendering.md, \"Media\")"
    } else {
        ""
    }
}

pub(crate) fn info(path: &Path) -> Result<()> {
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
    for (mi, m) in s.materials.iter().enumerate() {
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
            Some(Bsdf::Glass { ior, .. }) => format!("glass ior {ior}{}", holds_medium(s, mi)),
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
            _ if m.sigma_t().max_element() <= 0.0 => "clear (scatters and absorbs nothing)".to_string(),
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
        // Without a component `vbl` alone serves, a time budget may leave `vbl` out.
        let probed = solo.is_empty();
        let list = |v: &[Component]| v.iter().map(|c| c.name()).collect::<Vec<_>>().join(", ");
        let (caustics, blind): (Vec<Component>, Vec<Component>) = solo
            .into_iter()
            .partition(|c| matches!(c, Component::CausticSurface | Component::CausticVolume));
        let mut plan = Vec::new();
        if !both.is_empty() {
            plan.push(format!(
                "{}: pt and vbl, one weight per component from their measured errors (pt's after {} samples, vbl's after {} passes); vbl runs a component only while its passes lower the error faster per second than path tracing{}",
                list(&both),
                beamlight_render::combine::MIN_PT_SAMPLES,
                beamlight_render::auto::MIN_VBL_PASSES,
                if probed {
                    format!(
                        ", and with --time only on the components a probe (three vbl passes on a small image: their cost and noise against pt's first samples) does not find losing, as far as their {} passes fit in a tenth of the budget (four tenths where vbl promises to be much faster)",
                        beamlight_render::auto::MIN_VBL_PASSES
                    )
                } else {
                    String::new()
                }
            ));
        }
        if !caustics.is_empty() {
            plan.push(format!(
                "{}: vbl's photon maps and beams alone (the path tracer finds caustic light only by hitting an emitter through the mirror or glass: rare, heavy-tailed samples)",
                list(&caustics)
            ));
        }
        if !blind.is_empty() {
            let why = if s.lights.is_empty() {
                format!(
                    "{:.0} % of the lights' power leaves them through glass or a mirror: next-event estimation cannot reach it, and the path tracer finds it only by rare, heavy-tailed hits of an emitter behind the glass",
                    100.0 * beamlight_render::combine::power_through_delta(&ts)
                )
            } else {
                "the path tracer cannot follow light from point, spot or directional lights through mirrors or glass, which reaches these".to_string()
            };
            plan.push(format!("{}: vbl alone ({why})", list(&blind)));
        }
        let plan = plan.join("; ");
        outln!(out, "auto        {plan}");
    }
    let cam_medium = ts
        .camera_medium
        .map_or("vacuum".to_string(), |i| s.media[i as usize].name.clone());
    outln!(out, "camera in   {cam_medium}");
    // What `--backend auto` does for each method: the same decision a render makes.
    use beamlight_render::backend::{AutoChoice, adapter_lines, auto_choice};
    let mut on_gpu: Vec<&str> = Vec::new();
    let mut measured: Vec<&str> = Vec::new();
    let mut on_cpu: Vec<String> = Vec::new();
    let mut adapter = None;
    for m in Method::ALL {
        match auto_choice(m) {
            AutoChoice::Gpu(name) => {
                on_gpu.push(m.name());
                adapter = Some(name);
            }
            AutoChoice::Measure(name) => {
                measured.push(m.name());
                adapter = Some(name);
            }
            AutoChoice::Cpu(why) => on_cpu.push(format!("{} ({why})", m.name())),
        }
    }
    // What opening the adapter is expected to cost, as `--backend auto` weighs it against a
    // time budget.
    let opening_vbl = match beamlight_render::backend::expected_opening(Method::Vbl) {
        Some((s, true)) => (s, "as last measured"),
        Some((s, false)) => (s, "expected, not yet measured"),
        None => (0.0, "no adapter"),
    };
    let mut parts = Vec::new();
    if let Some(name) = &adapter {
        if !on_gpu.is_empty() {
            parts.push(format!("the gathers of {} on {name}", on_gpu.join(", ")));
        }
        if !measured.is_empty() {
            parts.push(format!(
                "{}: on {name} or the CPU, whichever ran a small trial pass of the render faster (the render's first line says which, with the times); with a --time budget under {} x what opening {name} and the trial take (here {:.1} s with vbl's kernels, {}), on the CPU without a trial",
                measured.join(", "),
                beamlight_render::backend::OPENING_BUDGET_RATIO,
                opening_vbl.0,
                opening_vbl.1
            ));
        }
    }
    parts.push(format!("on the CPU: {}", on_cpu.join("; ")));
    outln!(out, "backend     `--backend auto`: {}", parts.join("; "));
    for line in adapter_lines() {
        outln!(out, "{line}");
    }
    print_stdout(&out)
}
