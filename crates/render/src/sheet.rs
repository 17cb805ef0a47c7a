//! Contact sheets: several images side by side in one PNG, each labelled, for figures like the
//! paper's Fig. 9 (one tile per transport component, each tonemapped on its own so that a dim
//! component is as readable as the beauty image).
use crate::{Image, output};
use beamlight_scene::Rgb;

/// How each tile's radiance becomes display values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exposure {
    /// Each tile scaled so that its `percentile` (0–1) of pixel luminance maps to white.
    PerTile { percentile: f32 },
    /// Every tile × 2^stops (equal-time comparisons, where brightness must stay comparable).
    Shared { stops: f32 },
}

/// Pixels between tiles and around the sheet.
const GAP: u32 = 4;
/// The label font's glyphs are 8×8, drawn at this scale, or at 1 when a label would not fit
/// its tile at this scale.
const FONT_SCALE: u32 = 2;

/// Lays `tiles` out in rows of `columns`, each tonemapped per `exposure` and labelled with its
/// name in a bar above it. Tiles may differ in size; each cell is as large as the largest.
/// Returns 8-bit sRGB rows (`width`, `height`, RGB bytes).
pub fn contact_sheet(tiles: &[(&str, &Image)], columns: u32, exposure: Exposure) -> (u32, u32, Vec<u8>) {
    let columns = columns.clamp(1, tiles.len().max(1) as u32);
    let rows = (tiles.len() as u32).div_ceil(columns);
    let cell_w = tiles.iter().map(|t| t.1.width).max().unwrap_or(0);
    let longest = tiles.iter().map(|t| t.0.chars().count() as u32).max().unwrap_or(0);
    let font = if longest * 8 * FONT_SCALE <= cell_w {
        FONT_SCALE
    } else {
        1
    };
    let label = 8 * font + 2 * GAP;
    let cell_h = tiles.iter().map(|t| t.1.height).max().unwrap_or(0) + label;
    let width = GAP + columns * (cell_w + GAP);
    let height = GAP + rows * (cell_h + GAP);
    let mut rgb = vec![24u8; (width * height * 3) as usize];
    for (k, (name, img)) in tiles.iter().enumerate() {
        let (x0, y0) = (
            GAP + (k as u32 % columns) * (cell_w + GAP),
            GAP + (k as u32 / columns) * (cell_h + GAP),
        );
        draw_text(&mut rgb, width, (x0, x0 + cell_w), y0 + GAP, font, name);
        let scale = match exposure {
            Exposure::PerTile { percentile } => 1.0 / luminance_percentile(img, percentile).max(1e-12),
            Exposure::Shared { stops } => stops.exp2(),
        };
        for y in 0..img.height {
            for x in 0..img.width {
                let p = img.pixels[(y * img.width + x) as usize] * scale;
                let at = (((y0 + label + y) * width + x0 + x) * 3) as usize;
                for c in 0..3 {
                    rgb[at + c] = (output::srgb_encode(p[c]) * 255.0 + 0.5) as u8;
                }
            }
        }
    }
    (width, height, rgb)
}

/// The `q`-quantile (0–1) of the finite pixel luminances; 0 for an empty or black image.
pub fn luminance_percentile(img: &Image, q: f32) -> f32 {
    let mut lum: Vec<f32> = img
        .pixels
        .iter()
        .map(luminance)
        .filter(|l| l.is_finite() && *l > 0.0)
        .collect();
    if lum.is_empty() {
        return 0.0;
    }
    let k = ((lum.len() - 1) as f32 * q.clamp(0.0, 1.0)).round() as usize;
    *lum.select_nth_unstable_by(k, f32::total_cmp).1
}

fn luminance(p: &Rgb) -> f32 {
    0.2126 * p.x + 0.7152 * p.y + 0.0722 * p.z
}

/// Draws `text` in light grey at `scale` with its top-left corner at (`x`, `y`), clipped to
/// the columns `x..x_end` (its tile).
fn draw_text(rgb: &mut [u8], width: u32, (x, x_end): (u32, u32), y: u32, scale: u32, text: &str) {
    use font8x8::UnicodeFonts as _;
    let height = rgb.len() as u32 / (3 * width);
    for (i, ch) in text.chars().enumerate() {
        let glyph = font8x8::BASIC_FONTS.get(ch).unwrap_or([0; 8]);
        for (gy, bits) in glyph.iter().enumerate() {
            for gx in 0..8 {
                if bits >> gx & 1 == 0 {
                    continue;
                }
                for sy in 0..scale {
                    for sx in 0..scale {
                        let px = x + (i as u32 * 8 + gx) * scale + sx;
                        let py = y + gy as u32 * scale + sy;
                        if px < x_end.min(width) && py < height {
                            let at = ((py * width + px) * 3) as usize;
                            rgb[at..at + 3].copy_from_slice(&[220, 220, 220]);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(w: u32, h: u32, v: f32) -> Image {
        Image {
            width: w,
            height: h,
            pixels: vec![Rgb::splat(v); (w * h) as usize],
        }
    }

    #[test]
    fn tiles_are_laid_out_and_tonemapped_each_on_its_own() {
        let (a, b) = (flat(10, 6, 0.001), flat(8, 8, 50.0));
        let (w, h, rgb) = contact_sheet(&[("a", &a), ("b", &b)], 2, Exposure::PerTile { percentile: 0.99 });
        // A 16-pixel glyph does not fit the 10-pixel cells: labels at scale 1.
        let label = 8 + 2 * GAP;
        assert_eq!((w, h), (GAP + 2 * (10 + GAP), GAP + 8 + label + GAP));
        assert_eq!(rgb.len(), (w * h * 3) as usize);
        // Both flat tiles map to white under their own exposure, however different they are.
        let at = |x: u32, y: u32| rgb[((y * w + x) * 3) as usize];
        assert_eq!(at(GAP, GAP + label), 255);
        assert_eq!(at(GAP + 10 + GAP, GAP + label), 255);
        // With a shared exposure the dim tile stays dark.
        let (_, _, rgb) = contact_sheet(&[("a", &a), ("b", &b)], 2, Exposure::Shared { stops: 0.0 });
        assert!(rgb[((((GAP + label) * w) + GAP) * 3) as usize] < 20);
    }

    #[test]
    fn long_labels_shrink_and_stay_in_their_tile() {
        let a = flat(40, 4, 0.0);
        let tiles = [("a label far wider than its tile", &a), ("b", &a)];
        let (w, h, rgb) = contact_sheet(&tiles, 2, Exposure::Shared { stops: 0.0 });
        // Scale 1: the label bar is 8 + 2·GAP high.
        assert_eq!(h, GAP + 4 + 8 + 2 * GAP + GAP);
        // Nothing of the first label spills into the gap before the second tile.
        for y in 0..h {
            for x in GAP + 40..GAP + 40 + GAP {
                assert_eq!(rgb[((y * w + x) * 3) as usize], 24, "pixel ({x}, {y})");
            }
        }
    }

    #[test]
    fn percentile_ignores_black_and_non_finite_pixels() {
        let mut img = flat(4, 1, 0.0);
        img.pixels[1] = Rgb::splat(1.0);
        img.pixels[2] = Rgb::splat(f32::NAN);
        img.pixels[3] = Rgb::splat(3.0);
        assert!((luminance_percentile(&img, 1.0) - 3.0).abs() < 1e-5);
        assert!((luminance_percentile(&img, 0.0) - 1.0).abs() < 1e-5);
        assert_eq!(luminance_percentile(&flat(2, 2, 0.0), 0.5), 0.0);
    }
}
