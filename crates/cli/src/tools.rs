//! The commands around a render: `sheet`, `compare` and `export-mitsuba`.
use crate::{check_output_path, mitsuba, print_stdout};
use anyhow::{Result, bail};
use beamlight_render::TraceScene;
use beamlight_render::{compare, output};
use beamlight_scene::load::load_scene;
use std::path::{Path, PathBuf};

pub(crate) fn sheet_cmd(
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

pub(crate) fn export_mitsuba(scene_path: &Path, output: &Path, width: Option<u32>, height: Option<u32>) -> Result<()> {
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

pub(crate) fn compare_cmd(a: &Path, b: &Path, layers: bool) -> Result<()> {
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
