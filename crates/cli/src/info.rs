//! `beamlight info`: what a scene holds and what each method would do with it.
use crate::print_stdout;
use anyhow::Result;
use beamlight_gpu::Gpu;
use beamlight_render::components::{Component, SceneFeatures};
use beamlight_scene::{bsdf::Bsdf, load::load_scene};
use beamlight_trace::TraceScene;
use std::path::Path;

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
