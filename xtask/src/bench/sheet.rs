//! The equal-time contact sheet: one tile per renderer/method/backend at the same budget, plus
//! the reference, all tonemapped alike (radiance × 2^exposure, clamped, sRGB), each tile
//! labelled with a tiny built-in bitmap font.
use super::metrics::Image;
use anyhow::{Context, Result};
use std::path::Path;

/// 3×5 glyphs, rows top to bottom, '#' set.
fn glyph(c: char) -> [&'static str; 5] {
    match c.to_ascii_lowercase() {
        'a' => [".#.", "#.#", "###", "#.#", "#.#"],
        'b' => ["##.", "#.#", "##.", "#.#", "##."],
        'c' => [".##", "#..", "#..", "#..", ".##"],
        'd' => ["##.", "#.#", "#.#", "#.#", "##."],
        'e' => ["###", "#..", "##.", "#..", "###"],
        'f' => ["###", "#..", "##.", "#..", "#.."],
        'g' => [".##", "#..", "#.#", "#.#", ".##"],
        'h' => ["#.#", "#.#", "###", "#.#", "#.#"],
        'i' => ["###", ".#.", ".#.", ".#.", "###"],
        'j' => ["..#", "..#", "..#", "#.#", ".#."],
        'k' => ["#.#", "#.#", "##.", "#.#", "#.#"],
        'l' => ["#..", "#..", "#..", "#..", "###"],
        'm' => ["#.#", "###", "###", "#.#", "#.#"],
        'n' => ["##.", "#.#", "#.#", "#.#", "#.#"],
        'o' => [".#.", "#.#", "#.#", "#.#", ".#."],
        'p' => ["##.", "#.#", "##.", "#..", "#.."],
        'q' => [".#.", "#.#", "#.#", "##.", ".##"],
        'r' => ["##.", "#.#", "##.", "#.#", "#.#"],
        's' => [".##", "#..", ".#.", "..#", "##."],
        't' => ["###", ".#.", ".#.", ".#.", ".#."],
        'u' => ["#.#", "#.#", "#.#", "#.#", "###"],
        'v' => ["#.#", "#.#", "#.#", "#.#", ".#."],
        'w' => ["#.#", "#.#", "###", "###", "#.#"],
        'x' => ["#.#", "#.#", ".#.", "#.#", "#.#"],
        'y' => ["#.#", "#.#", ".#.", ".#.", ".#."],
        'z' => ["###", "..#", ".#.", "#..", "###"],
        '0' => ["###", "#.#", "#.#", "#.#", "###"],
        '1' => [".#.", "##.", ".#.", ".#.", "###"],
        '2' => ["##.", "..#", ".#.", "#..", "###"],
        '3' => ["##.", "..#", ".#.", "..#", "##."],
        '4' => ["#.#", "#.#", "###", "..#", "..#"],
        '5' => ["###", "#..", "##.", "..#", "##."],
        '6' => [".##", "#..", "###", "#.#", "###"],
        '7' => ["###", "..#", ".#.", ".#.", ".#."],
        '8' => ["###", "#.#", "###", "#.#", "###"],
        '9' => ["###", "#.#", "###", "..#", "##."],
        '-' => ["...", "...", "###", "...", "..."],
        '.' => ["...", "...", "...", "...", ".#."],
        ':' => ["...", ".#.", "...", ".#.", "..."],
        '(' => [".#.", "#..", "#..", "#..", ".#."],
        ')' => [".#.", "..#", "..#", "..#", ".#."],
        '/' => ["..#", "..#", ".#.", "#..", "#.."],
        '=' => ["...", "###", "...", "###", "..."],
        _ => ["...", "...", "...", "...", "..."],
    }
}

const SCALE: u32 = 2;
const LABEL_H: u32 = 7 * SCALE;

fn draw_text(img: &mut image::RgbImage, x0: u32, y0: u32, text: &str, max_width: u32) {
    let scale = if text.len() as u32 * 4 * SCALE <= max_width {
        SCALE
    } else {
        1
    };
    for (i, c) in text.chars().enumerate() {
        let gx = x0 + i as u32 * 4 * scale;
        for (row, bits) in glyph(c).iter().enumerate() {
            for (col, b) in bits.chars().enumerate() {
                if b != '#' {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        let (x, y) = (gx + col as u32 * scale + dx, y0 + row as u32 * scale + dy);
                        if x < img.width() && y < img.height() {
                            img.put_pixel(x, y, image::Rgb([255, 255, 255]));
                        }
                    }
                }
            }
        }
    }
}

fn srgb(x: f32) -> u8 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    let v = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (v * 255.0 + 0.5) as u8
}

/// Writes a sheet of `tiles` (label, image), `columns` per row, all with the same exposure.
pub fn write(path: &Path, tiles: &[(String, &Image)], columns: usize, exposure: f32) -> Result<()> {
    let Some((_, first)) = tiles.first() else {
        return Ok(());
    };
    let (tw, th) = (first.width as u32, first.height as u32);
    let columns = columns.clamp(1, tiles.len()) as u32;
    let rows = (tiles.len() as u32).div_ceil(columns);
    let gap = 4;
    let (cw, ch) = (tw + gap, th + LABEL_H + 2 + gap);
    let mut img = image::RgbImage::from_pixel(columns * cw + gap, rows * ch + gap, image::Rgb([24, 24, 24]));
    let scale = exposure.exp2();
    for (i, (label, tile)) in tiles.iter().enumerate() {
        let (cx, cy) = (gap + (i as u32 % columns) * cw, gap + (i as u32 / columns) * ch);
        draw_text(&mut img, cx, cy, label, tw);
        for y in 0..th.min(tile.height as u32) {
            for x in 0..tw.min(tile.width as u32) {
                let p = tile.pixels[(y * tile.width as u32 + x) as usize];
                img.put_pixel(
                    cx + x,
                    cy + LABEL_H + 2 + y,
                    image::Rgb([srgb(p[0] * scale), srgb(p[1] * scale), srgb(p[2] * scale)]),
                );
            }
        }
    }
    img.save(path).with_context(|| format!("writing {}", path.display()))
}
