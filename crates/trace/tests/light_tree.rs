//! The light tree of the VBL/VSL gathers (`beamlight_trace::light_tree`): its invariants, the
//! probabilities its descent reports against the enumerated pmf, and a chi-square test of
//! the draws. The chi-square harness is the scene crate's.
#[path = "../../scene/tests/common/mod.rs"]
mod common;

use beamlight_scene::rng::Sampler;
use beamlight_trace::light_tree::{Emission, Gloss, LightTree, Receiver, TreeLight, importance};
use common::*;
use glam::Vec3;

/// Statistical tests in this file (Šidák over them at 0.01 overall): one per receiver for the
/// descent, one per segment receiver for the flat draw.
const NUM_TESTS: usize = 6;
const R: f32 = 0.05;

/// Random lights in [−2, 2]³ (boxes up to 0.4 wide, as VBL segments), weights over three
/// orders of magnitude, 5 % without any.
fn random_lights(n: u32, seed: u32) -> Vec<(Vec3, Vec3, f32)> {
    let mut s = Sampler::new(seed, 0, 0);
    (0..n)
        .map(|_| {
            let a = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 4.0 - 2.0;
            let b = a + (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5) * 0.8;
            let w = if s.next_1d() < 0.05 {
                0.0
            } else {
                10f32.powf(3.0 * s.next_1d())
            };
            (a.min(b), a.max(b), w)
        })
        .collect()
}

/// Each light a segment along its box's main diagonal fading with σt = 0.5 (a VBL), or a
/// point when its box is one (a VSL).
fn tree_of(lights: &[(Vec3, Vec3, f32)]) -> LightTree {
    LightTree::build(lights.iter().enumerate().map(|(i, &(lo, hi, weight))| TreeLight {
        lo,
        hi,
        weight,
        sigma_t: 0.5,
        g: 0.5,
        emission: Emission::NONE,
        normal: Vec3::ZERO,
        index: i as u32,
    }))
}

/// A floor point looking up (part of the lights below its horizon), a tilted glossy point among
/// the lights, a camera segment through them and one ending before them.
fn receivers() -> [Receiver; 4] {
    [
        Receiver::Point {
            p: Vec3::new(0.1, -1.9, 0.2),
            n: Vec3::Y,
            gloss: Gloss::LAMBERT,
        },
        Receiver::Point {
            p: Vec3::new(0.3, 0.2, -0.1),
            n: Vec3::new(0.3, 0.4, -0.8).normalize(),
            // A glossy receiver (Phong exponent 80), its mirror direction among the lights.
            gloss: Gloss {
                mirror: Vec3::new(-0.5, 0.6, 0.2).normalize(),
                exponent: 80.0,
                diffuse: 0.1,
                specular: 0.8,
            },
        },
        Receiver::Segment {
            o: Vec3::new(-3.0, 0.5, 0.0),
            d: Vec3::X,
            len: 6.0,
            g: 0.7,
        },
        Receiver::Segment {
            o: Vec3::new(0.0, 0.0, -5.0),
            d: Vec3::new(0.1, 0.0, 1.0).normalize(),
            len: 2.0,
            g: -0.3,
        },
    ]
}

#[test]
fn tree_is_valid_and_pmfs_sum_to_one() {
    for n in [1u32, 2, 3, 17, 500] {
        let lights = random_lights(n, n);
        let tree = tree_of(&lights);
        tree.validate(lights.len()).unwrap();
        for rx in receivers() {
            let p = tree.pmfs(&rx, R, lights.len());
            let sum: f64 = p.iter().sum();
            // At most one: a node's box can reach above a receiver's horizon where none of
            // its children's does, and a draw that ends there counts zero (exactly what every
            // light under it contributes). For a segment nothing is culled.
            assert!(sum <= 1.0 + 1e-5, "n {n}: pmfs sum to {sum}");
            if matches!(rx, Receiver::Segment { .. }) {
                assert!((sum - 1.0).abs() < 1e-5, "n {n}: pmfs sum to {sum}");
            }
            // Drawable exactly when the light has weight and its own box can reach the
            // receiver (an ancestor's box holds the leaf's, so it reaches too).
            for (i, (&pi, l)) in p.iter().zip(&lights).enumerate() {
                let leaf = tree.nodes.iter().find(|nd| nd.is_leaf() && nd.light() == i as u32);
                let reachable = leaf.is_some_and(|nd| importance(nd, &rx, R) > 0.0);
                assert_eq!(
                    pi > 0.0,
                    l.2 > 0.0 && reachable,
                    "n {n} light {i}: weight {} pmf {pi}",
                    l.2
                );
            }
        }
    }
    assert!(tree_of(&[]).is_empty());
    assert!(tree_of(&[(Vec3::ZERO, Vec3::ONE, 0.0)]).is_empty());
}

/// A broken tree is reported: a child box outside its parent, and a weight that does not add up.
#[test]
fn validate_catches_broken_trees() {
    let lights = random_lights(40, 3);
    let mut tree = tree_of(&lights);
    tree.validate(lights.len()).unwrap();
    let c = tree.nodes[0].child as usize;
    tree.nodes[c].hi[0] += 10.0;
    assert!(tree.validate(lights.len()).is_err());
    let mut tree = tree_of(&lights);
    tree.nodes[c].weight *= 2.0;
    assert!(tree.validate(lights.len()).is_err());
}

/// Every draw's reported probability is the enumerated one, and the histogram of 10⁶ draws
/// fits the pmf (cells expecting < 5 pooled, any draw of a zero-pmf light a failure, 0.01 with
/// a Šidák correction over the receivers). A branch taken against its probability, or a
/// reported probability that is not the product of the branch choices, fails it.
#[test]
fn selection_pmf_passes_chi_square() {
    const N: usize = 1_000_000;
    let lights = random_lights(300, 11);
    let tree = tree_of(&lights);
    let alpha = sidak(0.01, NUM_TESTS);
    for (t, rx) in receivers().iter().enumerate() {
        let pmf = tree.pmfs(rx, R, lights.len());
        // One cell per light and a last one for draws that found no light.
        let mut observed = vec![0.0f64; lights.len() + 1];
        // Independent draws (the multinomial the test assumes); the gathers stratify them.
        let mut s = Sampler::new(5, t as u32, 0);
        for _ in 0..N {
            let u = s.next_1d();
            let Some((light, p)) = tree.sample(rx, R, u, &mut s) else {
                observed[lights.len()] += 1.0;
                continue;
            };
            let want = pmf[light as usize];
            assert!(want > 0.0, "drew light {light} of zero probability");
            assert!(((p as f64) / want - 1.0).abs() < 1e-4, "reported {p} vs {want}");
            observed[light as usize] += 1.0;
        }
        let none = (1.0 - pmf.iter().sum::<f64>()).max(0.0);
        let expected: Vec<f64> = pmf.iter().chain([&none]).map(|p| p * N as f64).collect();
        let r = chi2_test(&observed, &expected, alpha).unwrap_or_else(|e| panic!("receiver {t}: {e}"));
        eprintln!("receiver {t}: {r:?}");
    }
}

/// Stratified picks (what a record draws) report the same probabilities, one per stratum, and
/// the strata's root choices follow their numbers (the left subtree for the strata below the
/// root's left probability).
#[test]
fn stratified_picks_report_the_enumerated_pmf() {
    let lights = random_lights(120, 2);
    let tree = tree_of(&lights);
    let rx = receivers()[2];
    let pmf = tree.pmfs(&rx, R, lights.len());
    // Leaves left to right.
    let mut order = Vec::new();
    let mut stack = vec![0usize];
    while let Some(at) = stack.pop() {
        let n = tree.nodes[at];
        if n.is_leaf() {
            order.push(n.light());
        } else {
            stack.extend([n.child as usize + 1, n.child as usize]);
        }
    }
    let rank = |light: u32| order.iter().position(|&l| l == light).unwrap();
    let picks: Vec<_> = tree
        .sample_k(&rx, R, 16, 0.37, |slot| Sampler::new(9, 0, slot))
        .collect();
    assert_eq!(picks.len(), 16);
    // The root's left subtree holds the first `left` leaves in order.
    let root = tree.nodes[0];
    let c = root.child as usize;
    let (a, b) = (
        importance(&tree.nodes[c], &rx, R),
        importance(&tree.nodes[c + 1], &rx, R),
    );
    let left = {
        let mut n = 0;
        let mut stack = vec![c];
        while let Some(at) = stack.pop() {
            let nd = tree.nodes[at];
            if nd.is_leaf() {
                n += 1;
            } else {
                stack.extend([nd.child as usize, nd.child as usize + 1]);
            }
        }
        n
    };
    for (k, p) in picks.iter().enumerate() {
        assert_eq!(p.slot, k as u32);
        let u = (k as f32 + 0.37) / 16.0;
        assert_eq!(
            rank(p.light) < left,
            u < a / (a + b),
            "slot {k}: root choice against its number"
        );
    }
    for p in picks {
        assert!(((p.pmf as f64) / pmf[p.light as usize] - 1.0).abs() < 1e-4);
    }
}

/// The flat draw (`Lmm`'s): each leaf's mass is its importance's share mixed with its weight's,
/// the masses sum to one, every light with weight can be drawn (also when its importance is
/// tiny), one without never; each pick reports its mass; and 10⁵ draws with independent
/// numbers fit the masses (chi-square, Šidák over the file's tests). A pick taken at the wrong
/// point of the running sum (off by one leaf, or the sum started after the leaf's own mass),
/// or a reported probability that is not the drawn leaf's, fails it.
#[test]
fn flat_draws_pass_chi_square() {
    const N: usize = 100_000;
    let lights = random_lights(100, 13);
    let tree = tree_of(&lights);
    let alpha = sidak(0.01, NUM_TESTS);
    for (t, rx) in receivers()
        .iter()
        .enumerate()
        .filter(|(_, rx)| matches!(rx, Receiver::Segment { .. }))
    {
        let masses = tree.flat_masses(rx, R);
        let mut pmf = vec![0.0f64; lights.len()];
        for &(light, m) in &masses {
            pmf[light as usize] = m as f64;
        }
        let sum: f64 = pmf.iter().sum();
        assert!((sum - 1.0).abs() < 1e-5, "receiver {t}: masses sum to {sum}");
        for (i, (&p, l)) in pmf.iter().zip(&lights).enumerate() {
            assert_eq!(p > 0.0, l.2 > 0.0, "receiver {t} light {i}: weight {} mass {p}", l.2);
        }
        let mut observed = vec![0.0f64; lights.len()];
        let mut s = Sampler::new(7, t as u32, 0);
        for _ in 0..N {
            let picks = LightTree::sample_flat_k(&masses, 1, s.next_1d());
            assert_eq!(picks.len(), 1);
            let want = pmf[picks[0].light as usize];
            assert!(want > 0.0, "drew light {} of zero probability", picks[0].light);
            assert_eq!(picks[0].pmf as f64, want, "reported {} vs {want}", picks[0].pmf);
            observed[picks[0].light as usize] += 1.0;
        }
        let expected: Vec<f64> = pmf.iter().map(|p| p * N as f64).collect();
        let r = chi2_test(&observed, &expected, alpha).unwrap_or_else(|e| panic!("receiver {t}: {e}"));
        eprintln!("receiver {t} (flat): {r:?}");
        // K stratified picks: one per stratum, in slot order, each where its number falls.
        let picks = LightTree::sample_flat_k(&masses, 16, 0.37);
        assert_eq!(
            picks.iter().map(|p| p.slot).collect::<Vec<_>>(),
            (0..16).collect::<Vec<_>>()
        );
        let mut running = 0.0f32;
        let mut ends = Vec::new();
        for &(light, m) in &masses {
            running += m;
            ends.push((light, running));
        }
        for p in &picks {
            let u = (p.slot as f32 + 0.37) / 16.0;
            let at = ends.iter().position(|&(_, e)| u < e).unwrap_or(ends.len() - 1);
            assert_eq!(p.light, ends[at].0, "slot {} (u {u})", p.slot);
        }
    }
}

/// A VBL leaf's importance for a camera segment against the pair integral it stands for,
/// ∫ρ(u) ∫ F / d² dt du (ρ the light's normalised density, F both HG phase functions at the
/// pair's direction, the distance to the camera line floored at R), by a 400 × 400 midpoint
/// rule, over 300 random configurations (beams antiparallel to the camera ray among them,
/// where both phase functions peak along the lines). The importance is an estimate, not a
/// bound; what matters for the variance of a flat draw is that it is never far off. Catches a
/// phase function turned the wrong way, a lost Jacobian or density, a quadrature point out of
/// place (made to fail: the camera's phase function turned backwards gives 5 % 0.06, 95 % 10.6).
/// What it cannot: errors within a factor of 2–4 in a few configurations.
#[test]
fn segment_importance_tracks_the_pair_integral() {
    let mut s = Sampler::new(21, 0, 0);
    let mut ratios = Vec::new();
    for case in 0..300 {
        let v3 = |s: &mut Sampler| Vec3::new(s.next_1d(), s.next_1d(), s.next_1d());
        let o = v3(&mut s) * 2.0 - 1.0;
        let d = (v3(&mut s) - 0.5).normalize();
        let len = 1.0 + 3.0 * s.next_1d();
        let a = o + d * (len * s.next_1d()) + (v3(&mut s) - 0.5) * 0.6;
        // A third of the beams run against the camera ray, nearly parallel.
        let dir = if case % 3 == 0 {
            (-d + (v3(&mut s) - 0.5) * 0.2).normalize()
        } else {
            (v3(&mut s) - 0.5).normalize()
        };
        let l = 0.5 + 2.5 * s.next_1d();
        let (g_light, g, sigma_t) = ([0.7, 0.0, -0.3][case % 3], [0.7, 0.5, 0.0][(case / 3) % 3], 0.3);
        let b = a + dir * l;
        let diagonal = (a.x > b.x) as u32 | ((a.y > b.y) as u32) << 1 | ((a.z > b.z) as u32) << 2;
        let tree = LightTree::build(std::iter::once(TreeLight {
            lo: a.min(b),
            hi: a.max(b),
            weight: 1.0,
            sigma_t,
            g: g_light,
            emission: Emission::NONE,
            normal: Vec3::ZERO,
            index: diagonal << beamlight_trace::light_tree::DIAGONAL_SHIFT,
        }));
        let rx = Receiver::Segment { o, d, len, g };
        let got = tree.flat_importance(&tree.nodes[0], &rx, R) as f64;
        let hg = |g: f64, cos: f64| (1.0 - g * g) / (1.0 + g * g - 2.0 * g * cos).powf(1.5);
        let n = 400;
        let fade = (1.0 - (-(sigma_t as f64) * l as f64).exp()) / sigma_t as f64;
        let mut want = 0.0f64;
        for i in 0..n {
            let u = (i as f64 + 0.5) / n as f64 * l as f64;
            let y = a.as_dvec3() + dir.as_dvec3() * u;
            let rho = (-(sigma_t as f64) * u).exp() / fade;
            for j in 0..n {
                let t = (j as f64 + 0.5) / n as f64 * len as f64;
                let x = o.as_dvec3() + d.as_dvec3() * t;
                let v = y - o.as_dvec3();
                let tc = v.dot(d.as_dvec3());
                let h2 = (v.length_squared() - tc * tc).max(0.0).max((R * R) as f64);
                let to = (x - y).normalize();
                let f = hg(g_light as f64, dir.as_dvec3().dot(to)) * hg(g as f64, -to.dot(d.as_dvec3()));
                want += rho * f / (h2 + (t - tc) * (t - tc));
            }
        }
        want *= (l * len) as f64 / (n * n) as f64;
        ratios.push(got / want);
    }
    ratios.sort_by(f64::total_cmp);
    let q = |p: f64| ratios[((ratios.len() - 1) as f64 * p) as usize];
    eprintln!(
        "importance / pair integral: min {:.3}, 5 % {:.3}, median {:.3}, 95 % {:.3}, max {:.3}",
        q(0.0),
        q(0.05),
        q(0.5),
        q(0.95),
        q(1.0)
    );
    // Measured: min 0.017, 5 % 0.43, median 0.96, 95 % 1.01, max 1.20 (one point along the
    // light instead of two: min 3·10⁻⁵, 5 % 0.023; the phase functions at the closest points:
    // ratios down to 10⁻⁴).
    assert!(q(0.0) > 0.005 && q(0.05) > 0.25, "too low somewhere");
    assert!((0.7..1.3).contains(&q(0.5)), "the median is off");
    assert!(q(0.95) < 1.5 && q(1.0) < 3.0, "too high somewhere");
}
