//! A bounding-volume hierarchy over axis-aligned boxes, for the photon-mapping gathers: photons
//! become boxes of the gather radius around them (queried with a point), photon beams the
//! boxes of their segments grown by the radius (queried with a camera ray). Built once per
//! pass by median splits, so queries cost O(log n + hits) instead of a loop over all records.
use glam::Vec3;

/// Items per leaf; deeper trees cost more node tests than they save item tests.
const LEAF_SIZE: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Leaf: first index into `items`. Interior: index of the second child (the first child
    /// follows the node directly).
    start: u32,
    /// Items in a leaf; 0 marks an interior node.
    count: u32,
}

/// The hierarchy; item `k` is the k-th box given to [`BoxTree::build`].
#[derive(Clone, Debug, Default)]
pub struct BoxTree {
    nodes: Vec<Node>,
    items: Vec<u32>,
    /// The items' boxes, in `items` order, for the exact test at the leaves.
    boxes: Vec<(Vec3, Vec3)>,
}

impl BoxTree {
    /// Builds over `boxes` (`(lo, hi)` pairs). Boxes with non-finite corners are left out: no
    /// query could meet them meaningfully.
    pub fn build(boxes: &[(Vec3, Vec3)]) -> Self {
        let mut items: Vec<u32> = (0..boxes.len() as u32)
            .filter(|&i| {
                let (lo, hi) = boxes[i as usize];
                lo.is_finite() && hi.is_finite()
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * items.len() / LEAF_SIZE + 1);
        if !items.is_empty() {
            build_node(boxes, &mut items, 0, &mut nodes);
        }
        let boxes = items.iter().map(|&i| boxes[i as usize]).collect();
        Self { nodes, items, boxes }
    }

    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Calls `f` with every item whose box contains `p` (boundaries included).
    pub fn for_each_containing(&self, p: Vec3, mut f: impl FnMut(u32)) {
        self.traverse(|lo, hi| p.cmpge(lo).all() && p.cmple(hi).all(), &mut f);
    }

    /// Calls `f` with every item whose box the segment `o + t·d`, `t ∈ [0, tmax]`, touches.
    pub fn for_each_on_segment(&self, o: Vec3, d: Vec3, tmax: f32, mut f: impl FnMut(u32)) {
        self.traverse(|lo, hi| segment_meets_box(o, d, tmax, lo, hi), &mut f);
    }

    /// Depth-first walk over the nodes whose boxes pass `meets`, handing `f` the items of the
    /// leaves reached whose own boxes pass it too.
    fn traverse(&self, meets: impl Fn(Vec3, Vec3) -> bool, f: &mut impl FnMut(u32)) {
        if self.nodes.is_empty() {
            return;
        }
        // Median splits keep the depth at log2(n / LEAF_SIZE) + 1, far below the stack size.
        let mut stack = [0u32; 64];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let index = stack[top];
            let node = self.nodes[index as usize];
            if !meets(node.lo, node.hi) {
                continue;
            }
            if node.count > 0 {
                for k in node.start as usize..(node.start + node.count) as usize {
                    let (lo, hi) = self.boxes[k];
                    if meets(lo, hi) {
                        f(self.items[k]);
                    }
                }
            } else {
                stack[top] = node.start;
                stack[top + 1] = index + 1;
                top += 2;
            }
        }
    }
}

/// Builds the subtree over `items` (a slice of the final item order starting at `offset`),
/// appending nodes depth-first; returns the subtree root's index.
fn build_node(boxes: &[(Vec3, Vec3)], items: &mut [u32], offset: usize, nodes: &mut Vec<Node>) -> u32 {
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    let (mut clo, mut chi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for &i in items.iter() {
        let (a, b) = boxes[i as usize];
        lo = lo.min(a);
        hi = hi.max(b);
        let c = 0.5 * (a + b);
        clo = clo.min(c);
        chi = chi.max(c);
    }
    let index = nodes.len() as u32;
    nodes.push(Node {
        lo,
        hi,
        start: offset as u32,
        count: items.len() as u32,
    });
    if items.len() <= LEAF_SIZE {
        return index;
    }
    // Split at the median centre along the axis where the centres spread most.
    let extent = chi - clo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = items.len() / 2;
    let centre = |i: &u32| {
        let (a, b) = boxes[*i as usize];
        a[axis] + b[axis]
    };
    items.select_nth_unstable_by(mid, |x, y| centre(x).total_cmp(&centre(y)));
    let (left, right) = items.split_at_mut(mid);
    build_node(boxes, left, offset, nodes);
    let second = build_node(boxes, right, offset + mid, nodes);
    let node = &mut nodes[index as usize];
    node.start = second;
    node.count = 0;
    index
}

/// Slab test of the segment `[0, tmax]` against a box; axes the segment runs parallel to
/// are tested by position (no 0·∞).
fn segment_meets_box(o: Vec3, d: Vec3, tmax: f32, lo: Vec3, hi: Vec3) -> bool {
    let (mut t0, mut t1) = (0.0f32, tmax);
    for axis in 0..3 {
        let (oa, da) = (o[axis], d[axis]);
        if da.abs() < 1e-30 {
            if oa < lo[axis] || oa > hi[axis] {
                return false;
            }
            continue;
        }
        let inv = 1.0 / da;
        let (a, b) = ((lo[axis] - oa) * inv, (hi[axis] - oa) * inv);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
        if t0 > t1 {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use beamlight_scene::rng::Sampler;

    fn random_boxes(n: u32, s: &mut Sampler) -> Vec<(Vec3, Vec3)> {
        (0..n)
            .map(|_| {
                let c = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 10.0;
                let r = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 0.5;
                (c - r, c + r)
            })
            .collect()
    }

    /// Every query returns exactly the boxes a loop over all of them finds, each once.
    #[test]
    fn queries_match_brute_force() {
        let mut s = Sampler::new(3, 0, 0);
        for n in [0u32, 1, 3, 4, 5, 100, 2000] {
            let boxes = random_boxes(n, &mut s);
            let tree = BoxTree::build(&boxes);
            for _ in 0..200 {
                let p = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 10.0;
                let mut found = Vec::new();
                tree.for_each_containing(p, |i| found.push(i));
                found.sort();
                let expected: Vec<u32> = (0..n)
                    .filter(|&i| {
                        let (lo, hi) = boxes[i as usize];
                        p.cmpge(lo).all() && p.cmple(hi).all()
                    })
                    .collect();
                assert_eq!(found, expected, "point {p}");

                let o = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 10.0;
                let mut d = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - 0.5;
                if s.next_1d() < 0.2 {
                    d.y = 0.0; // parallel to a slab pair
                }
                let d = d.normalize();
                let tmax = s.next_1d() * 8.0;
                let mut found = Vec::new();
                tree.for_each_on_segment(o, d, tmax, |i| found.push(i));
                found.sort();
                // The tree must find what the per-box test finds for every box.
                let expected: Vec<u32> = (0..n)
                    .filter(|&i| {
                        let (lo, hi) = boxes[i as usize];
                        segment_meets_box(o, d, tmax, lo, hi)
                    })
                    .collect();
                assert_eq!(found, expected);
            }
        }
    }

    #[test]
    fn slab_test_is_exact_on_simple_cases() {
        let (lo, hi) = (Vec3::ZERO, Vec3::ONE);
        assert!(segment_meets_box(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 1.0, lo, hi));
        assert!(!segment_meets_box(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 0.99, lo, hi));
        assert!(!segment_meets_box(Vec3::new(-1.0, 1.5, 0.5), Vec3::X, 5.0, lo, hi));
        assert!(segment_meets_box(Vec3::new(0.5, 0.5, 0.5), -Vec3::Z, 0.0, lo, hi));
        assert!(!segment_meets_box(
            Vec3::new(2.0, 2.0, 2.0),
            Vec3::ONE.normalize(),
            9.0,
            lo,
            hi
        ));
    }

    #[test]
    fn non_finite_boxes_are_left_out() {
        let boxes = [(Vec3::ZERO, Vec3::ONE), (Vec3::splat(f32::NAN), Vec3::ONE)];
        let tree = BoxTree::build(&boxes);
        let mut found = Vec::new();
        tree.for_each_containing(Vec3::splat(0.5), |i| found.push(i));
        assert_eq!(found, vec![0]);
    }
}
