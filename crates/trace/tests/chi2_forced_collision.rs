//! Forced collisions (`media::forced_collision`), used by the path tracer restricted to some
//! components: the distances follow the claimed truncated-exponential mixture (chi-square), and
//! the weights make the estimate of anything after the collision unbiased: E[w·g(t)] equals
//! ∫₀^tmax σs·Tr(t)·g(t) dt per channel. The chi-square harness is the scene crate's.
#[path = "../../scene/tests/common/mod.rs"]
mod common;

use beamlight_scene::{Rgb, medium::Medium, rng::Sampler};
use beamlight_trace::media::{MediumEvent, forced_collision};
use common::*;

const N: usize = 400_000;
const BINS: usize = 40;
/// Statistical tests in this file (Šidák over them at 0.01 overall).
const NUM_TESTS: usize = 3;

fn medium(sigma_s: Rgb, sigma_a: Rgb) -> Medium {
    Medium {
        name: "m".into(),
        sigma_s,
        sigma_a,
        g: 0.0,
        density: None,
    }
}

/// Draws `N` forced collisions over [0, `tmax`] with throughput `beta`: the binned distances,
/// and per channel the mean and standard error of w and of w·t.
fn draw(m: &Medium, tmax: f32, beta: Rgb, seed: u32) -> (Vec<f64>, [[(f64, f64); 2]; 3]) {
    let mut observed = vec![0.0; BINS];
    let mut moments = [[(0.0f64, 0.0f64); 2]; 3];
    for i in 0..N {
        let mut s = Sampler::new(seed, 0, i as u32);
        let Some(MediumEvent::Scatter { t, weight }) = forced_collision(m, tmax, beta, &mut s) else {
            panic!("a finite segment in a homogeneous medium must collide");
        };
        assert!(t >= 0.0 && t < tmax, "t = {t} outside [0, {tmax})");
        assert!(weight.is_finite() && weight.min_element() >= 0.0, "weight {weight}");
        observed[((t / tmax * BINS as f32) as usize).min(BINS - 1)] += 1.0;
        for c in 0..3 {
            for (k, g) in [1.0, t as f64].into_iter().enumerate() {
                let v = weight[c] as f64 * g;
                moments[c][k].0 += v;
                moments[c][k].1 += v * v;
            }
        }
    }
    let n = N as f64;
    let stats = moments.map(|per| {
        per.map(|(sum, sq)| {
            let mean = sum / n;
            (mean, ((sq / n - mean * mean).max(0.0) / n).sqrt())
        })
    });
    (observed, stats)
}

fn check(name: &str, m: &Medium, tmax: f32, beta: Rgb, seed: u32) {
    let (observed, stats) = draw(m, tmax, beta, seed);
    let st = m.sigma_t();
    // The claimed density: channel c with probability ∝ beta_c (equal channels for grey
    // extinction), then σc·e^{−σc t}/(1 − e^{−σc tmax}) on [0, tmax].
    let grey = st.x == st.y && st.y == st.z;
    let pmf: [f64; 3] = if grey {
        [1.0, 0.0, 0.0]
    } else {
        let b = [beta.x as f64, beta.y as f64, beta.z as f64];
        let sum: f64 = b.iter().sum();
        b.map(|v| v / sum)
    };
    let tmax = tmax as f64;
    let cdf = |c: usize, t: f64| {
        let s = st[c] as f64;
        (1.0 - (-s * t).exp()) / (1.0 - (-s * tmax).exp())
    };
    let expected: Vec<f64> = (0..BINS)
        .map(|b| {
            let (a, z) = (b as f64 * tmax / BINS as f64, (b + 1) as f64 * tmax / BINS as f64);
            (0..3).map(|c| pmf[c] * (cdf(c, z) - cdf(c, a))).sum::<f64>() * N as f64
        })
        .collect();
    let report = chi2_test(&observed, &expected, sidak(0.01, NUM_TESTS)).unwrap_or_else(|e| panic!("{name}: {e}"));
    eprintln!("{name}: {report:?}");
    // Unbiased weights: E[w] = σs/σt·(1 − e^{−σt tmax}) and E[w·t] = σs·∫ t e^{−σt t} dt, per
    // channel, within 5 standard errors. This catches a wrong pdf in the weight (a missing
    // truncation factor is off by 1 − e^{−σt tmax}, tens of standard errors here); it
    // cannot catch a bias below ~5·SE (about 0.1 % of the mean here).
    for c in 0..3 {
        let (ss, s) = (m.sigma_s[c] as f64, st[c] as f64);
        let tr = (-s * tmax).exp();
        let exact = [ss / s * (1.0 - tr), ss * (1.0 - tr * (1.0 + s * tmax)) / (s * s)];
        for (k, e) in exact.iter().enumerate() {
            let (mean, se) = stats[c][k];
            // A grey medium's weight is a constant (zero standard error): only f32 rounding
            // may then separate it from the exact value.
            let se = se.max(1e-6 * e.abs());
            let z = (mean - e) / se;
            eprintln!("{name}: channel {c} moment {k}: {mean:.6} vs {e:.6} (z {z:.2})");
            assert!(
                z.abs() < 5.0,
                "{name}: channel {c} E[w·t^{k}] = {mean} vs {e} (z {z:.1})"
            );
        }
    }
}

#[test]
fn grey_medium_thin_segment() {
    check(
        "grey, optical depth 0.3",
        &medium(Rgb::splat(0.5), Rgb::splat(0.1)),
        0.5,
        Rgb::ONE,
        1,
    );
}

#[test]
fn grey_medium_thick_segment() {
    check(
        "grey, optical depth 8",
        &medium(Rgb::splat(1.5), Rgb::splat(0.5)),
        4.0,
        Rgb::ONE,
        2,
    );
}

#[test]
fn chromatic_medium() {
    check(
        "chromatic",
        &medium(Rgb::new(0.8, 0.3, 1.2), Rgb::new(0.2, 0.4, 0.05)),
        1.7,
        Rgb::new(1.0, 0.5, 0.25),
        3,
    );
}
