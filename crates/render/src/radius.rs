//! The radii of the virtual beam and spherical lights and of the caustics: their defaults R0
//! for a scene, and the progressive schedule of the paper's eq. 11 (Jarosz et al. 2011's reduction
//! applied to the squared radius):
//!
//! R_i² = R_0² · (∏_{k=1}^{Mi−1} (k + α) / k) · 1 / (Mi),  i = 1, 2, … the pass number,
//!
//! with M photons (lights) per pass and α ∈ (0, 1). After 10⁶ passes of 10⁶ lights the product
//! has 10¹² factors, so it is never formed: its logarithm
//! S(n) = Σ_{k=1}^{n} ln(1 + α/k) = ln Γ(n+1+α) − ln Γ(n+1) − ln Γ(1+α)
//! is summed exactly for the first terms and continued with the asymptotic (Stirling) series
//! of ln Γ(z+α) − ln Γ(z), which for z > 1000 is accurate to f64 rounding. Evaluating
//! ln Γ at z ≈ 10¹² directly would instead lose about three digits to cancellation.

/// The default initial VBL/VSL radius R0: 10 % of the diagonal of the scene's bounds. Eq. 11
/// makes R0 the radius of a pass with a single light path; with M paths per pass the first
/// pass already uses about R0 · M^((α−1)/2) (0.56 R0 for M = 64, α = 0.7), and 1000 passes
/// later 0.14 R0. The paper leaves R0 to the user; a sphere must be wide compared with the
/// distances at which a glossy surface or a forward-scattering medium would make a virtual
/// light's contribution spike, which is what a tenth of the scene is meant to be (measured
/// in `tests/vbl_progressive.rs`: 2.5 % left such spikes in a glossy-floored fog box).
pub fn default_radius(scene: &beamlight_scene::Scene) -> f32 {
    0.1 * diagonal(scene)
}

/// The default initial photon-mapping radius: 2.5 % of the scene's diagonal (caustics are
/// sharp, and photons are density-estimated, not connected: no singularity to spread).
pub fn default_photon_radius(scene: &beamlight_scene::Scene) -> f32 {
    0.025 * diagonal(scene)
}

fn diagonal(scene: &beamlight_scene::Scene) -> f32 {
    let (lo, hi) = scene.bounds();
    let d = (hi - lo).length();
    if d.is_finite() && d > 0.0 { d } else { 1.0 }
}

/// The squared radius of pass `pass` (0-based) for initial radius `r0`, `paths` light paths
/// per pass and α, from eq. 11 in log space.
pub fn paths_squared_radius(r0: f32, alpha: f32, paths: u32, pass: u32) -> f32 {
    squared_radius(r0 as f64, alpha as f64, paths.max(1) as u64, pass as u64 + 1) as f32
}

/// Terms of S(n) summed one by one before the asymptotic series takes over.
const DIRECT_TERMS: u64 = 1024;

/// ln Γ(z + a) − ln Γ(z) for z ≥ DIRECT_TERMS, from the Bernoulli-polynomial form of Stirling's
/// series: a ln z + Σ_k (−1)^{k+1} (B_{k+1}(a) − B_{k+1}(0)) / (k (k+1) z^k), three terms.
fn log_gamma_ratio(z: f64, a: f64) -> f64 {
    let (z2, z3) = (z * z, z * z * z);
    a * z.ln() + (a * a - a) / (2.0 * z) - (a * a * a - 1.5 * a * a + 0.5 * a) / (6.0 * z2)
        + (a * a * a * a - 2.0 * a * a * a + a * a) / (12.0 * z3)
}

/// S(n) = ln ∏_{k=1}^{n} (k + α)/k.
pub fn log_product(n: u64, alpha: f64) -> f64 {
    let direct: f64 = (1..=n.min(DIRECT_TERMS)).map(|k| (alpha / k as f64).ln_1p()).sum();
    if n <= DIRECT_TERMS {
        return direct;
    }
    // Σ_{k=K+1}^{n} ln((k+α)/k) = [ln Γ(n+1+α) − ln Γ(n+1)] − [ln Γ(K+1+α) − ln Γ(K+1)].
    let k = DIRECT_TERMS as f64;
    direct + log_gamma_ratio(n as f64 + 1.0, alpha) - log_gamma_ratio(k + 1.0, alpha)
}

/// Squared radius R_i² of eq. 11 for pass `i` (1-based), `m` lights per pass.
pub fn squared_radius(r0: f64, alpha: f64, m: u64, i: u64) -> f64 {
    assert!(i >= 1 && m >= 1, "passes and light counts start at 1");
    let mi = m as f64 * i as f64;
    let n = m.saturating_mul(i) - 1;
    (2.0 * r0.ln() + log_product(n, alpha) - mi.ln()).exp()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the literal formula (a running product) where that is still exact enough.
    #[test]
    fn matches_direct_product_for_small_passes() {
        for &(m, alpha) in &[(1u64, 0.7f64), (3, 0.5), (100, 0.7), (1000, 0.9), (10, 0.1)] {
            let mut product = 1.0f64;
            let mut k = 1u64;
            for i in 1..=40u64 {
                while k < m * i {
                    product *= (k as f64 + alpha) / k as f64;
                    k += 1;
                }
                let direct = 0.04 * product / (m * i) as f64;
                let ours = squared_radius(0.2, alpha, m, i);
                assert!(
                    (ours / direct - 1.0).abs() < 1e-11,
                    "m {m} α {alpha} i {i}: {ours} vs {direct}"
                );
            }
        }
    }

    #[test]
    fn first_pass_has_the_initial_radius() {
        assert!((squared_radius(0.5, 0.7, 1, 1) - 0.25).abs() < 1e-15);
    }

    /// The series and the direct sum agree where both are valid (just past the switch-over).
    #[test]
    fn series_continues_the_direct_sum_smoothly() {
        let alpha = 0.7;
        for n in [DIRECT_TERMS + 1, DIRECT_TERMS + 17, 5000, 40_000] {
            let direct: f64 = (1..=n).map(|k| (alpha / k as f64).ln_1p()).sum();
            assert!((log_product(n, alpha) - direct).abs() < 1e-11, "n {n}");
        }
    }

    /// Out to 10⁶ passes of 10⁶ lights: finite, positive, strictly decreasing, and following
    /// the asymptote R_i² → R_0² (Mi)^(α−1) / Γ(1+α).
    #[test]
    fn stays_exact_after_a_million_passes() {
        let (r0, alpha, m) = (1.0, 0.7, 1_000_000u64);
        let mut prev = f64::INFINITY;
        for i in [1u64, 2, 3, 10, 100, 1_000, 10_000, 100_000, 999_999, 1_000_000] {
            let r2 = squared_radius(r0, alpha, m, i);
            assert!(r2.is_finite() && r2 > 0.0 && r2 < prev, "i {i}: {r2}");
            prev = r2;
        }
        // Γ(1.7) = 0.908_638_732_853_290_2 (tabulated).
        let mi = 1e12f64;
        let asymptote = mi.powf(alpha - 1.0) / 0.908_638_732_853_290_2;
        let r2 = squared_radius(r0, alpha, m, 1_000_000);
        assert!((r2 / asymptote - 1.0).abs() < 1e-9, "{r2} vs {asymptote}");
        // Consecutive passes differ by the expected ratio ((i+1)/i)^(α−1), not by rounding noise.
        let (a, b) = (
            squared_radius(r0, alpha, m, 999_999),
            squared_radius(r0, alpha, m, 1_000_000),
        );
        let expected = (1_000_000f64 / 999_999f64).powf(alpha - 1.0);
        assert!((b / a / expected - 1.0).abs() < 1e-9);
    }
}
