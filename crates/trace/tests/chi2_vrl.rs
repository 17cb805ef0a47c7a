//! Goodness of fit of the VRL paper's two-stage `Lmm` sampling: the point on the VRL
//! ∝ 1/(distance to the camera line)², then the point on the camera segment equiangularly
//! about it. The joint samples (u, t) are binned on a grid and compared with the product
//! density integrated over each cell (stage 2's conditional probabilities in closed form,
//! stage 1 by quadrature of its pdf). The chi-square harness is the scene crate's.
#[path = "../../scene/tests/common/mod.rs"]
mod common;

use beamlight_scene::{rng::Sampler, sampling::equiangular};
use beamlight_trace::vrl::{near_line_pdf, sample_near_line};
use common::*;
use glam::{DVec3, Vec3};

const N: usize = 1_000_000;
/// Statistical tests in this file (Šidák over them at 0.01 overall).
const NUM_TESTS: usize = 3;

/// P(t ∈ [a, b]) for the equiangular density on [0, len] about `c` (exact, in f64).
fn equiangular_mass(o: DVec3, d: DVec3, len: f64, c: DVec3, a: f64, b: f64) -> f64 {
    let delta = (c - o).dot(d);
    let h = (c - (o + d * delta)).length();
    let angle = |t: f64| (t - delta).atan2(h);
    (angle(b) - angle(a)) / (angle(len) - angle(0.0))
}

fn chi2_two_stage(name: &str, ov: Vec3, dv: Vec3, lv: f32, oc: Vec3, dc: Vec3, lc: f32, seed: u32) {
    // Stage 1's density is the one claimed: pdf(u) · dist(y(u), camera line)² is constant.
    let line_dist2 = |u: f32| {
        let w = (ov + dv * u - oc).as_dvec3();
        (w - dc.as_dvec3() * w.dot(dc.as_dvec3())).length_squared()
    };
    let k0 = near_line_pdf(ov, dv, lv, oc, dc, 0.0, 0.0) as f64 * line_dist2(0.0);
    for k in 1..=20 {
        let u = lv * k as f32 / 20.0;
        let ku = near_line_pdf(ov, dv, lv, oc, dc, 0.0, u) as f64 * line_dist2(u);
        assert!(
            (ku / k0 - 1.0).abs() < 2e-3,
            "{name}: pdf · dist² varies: {ku} vs {k0} at u = {u}"
        );
    }
    let (nu, nt) = (12usize, 12usize);
    let mut observed = vec![0.0; nu * nt];
    for i in 0..N {
        let mut s = Sampler::new(seed, 0, i as u32);
        let (u, pdf_u) = sample_near_line(ov, dv, lv, oc, dc, 0.0, s.next_1d());
        assert!((0.0..=lv).contains(&u), "{name}: u = {u}");
        let p = near_line_pdf(ov, dv, lv, oc, dc, 0.0, u);
        assert!((pdf_u / p - 1.0).abs() < 1e-3, "{name}: pdf mismatch at u = {u}");
        let y = ov + dv * u;
        let (t, _) = equiangular(oc, dc, 0.0, lc, y, s.next_1d());
        let (iu, it) = (
            ((u / lv * nu as f32) as usize).min(nu - 1),
            ((t / lc * nt as f32) as usize).min(nt - 1),
        );
        observed[iu * nt + it] += 1.0;
    }
    let tol = Tol {
        abs: 1e-10,
        rel: 1e-7,
        depth: 24,
    };
    let mut expected = vec![0.0; nu * nt];
    let mut total = 0.0;
    for iu in 0..nu {
        let (u0, u1) = (
            iu as f64 * lv as f64 / nu as f64,
            (iu + 1) as f64 * lv as f64 / nu as f64,
        );
        for it in 0..nt {
            let (t0, t1) = (
                it as f64 * lc as f64 / nt as f64,
                (it + 1) as f64 * lc as f64 / nt as f64,
            );
            let mut f = |u: f64| {
                let y = (ov + dv * u as f32).as_dvec3();
                near_line_pdf(ov, dv, lv, oc, dc, 0.0, u as f32) as f64
                    * equiangular_mass(oc.as_dvec3(), dc.as_dvec3(), lc as f64, y, t0, t1)
            };
            let mass = adaptive(&mut f, u0, u1, tol);
            expected[iu * nt + it] = mass * N as f64;
            total += mass;
        }
    }
    assert!((total - 1.0).abs() < 1e-4, "{name}: density integrates to {total}");
    let r = chi2_test(&observed, &expected, sidak(0.01, NUM_TESTS)).unwrap_or_else(|e| panic!("{name}: {e}"));
    eprintln!("{name}: {r:?}");
}

#[test]
fn chi2_two_stage_lmm_sampling() {
    let dc = Vec3::new(0.2, -0.1, 1.0).normalize();
    // Skew lines whose closest approach lies inside both segments.
    chi2_two_stage(
        "two-stage, crossing",
        Vec3::new(-1.0, 0.1, 1.0),
        Vec3::new(1.0, 0.05, -0.1).normalize(),
        2.0,
        Vec3::ZERO,
        dc,
        2.5,
        1,
    );
    // A VRL passing very close to the camera ray (the peaked case the sampling is for).
    chi2_two_stage(
        "two-stage, nearly touching",
        Vec3::new(-1.0, 0.01, 1.2),
        Vec3::new(1.0, 0.0, 0.0),
        2.0,
        Vec3::ZERO,
        dc,
        3.0,
        2,
    );
    // Nearly parallel lines.
    chi2_two_stage(
        "two-stage, nearly parallel",
        Vec3::new(0.3, 0.2, 0.0),
        (dc + Vec3::new(0.01, 0.0, 0.0)).normalize(),
        1.5,
        Vec3::ZERO,
        dc,
        2.0,
        3,
    );
}
