//! Unbiasedness of ratio tracking (transmittance) and delta tracking (free-flight distances)
//! in baked density grids — a Perlin medium and the OpenVDB test volume — against a
//! brute-force ray march (midpoint rule, tiny steps) of the same trilinear density.
//!
//! Per ray: transmittance as the mean of many ratio-tracking estimates (z-test with the sample
//! standard error), and, for a grey purely scattering medium, the histogram of first-collision
//! distances (4 bins + "no collision") against `T(t_k) − T(t_{k+1})` (binomial z-tests). Every
//! |z| must stay below 5 (≈1,000 tests per medium: a false alarm has probability ~10⁻³), and
//! the mean of z² must be close to 1 (no systematic bias hiding under the tolerance).
use beamlight_scene::medium::{DensityGrid, Medium};
use beamlight_scene::noise::PerlinDensity;
use beamlight_scene::rng::Sampler;
use beamlight_scene::{Rgb, vdb::read_vdb};
use beamlight_trace::media::{MediumEvent, sample_distance, transmittance};
use glam::{UVec3, Vec3};

const RAYS: u32 = 200;
const SAMPLES: u32 = 2000;

/// ∫₀ᵗ d(o + s·dir) ds by the midpoint rule with `steps` steps.
fn optical_depth(g: &DensityGrid, o: Vec3, d: Vec3, t: f32, steps: u32) -> f64 {
    let h = t as f64 / steps as f64;
    (0..steps)
        .map(|i| g.density(o + d * ((i as f64 + 0.5) * h) as f32) as f64)
        .sum::<f64>()
        * h
}

/// Deterministic rays: origin in the box grown by 10 %, aimed at a point of the box's central
/// 60 %, length 0.5–2 times the distance to it.
fn rays(g: &DensityGrid) -> Vec<(Vec3, Vec3, f32)> {
    let mut state = 0x1234_5678u64;
    let mut u = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 40) as f32) / (1u64 << 24) as f32
    };
    let size = g.hi - g.lo;
    (0..RAYS)
        .map(|_| {
            let o = g.lo - 0.1 * size + Vec3::new(u(), u(), u()) * 1.2 * size;
            let target = g.lo + (Vec3::splat(0.2) + 0.6 * Vec3::new(u(), u(), u())) * size;
            let d = (target - o).normalize();
            let t = (0.5 + 1.5 * u()) * (target - o).length();
            (o, d, t)
        })
        .collect()
}

#[derive(Default, Debug)]
struct Z {
    n: u32,
    sum_sq: f64,
    max_abs: f64,
}

impl Z {
    fn add(&mut self, est: f64, expected: f64, se: f64) {
        let z = (est - expected) / se.max(1e-4);
        self.n += 1;
        self.sum_sq += z * z;
        self.max_abs = self.max_abs.max(z.abs());
    }
    fn check(&self, what: &str) {
        let mean_sq = self.sum_sq / self.n as f64;
        eprintln!(
            "{what}: {} z-tests, max |z| = {:.2}, mean z² = {mean_sq:.3}",
            self.n, self.max_abs
        );
        assert!(self.max_abs < 5.0, "{what}: {self:?}");
        assert!((0.7..1.3).contains(&mean_sq), "{what}: mean z² {mean_sq}");
    }
}

fn check_medium(label: &str, grid: DensityGrid, sigma_scale: f32) {
    // Chromatic, absorbing: ratio tracking must give every channel's transmittance.
    let sigma_s = Rgb::new(2.0, 1.0, 3.0) * sigma_scale;
    let sigma_a = Rgb::new(0.5, 0.2, 0.0) * sigma_scale;
    let chroma = Medium {
        name: label.into(),
        sigma_s,
        sigma_a,
        g: 0.0,
        density: Some(grid.clone()),
    };
    // Strongly chromatic (one channel 1000× thinner than the densest): ratio tracking walks
    // per group of similar channels (`media::extinction_groups`), here {R, B} and {G}. The
    // thin channel is dense enough that its walk takes a step on a few % of the rays: with
    // 2000 samples a rarer step would leave the sample variance, and so the z-test, blind.
    let sharp_chroma = Medium {
        name: label.into(),
        sigma_s: Rgb::new(32.0, 0.032, 16.0) * sigma_scale,
        sigma_a: Rgb::new(8.0, 0.008, 4.0) * sigma_scale,
        g: 0.0,
        density: Some(grid.clone()),
    };
    assert_eq!(
        beamlight_trace::media::extinction_groups(sharp_chroma.sigma_t()).count(),
        2
    );
    // Grey, purely scattering: delta tracking's first real collision has the free-flight law.
    let grey_sigma = 2.0 * sigma_scale;
    let grey = Medium {
        name: label.into(),
        sigma_s: Rgb::splat(grey_sigma),
        sigma_a: Rgb::ZERO,
        g: 0.0,
        density: Some(grid.clone()),
    };
    let (mut zt, mut zs, mut zd, mut zc) = (Z::default(), Z::default(), Z::default(), Z::default());
    let mut hit_density = 0;
    for (r, &(o, d, tmax)) in rays(&grid).iter().enumerate() {
        let depth = optical_depth(&grid, o, d, tmax, 20_000);
        if depth == 0.0 {
            continue; // misses the density: both estimators are exactly 1 (no information)
        }
        hit_density += 1;
        // Ratio tracking.
        for (k, m) in [&chroma, &sharp_chroma].into_iter().enumerate() {
            let st = m.sigma_t();
            let mut sum = [0.0f64; 3];
            let mut sum2 = [0.0f64; 3];
            for i in 0..SAMPLES {
                let mut s = Sampler::new(11 + 2 * k as u32, r as u32, i);
                let tr = transmittance(m, o, d, tmax, &mut s);
                for c in 0..3 {
                    sum[c] += tr[c] as f64;
                    sum2[c] += (tr[c] as f64).powi(2);
                }
            }
            let z = if k == 0 { &mut zt } else { &mut zs };
            for c in 0..3 {
                let n = SAMPLES as f64;
                let mean = sum[c] / n;
                let var = (sum2[c] / n - mean * mean).max(0.0) * n / (n - 1.0);
                let expected = (-(st[c] as f64) * depth).exp();
                if k == 1 && expected < 1e-6 && mean < 1e-4 {
                    // A dense channel the ray has all but extinguished: both are ~0 and the
                    // z-test (standard error floored at 1e-4) would only dilute the mean z².
                    continue;
                }
                z.add(mean, expected, (var / n).sqrt());
            }
        }
        // Delta tracking: bins at quarters of tmax, plus "no collision".
        let edges: Vec<f32> = (0..=4).map(|k| tmax * k as f32 / 4.0).collect();
        let tr_at: Vec<f64> = edges
            .iter()
            .map(|&t| (-(grey_sigma as f64) * optical_depth(&grid, o, d, t, 5_000)).exp())
            .collect();
        let mut counts = [0u32; 5];
        for i in 0..SAMPLES {
            let mut s = Sampler::new(12, r as u32, i);
            match sample_distance(&grey, o, d, tmax, Rgb::ONE, &mut s) {
                MediumEvent::Scatter { t, weight } => {
                    assert!(t > 0.0 && t < tmax);
                    assert!((weight - Rgb::ONE).abs().max_element() < 1e-3, "{weight}");
                    counts[((t / tmax * 4.0) as usize).min(3)] += 1;
                }
                MediumEvent::Pass { weight } => {
                    assert!((weight - Rgb::ONE).abs().max_element() < 1e-3, "{weight}");
                    counts[4] += 1;
                }
            }
        }
        for k in 0..5 {
            let p = if k < 4 { tr_at[k] - tr_at[k + 1] } else { tr_at[4] };
            let n = SAMPLES as f64;
            let se = (p * (1.0 - p) / n).sqrt();
            zd.add(counts[k] as f64 / n, p, se.max(0.5 / n));
        }
    }
    // Free flights in strongly chromatic media (one channel 1000× thinner; one without
    // extinction): a sample tracks one group of channels (`media::pick_group`), so each
    // channel's weighted histogram of first collisions must still be T_c(t_k) − T_c(t_{k+1})
    // per bin and T_c(tmax) for passing (purely scattering media).
    for (k, sigma) in [Rgb::new(40.0, 0.04, 20.0), Rgb::new(40.0, 0.0, 20.0)]
        .into_iter()
        .enumerate()
    {
        let sigma = sigma * sigma_scale;
        let m = Medium {
            name: label.into(),
            sigma_s: sigma,
            sigma_a: Rgb::ZERO,
            g: 0.0,
            density: Some(grid.clone()),
        };
        for (r, &(o, d, tmax)) in rays(&grid).iter().enumerate().step_by(4) {
            let edges: Vec<f32> = (0..=4).map(|k| tmax * k as f32 / 4.0).collect();
            let depth_at: Vec<f64> = edges.iter().map(|&t| optical_depth(&grid, o, d, t, 5_000)).collect();
            if depth_at[4] == 0.0 {
                continue;
            }
            let (mut sum, mut sum2) = ([[0.0f64; 3]; 5], [[0.0f64; 3]; 5]);
            for i in 0..SAMPLES {
                let mut s = Sampler::new(20 + k as u32, r as u32, i);
                let (bin, weight) = match sample_distance(&m, o, d, tmax, Rgb::ONE, &mut s) {
                    MediumEvent::Scatter { t, weight } => (((t / tmax * 4.0) as usize).min(3), weight),
                    MediumEvent::Pass { weight } => (4, weight),
                };
                assert!(weight.is_finite() && weight.min_element() >= 0.0, "{weight}");
                for c in 0..3 {
                    sum[bin][c] += weight[c] as f64;
                    sum2[bin][c] += (weight[c] as f64).powi(2);
                }
            }
            for bin in 0..5 {
                for c in 0..3 {
                    let tr = |j: usize| (-(sigma[c] as f64) * depth_at[j]).exp();
                    let expected = if bin < 4 { tr(bin) - tr(bin + 1) } else { tr(4) };
                    let n = SAMPLES as f64;
                    let mean = sum[bin][c] / n;
                    let var = (sum2[bin][c] / n - mean * mean).max(0.0) * n / (n - 1.0);
                    if expected < 1e-6 && mean < 1e-4 {
                        continue; // nothing there, nothing seen: no information
                    }
                    // A bin the thin channel reaches on a few samples in 2000 may have seen none,
                    // and a sample variance of 0 then: the standard error is floored at that of
                    // a Poisson count of unit-weight events with the expected mean.
                    zc.add(mean, expected, (var / n).sqrt().max((expected / n).sqrt()));
                }
            }
        }
    }
    zc.check(&format!(
        "{label}: free flights, one channel 1000× thinner or without extinction"
    ));
    assert!(
        hit_density > RAYS / 2,
        "{label}: only {hit_density} rays meet the medium"
    );
    zt.check(&format!("{label}: ratio-tracking transmittance"));
    zs.check(&format!(
        "{label}: ratio-tracking transmittance, one channel 1000× thinner"
    ));
    zd.check(&format!("{label}: delta-tracking free-flight distances"));
}

#[test]
fn perlin_grid_tracking_is_unbiased() {
    let p = PerlinDensity {
        seed: 7,
        ..Default::default()
    };
    let grid = p.bake(
        UVec3::new(32, 24, 28),
        Vec3::new(-1.0, 0.0, -0.5),
        Vec3::new(1.0, 1.5, 1.25),
    );
    check_medium("perlin", grid, 1.0);
}

#[test]
fn vdb_grid_tracking_is_unbiased() {
    let bytes = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/volumes/blob.vdb")).unwrap();
    let v = read_vdb(&bytes, "density").unwrap();
    let (lo, hi) = v.world_box();
    let grid = DensityGrid::new(v.res, lo.as_vec3(), hi.as_vec3(), v.values);
    // The volume is ~3 × 0.7 × 1.2 units: denser coefficients so rays see real attenuation.
    check_medium("vdb", grid, 3.0);
}

/// A NaN density (one voxel) makes the transmittance of rays that meet it NaN, for the
/// estimators' admission to count, not 0: clamping with `max` turned it into an opaque wall
/// that nothing reported (failed before: 0 of 2000 estimates NaN).
#[test]
fn a_nan_density_gives_a_nan_transmittance() {
    let res = UVec3::splat(5);
    let mut values = vec![1.0f32; 125];
    values[2 + 5 * (2 + 5 * 2)] = f32::NAN;
    let grid = DensityGrid::new(res, Vec3::ZERO, Vec3::ONE, values);
    let m = Medium {
        name: "nan".into(),
        sigma_s: Rgb::splat(2.0),
        sigma_a: Rgb::splat(0.5),
        g: 0.0,
        density: Some(grid),
    };
    // Straight through the middle voxel.
    let (o, d) = (Vec3::new(0.5, 0.5, -0.1), Vec3::Z);
    let mut nan = 0;
    for k in 0..2000 {
        let mut s = Sampler::new(3, 0, k);
        let tr = transmittance(&m, o, d, 1.2, &mut s);
        assert!(tr.is_nan() || tr.min_element() >= 0.0, "{tr}");
        nan += tr.is_nan() as u32;
    }
    assert!(nan > 100, "{nan} of 2000 transmittance estimates were NaN");
}

/// A majorant too small for its grid (here half the density) is reported, not hidden: ratio
/// tracking's negative factors make the transmittance NaN, and delta tracking's negative null
/// density makes the event's weight NaN, for the estimators' and the film's counters. With the
/// true majorant neither ever happens. Before, the transmittance's negative factor sent the
/// walk into Russian roulette, which ended it at 0 (an opaque wall), and the null density was
/// clamped to 0 (failed before: 0 of 2000 NaN for both).
#[test]
fn a_majorant_too_small_gives_nan_not_an_opaque_wall() {
    let grid = DensityGrid::new(UVec3::splat(5), Vec3::ZERO, Vec3::ONE, vec![1.0f32; 125]);
    let mut broken = grid.clone();
    broken.majorants.iter_mut().for_each(|m| *m *= 0.5);
    let (o, d) = (Vec3::new(0.5, 0.5, -0.1), Vec3::Z);
    for (g, is_broken) in [(grid, false), (broken, true)] {
        let m = Medium {
            name: "m".into(),
            sigma_s: Rgb::splat(2.0),
            sigma_a: Rgb::splat(0.5),
            g: 0.0,
            density: Some(g),
        };
        let (mut nan_tr, mut nan_event) = (0, 0);
        for k in 0..2000 {
            let mut s = Sampler::new(3, 0, k);
            let tr = transmittance(&m, o, d, 1.2, &mut s);
            assert!(tr.is_nan() || tr.min_element() >= 0.0, "{tr}");
            nan_tr += tr.is_nan() as u32;
            let weight = match sample_distance(&m, o, d, 1.2, Rgb::ONE, &mut s) {
                MediumEvent::Scatter { weight, .. } | MediumEvent::Pass { weight } => weight,
            };
            nan_event += weight.is_nan() as u32;
        }
        if is_broken {
            assert!(nan_tr > 1000, "{nan_tr} of 2000 transmittance estimates NaN");
            assert!(
                nan_event > 1000,
                "{nan_event} of 2000 sampled distances with a NaN weight"
            );
        } else {
            assert_eq!((nan_tr, nan_event), (0, 0), "a true majorant");
        }
    }
}
