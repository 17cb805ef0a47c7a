//! Goodness-of-fit tests for every sampling routine (warps, phase function, BSDFs) and
//! quadrature checks of their normalization / albedo.
//!
//! Each chi-square test bins ~10^6 samples and compares the counts with the pdf integrated over
//! the cells (cells expecting < 5 samples pooled, any sample in a zero-pdf cell a failure).
//! The significance is 0.01 for the whole file, split over the tests with a Šidák correction,
//! so the suite does not flake; all seeds are fixed, so a failure reproduces.
mod common;

use beamlight_scene::Rgb;
use beamlight_scene::bsdf::{Bsdf, TransportMode, fresnel_dielectric};
use beamlight_scene::phase::{HenyeyGreenstein, hg_sample_cos_theta};
use beamlight_scene::rng::Sampler;
use beamlight_scene::sampling::*;
use common::*;
use glam::{DVec3, Vec2, Vec3};

const N: usize = 1_000_000;

/// Number of statistical tests (chi-square and binomial) in this file; keep in sync.
const NUM_TESTS: usize = 44;

fn alpha() -> f64 {
    sidak(0.01, NUM_TESTS)
}

fn dir(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z).normalize()
}

/// Direction at polar angle `theta_deg` from +z, azimuth chosen off the axes.
fn at_angle(theta_deg: f32) -> Vec3 {
    let t = theta_deg.to_radians();
    let phi = 0.7f32;
    Vec3::new(t.sin() * phi.cos(), t.sin() * phi.sin(), t.cos()).normalize()
}

fn z_grid() -> SphereGrid {
    SphereGrid::new(DFrame::world_z(), 20, 40, 1.0)
}

fn grid_around(axis: Vec3, p: f64) -> SphereGrid {
    SphereGrid::new(DFrame::from_normal(axis.as_dvec3()), 20, 40, p)
}

fn close(a: f32, b: f32, rel: f32) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) + 1e-7
}

// ---------------------------------------------------------------------------------------------
// The helpers themselves
// ---------------------------------------------------------------------------------------------

#[test]
fn chi2_p_values_match_tables() {
    // 95th and 99th percentiles of χ² (standard tables), and the dof = 2 closed form e^{-x/2}.
    for (x, dof, p) in [
        (3.841_459, 1, 0.05),
        (6.634_897, 1, 0.01),
        (18.307_04, 10, 0.05),
        (124.342_1, 100, 0.05),
    ] {
        let got = chi2_p_value(x, dof);
        assert!((got - p).abs() < 1e-6, "χ²({x}, {dof}) = {got}, want {p}");
    }
    for x in [0.1, 1.0, 5.0, 40.0] {
        assert!((chi2_p_value(x, 2) - (-x / 2.0f64).exp()).abs() < 1e-12);
    }
    assert!((ln_gamma(10.0) - 362_880f64.ln()).abs() < 1e-12);
    assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-12);
}

#[test]
fn chi2_rejects_a_wrong_pdf_and_a_sample_in_a_zero_cell() {
    let uniform_sphere_pdf = |_: Vec3| 1.0 / (4.0 * std::f64::consts::PI);
    let grid = z_grid();
    let cells = grid.integrate_cells(&uniform_sphere_pdf, 1e-9);
    // Cosine-distributed samples against the uniform pdf must fail.
    let mut observed = vec![0.0; grid.cells()];
    for i in 0..100_000 {
        observed[grid.cell(cosine_hemisphere(Sampler::new(1, 0, i).next_2d()))] += 1.0;
    }
    let expected: Vec<f64> = cells.iter().map(|p| p * 100_000.0).collect();
    assert!(chi2_test(&observed, &expected, alpha()).is_err());
    // One sample where the pdf is zero fails even if everything else fits.
    let mut expected = vec![100.0; 10];
    expected[3] = 0.0;
    let mut observed = expected.clone();
    observed[3] = 1.0;
    assert!(
        chi2_test(&observed, &expected, alpha())
            .unwrap_err()
            .contains("expected count is 0")
    );
}

// ---------------------------------------------------------------------------------------------
// Warps
// ---------------------------------------------------------------------------------------------

#[test]
fn chi2_uniform_sphere() {
    chi2_sphere(
        "uniform sphere",
        &z_grid(),
        N,
        11,
        alpha(),
        &mut |rng| Some(uniform_sphere(rng.next_2d())),
        &|_| uniform_sphere_pdf() as f64,
    );
}

#[test]
fn chi2_cosine_hemisphere() {
    chi2_sphere(
        "cosine hemisphere",
        &z_grid(),
        N,
        12,
        alpha(),
        &mut |rng| Some(cosine_hemisphere(rng.next_2d())),
        &|w| cosine_hemisphere_pdf(w.z) as f64,
    );
}

#[test]
fn chi2_uniform_cone() {
    for (k, cos_max, p) in [(0, 0.5f32, 1.0), (1, 0.995, 3.0)] {
        let pdf = move |w: Vec3| {
            if w.z >= cos_max {
                uniform_cone_pdf(cos_max) as f64
            } else {
                0.0
            }
        };
        chi2_sphere(
            &format!("uniform cone cos_max = {cos_max}"),
            &grid_around(Vec3::Z, p).with_jump(DVec3::Z, cos_max as f64),
            N,
            13 + k,
            alpha(),
            &mut |rng| Some(uniform_cone(rng.next_2d(), cos_max)),
            &pdf,
        );
    }
}

#[test]
fn chi2_uniform_triangle() {
    // K×K square cells over the (b1, b2) unit square: the diagonal b1 + b2 = 1 cuts the cells
    // with i + j = K − 1 exactly in half, cells beyond it are empty. Density is 2.
    const K: usize = 32;
    let mut observed = vec![0.0; K * K];
    for i in 0..N {
        let b = uniform_triangle(Sampler::new(15, 0, i as u32).next_2d());
        assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6, "{b}");
        let ix = ((b.x * K as f32) as usize).min(K - 1);
        let iy = ((b.y * K as f32) as usize).min(K - 1);
        observed[ix * K + iy] += 1.0;
    }
    let cell = 2.0 / (K * K) as f64 * N as f64;
    let expected: Vec<f64> = (0..K * K)
        .map(|c| match (c / K + c % K).cmp(&(K - 1)) {
            std::cmp::Ordering::Less => cell,
            std::cmp::Ordering::Equal => 0.5 * cell,
            std::cmp::Ordering::Greater => 0.0,
        })
        .collect();
    let r = chi2_test(&observed, &expected, alpha()).unwrap_or_else(|e| panic!("triangle: {e}"));
    eprintln!("triangle: {r:?}");
}

#[test]
fn chi2_distribution_1d() {
    let weights: Vec<f32> = (0..64)
        .map(|i| {
            if i % 7 == 3 || i == 0 || i == 63 {
                0.0
            } else {
                1.0 + (i as f32 * 0.37).sin()
            }
        })
        .collect();
    let d = Distribution1D::new(&weights);
    let total: f64 = weights.iter().map(|&w| w as f64).sum();
    let mut observed = vec![0.0; weights.len()];
    for i in 0..N {
        let (k, pmf) = d.sample(Sampler::new(16, 0, i as u32).next_1d());
        assert!(weights[k] > 0.0, "picked zero-weight item {k}");
        let want = weights[k] as f64 / total;
        // The pmf is a difference of f32 CDF entries (~1e-7 absolute error near 1).
        assert!(
            ((pmf as f64) - want).abs() < 1e-3 * want,
            "pmf({k}) = {pmf}, want {want}"
        );
        observed[k] += 1.0;
    }
    let expected: Vec<f64> = weights.iter().map(|&w| w as f64 / total * N as f64).collect();
    let r = chi2_test(&observed, &expected, alpha()).unwrap_or_else(|e| panic!("Distribution1D: {e}"));
    eprintln!("Distribution1D: {r:?}");
}

/// Equiangular sampling along a line: bins uniform in the angle subtended at `c` (computed here
/// in f64), expected counts from integrating `equiangular_pdf` over each bin's t-interval.
fn chi2_equiangular(name: &str, o: Vec3, d: Vec3, t0: f32, t1: f32, c: Vec3, seed: u32) {
    let (o64, d64, c64) = (o.as_dvec3(), d.as_dvec3(), c.as_dvec3());
    let delta = (c64 - o64).dot(d64);
    let h = (c64 - (o64 + d64 * delta)).length();
    let (a0, a1) = ((t0 as f64 - delta).atan2(h), (t1 as f64 - delta).atan2(h));
    let bins = 40;
    let edges: Vec<f64> = (0..=bins)
        .map(|k| match k {
            0 => t0 as f64,
            k if k == bins => t1 as f64,
            k => delta + h * (a0 + (a1 - a0) * k as f64 / bins as f64).tan(),
        })
        .collect();
    let mut pdf = |t: f64| equiangular_pdf(o, d, t0, t1, c, t as f32) as f64;
    let mut expected: Vec<f64> = edges
        .windows(2)
        .map(|e| {
            if e[1].is_finite() {
                adaptive(
                    &mut pdf,
                    e[0],
                    e[1],
                    Tol {
                        abs: 1e-9,
                        rel: 1e-7,
                        depth: 30,
                    },
                )
            } else {
                0.0
            }
        })
        .collect();
    if !t1.is_finite() {
        let rest: f64 = expected.iter().sum();
        *expected.last_mut().unwrap() = (1.0 - rest).max(0.0);
    } else {
        let total: f64 = expected.iter().sum();
        assert!((total - 1.0).abs() < 1e-4, "{name}: pdf integrates to {total}");
    }
    let mut observed = vec![0.0; bins];
    for i in 0..N {
        let u = Sampler::new(seed, 0, i as u32).next_1d();
        let (t, p) = equiangular(o, d, t0, t1, c, u);
        assert!(t >= t0 && t <= t1, "{name}: t = {t} outside [{t0}, {t1}]");
        assert!(
            close(p, equiangular_pdf(o, d, t0, t1, c, t), 1e-3),
            "{name}: pdf mismatch at t = {t}"
        );
        let k = edges.partition_point(|&e| e <= t as f64).clamp(1, bins) - 1;
        observed[k] += 1.0;
    }
    let expected: Vec<f64> = expected.iter().map(|e| e * N as f64).collect();
    let r = chi2_test(&observed, &expected, alpha()).unwrap_or_else(|e| panic!("{name}: {e}"));
    eprintln!("{name}: {r:?}");
}

#[test]
fn chi2_equiangular_sampling() {
    let d = dir(0.3, -0.2, 0.9);
    let o = Vec3::new(0.1, 0.4, -0.3);
    // The closest approach inside the interval, at one end, outside it, and an infinite ray.
    chi2_equiangular("equiangular, apex inside", o, d, 0.0, 3.0, Vec3::new(0.6, 0.9, 1.0), 40);
    chi2_equiangular(
        "equiangular, close point",
        o,
        d,
        0.5,
        2.5,
        o + d * 1.0 + Vec3::new(0.02, 0.0, 0.0),
        41,
    );
    chi2_equiangular(
        "equiangular, apex outside",
        o,
        d,
        2.0,
        5.0,
        Vec3::new(0.0, 0.0, 0.0),
        42,
    );
    chi2_equiangular(
        "equiangular, infinite",
        o,
        d,
        0.0,
        f32::INFINITY,
        Vec3::new(1.0, 1.0, 1.0),
        43,
    );
    // An interval seen from far away (10⁵ units, at 45°): its angles are within 10⁻⁴ of each
    // other, so it is sampled uniformly (`subtends_no_angle`), and the density must say so.
    let side = d.cross(Vec3::Y).normalize();
    let (t0, t1, c) = (0.0f32, 1.0f32, o + (d + side) * 7.0e4);
    let uniform = beamlight_scene::sampling::equiangular_pdf(o, d, t0, t1, c, t0 + 0.01);
    assert_eq!(uniform, 1.0 / (t1 - t0), "the uniform fallback");
    assert!(
        beamlight_scene::sampling::equiangular_pdf(o, d, 0.0, 100.0, c, 50.0) != 0.01,
        "a longer one is not"
    );
    chi2_equiangular("equiangular, far short interval", o, d, t0, t1, c, 44);
}

#[test]
fn equiangular_is_finite_for_a_point_on_the_line() {
    let (o, d) = (Vec3::ZERO, Vec3::X);
    for (i, c) in [
        Vec3::new(0.5, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
    ]
    .into_iter()
    .enumerate()
    {
        for k in 0..1000 {
            let u = Sampler::new(44, i as u32, k).next_1d();
            let (t, p) = equiangular(o, d, 0.0, 1.0, c, u);
            assert!(
                (0.0..=1.0).contains(&t) && p.is_finite() && p >= 0.0,
                "c {c}: t {t} pdf {p}"
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Henyey–Greenstein
// ---------------------------------------------------------------------------------------------

fn hg_wo() -> Vec3 {
    dir(0.3, -0.5, 0.8)
}

/// Sampler closure that also checks the sample's own claims (weight 1, pdf == pdf()).
fn hg_sampler(hg: HenyeyGreenstein, wo: Vec3) -> impl FnMut(&mut Sampler) -> Option<Vec3> {
    move |rng| {
        let s = hg.sample(wo, rng.next_2d());
        assert!(s.weight == 1.0, "weight {}", s.weight);
        let pdf = hg.pdf(wo, s.wi);
        assert!(
            close(s.pdf, pdf, 1e-3),
            "g={}: sampled pdf {} vs pdf() {pdf}",
            hg.g,
            s.pdf
        );
        assert!(close(hg.eval(wo, s.wi) / s.pdf, s.weight, 1e-3));
        Some(s.wi)
    }
}

#[test]
fn chi2_henyey_greenstein_world_grid() {
    // A world-aligned grid with an off-axis wo, so the lobe's placement in φ is tested too.
    for (k, g) in [-0.9f32, -0.3, 0.0, 0.5, 0.95].into_iter().enumerate() {
        let hg = HenyeyGreenstein { g };
        let wo = hg_wo();
        chi2_sphere(
            &format!("HG g = {g} (world grid)"),
            &z_grid(),
            N,
            20 + k as u32,
            alpha(),
            &mut hg_sampler(hg, wo),
            &|wi| hg.pdf(wo, wi) as f64,
        );
    }
}

#[test]
fn chi2_henyey_greenstein_lobe_grid() {
    // Grid centred on the peak (−wo forward, +wo backward) with rows concentrated near it,
    // so that the shape inside the sharp lobes is resolved.
    for (k, g, axis, p) in [
        (0, 0.95f32, -hg_wo(), 3.0),
        (1, -0.9, hg_wo(), 2.0),
        (2, 0.5, -hg_wo(), 1.5),
    ] {
        let hg = HenyeyGreenstein { g };
        let wo = hg_wo();
        chi2_sphere(
            &format!("HG g = {g} (lobe grid)"),
            &grid_around(axis, p),
            N,
            30 + k,
            alpha(),
            &mut hg_sampler(hg, wo),
            &|wi| hg.pdf(wo, wi) as f64,
        );
    }
}

#[test]
fn chi2_henyey_greenstein_extreme_g_in_double_precision() {
    // For |g| → 1 the lobe is far narrower than an f32 direction can resolve near the peak,
    // so test the f32 inversion of the CDF itself: x = 1 − cos θ (forward, g > 0) or
    // x = 1 + cos θ (backward, g < 0), binned logarithmically from 1e-4 (1 − |g|)² to 2
    // against the exact CDF in f64: P(x ≤ X) = (1 − g²)/(2g) [1/(1 − g) − 1/√((1 − g)² + 2gX)].
    for (k, g) in [0.999f32, 0.99999, -0.99999].into_iter().enumerate() {
        let ga = g.abs() as f64;
        let cdf = |x: f64| {
            let tail = 1.0 / (1.0 - ga) - 1.0 / ((1.0 - ga) * (1.0 - ga) + 2.0 * ga * x).sqrt();
            (1.0 - ga * ga) / (2.0 * ga) * tail
        };
        const BINS: usize = 60;
        let x_min = 1e-4 * (1.0 - ga) * (1.0 - ga);
        let edge = |b: usize| x_min * (2.0 / x_min).powf(b as f64 / BINS as f64);
        // Bin 0 is [0, x_min); bin b ≥ 1 is [edge(b − 1), edge(b)).
        let mut observed = vec![0.0; BINS + 1];
        for i in 0..N {
            let u = Sampler::new(40 + k as u32, 0, i as u32).next_1d();
            let (one_minus, one_plus) = hg_sample_cos_theta(g, u);
            assert!(one_minus.is_finite() && one_plus.is_finite() && one_minus >= 0.0 && one_plus >= 0.0);
            let x = if g > 0.0 { one_minus } else { one_plus } as f64;
            let b = if x < x_min {
                0
            } else {
                ((x / x_min).ln() / (2.0 / x_min).ln() * BINS as f64) as usize + 1
            };
            observed[b.min(BINS)] += 1.0;
        }
        let mut expected = vec![cdf(x_min) * N as f64];
        expected.extend((1..=BINS).map(|b| (cdf(edge(b)) - cdf(edge(b - 1))) * N as f64));
        let r = chi2_test(&observed, &expected, alpha()).unwrap_or_else(|e| panic!("HG g = {g}: {e}"));
        eprintln!("HG cos θ, g = {g}: {r:?}");
    }
}

#[test]
fn henyey_greenstein_integrates_to_one() {
    // θ-concentrated fixed quadrature (rows ∝ t⁴ around the peak, 512 × 8 nodes in t) resolves
    // lobes down to a width of 1e-5; adaptive quadrature would chase the f32 rounding noise.
    let gs = [-0.99999f32, -0.999, -0.9, -0.3, 0.0, 1e-7, 0.5, 0.95, 0.999, 0.99999];
    for g in gs {
        let hg = HenyeyGreenstein { g };
        let wo = hg_wo();
        let axis = if g >= 0.0 { -wo } else { wo };
        let grid = grid_around(axis, 4.0);
        let integral = grid.integrate_sphere(&|wi| hg.eval(wo, wi) as f64, 512, 4);
        assert!((integral - 1.0).abs() < 1e-4, "g = {g}: ∫ p dω = {integral}");
    }
}

// ---------------------------------------------------------------------------------------------
// BSDFs
// ---------------------------------------------------------------------------------------------

/// Sampler closure that checks each sample against `eval`/`pdf`: the returned pdf equals
/// `pdf(wo, wi)` and the weight equals f·|cos θi|/pdf (relative 1e-3).
fn bsdf_sampler(m: &Bsdf, wo: Vec3) -> impl FnMut(&mut Sampler) -> Option<Vec3> + '_ {
    move |rng| {
        let u = rng.next_2d();
        let s = m.sample(wo, u, rng.next_1d())?;
        assert!(!s.is_delta);
        assert!(s.wi.z * wo.z > 0.0, "{m:?}: sample on the wrong side");
        let pdf = m.pdf(wo, s.wi);
        assert!(close(s.pdf, pdf, 1e-3), "{m:?}: sampled pdf {} vs pdf() {pdf}", s.pdf);
        let want = m.eval(wo, s.wi) * s.wi.z.abs() / s.pdf;
        for c in 0..3 {
            assert!(
                close(s.weight[c], want[c], 1e-3),
                "{m:?}: weight {} vs f·cos/pdf {want}",
                s.weight
            );
        }
        Some(s.wi)
    }
}

fn chi2_bsdf(name: &str, m: &Bsdf, wo: Vec3, grid: SphereGrid, seed: u32) {
    // The horizon, and the edge cos α = 0 of the Phong lobe (a kink, or a jump for n = 0).
    let grid = &grid.with_jump(DVec3::Z, 0.0).with_jump(mirror_dir(wo).as_dvec3(), 0.0);
    chi2_sphere(name, grid, N, seed, alpha(), &mut bsdf_sampler(m, wo), &|wi| {
        m.pdf(wo, wi) as f64
    });
}

#[test]
fn chi2_lambert() {
    let m = Bsdf::Lambert {
        albedo: Rgb::new(0.8, 0.5, 0.2),
    };
    chi2_bsdf("Lambert, wo above", &m, dir(0.3, -0.5, 0.8), z_grid(), 50);
    chi2_bsdf("Lambert, wo below", &m, dir(-0.6, 0.2, -0.3), z_grid(), 51);
}

fn phong(kd: f32, ks: f32, n: f32) -> Bsdf {
    Bsdf::Phong {
        diffuse: Rgb::new(kd, kd * 0.5, kd),
        specular: Rgb::new(ks, ks, ks * 0.7),
        exponent: n,
    }
}

fn mirror_dir(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

#[test]
fn chi2_phong_low_exponents() {
    // World grid: the horizon is a row boundary, the lobe is off-axis.
    let cases = [(1.0, 30.0, 0.3, 0.5), (20.0, 45.0, 0.2, 0.6), (20.0, 100.0, 0.5, 0.5)];
    for (k, (n, theta, kd, ks)) in cases.into_iter().enumerate() {
        let m = phong(kd, ks, n);
        chi2_bsdf(
            &format!("Phong n = {n}, θo = {theta}° (world grid)"),
            &m,
            at_angle(theta),
            z_grid(),
            60 + k as u32,
        );
    }
}

/// Phong on a grid around the mirror direction with rows concentrated near it (θ = π t^p).
fn chi2_phong_lobe_grid(n: f32, theta: f32, kd: f32, ks: f32, p: f64, seed: u32) {
    let m = phong(kd, ks, n);
    let wo = at_angle(theta);
    let grid = grid_around(mirror_dir(wo), p);
    chi2_bsdf(&format!("Phong n = {n}, θo = {theta}° (lobe grid)"), &m, wo, grid, seed);
}

#[test]
fn chi2_phong_high_exponents() {
    chi2_phong_lobe_grid(100.0, 10.0, 0.0, 1.0, 2.0, 70);
    chi2_phong_lobe_grid(80.0, 70.0, 0.1, 0.8, 2.0, 71);
    chi2_phong_lobe_grid(1000.0, 40.0, 0.05, 0.9, 3.0, 72);
}

#[test]
fn chi2_phong_grazing_and_below() {
    // wo below the surface: the two-sided flip.
    chi2_phong_lobe_grid(100.0, 150.0, 0.2, 0.7, 2.0, 73);
    // Grazing: the horizon clips a large part of the lobe, those samples are rejected.
    chi2_phong_lobe_grid(100.0, 85.0, 0.0, 1.0, 2.0, 74);
    // The same clipping seen on the world grid, where the horizon is a row boundary.
    let m = phong(0.1, 0.8, 80.0);
    chi2_bsdf("Phong n = 80, θo = 70° (world grid)", &m, at_angle(70.0), z_grid(), 80);
}

#[test]
fn lambert_and_phong_directional_albedo() {
    let albedo_of = |m: &Bsdf, wo: Vec3| {
        let r = mirror_dir(wo);
        // Centre the grid on the lobe; rows ∝ t³ resolve exponents up to ~1e4.
        let grid = grid_around(r, 3.0).with_jump(DVec3::Z, 0.0);
        grid.integrate_sphere(&|wi| (m.eval(wo, wi).x * wi.z.abs()) as f64, 256, 16)
    };
    let lambert = Bsdf::Lambert {
        albedo: Rgb::new(0.7, 0.1, 0.3),
    };
    for theta in [0.0, 30.0, 60.0, 89.0, 120.0] {
        let a = albedo_of(&lambert, at_angle(theta));
        assert!((a - 0.7).abs() < 1e-4, "Lambert θo = {theta}°: {a}");
    }
    for n in [1.0, 20.0, 100.0, 1000.0, 1e4] {
        let (kd, ks) = (0.25f32, 0.7f32);
        let m = Bsdf::Phong {
            diffuse: Rgb::splat(kd),
            specular: Rgb::splat(ks),
            exponent: n,
        };
        // At normal incidence the whole lobe is above the horizon: exactly kd + ks.
        let a = albedo_of(&m, Vec3::Z);
        assert!(
            (a - (kd + ks) as f64).abs() < 1e-4,
            "Phong n = {n} at normal incidence: {a}"
        );
        // Elsewhere it never gains energy and loses more towards grazing. The specular part
        // is not just clipped by the horizon: (n+2)/(2π) ∫ cos^n α cos θi dω = cos θo for a
        // whole lobe (cos θi averages to cos α cos θo around the mirror direction), so the
        // modified Phong albedo is kd + ks cos θo minus what the horizon clips.
        let mut previous = a;
        for theta in [20.0f32, 45.0, 70.0, 85.0, 89.5] {
            let a = albedo_of(&m, at_angle(theta));
            assert!(
                a <= (kd + ks) as f64 + 1e-4,
                "Phong n = {n}, θo = {theta}°: {a} > kd + ks"
            );
            assert!(
                a <= previous + 1e-4,
                "Phong n = {n}: albedo grows towards grazing ({a} > {previous})"
            );
            if n >= 20.0 && theta <= 45.0 {
                let whole_lobe = (kd + ks * theta.to_radians().cos()) as f64;
                assert!(
                    (a - whole_lobe).abs() < 1e-3,
                    "Phong n = {n}, θo = {theta}°: {a} vs {whole_lobe}"
                );
            }
            previous = a;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Delta BSDFs
// ---------------------------------------------------------------------------------------------

/// Fresnel reflectance from the angle form (an independent formula from the implementation's
/// cosine form), f64. `eta` = n_t / n_i.
fn fresnel_reference(theta_i: f64, eta: f64) -> f64 {
    let sin_t = theta_i.sin() / eta;
    if sin_t >= 1.0 {
        return 1.0;
    }
    if theta_i == 0.0 {
        return ((eta - 1.0) / (eta + 1.0)).powi(2);
    }
    let theta_t = sin_t.asin();
    let rs = ((theta_i - theta_t).sin() / (theta_i + theta_t).sin()).powi(2);
    let rp = ((theta_i - theta_t).tan() / (theta_i + theta_t).tan()).powi(2);
    0.5 * (rs + rp)
}

#[test]
fn glass_directions_obey_reflection_and_snell() {
    for ior in [1.5f32, 1.33, 2.4, 0.7] {
        let glass = Bsdf::Glass { ior, tint: Rgb::ONE };
        for theta in [
            0.0f32, 10.0, 30.0, 41.0, 45.0, 60.0, 80.0, 89.9, 100.0, 135.0, 170.0, 180.0,
        ] {
            let wo = at_angle(theta);
            let outside = wo.z >= 0.0;
            let eta = if outside { ior } else { 1.0 / ior } as f64;
            let theta_i = (wo.z.abs() as f64).acos();
            let f_ref = fresnel_reference(theta_i, eta);
            assert!(
                (fresnel_dielectric(wo.z.abs(), eta as f32) as f64 - f_ref).abs() < 1e-5,
                "ior {ior} θ {theta}"
            );
            for u_lobe in [0.0f32, 0.5, 0.999_999] {
                let s = glass.sample(wo, Vec2::new(0.3, 0.6), u_lobe).unwrap();
                assert!(s.is_delta && (s.wi.length() - 1.0).abs() < 1e-5);
                if s.wi.z * wo.z > 0.0 || (wo.z == 0.0 && s.wi == mirror_dir(wo)) {
                    // Reflection: chosen with probability F.
                    assert_eq!(s.wi, mirror_dir(wo));
                    assert!((s.pdf as f64 - f_ref).abs() < 1e-5);
                    assert_eq!(s.weight, Rgb::ONE);
                } else {
                    // Refraction: opposite side, tangential part antiparallel to wo's, Snell.
                    assert!(f_ref < 1.0, "refraction under TIR (ior {ior}, θ {theta})");
                    assert!((s.pdf as f64 - (1.0 - f_ref)).abs() < 1e-5);
                    let (wo_t, wi_t) = (wo.truncate().as_dvec2(), s.wi.truncate().as_dvec2());
                    assert!(wo_t.perp_dot(wi_t).abs() < 1e-6 && wo_t.dot(wi_t) <= 0.0);
                    let (sin_o, sin_i) = (wo_t.length(), wi_t.length());
                    assert!((sin_o - eta * sin_i).abs() < 1e-5, "Snell: {sin_o} vs {eta}·{sin_i}");
                    assert!((s.weight.x as f64 - 1.0 / (eta * eta)).abs() < 1e-5);
                }
            }
        }
    }
}

#[test]
fn glass_reflects_with_the_fresnel_probability() {
    // Binomial test per configuration (z² is χ² with one dof), same Šidák budget.
    let configs = [
        (1.5f32, 20.0f32),
        (1.5, 75.0),
        (1.5, 160.0),
        (1.33, 88.0),
        (2.4, 50.0),
        (0.7, 30.0),
    ];
    for (k, (ior, theta)) in configs.into_iter().enumerate() {
        let glass = Bsdf::Glass { ior, tint: Rgb::ONE };
        let wo = at_angle(theta);
        let eta = if wo.z >= 0.0 { ior } else { 1.0 / ior } as f64;
        let f = fresnel_reference((wo.z.abs() as f64).acos(), eta);
        let mut reflected = 0.0;
        let mut mean_weight_importance = 0.0;
        for i in 0..N {
            let mut rng = Sampler::new(90 + k as u32, 0, i as u32);
            let (u, u_lobe) = (rng.next_2d(), rng.next_1d());
            let s = glass.sample(wo, u, u_lobe).unwrap();
            if s.wi.z * wo.z > 0.0 {
                reflected += 1.0;
            }
            let s = glass.sample_mode(wo, u, u_lobe, TransportMode::Importance).unwrap();
            mean_weight_importance += s.weight.x as f64 / N as f64;
        }
        let n = N as f64;
        let z2 = (reflected - n * f).powi(2) / (n * f * (1.0 - f));
        let p = chi2_p_value(z2, 1);
        assert!(
            p >= alpha(),
            "ior {ior}, θ {theta}: reflected {reflected} of {n}, F = {f}, p = {p:.2e}"
        );
        // Photon weights: the tint (1) whichever lobe is chosen, so flux is conserved.
        assert!((mean_weight_importance - 1.0).abs() < 1e-6);
    }
}

#[test]
fn mirror_reflects_exactly() {
    let m = Bsdf::Mirror {
        reflectance: Rgb::new(0.9, 0.8, 0.7),
    };
    for theta in [0.0, 30.0, 89.999, 90.0, 120.0, 180.0] {
        let wo = at_angle(theta);
        let s = m.sample(wo, Vec2::new(0.2, 0.9), 0.4).unwrap();
        assert_eq!(s.wi, mirror_dir(wo));
        assert_eq!((s.weight, s.pdf, s.is_delta), (Rgb::new(0.9, 0.8, 0.7), 1.0, true));
        // Angle of incidence equals angle of reflection, in the plane of incidence.
        let n = DVec3::Z;
        let (a, b) = (wo.as_dvec3(), s.wi.as_dvec3());
        assert!((a.dot(n) - b.dot(n)).abs() < 1e-7 && a.cross(n).dot(b).abs() < 1e-7);
    }
}

// ---------------------------------------------------------------------------------------------
// Piecewise-linear densities (the VRL and VBL papers' angular PDFs)
// ---------------------------------------------------------------------------------------------

/// Samples `pl` N times into `bins` equal bins over its interval; expected counts from
/// integrating `pl.pdf` per bin (adaptively, so the kinks at the vertices are resolved).
fn chi2_piecewise_linear(name: &str, pl: &PiecewiseLinear, bins: usize, seed: u32) {
    let (x0, x1) = pl.interval();
    let (a, b) = (x0 as f64, x1 as f64);
    let edge = |k: usize| a + (b - a) * k as f64 / bins as f64;
    let mut pdf = |x: f64| pl.pdf(x as f32) as f64;
    let tol = Tol {
        abs: 1e-10,
        rel: 1e-7,
        depth: 20,
    };
    let cells: Vec<f64> = (0..bins)
        .map(|k| adaptive(&mut pdf, edge(k), edge(k + 1), tol))
        .collect();
    let total: f64 = cells.iter().sum();
    assert!((total - 1.0).abs() < 1e-4, "{name}: pdf integrates to {total}");
    let mut observed = vec![0.0; bins];
    for i in 0..N {
        let (x, p) = pl.sample(Sampler::new(seed, 0, i as u32).next_1d());
        assert!(x >= x0 && x <= x1, "{name}: x = {x} outside [{x0}, {x1}]");
        assert!(
            p > 0.0 && close(p, pl.pdf(x), 1e-3),
            "{name}: pdf {p} vs pdf() {}",
            pl.pdf(x)
        );
        let k = (((x as f64 - a) / (b - a) * bins as f64) as usize).min(bins - 1);
        observed[k] += 1.0;
    }
    let expected: Vec<f64> = cells.iter().map(|c| c * N as f64).collect();
    let r = chi2_test(&observed, &expected, alpha()).unwrap_or_else(|e| panic!("{name}: {e}"));
    eprintln!("{name}: {r:?}");
}

#[test]
fn chi2_piecewise_linear_densities() {
    // Uneven values with runs of zeros (no sample may land between two zero vertices) and
    // spikes; 11 segments of 5 bins each, so empty segments are whole bins.
    let values = [0.0, 0.0, 3.0, 0.2, 0.0, 0.0, 0.0, 7.5, 1e-3, 1.0, 1.0, 0.0];
    let pl = PiecewiseLinear::new(-1.2, 0.9, &values, 0.0);
    chi2_piecewise_linear("piecewise linear, zeros and spikes", &pl, 55, 100);
    // The same with a uniform share mixed in: now positive everywhere.
    let pl = PiecewiseLinear::new(-1.2, 0.9, &values, 0.3);
    chi2_piecewise_linear("piecewise linear, 30 % uniform", &pl, 55, 101);
    // Smoothly varying values over many vertices, bins not aligned with them.
    let values: Vec<f32> = (0..40).map(|i| 1.0 + (i as f32 * 0.4).sin() * 0.9).collect();
    let pl = PiecewiseLinear::new(0.0, 3.0, &values, 0.0);
    chi2_piecewise_linear("piecewise linear, 40 smooth vertices", &pl, 64, 102);
    // Nothing positive: uniform.
    let pl = PiecewiseLinear::new(-0.5, 0.5, &[0.0, f32::NAN, -1.0, 0.0], 0.0);
    for x in [-0.5f32, 0.0, 0.3, 0.5] {
        assert!(
            (pl.pdf(x) - 1.0).abs() < 1e-6,
            "all-zero values must give a uniform pdf"
        );
    }
    chi2_piecewise_linear("piecewise linear, all zero", &pl, 20, 103);
}

#[test]
fn piecewise_linear_degenerate_inputs() {
    for (x0, x1) in [(1.0f32, 1.0f32), (1.0, 0.5), (0.0, f32::INFINITY), (f32::NAN, 1.0)] {
        let pl = PiecewiseLinear::new(x0, x1, &[1.0, 2.0, 3.0], 0.1);
        assert!(!pl.is_valid());
        for u in [0.0, 0.5, 1.0] {
            let (x, p) = pl.sample(u);
            assert_eq!(p, 0.0, "[{x0}, {x1}]");
            assert!(x == x0 || x.is_nan() == x0.is_nan());
        }
        assert_eq!(pl.pdf(x0), 0.0);
    }
    // One vertex, huge and tiny values, NaN u, the ends of [0, 1]: finite and inside.
    for values in [&[5.0f32][..], &[1e30, 1e-30, 1e30][..], &[0.0, 0.0, 1e-38][..]] {
        let pl = PiecewiseLinear::new(-1.0, 2.0, values, 0.0);
        for u in [0.0, 1e-9, 0.5, ONE_MINUS_EPSILON, 1.0, f32::NAN, -3.0] {
            let (x, p) = pl.sample(u);
            assert!(
                (-1.0..=2.0).contains(&x) && p.is_finite() && p >= 0.0,
                "{values:?} u {u}: {x} {p}"
            );
        }
    }
}

/// Points on a segment sampled by a piecewise-linear density in the angle they subtend at `c`
/// (how the VBL estimators pick points): bins in t, expected counts from the density in t,
/// pdf_θ(θ(t))·dθ/dt, integrated per bin.
fn chi2_line_angles(name: &str, o: Vec3, d: Vec3, t1: f32, c: Vec3, h_min: f32, seed: u32) {
    let line = LineAngles::new(o, d, 0.0, t1, c, h_min);
    let values: Vec<f32> = (0..9)
        .map(|i| [0.3, 2.0, 0.1, 0.0, 0.0, 1.0, 4.0, 0.5, 0.2][i])
        .collect();
    let pl = PiecewiseLinear::new(line.theta0, line.theta1, &values, 0.05);
    let density = |t: f32| pl.pdf(line.theta(t)) * line.dtheta_dt(t);
    let bins = 50;
    let edge = |k: usize| t1 as f64 * k as f64 / bins as f64;
    let mut pdf = |t: f64| density(t as f32) as f64;
    let tol = Tol {
        abs: 1e-10,
        rel: 1e-7,
        depth: 24,
    };
    let cells: Vec<f64> = (0..bins)
        .map(|k| adaptive(&mut pdf, edge(k), edge(k + 1), tol))
        .collect();
    let total: f64 = cells.iter().sum();
    assert!((total - 1.0).abs() < 1e-3, "{name}: density in t integrates to {total}");
    let mut observed = vec![0.0; bins];
    for i in 0..N {
        let (theta, p) = pl.sample(Sampler::new(seed, 0, i as u32).next_1d());
        let t = line.t(theta).clamp(0.0, t1);
        let p_t = p * line.dtheta_dt(t);
        assert!(
            close(p_t, density(t), 2e-3),
            "{name}: pdf {p_t} vs {} at t = {t}",
            density(t)
        );
        let k = ((t as f64 / t1 as f64 * bins as f64) as usize).min(bins - 1);
        observed[k] += 1.0;
    }
    let expected: Vec<f64> = cells.iter().map(|c| c * N as f64).collect();
    let r = chi2_test(&observed, &expected, alpha()).unwrap_or_else(|e| panic!("{name}: {e}"));
    eprintln!("{name}: {r:?}");
}

#[test]
fn chi2_piecewise_linear_in_the_angle_along_a_segment() {
    let (o, d) = (Vec3::new(0.1, 0.4, -0.3), dir(0.3, -0.2, 0.9));
    // The closest approach inside the segment, seen from close by; the same point with its
    // distance floored at a radius (the VBL case of a line passing through a sphere).
    let c = o + d * 0.7 + Vec3::new(0.05, 0.0, 0.0);
    chi2_line_angles("angular piecewise linear, close point", o, d, 2.0, c, 0.0, 104);
    let c = o + d * 0.7;
    chi2_line_angles("angular piecewise linear, on the line, h ≥ 0.2", o, d, 2.0, c, 0.2, 105);
}
