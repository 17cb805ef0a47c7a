//! Accumulators and images.
use beamlight_scene::Rgb;

/// A linear-RGB image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Rgb>,
}

impl Image {
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            pixels: vec![Rgb::ZERO; (width * height) as usize],
        }
    }

    pub fn get(&self, x: u32, y: u32) -> Rgb {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Mean over all pixels.
    pub fn mean(&self) -> Rgb {
        let mut s = [0f64; 3];
        for p in &self.pixels {
            for c in 0..3 {
                s[c] += p[c] as f64;
            }
        }
        let n = self.pixels.len().max(1) as f64;
        Rgb::new((s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32)
    }

    /// The image averaged over `factor`×`factor` pixel blocks (a box filter; rows and columns
    /// beyond the last whole block are left out). `factor` 0 or 1 returns a copy.
    pub fn downsample(&self, factor: u32) -> Image {
        let f = factor.max(1);
        let (w, h) = (self.width / f, self.height / f);
        let mut out = Image::new(w, h);
        for y in 0..h * f {
            for x in 0..w * f {
                out.pixels[((y / f) * w + x / f) as usize] += self.pixels[(y * self.width + x) as usize];
            }
        }
        let n = (f * f) as f32;
        out.pixels.iter_mut().for_each(|p| *p /= n);
        out
    }
}

/// The mean of `n` samples with sum `sum` and sum of squares `sum_sq`, and the estimated
/// variance of that mean (the sample variance over n; 0 with fewer than two samples).
pub fn mean_and_variance(n: f64, sum: f64, sum_sq: f64) -> (f64, f64) {
    if n < 1.0 {
        return (0.0, 0.0);
    }
    let mean = sum / n;
    if n < 2.0 {
        return (mean, 0.0);
    }
    (mean, ((sum_sq / n - mean * mean) * n / (n - 1.0)).max(0.0) / n)
}

/// Per-pixel running sums of samples (and of their squares, for variance estimates), in f64 so
/// that millions of samples can be added without losing the small ones.
#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    sum: Vec<[f64; 3]>,
    sum_sq: Vec<[f64; 3]>,
    /// Samples per pixel accumulated so far (every pixel gets the same count).
    pub samples: u64,
    /// Samples that were NaN or infinite and were dropped (a bug if ever non-zero).
    pub rejected: u64,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Self {
        let n = (width * height) as usize;
        Self {
            width,
            height,
            sum: vec![[0.0; 3]; n],
            sum_sq: vec![[0.0; 3]; n],
            samples: 0,
            rejected: 0,
        }
    }

    /// Adds one pass: one sample per pixel. Non-finite samples are counted and dropped so that
    /// no NaN or Inf ever reaches the accumulator.
    pub fn add_pass(&mut self, pass: &[Rgb]) {
        assert_eq!(pass.len(), self.sum.len());
        for ((s, s2), v) in self.sum.iter_mut().zip(self.sum_sq.iter_mut()).zip(pass) {
            if !v.is_finite() {
                self.rejected += 1;
                continue;
            }
            for c in 0..3 {
                let x = v[c] as f64;
                s[c] += x;
                s2[c] += x * x;
            }
        }
        self.samples += 1;
    }

    /// Adds another film's samples (the same pixels, other passes): the sums add, so merging
    /// the films of passes 0..k and k..n gives the film of 0..n up to f64 rounding.
    pub fn add_film(&mut self, other: &Film) {
        assert_eq!((self.width, self.height), (other.width, other.height));
        for (a, b) in self.sum.iter_mut().zip(&other.sum) {
            for c in 0..3 {
                a[c] += b[c];
            }
        }
        for (a, b) in self.sum_sq.iter_mut().zip(&other.sum_sq) {
            for c in 0..3 {
                a[c] += b[c];
            }
        }
        self.samples += other.samples;
        self.rejected += other.rejected;
    }

    /// The running sums (of the samples and of their squares), per pixel: what a checkpoint
    /// stores.
    pub fn sums(&self) -> (&[[f64; 3]], &[[f64; 3]]) {
        (&self.sum, &self.sum_sq)
    }

    /// A film from stored sums; `None` when their lengths do not match the size.
    pub fn from_sums(
        width: u32,
        height: u32,
        sum: Vec<[f64; 3]>,
        sum_sq: Vec<[f64; 3]>,
        samples: u64,
        rejected: u64,
    ) -> Option<Film> {
        let n = width as usize * height as usize;
        (sum.len() == n && sum_sq.len() == n).then_some(Film {
            width,
            height,
            sum,
            sum_sq,
            samples,
            rejected,
        })
    }

    /// A film that reads as an estimate: its [`Film::image`] is `mean` and its
    /// [`Film::variance_of_mean`] is `variance` (for `n` ≥ 2; with fewer there is no variance),
    /// as if `n` samples had been added. For estimates that are not plain averages (the
    /// combination of `--method auto`): its sums are not a render's and cannot be continued.
    pub fn from_estimate(mean: &Image, variance: &Image, n: u64) -> Film {
        let nf = n.max(1) as f64;
        let (sum, sum_sq) = mean
            .pixels
            .iter()
            .zip(&variance.pixels)
            .map(|(m, v)| {
                let m = [m[0] as f64, m[1] as f64, m[2] as f64];
                let v = [v[0] as f64, v[1] as f64, v[2] as f64];
                // variance_of_mean = (sum_sq/n − mean²)/(n − 1)
                let s2 = |c: usize| nf * (m[c] * m[c] + v[c] * (nf - 1.0));
                ([m[0] * nf, m[1] * nf, m[2] * nf], [s2(0), s2(1), s2(2)])
            })
            .unzip();
        Film {
            width: mean.width,
            height: mean.height,
            sum,
            sum_sq,
            samples: n,
            rejected: 0,
        }
    }

    /// The current estimate: the plain average of the samples per pixel.
    pub fn image(&self) -> Image {
        let n = self.samples.max(1) as f64;
        let pixels = self
            .sum
            .iter()
            .map(|s| Rgb::new((s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32))
            .collect();
        Image {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// Pixel `i`'s channel `c`: its mean and the variance of that mean ([`mean_and_variance`]).
    pub fn entry(&self, i: usize, c: usize) -> (f64, f64) {
        mean_and_variance(self.samples as f64, self.sum[i][c], self.sum_sq[i][c])
    }

    /// Estimated variance of each pixel's mean (sample variance / n).
    pub fn variance_of_mean(&self) -> Image {
        let pixels = (0..self.sum.len())
            .map(|i| {
                let v = |c: usize| self.entry(i, c).1 as f32;
                Rgb::new(v(0), v(1), v(2))
            })
            .collect();
        Image {
            width: self.width,
            height: self.height,
            pixels,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsample_averages_whole_blocks() {
        let mut img = Image::new(5, 3);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = Rgb::splat(i as f32);
        }
        let d = img.downsample(2);
        assert_eq!((d.width, d.height), (2, 1));
        // Block (0, 0) holds pixels 0, 1, 5, 6; block (1, 0) holds 2, 3, 7, 8.
        assert_eq!(d.pixels, vec![Rgb::splat(3.0), Rgb::splat(5.0)]);
        assert_eq!(img.downsample(1).pixels, img.pixels);
    }
}
