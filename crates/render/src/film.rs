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
///
/// Each pixel's estimate is the mean of its own samples: every pass adds one to each pixel,
/// but a *partial* pass (a time budget's shortened last pass) only to the pixels it covered,
/// which are counted apart.
#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    sum: Vec<[f64; 3]>,
    sum_sq: Vec<[f64; 3]>,
    /// Whole passes accumulated: samples every pixel has.
    pub samples: u64,
    /// Partial passes accumulated, and per pixel how many of them covered it (empty while
    /// there are none).
    partial: u64,
    extra: Vec<u32>,
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
            partial: 0,
            extra: Vec::new(),
            rejected: 0,
        }
    }

    /// Partial passes added ([`Film::add_partial_pass`]).
    pub fn partial_passes(&self) -> u64 {
        self.partial
    }

    /// Passes added, whole and partial.
    pub fn passes(&self) -> u64 {
        self.samples + self.partial
    }

    /// Per pixel, the partial passes that covered it (empty when there were none).
    pub fn partial_counts(&self) -> &[u32] {
        &self.extra
    }

    /// The samples pixel `i` holds.
    pub fn count(&self, i: usize) -> u64 {
        self.samples + self.extra.get(i).map_or(0, |&e| e as u64)
    }

    /// Adds a partial pass: a sample to each pixel `covered` says it covered (the others' values
    /// are ignored). Non-finite samples are counted and dropped, as by [`Film::add_pass`].
    pub fn add_partial_pass(&mut self, pass: &[Rgb], covered: impl Fn(usize) -> bool) {
        assert_eq!(pass.len(), self.sum.len());
        if self.extra.is_empty() {
            self.extra = vec![0; self.sum.len()];
        }
        for (i, v) in pass.iter().enumerate() {
            if !covered(i) {
                continue;
            }
            self.extra[i] += 1;
            if !v.is_finite() {
                self.rejected += 1;
                continue;
            }
            for c in 0..3 {
                let x = v[c] as f64;
                self.sum[i][c] += x;
                self.sum_sq[i][c] += x * x;
            }
        }
        self.partial += 1;
    }

    /// Adds one pass: one sample per pixel. Non-finite samples are counted and dropped so that
    /// no NaN or Inf ever reaches the accumulator.
    pub fn add_pass(&mut self, pass: &[Rgb]) {
        assert_eq!(pass.len(), self.sum.len());
        // A pass that is zero everywhere (a component absent from the scene, or one the pass
        // did not estimate) is a sample of 0 in every pixel: adding it leaves the sums as they
        // are, so only the count moves. Reading the pass (12 bytes a pixel) costs a fraction
        // of adding it to the f64 sums (48 bytes a pixel, read and written), which a path
        // tracer's pass, one sample per pixel, pays for every component film: in the Cornell
        // box five of the seven are empty.
        if pass.iter().all(|v| *v == Rgb::ZERO) {
            self.samples += 1;
            return;
        }
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
        if !other.extra.is_empty() {
            if self.extra.is_empty() {
                self.extra = vec![0; self.sum.len()];
            }
            for (a, b) in self.extra.iter_mut().zip(&other.extra) {
                *a += b;
            }
        }
        self.partial += other.partial;
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
            partial: 0,
            extra: Vec::new(),
            rejected,
        })
    }

    /// The film with `partial` partial passes whose per-pixel counts are `counts` (what a
    /// checkpoint stores); `None` when the counts do not fit the film or the passes.
    pub fn with_partial(mut self, partial: u64, counts: Vec<u32>) -> Option<Film> {
        let fits = match partial {
            0 => counts.is_empty() || counts.iter().all(|&c| c == 0),
            _ => counts.len() == self.sum.len() && counts.iter().all(|&c| c as u64 <= partial),
        };
        if !fits {
            return None;
        }
        self.partial = partial;
        self.extra = if partial == 0 { Vec::new() } else { counts };
        Some(self)
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
            partial: 0,
            extra: Vec::new(),
            rejected: 0,
        }
    }

    /// The current estimate: the plain average of each pixel's samples.
    pub fn image(&self) -> Image {
        let pixels = self
            .sum
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let n = self.count(i).max(1) as f64;
                Rgb::new((s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32)
            })
            .collect();
        Image {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// Pixel `i`'s channel `c`: its mean and the variance of that mean ([`mean_and_variance`]).
    pub fn entry(&self, i: usize, c: usize) -> (f64, f64) {
        mean_and_variance(self.count(i) as f64, self.sum[i][c], self.sum_sq[i][c])
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

    /// A partial pass adds a sample to the pixels it covered alone: each pixel's mean and
    /// variance are those of its own samples, and merging films adds the counts. Catches a
    /// partial pass divided by the whole passes' count (pixel 0 would read 3.0, not 2.0) or
    /// counted for every pixel (pixel 1 would read 2/3 of its value).
    #[test]
    fn a_partial_pass_counts_for_the_pixels_it_covered() {
        let mut f = Film::new(2, 1);
        f.add_pass(&[Rgb::splat(1.0), Rgb::splat(2.0)]);
        f.add_pass(&[Rgb::splat(2.0), Rgb::splat(2.0)]);
        f.add_partial_pass(&[Rgb::splat(3.0), Rgb::splat(100.0)], |i| i == 0);
        assert_eq!((f.samples, f.partial_passes(), f.passes()), (2, 1, 3));
        assert_eq!((f.count(0), f.count(1)), (3, 2));
        assert_eq!(f.image().pixels, vec![Rgb::splat(2.0), Rgb::splat(2.0)]);
        // Pixel 0: samples 1, 2, 3, sample variance 1, variance of the mean 1/3.
        assert!((f.entry(0, 0).1 - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(f.entry(1, 0).1, 0.0);
        let mut g = Film::new(2, 1);
        g.add_partial_pass(&[Rgb::splat(0.0), Rgb::splat(5.0)], |i| i == 1);
        g.add_film(&f);
        assert_eq!((g.samples, g.partial_passes(), g.partial_counts()), (2, 2, &[1, 1][..]));
        assert_eq!(g.image().pixels, vec![Rgb::splat(2.0), Rgb::splat(3.0)]);
        // Stored counts must fit the passes.
        let stored = |partial, counts| Film::new(2, 1).with_partial(partial, counts).is_some();
        assert!(stored(1, vec![1, 0]) && stored(0, vec![]));
        assert!(!stored(1, vec![2, 0]) && !stored(1, vec![1]) && !stored(0, vec![1, 0]));
    }

    /// A pass that is zero everywhere is a sample of 0 in every pixel (means and variances as
    /// if it had been added), also as −0; a pass with a NaN in it is not such a pass (the NaN is
    /// counted and dropped). Catches the shortcut leaving the count alone (pixel 0 would read
    /// 2.0, not 4/3) or taking a NaN pass for an empty one.
    #[test]
    fn an_empty_pass_is_a_sample_of_zero() {
        let mut f = Film::new(2, 1);
        f.add_pass(&[Rgb::splat(1.0), Rgb::splat(2.0)]);
        f.add_pass(&[Rgb::ZERO, Rgb::splat(-0.0)]);
        f.add_pass(&[Rgb::splat(3.0), Rgb::ZERO]);
        assert_eq!(f.samples, 3);
        assert_eq!(f.image().pixels, vec![Rgb::splat(4.0 / 3.0), Rgb::splat(2.0 / 3.0)]);
        // Pixel 0: samples 1, 0, 3: sample variance 7/3, variance of the mean 7/9.
        assert!((f.entry(0, 0).1 - 7.0 / 9.0).abs() < 1e-12);
        f.add_pass(&[Rgb::new(f32::NAN, 0.0, 0.0), Rgb::ZERO]);
        assert_eq!((f.samples, f.rejected), (4, 1));
    }

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
