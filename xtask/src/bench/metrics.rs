//! Images as the bench sees them and the error metrics: the renderer's own (`beamlight_render`
//! `Image`, OpenEXR reading and `compare`), so the bench measures exactly what
//! `beamlight compare` reports.
use anyhow::{Result, anyhow, bail};
pub use beamlight_render::Image;
use beamlight_render::{compare::compare, output};
use std::path::Path;

/// `wa·a + wb·b` (averaging the halves of a reference).
pub fn blend(a: &Image, wa: f64, b: &Image, wb: f64) -> Result<Image> {
    same_size(a, b)?;
    let pixels = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(pa, pb)| (pa.as_dvec3() * wa + pb.as_dvec3() * wb).as_vec3())
        .collect();
    Ok(Image {
        width: a.width,
        height: a.height,
        pixels,
    })
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
    Ok(compare(a, b).map_err(|e| anyhow!(e))?.rel_mse)
}

/// Root-mean-square error of `a` against `b` over pixels and channels.
pub fn rmse(a: &Image, b: &Image) -> Result<f64> {
    Ok(compare(a, b).map_err(|e| anyhow!(e))?.rmse)
}

/// The beauty image (first layer) and the named component layers of an EXR.
pub fn read_beauty_and_layers(path: &Path) -> Result<(Image, Vec<(String, Image)>)> {
    let mut layers = output::read_exr_layers(path)?;
    if layers.is_empty() {
        bail!("{}: no RGB layer", path.display());
    }
    let beauty = layers.remove(0).1;
    Ok((beauty, layers))
}

/// Writes a float32 RGB OpenEXR (the merged reference), atomically.
pub fn write_exr(path: &Path, image: &Image) -> Result<()> {
    Ok(output::write_exr(path, image, &[])?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use beamlight_scene::Rgb;

    fn img(values: &[[f32; 3]]) -> Image {
        Image {
            width: values.len() as u32,
            height: 1,
            pixels: values.iter().map(|&v| Rgb::from_array(v)).collect(),
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
        let mean = blend(&a, 0.5, &reference, 0.5).unwrap();
        assert!((mean.pixels[0][0] - 1.05).abs() < 1e-6);
    }

    #[test]
    fn exr_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        let a = Image {
            width: 2,
            height: 2,
            pixels: [[1.0, 2.0, 3.0], [0.5, 0.25, 0.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]]
                .map(Rgb::from_array)
                .to_vec(),
        };
        write_exr(&path, &a).unwrap();
        let (b, layers) = read_beauty_and_layers(&path).unwrap();
        assert_eq!(a.pixels, b.pixels);
        assert!(layers.is_empty());
    }
}
