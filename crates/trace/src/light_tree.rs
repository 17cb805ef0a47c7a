//! Light selection for the VBL/VSL gathers: a binary tree over one pass's virtual lights from
//! which each gather record draws a few lights in proportion to a cheap bound of their
//! contribution, instead of evaluating all of them (in the spirit of Conty Estevez & Kulla,
//! "Importance Sampling of Many Lights with Adaptive Tree Splitting", HPG 2018, and Vibert et
//! al., "Scalable Virtual Ray Lights Rendering for Participating Media", EGSR 2019).
//!
//! **Nodes.** Every node holds the box of its lights (a VSL's centre, a VBL's segment) and the
//! sum of their selection weights ([`vsl_weight`], [`vbl_weight`]: the flux a light can
//! scatter). Children of an interior node sit next to each other; a leaf holds one light.
//! [`LightTreeNode`] is `Pod` and mirrored in `shaders/lib/light_tree.wgsl`, whose descent is
//! the twin of [`LightTree::sample`] (the same operations in the same order, so the GPU picks
//! the same lights as the CPU up to rounding ties).
//!
//! **Importance of a node for a receiver** ([`importance`]): the node's weight times the
//! geometric falloff towards it, with every distance floored at the pass's radius R (a VSL or
//! VBL stops growing closer than R, so the bound is finite where a VRL's is not):
//! * a shading point p with normal n: 1/max(dist²(p, box), R²) times a bound of the cosine
//!   over the box (seen as its bounding sphere grown by R); a box that lies wholly below the
//!   tangent plane, by more than R, cannot light p (the receiver's BSDF reflects only on the
//!   side of n) and gets 0;
//! * a camera media segment: ∫ dt / (H² + (t − t_c)²) along it, with t_c the segment parameter
//!   closest to the box centre and H the centre's distance to the line minus the box's
//!   half-diagonal, floored at R: the 1/d² falloff integrated over the receiving segment.
//!
//! **Sampling.** A record descends from the root, choosing the left child with probability
//! a/(a+b) of the children's importances and rescaling its uniform number, so one number picks
//! one leaf by inversion and the product of the choices is the leaf's probability. K lights
//! per record use the stratified numbers (k + ξ)/K. The estimate Σ f(light)/(K p(light)) is
//! unbiased against the all-pairs sum as long as p > 0 wherever f ≠ 0: the importance is
//! positive except for boxes that provably cannot contribute (below the receiver's horizon),
//! and lights with zero weight (no flux, black BSDF, no scattering) contribute exactly nothing.
//! A node's box can reach above a horizon where none of its children's boxes does; a draw
//! that ends there finds no light and counts zero, which is exactly what every light under
//! that node contributes (so the probabilities sum to at most 1 and nothing is biased).
//! The all-pairs gather stays the oracle (`tests/light_selection.rs`).
use crate::{
    camera_paths::{MediaSegment, ShadingPoint},
    light_paths::{LightSegment, SurfaceVertex},
};
use beamlight_scene::{Rgb, Scene, bsdf::Bsdf};
use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};

/// A node of a [`LightTree`] (`LightTreeNode` in `shaders/lib/light_tree.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct LightTreeNode {
    /// Lower corner of the box around the node's lights (centres or segments, without R).
    pub lo: [f32; 3],
    /// Sum of the node's lights' selection weights (> 0).
    pub weight: f32,
    pub hi: [f32; 3],
    /// Interior node: index of the left child (the right one follows it). Leaf: [`LEAF`] | the
    /// light's index in the pass's light array.
    pub child: u32,
}

/// `LightTreeNode::child` of a leaf.
pub const LEAF: u32 = 1 << 31;

/// The largest f32 below 1: a rescaled uniform number never reaches 1.
const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;

/// A tree over one pass's VSLs or VBLs; empty when no light can contribute.
#[derive(Clone, Debug, Default)]
pub struct LightTree {
    pub nodes: Vec<LightTreeNode>,
}

/// What receives light: a camera shading point or a camera media segment.
#[derive(Clone, Copy, Debug)]
pub enum Receiver {
    /// A shading point and its normal on the side light is gathered from.
    Point { p: Vec3, n: Vec3 },
    /// A stretch `o + d t`, t in [0, len], of a camera ray in a medium.
    Segment { o: Vec3, d: Vec3, len: f32 },
}

impl Receiver {
    /// A camera shading point, gathering on the side of its normal (the side of `wo`).
    pub fn at_point(sp: &ShadingPoint) -> Receiver {
        Receiver::Point {
            p: Vec3::from(sp.pos),
            n: Vec3::from(sp.normal),
        }
    }

    /// A camera media segment.
    pub fn along_segment(seg: &MediaSegment) -> Receiver {
        Receiver::Segment {
            o: Vec3::from(seg.origin),
            d: Vec3::from(seg.dir),
            len: seg.length,
        }
    }
}

/// One light a record drew: its index, the probability it had, and the stratum it came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pick {
    pub light: u32,
    pub pmf: f32,
    pub slot: u32,
}

/// The selection weight of a VSL: the flux arriving at the VPL times its BSDF's largest
/// albedo (the flux it can reflect). Zero for a black or delta BSDF, which never gathers.
pub fn vsl_weight(scene: &Scene, vpl: &SurfaceVertex) -> f32 {
    let albedo = match scene.bsdf_at(vpl.material, Some(Vec2::new(vpl.u, vpl.v))) {
        Some(Bsdf::Lambert { albedo }) => albedo.max_element(),
        Some(Bsdf::Phong { diffuse, specular, .. }) => (diffuse + specular).max_element(),
        _ => 0.0,
    };
    positive_or_zero(Rgb::from(vpl.power).max_element() * albedo)
}

/// The selection weight of a VBL: its flux times σs and the length over which it can scatter,
/// (1 − e^(−σt L))/σt for the medium's densest point (the whole length if σt is 0).
pub fn vbl_weight(scene: &Scene, vrl: &LightSegment) -> f32 {
    let m = &scene.media[vrl.medium as usize];
    let density = m.density.as_ref().map_or(1.0, |g| g.max_density());
    let sigma_s = m.sigma_s.max_element() * density;
    let sigma_t = m.sigma_t().max_element() * density;
    let len = vrl.length;
    let reach = if sigma_t * len > 1e-4 {
        -(-sigma_t * len).exp_m1() / sigma_t
    } else {
        len
    };
    positive_or_zero(Rgb::from(vrl.power).max_element() * sigma_s * reach)
}

fn positive_or_zero(x: f32) -> f32 {
    if x > 0.0 && x.is_finite() { x } else { 0.0 }
}

/// A light before the build: its box, weight and index.
#[derive(Clone, Copy)]
struct Item {
    lo: Vec3,
    hi: Vec3,
    weight: f32,
    index: u32,
}

impl LightTree {
    /// The tree over a pass's VSLs (VPLs inflated by the pass's radius).
    pub fn over_vsls(scene: &Scene, vpls: &[SurfaceVertex]) -> LightTree {
        Self::build(vpls.iter().enumerate().map(|(i, v)| {
            let p = Vec3::from(v.pos);
            (p, p, vsl_weight(scene, v), i as u32)
        }))
    }

    /// The tree over a pass's VBLs (VRLs inflated by the pass's radius).
    pub fn over_vbls(scene: &Scene, vrls: &[LightSegment]) -> LightTree {
        Self::build(vrls.iter().enumerate().map(|(i, v)| {
            let (a, b) = (
                Vec3::from(v.origin),
                Vec3::from(v.origin) + Vec3::from(v.dir) * v.length,
            );
            (a.min(b), a.max(b), vbl_weight(scene, v), i as u32)
        }))
    }

    /// Builds a tree over lights given as (box lo, box hi, weight, index); lights whose weight
    /// is not positive or whose box is not finite are left out (they contribute nothing).
    pub fn build(lights: impl Iterator<Item = (Vec3, Vec3, f32, u32)>) -> LightTree {
        let mut items: Vec<Item> = lights
            .filter(|(lo, hi, w, _)| *w > 0.0 && w.is_finite() && lo.is_finite() && hi.is_finite())
            .map(|(lo, hi, weight, index)| Item { lo, hi, weight, index })
            .collect();
        let mut tree = LightTree {
            nodes: Vec::with_capacity(2 * items.len()),
        };
        if !items.is_empty() {
            tree.nodes.push(LightTreeNode::default());
            tree.fill(0, &mut items);
        }
        tree
    }

    /// Writes node `at` over `items`: a leaf for one light, else the two halves of a median
    /// split of the centres along the widest axis of their bounds.
    fn fill(&mut self, at: usize, items: &mut [Item]) {
        let (mut lo, mut hi, mut weight) = (Vec3::INFINITY, Vec3::NEG_INFINITY, 0.0f32);
        let (mut clo, mut chi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for it in items.iter() {
            lo = lo.min(it.lo);
            hi = hi.max(it.hi);
            weight += it.weight;
            let c = 0.5 * (it.lo + it.hi);
            clo = clo.min(c);
            chi = chi.max(c);
        }
        if items.len() == 1 {
            self.nodes[at] = LightTreeNode {
                lo: lo.into(),
                weight,
                hi: hi.into(),
                child: LEAF | items[0].index,
            };
            return;
        }
        let extent = chi - clo;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        let mid = items.len() / 2;
        items.select_nth_unstable_by(mid, |a, b| {
            let (ca, cb) = ((a.lo + a.hi)[axis], (b.lo + b.hi)[axis]);
            ca.total_cmp(&cb)
        });
        let left = self.nodes.len();
        self.nodes.push(LightTreeNode::default());
        self.nodes.push(LightTreeNode::default());
        self.nodes[at] = LightTreeNode {
            lo: lo.into(),
            weight,
            hi: hi.into(),
            child: left as u32,
        };
        let (a, b) = items.split_at_mut(mid);
        self.fill(left, a);
        self.fill(left + 1, b);
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Draws one light for the uniform number `u` in [0, 1): its index and probability, or
    /// `None` when no light in the tree can reach the receiver.
    pub fn sample(&self, rx: &Receiver, r: f32, mut u: f32) -> Option<(u32, f32)> {
        let mut at = 0usize;
        let mut pmf = 1.0f32;
        loop {
            let node = self.nodes.get(at)?;
            if node.child & LEAF != 0 {
                return Some((node.child & !LEAF, pmf));
            }
            let c = node.child as usize;
            let a = importance(&self.nodes[c], rx, r);
            let b = importance(&self.nodes[c + 1], rx, r);
            let total = a + b;
            if !(total > 0.0) {
                return None;
            }
            let p_left = a / total;
            if u < p_left {
                u = (u / p_left).min(ONE_BELOW);
                pmf *= p_left;
                at = c;
            } else {
                let p_right = 1.0 - p_left;
                u = ((u - p_left) / p_right).min(ONE_BELOW);
                pmf *= p_right;
                at = c + 1;
            }
        }
    }

    /// `k` lights for one record, drawn with the stratified numbers (slot + ξ)/k.
    pub fn sample_k(&self, rx: &Receiver, r: f32, k: u32, xi: f32) -> impl Iterator<Item = Pick> + '_ {
        let rx = *rx;
        (0..k).filter_map(move |slot| {
            let u = ((slot as f32 + xi) / k as f32).min(ONE_BELOW);
            self.sample(&rx, r, u).map(|(light, pmf)| Pick { light, pmf, slot })
        })
    }

    /// The light-selection estimate of the sum over the tree's lights of `f(slot, light)`:
    /// `k` lights drawn for the receiver (strata (slot + ξ)/k), each contribution over its
    /// probability, averaged. Unbiased for the all-pairs sum when `f` is zero for every
    /// light the tree cannot draw (see the module documentation).
    pub fn estimate(&self, rx: &Receiver, r: f32, k: u32, xi: f32, mut f: impl FnMut(u32, usize) -> Rgb) -> Rgb {
        if self.nodes.is_empty() {
            return Rgb::ZERO;
        }
        let sum: Rgb = self
            .sample_k(rx, r, k, xi)
            .map(|p| f(p.slot, p.light as usize) / p.pmf)
            .sum();
        sum / k as f32
    }

    /// Every light's probability of being drawn for `rx` (0 for lights not in the tree), by
    /// enumerating the tree: what [`LightTree::sample`] realises, for tests.
    pub fn pmfs(&self, rx: &Receiver, r: f32, lights: usize) -> Vec<f64> {
        let mut out = vec![0.0; lights];
        if self.nodes.is_empty() {
            return out;
        }
        let mut stack = vec![(0usize, 1.0f64)];
        while let Some((at, p)) = stack.pop() {
            let node = self.nodes[at];
            if node.child & LEAF != 0 {
                out[(node.child & !LEAF) as usize] += p;
                continue;
            }
            let c = node.child as usize;
            let a = importance(&self.nodes[c], rx, r);
            let b = importance(&self.nodes[c + 1], rx, r);
            let total = a + b;
            if !(total > 0.0) {
                continue;
            }
            let p_left = a / total;
            stack.push((c, p * p_left as f64));
            stack.push((c + 1, p * (1.0 - p_left) as f64));
        }
        out
    }

    /// Checks the tree's invariants: children adjacent and inside the array, every box
    /// containing its children's, weights summing up, every light in exactly one leaf.
    pub fn validate(&self, lights: usize) -> Result<(), String> {
        if self.nodes.is_empty() {
            return Ok(());
        }
        let mut seen = vec![false; lights];
        let mut stack = vec![0usize];
        let mut visited = 0;
        while let Some(at) = stack.pop() {
            visited += 1;
            let n = self.nodes.get(at).ok_or(format!("node {at} is out of range"))?;
            if !(n.weight > 0.0 && n.weight.is_finite()) {
                return Err(format!("node {at} has weight {}", n.weight));
            }
            if n.child & LEAF != 0 {
                let light = (n.child & !LEAF) as usize;
                if light >= lights || std::mem::replace(&mut seen[light], true) {
                    return Err(format!("leaf {at}: light {light} is out of range or seen twice"));
                }
                continue;
            }
            let c = n.child as usize;
            if c <= at || c + 1 >= self.nodes.len() {
                return Err(format!("node {at}: children at {c} out of order or range"));
            }
            let sum = self.nodes[c].weight + self.nodes[c + 1].weight;
            if (sum - n.weight).abs() > 1e-4 * n.weight {
                return Err(format!("node {at}: weight {} but children sum to {sum}", n.weight));
            }
            for k in [c, c + 1] {
                let ch = self.nodes[k];
                let inside = (0..3).all(|i| ch.lo[i] >= n.lo[i] && ch.hi[i] <= n.hi[i]);
                if !inside {
                    return Err(format!("node {k}'s box is not inside its parent {at}'s"));
                }
            }
            stack.extend([c, c + 1]);
        }
        if visited != self.nodes.len() {
            return Err(format!("{} nodes, {visited} reachable", self.nodes.len()));
        }
        Ok(())
    }
}

/// A node's importance for a receiver (see the module documentation); `r` is the pass's VBL
/// radius. Positive unless the node provably cannot light the receiver. The WGSL twin is
/// `light_importance` in `shaders/lib/light_tree.wgsl`.
pub fn importance(node: &LightTreeNode, rx: &Receiver, r: f32) -> f32 {
    let (lo, hi) = (Vec3::from(node.lo), Vec3::from(node.hi));
    let c = 0.5 * (lo + hi);
    let half = 0.5 * (hi - lo);
    let rb = half.length();
    let r = r.max(1e-12);
    match *rx {
        Receiver::Point { p, n } => {
            // Highest point of the box (grown by R) above the tangent plane.
            let top = n.dot(c - p) + n.abs().dot(half) + r;
            if top < 0.0 {
                return 0.0;
            }
            let q = p.clamp(lo, hi);
            let d2 = (q - p).length_squared().max(r * r);
            // The cosine bound over the box's bounding sphere grown by R.
            let to = c - p;
            let dc = to.length();
            let reach = rb + r;
            let cos_bound = if dc <= reach {
                1.0
            } else {
                let cos_t = (n.dot(to) / dc).clamp(-1.0, 1.0);
                let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                let sin_a = reach / dc;
                let cos_a = (1.0 - sin_a * sin_a).max(0.0).sqrt();
                // cos(θ − α) when θ > α, else 1 (the normal points into the sphere).
                if cos_t >= cos_a {
                    1.0
                } else {
                    cos_t * cos_a + sin_t * sin_a
                }
            };
            // The box reaches above the horizon (top ≥ 0): keep a floor so that rounding in
            // the bound never gives such a box a zero probability.
            node.weight * cos_bound.max(1e-3) / d2
        }
        Receiver::Segment { o, d, len } => {
            let v = c - o;
            let tc = v.dot(d);
            let h2 = (v.length_squared() - tc * tc).max(0.0);
            let h = (h2.sqrt() - rb).max(r);
            // ∫₀^len dt / (h² + (t − tc)²) = (atan((len − tc)/h) + atan(tc/h)) / h.
            let angle = ((len - tc) / h).atan() + (tc / h).atan();
            node.weight * angle.max(0.0) / h
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Boxes wholly below a shading point's horizon get nothing; just above, something.
    #[test]
    fn horizon_culling_is_conservative() {
        let node = |y: f32| LightTreeNode {
            lo: [-1.0, y - 0.1, -1.0],
            weight: 1.0,
            hi: [1.0, y + 0.1, 1.0],
            child: LEAF,
        };
        let rx = Receiver::Point {
            p: Vec3::ZERO,
            n: Vec3::Y,
        };
        let r = 0.05;
        assert_eq!(importance(&node(-0.2), &rx, r), 0.0);
        assert!(importance(&node(-0.149), &rx, r) > 0.0, "the sphere of R reaches above");
        assert!(importance(&node(2.0), &rx, r) > 0.0);
        // Segments: finite and positive wherever the box sits, also on the line itself.
        let seg = Receiver::Segment {
            o: Vec3::ZERO,
            d: Vec3::X,
            len: 1.0,
        };
        for y in [-3.0, 0.0, 0.5, 40.0] {
            let v = importance(&node(y), &seg, r);
            assert!(v > 0.0 && v.is_finite(), "y {y}: {v}");
        }
    }
}
