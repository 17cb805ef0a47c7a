//! Images as the bench sees them (linear RGB float, read from OpenEXR) and the error metrics.
use anyhow::{Context, Result, bail};
use std::path::Path;

/// A linear-RGB image, rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            pixels: vec![[0.0; 3]; width * height],
        }
    }

    /// `wa·a + wb·b` (averaging the halves of a reference).
    pub fn blend(a: &Image, wa: f64, b: &Image, wb: f64) -> Result<Image> {
        same_size(a, b)?;
        let mut out = Image::new(a.width, a.height);
        for ((o, pa), pb) in out.pixels.iter_mut().zip(&a.pixels).zip(&b.pixels) {
            for c in 0..3 {
                o[c] = (wa * pa[c] as f64 + wb * pb[c] as f64) as f32;
            }
        }
        Ok(out)
    }

    /// Mean of each channel.
    pub fn mean(&self) -> [f64; 3] {
        let mut m = [0f64; 3];
        for p in &self.pixels {
            for c in 0..3 {
                m[c] += p[c] as f64;
            }
        }
        m.map(|v| v / self.pixels.len().max(1) as f64)
    }
}

fn same_size(a: &Image, b: &Image) -> Result<()> {
    if (a.width, a.height) != (b.width, b.height) {
        bail!(
            "image sizes differ: {}x{} vs {}x{}",
            a.width,
            a.height,
            b.width,
            b.height
        );
    }
    Ok(())
}

/// Relative MSE of `a` against the reference `b`: the mean over pixels and channels of
/// (a − b)² / (b² + 0.01), as `beamlight compare` computes it (the 0.01 keeps black pixels from
/// dominating).
pub fn rel_mse(a: &Image, b: &Image) -> Result<f64> {
    same_size(a, b)?;
    let mut sum = 0f64;
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let (x, y) = (pa[c] as f64, pb[c] as f64);
            sum += (x - y) * (x - y) / (y * y + 1e-2);
        }
    }
    Ok(sum / (3 * a.pixels.len()).max(1) as f64)
}

/// Root-mean-square error of `a` against `b` over pixels and channels.
pub fn rmse(a: &Image, b: &Image) -> Result<f64> {
    same_size(a, b)?;
    let mut sum = 0f64;
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let e = pa[c] as f64 - pb[c] as f64;
            sum += e * e;
        }
    }
    Ok((sum / (3 * a.pixels.len()).max(1) as f64).sqrt())
}

/// Every RGB layer of an OpenEXR file by name ("" for an unnamed single layer; beamlight's
/// first layer of a multi-layer file is "beauty"). Alpha is ignored.
pub fn read_exr_layers(path: &Path) -> Result<Vec<(String, Image)>> {
    use exr::prelude::*;
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |res, _| self::Image::new(res.width(), res.height()),
            |img: &mut self::Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let w = img.width;
                img.pixels[pos.y() * w + pos.x()] = [r, g, b]
            },
        )
        .all_layers()
        .all_attributes()
        .from_file(path)
        .with_context(|| format!("reading {}", path.display()))?;
    Ok(img
        .layer_data
        .into_iter()
        .map(|l| {
            let name = l.attributes.layer_name.map(|n| n.to_string()).unwrap_or_default();
            (name, l.channel_data.pixels)
        })
        .collect())
}

/// The beauty image (first layer) and the named component layers of an EXR.
pub fn read_beauty_and_layers(path: &Path) -> Result<(Image, Vec<(String, Image)>)> {
    let mut layers = read_exr_layers(path)?;
    if layers.is_empty() {
        bail!("{}: no RGB layer", path.display());
    }
    let beauty = layers.remove(0).1;
    Ok((beauty, layers))
}

/// Writes a float32 RGB OpenEXR (the merged reference).
pub fn write_exr(path: &Path, image: &Image) -> Result<()> {
    use exr::prelude::*;
    let w = image.width;
    write_rgb_file(path, image.width, image.height, |x, y| {
        let p = image.pixels[y * w + x];
        (p[0], p[1], p[2])
    })
    .with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(values: &[[f32; 3]]) -> Image {
        Image {
            width: values.len(),
            height: 1,
            pixels: values.to_vec(),
        }
    }

    #[test]
    fn metrics_on_known_arrays() {
        let reference = img(&[[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]]);
        let a = img(&[[1.1, 1.0, 0.9], [0.1, 0.0, 0.0]]);
        // Squared errors 0.01, 0, 0.01 over (1 + 0.01); 0.01 over (0 + 0.01) → 1.
        let expected = (0.01 / 1.01 * 2.0 + 1.0) / 6.0;
        assert!((rel_mse(&a, &reference).unwrap() - expected).abs() < 1e-6);
        assert!((rmse(&a, &reference).unwrap() - (0.03f64 / 6.0).sqrt()).abs() < 1e-6);
        assert_eq!(rel_mse(&reference, &reference).unwrap(), 0.0);
        assert!(rel_mse(&a, &img(&[[0.0; 3]])).is_err());
        let mean = Image::blend(&a, 0.5, &reference, 0.5).unwrap();
        assert!((mean.pixels[0][0] - 1.05).abs() < 1e-6);
    }

    #[test]
    fn exr_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        let a = Image {
            width: 2,
            height: 2,
            pixels: vec![[1.0, 2.0, 3.0], [0.5, 0.25, 0.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]],
        };
        write_exr(&path, &a).unwrap();
        let (b, layers) = read_beauty_and_layers(&path).unwrap();
        assert_eq!(a, b);
        assert!(layers.is_empty());
    }
}
