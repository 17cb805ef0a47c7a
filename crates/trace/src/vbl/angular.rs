//! The piecewise-linear angular PDFs: vertices equally spaced in the angle a segment subtends
//! at a fixed point, and sampling by them (see the parent module).
use super::VblSettings;
use beamlight_scene::sampling::{LineAngles, PIECEWISE_LINEAR_MAX_VERTICES, PiecewiseLinear};

/// The vertex angles of a piecewise-linear PDF over [θ0, θ1] with `k` vertices.
#[inline]
pub(super) fn vertex_angle(line: &LineAngles, i: usize, k: usize) -> f32 {
    let f = i as f32 / (k - 1) as f32;
    line.theta0 + (line.theta1 - line.theta0) * f
}

/// Vertices for a PDF over an angle range `extent` of an integrand varying on the angular scale
/// `scale`: four per scale unit (a lobe is then resolved by several vertices), at most
/// `settings.pdf_vertices`. A segment that subtends a small angle, e.g. a far VRL, needs only
/// a few: the PDF shape changes the variance, never the expected value. A `scale` of 0 (a
/// density grid's values, on no angular scale) takes the most.
#[inline]
pub(super) fn vertex_count(settings: &VblSettings, extent: f32, scale: f32) -> usize {
    let max = (settings.pdf_vertices as usize).clamp(2, PIECEWISE_LINEAR_MAX_VERTICES);
    if !(scale > 0.0) {
        return max;
    }
    let wanted = (4.0 * extent.abs() / scale).ceil() + 1.0;
    if wanted < max as f32 {
        (wanted as usize).max(2)
    } else {
        max
    }
}

/// The transmittance that shapes a PDF along its line: e^(−τ) from the first vertex to each
/// next one, τ by the trapezoid rule over the vertices' extinctions, which come in increasing
/// t (exact in a homogeneous medium). Only the PDF's shape: the estimators still take their
/// transmittance by tracking, so a coarse τ costs variance, never bias. The WGSL twin is
/// `fade_next` in `shaders/lib/angular.wgsl`.
#[derive(Default)]
pub(super) struct Fading {
    depth: f32,
    last: Option<(f32, f32)>,
}

impl Fading {
    /// e^(−τ) from the first vertex to the next one, at `t` with extinction `extinction`.
    pub(super) fn next(&mut self, t: f32, extinction: f32) -> f32 {
        if let Some((t_last, e_last)) = self.last {
            self.depth += 0.5 * (e_last + extinction) * (t - t_last);
        }
        self.last = Some((t, extinction));
        (-self.depth).exp()
    }
}

/// Samples the line parameter by a piecewise-linear density in the angle. `value(t)` gives a
/// vertex's (unnormalised) value and the extinction σt at t; the density follows the value
/// times the transmittance from the first vertex ([`Fading`]; an extinction of 0 leaves the
/// value as it is). Returns `(t, pdf in t)`; pdf 0 when there is nothing to sample.
pub(super) fn sample_angular(
    line: &LineAngles,
    t0: f32,
    t1: f32,
    settings: &VblSettings,
    scale: f32,
    u: f32,
    mut value: impl FnMut(f32) -> (f32, f32),
) -> (f32, f32) {
    let k = vertex_count(settings, line.theta1 - line.theta0, scale);
    let mut values = [0.0f32; PIECEWISE_LINEAR_MAX_VERTICES];
    let mut fading = Fading::default();
    for (i, v) in values.iter_mut().enumerate().take(k) {
        let t = line.t(vertex_angle(line, i, k)).clamp(t0, t1);
        let (value, extinction) = value(t);
        *v = value * fading.next(t, extinction);
    }
    let pl = PiecewiseLinear::new(line.theta0, line.theta1, &values[..k], settings.uniform_share);
    let (theta, pdf_theta) = pl.sample(u);
    let t = line.t(theta).clamp(t0, t1);
    let pdf = pdf_theta * line.dtheta_dt(t);
    (t, if pdf.is_finite() && pdf > 0.0 { pdf } else { 0.0 })
}

#[cfg(test)]
mod tests {
    use super::super::chi2;
    use super::*;
    use beamlight_scene::rng::Sampler;
    use glam::Vec3;

    /// `sample_angular` draws t by its claimed density: the t-samples of a bumpy value function
    /// with empty stretches (a density grid's shape along a VRL, stage 1's line about an apex
    /// off the segment) binned in t against the density integrated over each bin, that density
    /// built here from `PiecewiseLinear::pdf` in θ (the piecewise-linear law itself has its own
    /// chi-square test in the scene crate), and each sample's pdf against the same density at
    /// its t. Catches a vertex at the wrong t, a missing or wrong dθ/dt, a sample mapped back
    /// to the wrong t, a transmittance applied from the wrong end or with the wrong sign (a
    /// third case fades by a constant σt); made to fail once by dropping dθ/dt from the
    /// returned pdf, once by taking the vertex values 0.05 further along the line, and once
    /// by flipping the sign of the trapezoid's step.
    #[test]
    fn angular_samples_follow_their_density() {
        let len = 3.0f32;
        let settings = VblSettings::default();
        let shape = |t: f32| (3.0 * t).sin().max(0.0) + if t > 2.2 { 0.3 } else { 0.0 };
        for (name, apex, sigma_t) in [
            ("apex over the segment", Vec3::new(1.2, 0.4, 0.0), 0.0),
            ("apex beyond it", Vec3::new(-0.5, 0.2, 0.0), 0.0),
            ("fading", Vec3::new(1.2, 0.4, 0.0), 1.3),
        ] {
            let value = |t: f32| (shape(t), sigma_t);
            let line = LineAngles::new(Vec3::ZERO, Vec3::X, 0.0, len, apex, 0.0);
            let k = vertex_count(&settings, line.theta1 - line.theta0, 0.0);
            // A constant extinction fades the vertex values by e^(−σt t) exactly (the first
            // vertex is at t = 0).
            let values: Vec<f32> = (0..k)
                .map(|i| line.t(vertex_angle(&line, i, k)).clamp(0.0, len))
                .map(|t| shape(t) * (-sigma_t * t).exp())
                .collect();
            let pl = PiecewiseLinear::new(line.theta0, line.theta1, &values, settings.uniform_share);
            let density = |t: f32| pl.pdf(line.theta(t)) as f64 * line.dtheta_dt(t) as f64;
            let (n, bins) = (400_000usize, 60usize);
            let mut observed = vec![0.0; bins];
            for i in 0..n {
                let mut s = Sampler::new(11, 0, i as u32);
                let (t, pdf) = sample_angular(&line, 0.0, len, &settings, 0.0, s.next_1d(), value);
                assert!((0.0..=len).contains(&t) && pdf > 0.0, "{name}: t {t}, pdf {pdf}");
                let want = density(t);
                assert!(
                    ((pdf as f64) / want - 1.0).abs() < 1e-3,
                    "{name}: pdf {pdf} at t {t}, density {want}"
                );
                observed[((t / len * bins as f32) as usize).min(bins - 1)] += 1.0;
            }
            // Each bin's mass by the trapezoid rule in θ on a fine grid (the density in θ is
            // piecewise linear, so 64 steps a bin leave a relative error far below the noise).
            let expected: Vec<f64> = (0..bins)
                .map(|b| {
                    let (a, z) = (
                        line.theta(len * b as f32 / bins as f32),
                        line.theta(len * (b + 1) as f32 / bins as f32),
                    );
                    let steps = 64;
                    let h = (z - a) as f64 / steps as f64;
                    (0..steps)
                        .map(|j| {
                            0.5 * h
                                * (pl.pdf(a + (h * j as f64) as f32) as f64
                                    + pl.pdf(a + (h * (j + 1) as f64) as f32) as f64)
                        })
                        .sum::<f64>()
                        * n as f64
                })
                .collect();
            chi2::chi2_test(&observed, &expected, 0.01 / 2.0).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
    }
}
