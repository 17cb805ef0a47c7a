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

/// Samples the line parameter by a piecewise-linear density in the angle (`value(t)` gives the
/// vertex values). Returns `(t, pdf in t)`; pdf 0 when there is nothing to sample.
pub(super) fn sample_angular(
    line: &LineAngles,
    t0: f32,
    t1: f32,
    settings: &VblSettings,
    scale: f32,
    u: f32,
    mut value: impl FnMut(f32) -> f32,
) -> (f32, f32) {
    let k = vertex_count(settings, line.theta1 - line.theta0, scale);
    let mut values = [0.0f32; PIECEWISE_LINEAR_MAX_VERTICES];
    for (i, v) in values.iter_mut().enumerate().take(k) {
        *v = value(line.t(vertex_angle(line, i, k)).clamp(t0, t1));
    }
    let pl = PiecewiseLinear::new(line.theta0, line.theta1, &values[..k], settings.uniform_share);
    let (theta, pdf_theta) = pl.sample(u);
    let t = line.t(theta).clamp(t0, t1);
    let pdf = pdf_theta * line.dtheta_dt(t);
    (t, if pdf.is_finite() && pdf > 0.0 { pdf } else { 0.0 })
}
