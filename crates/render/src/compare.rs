//! Image error metrics (`beamlight compare`, benchmarks, tests).
use crate::Image;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    pub rmse: f64,
    /// Mean over pixels and channels of (a−b)² / (b² + 0.01).
    pub rel_mse: f64,
    pub mae: f64,
    pub max_abs: f64,
}

/// Compares `a` against the reference `b`; errors when the sizes differ.
pub fn compare(a: &Image, b: &Image) -> Result<Metrics, String> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(format!(
            "image sizes differ: {}x{} vs {}x{}",
            a.width, a.height, b.width, b.height
        ));
    }
    let (mut se, mut rel, mut ae, mut max) = (0f64, 0f64, 0f64, 0f64);
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let (x, y) = (pa[c] as f64, pb[c] as f64);
            let e = x - y;
            se += e * e;
            rel += e * e / (y * y + 1e-2);
            ae += e.abs();
            max = max.max(e.abs());
        }
    }
    let n = (a.pixels.len() * 3).max(1) as f64;
    Ok(Metrics {
        rmse: (se / n).sqrt(),
        rel_mse: rel / n,
        mae: ae / n,
        max_abs: max,
    })
}
