//! Statistical test helpers: chi-square goodness of fit (in the style of pbrt-v4
//! `bsdfs_test.cpp` and Mitsuba 3 `chi2.py`), the special functions behind its p-value, and
//! adaptive quadrature over the sphere.
#![allow(dead_code)] // each test file uses a different subset

use beamlight_scene::rng::Sampler;
use glam::{DVec3, Vec2, Vec3};
use std::f64::consts::{PI, TAU};

// ---------------------------------------------------------------------------------------------
// Special functions
// ---------------------------------------------------------------------------------------------

/// ln Γ(x) for x > 0 (Lanczos, g = 7, 9 terms; ~1e-15 relative).
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection formula keeps the series in its accurate range.
        return (PI / (PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, &c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularized upper incomplete gamma function Q(a, x) = Γ(a, x) / Γ(a)
/// (Numerical Recipes §6.2: series for x < a + 1, Lentz continued fraction otherwise).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    assert!(a > 0.0, "gamma_q: a = {a}");
    if x <= 0.0 {
        return 1.0;
    }
    let log_prefactor = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        // P(a, x) = e^{-x} x^a / Γ(a) · Σ xⁿ / (a (a+1) … (a+n))
        let mut ap = a;
        let mut del = 1.0 / a;
        let mut sum = del;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (1.0 - sum * log_prefactor.exp()).max(0.0)
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (log_prefactor.exp() * h).min(1.0)
    }
}

/// P(χ²_dof ≥ stat): the p-value of a chi-square statistic.
pub fn chi2_p_value(stat: f64, dof: usize) -> f64 {
    gamma_q(0.5 * dof as f64, 0.5 * stat)
}

/// Per-test significance so that `num_tests` independent tests together fail with
/// probability `alpha` when every sampler is correct (Šidák correction).
pub fn sidak(alpha: f64, num_tests: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / num_tests as f64)
}

// ---------------------------------------------------------------------------------------------
// Chi-square test
// ---------------------------------------------------------------------------------------------

/// Outcome of a passing test, for the log.
#[derive(Debug)]
pub struct Chi2Report {
    pub stat: f64,
    pub dof: usize,
    pub p_value: f64,
    pub pooled_cells: usize,
}

/// Pearson chi-square test of `observed` counts against `expected` counts.
///
/// Cells are visited in order of increasing expected count; cells expecting fewer than
/// `MIN_EXPECTED` samples are pooled together (and the pool keeps absorbing cells until it
/// expects enough), which keeps the chi-square approximation valid in the tails. A sample in
/// a cell whose expected count is exactly 0 is an immediate failure: the sampler produced a
/// direction its pdf says is impossible.
pub fn chi2_test(observed: &[f64], expected: &[f64], alpha: f64) -> Result<Chi2Report, String> {
    const MIN_EXPECTED: f64 = 5.0;
    assert_eq!(observed.len(), expected.len());
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));

    let (mut pooled_obs, mut pooled_exp, mut pooled_cells) = (0.0, 0.0, 0);
    let (mut stat, mut dof) = (0.0, 0usize);
    for &i in &order {
        let (o, e) = (observed[i], expected[i]);
        assert!(e >= 0.0 && e.is_finite(), "cell {i}: expected count {e}");
        if e == 0.0 && o > 0.0 {
            return Err(format!("{o} samples in cell {i}, whose expected count is 0"));
        }
        if e < MIN_EXPECTED || (pooled_exp > 0.0 && pooled_exp < MIN_EXPECTED) {
            pooled_obs += o;
            pooled_exp += e;
            pooled_cells += 1;
        } else {
            stat += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    if pooled_exp > 0.0 {
        stat += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        dof += 1;
    } else if pooled_obs > 0.0 {
        return Err(format!("{pooled_obs} samples in cells whose expected count is 0"));
    }
    // The total is fixed, so one cell is determined by the others.
    let dof = dof.saturating_sub(1);
    if dof == 0 {
        return Err("fewer than two usable cells: the grid is too coarse".into());
    }
    let p_value = chi2_p_value(stat, dof);
    let report = Chi2Report {
        stat,
        dof,
        p_value,
        pooled_cells,
    };
    if p_value < alpha {
        // Show the worst cells to help debugging.
        let mut worst: Vec<usize> = (0..observed.len()).filter(|&i| expected[i] > 0.0).collect();
        worst.sort_by(|&a, &b| {
            let z = |i: usize| (observed[i] - expected[i]).abs() / expected[i].sqrt();
            z(b).total_cmp(&z(a))
        });
        let cells: Vec<String> = worst
            .iter()
            .take(5)
            .map(|&i| format!("cell {i}: observed {} expected {:.1}", observed[i], expected[i]))
            .collect();
        return Err(format!(
            "rejected: χ² = {stat:.1} with {dof} dof, p = {p_value:.3e} < α = {alpha:.3e}; worst: {}",
            cells.join("; ")
        ));
    }
    Ok(report)
}

// ---------------------------------------------------------------------------------------------
// Quadrature
// ---------------------------------------------------------------------------------------------

/// 8-point Gauss–Legendre rule on [a, b] (exact for polynomials of degree 15).
pub fn gauss_legendre(f: &mut dyn FnMut(f64) -> f64, a: f64, b: f64) -> f64 {
    const X: [f64; 4] = [
        0.183_434_642_495_649_8,
        0.525_532_409_916_329,
        0.796_666_477_413_626_7,
        0.960_289_856_497_536_3,
    ];
    const W: [f64; 4] = [
        0.362_683_783_378_362,
        0.313_706_645_877_887_3,
        0.222_381_034_453_374_5,
        0.101_228_536_290_376_3,
    ];
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let mut sum = 0.0;
    for k in 0..4 {
        sum += W[k] * (f(c - h * X[k]) + f(c + h * X[k]));
    }
    sum * h
}

/// Tolerances of [`adaptive`]: an interval is accepted when the halves agree with the whole
/// within max(`abs`, `rel`·|integral|), or after `depth` halvings.
///
/// The relative floor matters: the integrands are f32 functions whose rounding noise
/// (~1e-7 relative) would otherwise drive every interval to the depth limit.
#[derive(Clone, Copy, Debug)]
pub struct Tol {
    pub abs: f64,
    pub rel: f64,
    pub depth: u32,
}

/// Adaptive Gauss–Legendre on [a, b]. Smooth integrands converge at the first level; at a
/// discontinuity the recursion runs to `tol.depth` along it (cost linear in the depth).
pub fn adaptive(f: &mut dyn FnMut(f64) -> f64, a: f64, b: f64, tol: Tol) -> f64 {
    let whole = gauss_legendre(f, a, b);
    adaptive_rec(f, a, b, whole, tol.abs, tol)
}

fn adaptive_rec(f: &mut dyn FnMut(f64) -> f64, a: f64, b: f64, whole: f64, eps: f64, tol: Tol) -> f64 {
    let m = 0.5 * (a + b);
    let (left, right) = (gauss_legendre(f, a, m), gauss_legendre(f, m, b));
    let sum = left + right;
    if tol.depth == 0 || (sum - whole).abs() <= eps.max(tol.rel * sum.abs()) {
        return sum;
    }
    let tol = Tol {
        depth: tol.depth - 1,
        ..tol
    };
    adaptive_rec(f, a, m, left, 0.5 * eps, tol) + adaptive_rec(f, m, b, right, 0.5 * eps, tol)
}

/// Fixed composite Gauss–Legendre rule with `pieces` panels (for integrands too noisy for
/// adaptivity, e.g. lobes near the angular resolution of f32).
pub fn composite(f: &mut dyn FnMut(f64) -> f64, a: f64, b: f64, pieces: usize) -> f64 {
    let h = (b - a) / pieces as f64;
    (0..pieces)
        .map(|k| gauss_legendre(f, a + k as f64 * h, a + (k + 1) as f64 * h))
        .sum()
}

/// An orthonormal frame in f64 (same construction as `beamlight_scene::frame::Frame`).
#[derive(Clone, Copy, Debug)]
pub struct DFrame {
    pub s: DVec3,
    pub t: DVec3,
    pub n: DVec3,
}

impl DFrame {
    pub fn from_normal(n: DVec3) -> Self {
        let n = n.normalize();
        let sign = 1.0f64.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = DVec3::new(b, sign + n.y * n.y * a, -n.y);
        Self { s, t, n }
    }
    pub fn world_z() -> Self {
        Self {
            s: DVec3::X,
            t: DVec3::Y,
            n: DVec3::Z,
        }
    }
}

/// A θ/φ grid over the whole sphere, in spherical coordinates around `frame.n`, with the polar
/// coordinate warped as θ = π t^p (t uniform over the rows): p > 1 makes rows near the axis
/// narrow, so a sharp lobe centred on the axis spreads over many cells.
///
/// `jumps` lists the surfaces {w : w·a = c} where integrands may be discontinuous (the
/// horizon of a BSDF, the rim of a cone); the quadrature splits its inner integrals exactly
/// there instead of hunting for the jump by bisection.
#[derive(Clone, Debug)]
pub struct SphereGrid {
    pub frame: DFrame,
    pub rows: usize,
    pub cols: usize,
    pub p: f64,
    pub jumps: Vec<(DVec3, f64)>,
}

impl SphereGrid {
    pub fn new(frame: DFrame, rows: usize, cols: usize, p: f64) -> Self {
        Self {
            frame,
            rows,
            cols,
            p,
            jumps: Vec::new(),
        }
    }

    /// Declares a possible discontinuity of the integrands on {w : w·a = c}.
    pub fn with_jump(mut self, a: DVec3, c: f64) -> Self {
        self.jumps.push((a.normalize(), c));
        self
    }

    /// Grid coordinates t in (t0, t1) where the meridian at azimuth φ crosses a jump surface.
    fn crossings(&self, phi: f64, t0: f64, t1: f64) -> Vec<f64> {
        let mut out = Vec::new();
        let m = self.frame.s * phi.cos() + self.frame.t * phi.sin();
        for &(a, c) in &self.jumps {
            // Along the meridian w(θ)·a = A cos θ + B sin θ = R cos(θ − θ0).
            let (aa, bb) = (a.dot(self.frame.n), a.dot(m));
            let r = aa.hypot(bb);
            if r <= c.abs() {
                continue;
            }
            let (theta0, delta) = (bb.atan2(aa), (c / r).acos());
            for theta in [
                theta0 - delta,
                theta0 + delta,
                theta0 - delta + TAU,
                theta0 + delta - TAU,
            ] {
                if (0.0..=PI).contains(&theta) {
                    let t = (theta / PI).powf(1.0 / self.p);
                    if t > t0 && t < t1 {
                        out.push(t);
                    }
                }
            }
        }
        out.sort_by(f64::total_cmp);
        out
    }

    pub fn cells(&self) -> usize {
        self.rows * self.cols
    }

    /// Unit direction at grid coordinates (t, φ), and the Jacobian dω / (dt dφ).
    pub fn direction(&self, t: f64, phi: f64) -> (DVec3, f64) {
        let theta = PI * t.powf(self.p);
        let (st, ct) = theta.sin_cos();
        let d = self.frame.s * (st * phi.cos()) + self.frame.t * (st * phi.sin()) + self.frame.n * ct;
        let dtheta_dt = if self.p == 1.0 {
            PI
        } else {
            PI * self.p * t.powf(self.p - 1.0)
        };
        (d, st.abs() * dtheta_dt)
    }

    /// The cell a direction falls into (atan2, not acos, so small angles resolve).
    pub fn cell(&self, d: Vec3) -> usize {
        let d = d.as_dvec3();
        let (x, y, z) = (d.dot(self.frame.s), d.dot(self.frame.t), d.dot(self.frame.n));
        let theta = (x * x + y * y).sqrt().atan2(z);
        let t = (theta / PI).clamp(0.0, 1.0);
        let t = if self.p == 1.0 { t } else { t.powf(1.0 / self.p) };
        let mut phi = y.atan2(x);
        if phi < 0.0 {
            phi += TAU;
        }
        let row = ((t * self.rows as f64) as usize).min(self.rows - 1);
        let col = ((phi / TAU * self.cols as f64) as usize).min(self.cols - 1);
        row * self.cols + col
    }

    /// ∫ pdf dω over every cell (nested adaptive Gauss–Legendre, absolute tolerance `eps`
    /// per cell).
    pub fn integrate_cells(&self, pdf: &dyn Fn(Vec3) -> f64, eps: f64) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.cells());
        let (dt, dphi) = (1.0 / self.rows as f64, TAU / self.cols as f64);
        for r in 0..self.rows {
            for c in 0..self.cols {
                let (t0, p0) = (r as f64 * dt, c as f64 * dphi);
                out.push(self.integrate_cell(pdf, t0, t0 + dt, p0, p0 + dphi, eps));
            }
        }
        out
    }

    /// Integrand of ∫ f dω in grid coordinates (t, φ).
    fn integrand(&self, f: &dyn Fn(Vec3) -> f64, t: f64, phi: f64) -> f64 {
        let (d, jac) = self.direction(t, phi);
        if jac == 0.0 {
            0.0
        } else {
            f(d.normalize().as_vec3()) * jac
        }
    }

    /// ∫ f dω over the rectangle [t0, t1] × [φ0, φ1] of grid coordinates.
    pub fn integrate_cell(&self, f: &dyn Fn(Vec3) -> f64, t0: f64, t1: f64, phi0: f64, phi1: f64, eps: f64) -> f64 {
        // The inner integrals split at the declared jumps and resolve any other discontinuity
        // deeply, so that their residual error stays below the outer relative floor and does
        // not drive the outer recursion to its depth limit. A relative error of 1e-4 is
        // far below the statistical resolution of 10^6 samples (≥ 1 % per cell).
        let inner_tol = Tol {
            abs: 0.01 * eps / (phi1 - phi0),
            rel: 1e-6,
            depth: 24,
        };
        let outer_tol = Tol {
            abs: eps,
            rel: 1e-5,
            depth: 10,
        };
        let mut outer = |phi: f64| {
            // Integrate piecewise between the jumps crossing this meridian.
            let mut edges = vec![t0];
            edges.extend(self.crossings(phi, t0, t1));
            edges.push(t1);
            let inner = &mut |t| self.integrand(f, t, phi);
            edges
                .windows(2)
                .map(|e| adaptive(inner, e[0], e[1], inner_tol))
                .sum::<f64>()
        };
        adaptive(&mut outer, phi0, phi1, outer_tol)
    }

    /// ∫ f dω over the whole sphere with a fixed rule: about `t_panels` × `phi_panels` panels
    /// of 8 × 8 Gauss–Legendre nodes (choose the warp `p` so the panels resolve the lobe),
    /// with the t panels split at the declared jumps.
    pub fn integrate_sphere(&self, f: &dyn Fn(Vec3) -> f64, t_panels: usize, phi_panels: usize) -> f64 {
        let mut outer = |phi: f64| {
            let mut edges = vec![0.0];
            edges.extend(self.crossings(phi, 0.0, 1.0));
            edges.push(1.0);
            let inner = &mut |t| self.integrand(f, t, phi);
            let panels = |len: f64| ((len * t_panels as f64).ceil() as usize).max(1);
            edges
                .windows(2)
                .map(|e| composite(inner, e[0], e[1], panels(e[1] - e[0])))
                .sum::<f64>()
        };
        composite(&mut outer, 0.0, TAU, phi_panels)
    }
}

/// Draws `n` samples (each from its own fixed-seed `Sampler` stream), bins them on `grid`
/// and runs the chi-square test against `pdf` integrated over the cells. `sample` returns
/// `None` for an absorbed sample; those are compared, as one more cell, against the mass the
/// pdf is missing (1 − ∫ pdf).
pub fn chi2_sphere(
    name: &str,
    grid: &SphereGrid,
    n: usize,
    seed: u32,
    alpha: f64,
    sample: &mut dyn FnMut(&mut Sampler) -> Option<Vec3>,
    pdf: &dyn Fn(Vec3) -> f64,
) {
    let start = std::time::Instant::now();
    let mut observed = vec![0.0; grid.cells() + 1];
    for i in 0..n {
        let mut rng = Sampler::new(seed, 0, i as u32);
        match sample(&mut rng) {
            Some(d) => {
                assert!(
                    d.is_finite() && (d.length() - 1.0).abs() < 1e-4,
                    "{name}: bad direction {d}"
                );
                observed[grid.cell(d)] += 1.0;
            }
            None => observed[grid.cells()] += 1.0,
        }
    }
    let sampled = start.elapsed();
    let mut expected: Vec<f64> = grid
        .integrate_cells(pdf, 1e-3 / n as f64)
        .into_iter()
        .map(|p| p * n as f64)
        .collect();
    let total: f64 = expected.iter().sum();
    assert!(
        total <= n as f64 * (1.0 + 1e-4),
        "{name}: pdf integrates to {} > 1",
        total / n as f64
    );
    expected.push((n as f64 - total).max(0.0));
    match chi2_test(&observed, &expected, alpha) {
        Ok(r) => eprintln!(
            "{name}: χ² = {:.1}, dof = {}, p = {:.3} (sampling {:.2?}, quadrature {:.2?})",
            r.stat,
            r.dof,
            r.p_value,
            sampled,
            start.elapsed() - sampled
        ),
        Err(e) => panic!("{name}: {e}"),
    }
}

/// Uniform numbers for one sample.
pub fn u2(rng: &mut Sampler) -> Vec2 {
    rng.next_2d()
}
