//! What a virtual light's estimate is when it cannot be made: never a silent zero.
use beamlight_scene::Rgb;

/// What a virtual light's estimate is when it cannot be made: the density its sample was drawn
/// by came out zero or not finite, or a segment of the pair has a length that is negative,
/// infinite or NaN. It is NaN, which the gathers' `admit` counts as a discarded estimate
/// (`--stats`, the EXR header): every sampler here gives a positive, finite density wherever
/// its integrand can be non-zero (tested per sampler) and paths keep finite lengths, so a sound
/// render never returns it; a zero instead would be a bias no check sees. The WGSL twin is
/// `failed_estimate` in `lib/gather.wgsl`.
pub const FAILED_ESTIMATE: Rgb = Rgb::NAN;

/// How a pair's estimate ends before sampling when one of its segments has this `length`: zero
/// for no length (nothing scatters along it), [`FAILED_ESTIMATE`] for a negative, infinite or
/// NaN one (a broken path: counted); `None` for a usable length. WGSL: `degenerate_length`.
pub fn degenerate_length(length: f32) -> Option<Rgb> {
    if length > 0.0 && length.is_finite() {
        None
    } else if length == 0.0 {
        Some(Rgb::ZERO)
    } else {
        Some(FAILED_ESTIMATE)
    }
}
