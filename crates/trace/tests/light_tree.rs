//! The light tree of the VBL/VSL gathers (`beamlight_trace::light_tree`): its invariants, the
//! probabilities its descent reports against the enumerated pmf, and a chi-square test of
//! the draws. The chi-square harness is the scene crate's.
#[path = "../../scene/tests/common/mod.rs"]
mod common;

use beamlight_scene::rng::Sampler;
use beamlight_trace::light_tree::{Gloss, LightTree, Receiver, TreeLight, importance};
use common::*;
use glam::Vec3;

/// Statistical tests in this file (Šidák over them at 0.01 overall): one per receiver.
const NUM_TESTS: usize = 4;
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
        index: i as u32,
    }))
}

/// A floor point looking up (part of the lights below its horizon), a tilted glossy point among
/// the lights, a camera segment through them and one ending before them.
fn receivers() -> [Receiver; NUM_TESTS] {
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
