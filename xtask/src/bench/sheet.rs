//! The equal-time contact sheet: one tile per renderer/method/backend at the same budget, plus
//! the reference, all tonemapped alike (radiance × 2^exposure, clamped, sRGB) so brightness
//! stays comparable, each tile labelled (the renderer's `sheet` module draws it).
use super::metrics::Image;
use anyhow::Result;
use beamlight_render::{
    output::write_png_rgb8,
    sheet::{Exposure, contact_sheet},
};
use std::path::Path;

/// Writes a sheet of `tiles` (label, image), `columns` per row, all with the same exposure.
pub fn write(path: &Path, tiles: &[(String, &Image)], columns: usize, exposure: f32) -> Result<()> {
    if tiles.is_empty() {
        return Ok(());
    }
    let tiles: Vec<(&str, &Image)> = tiles.iter().map(|(l, i)| (l.as_str(), *i)).collect();
    let (w, h, rgb) = contact_sheet(&tiles, columns as u32, Exposure::Shared { stops: exposure });
    Ok(write_png_rgb8(path, w, h, rgb)?)
}
