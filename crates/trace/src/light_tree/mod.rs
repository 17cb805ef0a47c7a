//! Light selection for the VBL/VSL gathers: a binary tree over one pass's virtual lights from
//! which each gather record draws a few lights in proportion to a cheap bound of their
//! contribution, instead of evaluating all of them (in the spirit of Conty Estevez & Kulla,
//! "Importance Sampling of Many Lights with Adaptive Tree Splitting", HPG 2018, and Vibert et
//! al., "Scalable Virtual Ray Lights Rendering for Participating Media", EGSR 2019).
//!
//! **Nodes.** Every node holds the box of its lights (a VSL's centre, the stretch of a VBL
//! where its light scatters, [`VblStretch`]) and the sum of their selection weights
//! ([`vsl_weight`], [`VblStretch`]: the flux a light can scatter). Children of an interior
//! node sit next to each other; a leaf holds one light, a segment's leaf also its σt and which diagonal of the
//! box it runs along. [`LightTreeNode`] is `Pod` and mirrored in `shaders/lib/light_tree.wgsl`,
//! whose descent is the twin of [`LightTree::sample`] (the same operations in the same order,
//! so the GPU picks the same lights as the CPU up to rounding ties).
//!
//! **Importance of a node for a receiver** ([`importance`]): the node's weight times an
//! estimate of the geometric falloff towards it, every distance floored at the pass's radius R
//! (a VSL or VBL stops growing closer than R, so nothing divides by zero):
//! * a shading point p with normal n: 1/max(d², r_b², R²), d the distance to the box centre
//!   and r_b its half-diagonal (the mean falloff of lights spread over the box, as in Conty
//!   Estevez & Kulla), times a bound of the cosine over the box seen as its bounding sphere
//!   grown by R; a box of point lights wholly below the tangent plane, by more than R, cannot
//!   light p (the receiver's BSDF reflects only on the side of n) and gets 0;
//! * a camera media segment: ∫ dt / (H² + (t − t_c)²) along it, with t_c the segment parameter
//!   closest to the box centre and H the centre's distance to the line floored at r_b and R;
//! * a VBL's leaf: its own segment instead of its box. Its light's density along it, fading
//!   like e^(−σt t), taken at the point closest to the receiver, times the falloff integrated
//!   along the VBL (for a shading point the cosine-weighted falloff over the part above the
//!   horizon; for a camera segment along both lines, times both phase functions between the
//!   two lines' closest points); or, if larger, the density at the end of the VBL's first mean
//!   free path times the same integral over that first stretch. A VSL's leaf seen from a
//!   camera segment gets the camera medium's phase function likewise. A flat draw weighs a
//!   VBL leaf for a camera segment by the pair integral ∫∫ ρ F / d² itself instead
//!   ([`flat_importance`]: F both phase functions at each pair's own direction; in a density
//!   grid ρ from the VBL's [`Profile`], not its fading).
//!
//! **Sampling.** A record descends from the root, choosing the left child with probability
//! a/(a+b) of the children's importances; the product of the choices is the leaf's
//! probability. K lights per record make their root choices with the stratified numbers
//! (k + ξ)/K, their deeper ones with fresh numbers (see [`LightTree::sample`]). Camera media
//! segments may draw VBLs flat instead (`--media-light-draw`, the default, [`Drawing`]):
//! every leaf at once, by its own importance for one record of a group of neighbours
//! ([`FLAT_GROUP`]), the same stratified numbers on the running sum
//! ([`LightTree::flat_masses`] says why). The estimate
//! Σ f(light)/(K p(light)) is unbiased against the all-pairs sum as long as p > 0 wherever
//! f ≠ 0: the importance is positive except for boxes of VSLs that provably cannot contribute
//! (below the receiver's horizon),
//! and lights with zero weight (no flux, black BSDF, no scattering) contribute exactly nothing.
//! A node's box can reach above a horizon where none of its children's boxes does; a draw
//! that ends there finds no light and counts zero, which is exactly what every light under
//! that node contributes (so the probabilities sum to at most 1 and nothing is biased).
//! The all-pairs gather stays the oracle (`tests/light_selection.rs`).
use crate::{
    camera_paths::MediaSegment,
    light_paths::{LightSegment, SurfaceVertex},
    streams::GatherKind,
};
use beamlight_scene::{Rgb, Scene, bsdf::Bsdf, medium::Medium, rng::Sampler};
use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};

mod importance;
pub use importance::{Emission, Gloss, Receiver, cone_union, facing, flat_importance, importance};

/// A node of a [`LightTree`] (`LightTreeNode` in `shaders/lib/light_tree.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct LightTreeNode {
    /// Lower corner of the box around the node's lights (centres or segments, without R).
    pub lo: [f32; 3],
    /// Sum of the node's lights' selection weights (> 0).
    pub weight: f32,
    pub hi: [f32; 3],
    /// Interior node: index of the left child (the right one follows it). Leaf: [`LEAF`] |
    /// the segment's diagonal of the box ([`DIAGONAL_SHIFT`]) | the light's index in the pass's
    /// light array ([`LIGHT_MASK`]).
    pub child: u32,
    /// A segment light's extinction σt (the densest along it; for an interior node the largest
    /// of its lights'): its light fades like e^(−σt t) along the segment. 0 for points.
    pub sigma_t: f32,
    /// A segment leaf's Henyey–Greenstein g (its light scatters off it by that phase
    /// function); 0 otherwise.
    pub g: f32,
    /// The glossy lobes its lights send their light in ([`Emission`], as
    /// [`LightTreeNode::emission`] reads them): the share of the weight in lights with lobes,
    /// the cosine of the cone around `lobe_axis` that holds every lobe's axis, the smallest
    /// exponent, the largest peak and base. All zero where no light has a lobe (every factor
    /// is then 1). (The order keeps each vec3 16-byte aligned, as WGSL places them.)
    pub lobe_share: f32,
    pub lobe_cos: f32,
    pub lobe_axis: [f32; 3],
    pub lobe_exponent: f32,
    /// The cone of its lights' normals (a VSL sends its light to the side of its normal,
    /// with its cosine); zero for segment lights.
    pub normal: [f32; 3],
    pub normal_cos: f32,
    pub lobe_peak: f32,
    pub lobe_base: f32,
    pub _pad: [u32; 2],
}

/// `LightTreeNode::child` of a leaf.
pub const LEAF: u32 = 1 << 31;
/// A leaf's bits 28–30: which diagonal of its box the light's segment runs along (bit i set:
/// from `hi` to `lo` along axis i, i.e. the segment's direction is negative there).
pub const DIAGONAL_SHIFT: u32 = 28;
/// A leaf's light index (at most 2²⁸ lights per tree).
pub const LIGHT_MASK: u32 = (1 << DIAGONAL_SHIFT) - 1;

impl LightTreeNode {
    /// A node with these lobes and nothing else (for the builder to fill in).
    fn with_emission(e: &Emission) -> LightTreeNode {
        LightTreeNode {
            lobe_share: e.share,
            lobe_cos: e.cos_spread,
            lobe_exponent: e.exponent,
            lobe_axis: e.axis.into(),
            lobe_peak: e.peak,
            lobe_base: e.base,
            ..Default::default()
        }
    }

    pub fn is_leaf(&self) -> bool {
        self.child & LEAF != 0
    }

    /// A leaf's light index.
    pub fn light(&self) -> u32 {
        self.child & LIGHT_MASK
    }

    /// The lobes of the node's lights.
    pub fn emission(&self) -> Emission {
        Emission {
            share: self.lobe_share,
            axis: Vec3::from(self.lobe_axis),
            cos_spread: self.lobe_cos,
            base: self.lobe_base,
            peak: self.lobe_peak,
            exponent: self.lobe_exponent,
        }
    }

    /// A leaf's segment (start, end) along its box's diagonal; a point light's box is a point.
    pub fn segment(&self) -> (Vec3, Vec3) {
        let bits = self.child >> DIAGONAL_SHIFT;
        let (lo, hi) = (Vec3::from(self.lo), Vec3::from(self.hi));
        let pick = |i: usize| {
            if bits & (1 << i) != 0 {
                (hi[i], lo[i])
            } else {
                (lo[i], hi[i])
            }
        };
        let (x, y, z) = (pick(0), pick(1), pick(2));
        (Vec3::new(x.0, y.0, z.0), Vec3::new(x.1, y.1, z.1))
    }
}

/// How a record draws its lights from a tree (`--media-light-draw` for `Lmm`'s records).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Drawing {
    /// Down from the root, by the children's importances ([`LightTree::sample`]).
    #[default]
    Descent,
    /// From all leaves at once, by each one's importance ([`LightTree::flat_masses`]), the
    /// masses shared by groups of records ([`FLAT_GROUP`]).
    Flat,
}

impl Drawing {
    /// How records of `kind` draw: camera media segments against VBLs (`Lmm`) as `media`
    /// says, every other kind by the descent. The GPU's gather entry
    /// (`shaders/lib/gather_entry.wgsl`) makes the same choice by its kernel's kind.
    pub fn of(kind: GatherKind, media: Drawing) -> Drawing {
        if kind == GatherKind::VrlToMedia {
            media
        } else {
            Drawing::Descent
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Drawing::Descent => "descent",
            Drawing::Flat => "flat",
        }
    }
}

/// What one record draws its lights by: the descent, or the masses of a flat draw
/// ([`LightTree::flat_masses`]), which a group of records shares ([`FLAT_GROUP`]).
#[derive(Clone, Copy, Debug)]
pub enum Draw<'a> {
    Descent,
    Flat(&'a [(u32, f32)]),
    /// Flat by the record's own masses, weighed as it draws ([`LightTree::sample_flat_own`]).
    Own,
}

/// Consecutive gather records that share one flat draw: the masses of each group of this
/// many are those of one record's receiver ([`flat_group_representative`];
/// [`LightTree::group_masses`], which the GPU's kernel draws by too: `flat_masses` in
/// `shaders/lib/light_tree.wgsl`). Camera records are traced in 4×4 tiles of pixels, so a group
/// is about one tile's camera segments, which see the VBLs alike. The masses only steer the
/// draw: any positive probability where a light can contribute keeps the estimate unbiased,
/// and a leaf's mass is never below its share of the flux ([`DEFENSIVE_SHARE`]). Measured in
/// the glossy fog box (`examples/lmm_variance.rs`, `SHARE=16`): a draw's relative variance
/// 1.93 by its own masses, 2.16 by its tile's first record's (3.96 by 16 consecutive records
/// of a row, before the tiles), against 55.9 descending; an importance per light per 16
/// records instead of per record.
pub const FLAT_GROUP: usize = 16;

/// Which record of a group of `len` ([`FLAT_GROUP`]) the group's flat masses are weighed for:
/// the 6th, pixel (1, 1) of its 4×4 tile when each pixel has one segment, one of the four
/// central ones, whose receiver is nearer the others' than a corner's (the last record of a
/// shorter group). Measured (`examples/lmm_variance.rs`, `SHARE=16`, 400 records, `OFFSET` 0
/// or 5): a draw's relative variance in the smoke box 3.64 by the tile's first record's
/// masses, 3.40 by this one's (2.89 by each record's own); in the glossy fog box 2.01 and 1.89
/// (1.77). The mean of two records' masses gained little more (3.22–3.25) at twice the cost.
pub fn flat_group_representative(len: usize) -> usize {
    5.min(len.saturating_sub(1))
}

/// The largest f32 below 1: a stratified number (k + ξ)/K never reaches 1.
const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;

/// A tree over one pass's VSLs or VBLs; empty when no light can contribute.
#[derive(Clone, Debug, Default)]
pub struct LightTree {
    pub nodes: Vec<LightTreeNode>,
    /// Over VBLs in a density grid, by light index: where along its leaf's segment each
    /// scatters its light ([`VblStretch::profile`]), for the flat draw. Empty otherwise.
    pub profiles: Vec<Option<Profile>>,
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

/// The selection weight of a VBL and the σt it fades with: its flux times σs and the length
/// over which it can scatter, (1 − e^(−σt L))/σt, for the medium's densest point (the whole
/// length if σt is 0). A bound for a VBL in a density grid; [`VblStretch::of`] measures it.
pub fn vbl_weight(scene: &Scene, vrl: &LightSegment) -> (f32, f32) {
    let m = &scene.media[vrl.medium as usize];
    let density = m.density.as_ref().map_or(1.0, |g| g.max_density());
    let sigma_s = m.sigma_s.max_element() * density;
    let sigma_t = positive_or_zero(m.sigma_t().max_element() * density);
    let reach = fade_length(sigma_t, vrl.length);
    (
        positive_or_zero(Rgb::from(vrl.power).max_element() * sigma_s * reach),
        sigma_t,
    )
}

/// The stretch of a VBL where its light scatters, as its tree leaf holds it: from `start` to
/// `end` along the VBL, its light fading like e^(−σt t) from `start`, and its selection weight
/// (flux times ∫ σs T du, the light it can scatter, σs taken within the VBL's radius), and in a
/// density grid where along the stretch it scatters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VblStretch {
    pub start: f32,
    pub end: f32,
    pub sigma_t: f32,
    pub weight: f32,
    pub profile: Option<Profile>,
}

/// Steps of a VBL's march through a density grid per voxel it crosses ([`VblStretch::of`]).
const STRETCH_STEPS_PER_VOXEL: f32 = 2.0;
/// The most steps of that march (a longer VBL takes longer steps).
const STRETCH_MAX_STEPS: usize = 256;
/// The share of a VBL's scattered light left outside its stretch at either end.
const STRETCH_TAIL: f32 = 1e-3;
/// The weight a VBL in a grid keeps, as a share of its bound ([`vbl_weight`]), when the march
/// finds less: between the march's points the grid may still hold a little medium, and a
/// light left out of the tree would never be drawn.
const STRETCH_FLOOR: f32 = 1e-3;

impl VblStretch {
    /// In a homogeneous medium the whole VBL up to its first [`CLIP_FREE_PATHS`] mean free
    /// paths (beyond, less than e^(−8) of its light is left), fading with the medium's σt.
    /// In a density grid the medium's densest σt would make a VBL crossing thin or empty
    /// medium look as if its light were gone after a few centimetres, and so would its leaf:
    /// in the smoke box a 4-unit VBL along a camera ray, a quarter of that ray's `Lmm`, was
    /// drawn 33× less often than its share. So the VBL is marched through the grid
    /// ([`scattering_stretch`]): the leaf holds the stretch where its light scatters, fading
    /// with the mean σt over it, and the weight is the light it scatters (at least
    /// [`STRETCH_FLOOR`] of the bound), σs taken within the pass's radius `r`.
    pub fn of(scene: &Scene, vrl: &LightSegment, r: f32) -> VblStretch {
        let m = &scene.media[vrl.medium as usize];
        let (bound, sigma_t) = vbl_weight(scene, vrl);
        let len = vrl.length;
        // The bound's stretch: exact in a homogeneous medium.
        let by_bound = VblStretch {
            start: 0.0,
            end: if sigma_t > 0.0 {
                len.min(CLIP_FREE_PATHS / sigma_t)
            } else {
                len
            },
            sigma_t,
            weight: bound,
            profile: None,
        };
        if !(len > 0.0 && bound > 0.0) {
            return by_bound;
        }
        let (o, d) = (Vec3::from(vrl.origin), Vec3::from(vrl.dir));
        match scattering_stretch(m, o, d, len, r) {
            None => by_bound,
            // The march found no medium: the bound's geometry, at the floor's weight.
            Some((_, 0.0, _)) => VblStretch {
                weight: STRETCH_FLOOR * bound,
                ..by_bound
            },
            Some((stretch, scattered, profile)) => VblStretch {
                start: stretch.start,
                end: stretch.end,
                sigma_t: stretch.sigma_t,
                weight: positive_or_zero(Rgb::from(vrl.power).max_element() * scattered).max(STRETCH_FLOOR * bound),
                profile,
            },
        }
    }
}

/// The receiver a flat draw weighs a camera media segment's VBLs for
/// ([`LightTree::flat_masses`]): in a density grid the segment clipped to the stretch where
/// light can scatter towards the camera ([`scattering_stretch`]: σs at the camera point, as
/// the estimator takes it), else the whole segment. The pair integral runs along the whole
/// segment, so in the smoke box, whose camera rays cross metres of clear air before the
/// plume, VBLs beside the clear air were weighed as if they lit it. Only the masses change
/// (any positive ones keep the draw unbiased, and 10 % of each goes by flux).
pub fn flat_draw_receiver(scene: &Scene, seg: &MediaSegment) -> Receiver {
    let whole = Receiver::along_segment(scene, seg);
    let m = &scene.media[seg.medium as usize];
    let (o, d) = (Vec3::from(seg.origin), Vec3::from(seg.dir));
    match (whole, scattering_stretch(m, o, d, seg.length, 0.0)) {
        (Receiver::Segment { g, .. }, Some((st, scattered, _))) if scattered > 0.0 && st.end > st.start => {
            Receiver::Segment {
                o: o + d * st.start,
                d,
                len: st.end - st.start,
                g,
            }
        }
        _ => whole,
    }
}

/// A stretch of a line: from `start` to `end`, its light fading like e^(−σt t) from `start`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stretch {
    pub start: f32,
    pub end: f32,
    pub sigma_t: f32,
}

/// Where light scatters along the line `o + d t`, t in [0, len], through medium `m`'s density
/// grid (`None` without one), and ∫ σs T dt, σs taken within `r` of the line when `r` > 0
/// ([`Medium::density_within`]: a VBL's light scatters anywhere in its sphere of radius R,
/// also from clear air next to smoke), on it otherwise, and T the line's own transmittance
/// from its start. A midpoint march at [`STRETCH_STEPS_PER_VOXEL`] steps a voxel
/// (at most [`STRETCH_MAX_STEPS`]); the stretch holds all but [`STRETCH_TAIL`] of the integral
/// at either end and fades with the mean σt over it, and [`Profile`] says where along it the
/// light scatters. An integral of 0 (no medium met) comes with the whole line and no profile.
pub fn scattering_stretch(m: &Medium, o: Vec3, d: Vec3, len: f32, r: f32) -> Option<(Stretch, f32, Option<Profile>)> {
    let grid = m.density.as_ref()?;
    let voxel = ((grid.hi - grid.lo) / grid.res.as_vec3()).min_element();
    let wanted = (len / voxel * STRETCH_STEPS_PER_VOXEL).ceil();
    let steps = if wanted >= 1.0 {
        (wanted as usize).min(STRETCH_MAX_STEPS)
    } else {
        1
    };
    let h = len / steps as f32;
    let (sigma_s, sigma_t) = (m.sigma_s.max_element(), m.sigma_t().max_element());
    // Per step: the scattered light up to its end, and the optical depth at its end.
    let mut cumulative = [0f32; STRETCH_MAX_STEPS];
    let mut depth = [0f32; STRETCH_MAX_STEPS];
    let (mut scattered, mut tau) = (0f32, 0f32);
    for i in 0..steps {
        let p = o + d * ((i as f32 + 0.5) * h);
        let density = grid.density(p);
        let step_tau = sigma_t * density * h;
        let scattering = if r > 0.0 { m.density_within(p, r) } else { density };
        // The step's light at its middle: e^(−τ) at its start times e^(−τ_step/2).
        scattered += sigma_s * scattering * h * (-(tau + 0.5 * step_tau)).exp();
        tau += step_tau;
        cumulative[i] = scattered;
        depth[i] = tau;
    }
    if !(scattered > 0.0 && scattered.is_finite()) {
        let whole = Stretch {
            start: 0.0,
            end: len,
            sigma_t: 0.0,
        };
        return Some((whole, 0.0, None));
    }
    let first = cumulative[..steps].partition_point(|&c| c <= STRETCH_TAIL * scattered);
    let last = cumulative[..steps]
        .partition_point(|&c| c < (1.0 - STRETCH_TAIL) * scattered)
        .min(steps - 1);
    let (start, end) = (first as f32 * h, ((last + 1) as f32 * h).min(len));
    let before = if first > 0 { depth[first - 1] } else { 0.0 };
    let stretch = Stretch {
        start,
        end,
        sigma_t: positive_or_zero((depth[last] - before) / (end - start)),
    };
    let profile = Profile::of_march(&cumulative[..steps], h, start, end);
    Some((stretch, scattered, profile))
}

/// Where along a stretch of a line in a density grid its light scatters: the share of
/// ∫ σs T dt ([`scattering_stretch`]) up to each of [`PROFILE_BINS`] equal bins' ends, t from
/// the stretch's start, linear within a bin. A flat draw weighs a VBL by its profile
/// ([`flat_importance`]): the stretch's mean σt, all a leaf holds, says nothing of where in the
/// stretch the smoke lies. Measured with `examples/lmm_variance.rs` (smoke box, 48², pass 200,
/// 300 records, `SHARE=16`): a draw's relative variance 3.88 → 2.89 with the masses a group
/// shares, 2.49 → 1.82 with each record's own. The camera segment's own profile, weighing the
/// eight panels of [`flat_importance`]'s inner quadrature, made it worse (2.49 → 3.58 by each
/// record's own masses), although the pair integral by a 16 × 16 quadrature gains from the
/// camera side's density (2.21 → 1.62): left out until a quadrature that takes it well.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Profile {
    len: f32,
    /// The share up to the end of each bin (the last is 1); 0 at the stretch's start.
    shares: [f32; PROFILE_BINS],
}

/// Bins of a [`Profile`].
pub const PROFILE_BINS: usize = 32;

impl Profile {
    /// The profile of [`start`, `end`] from a march's running integral, `cumulative[i]` up to
    /// the end of step i (steps of length `h` from t = 0), which is linear within a step.
    /// `None` when the stretch holds nothing.
    fn of_march(cumulative: &[f32], h: f32, start: f32, end: f32) -> Option<Profile> {
        let at = |t: f32| {
            let x = (t / h).max(0.0);
            let i = (x as usize).min(cumulative.len() - 1);
            let before = if i > 0 { cumulative[i - 1] } else { 0.0 };
            before + (cumulative[i] - before) * (x - i as f32).clamp(0.0, 1.0)
        };
        let len = end - start;
        let (below, total) = (at(start), at(end) - at(start));
        if !(total > 0.0 && len > 0.0 && total.is_finite()) {
            return None;
        }
        let mut shares = [1.0f32; PROFILE_BINS];
        for (k, share) in shares.iter_mut().enumerate().take(PROFILE_BINS - 1) {
            let t = start + len * (k + 1) as f32 / PROFILE_BINS as f32;
            *share = ((at(t) - below) / total).clamp(0.0, 1.0);
        }
        Some(Profile { len, shares })
    }

    /// The share of the light scattered before `t` (0 before the stretch, 1 after it).
    pub fn share_before(&self, t: f32) -> f32 {
        let x = (t / self.len * PROFILE_BINS as f32).clamp(0.0, PROFILE_BINS as f32);
        let i = (x as usize).min(PROFILE_BINS - 1);
        let below = if i > 0 { self.shares[i - 1] } else { 0.0 };
        below + (self.shares[i] - below) * (x - i as f32)
    }

    /// ∫ ρ dz over t < `split` and over t ≥ `split` (each bin by its centre), ρ the profile's
    /// density and z = asinh((t − t₀)/k): where a quadrature in z wants the light of a line
    /// whose other factors are flat in z (see [`flat_importance`]). One square root a bin.
    pub fn in_z(&self, t0: f32, k: f32, split: f32) -> [f32; 2] {
        let mut sums = [0.0f32; 2];
        let width = self.len / PROFILE_BINS as f32;
        let mut below = 0.0;
        for (b, &share) in self.shares.iter().enumerate() {
            let t = (b as f32 + 0.5) * width;
            let x = t - t0;
            sums[(t >= split) as usize] += (share - below) / (k * k + x * x).sqrt();
            below = share;
        }
        sums
    }

    /// The mean density of the light scattered over [`t0`, `t1`] (per unit of t; the density
    /// integrates to 1 over the stretch), at a point where the two meet.
    pub fn mean(&self, t0: f32, t1: f32) -> f32 {
        let (lo, hi) = (t0.min(t1), t0.max(t1));
        let width = hi - lo;
        let floor = self.len * 1e-4;
        if width > floor {
            (self.share_before(hi) - self.share_before(lo)) / width
        } else {
            let mid = 0.5 * (lo + hi);
            (self.share_before(mid + floor) - self.share_before(mid - floor)) / (2.0 * floor)
        }
    }
}

/// ∫₀^L e^(−σt t) dt = (1 − e^(−σt L))/σt, L when σt L is tiny. (Written as the WGSL twin
/// computes it, without `exp_m1`: a bound needs no more accuracy, and the twins' choices then
/// part only where `exp` itself rounds differently.)
fn fade_length(sigma_t: f32, len: f32) -> f32 {
    if sigma_t * len > 1e-4 {
        -((-sigma_t * len).exp() - 1.0) / sigma_t
    } else {
        len
    }
}

/// Share of every choice in the descent made by the children's weights alone (their flux,
/// the same for every receiver) rather than by their importance for the receiver.
const DEFENSIVE_SHARE: f32 = 0.1;

/// The probability of descending into the left child, of importances `a` and `b` (not both
/// zero) for the receiver: a/(a + b), mixed with the weights' share [`DEFENSIVE_SHARE`] when
/// both can contribute. The importances are bounds, some loose by orders of magnitude (a wide
/// box's cosine or glossy lobe at its most favourable direction); without the mixture a
/// sibling's loose bound can starve a subtree of probability and turn the light it holds into
/// a rare, bright outlier. A child that cannot contribute (importance 0) keeps probability 0.
fn left_probability(a: f32, b: f32, left: &LightTreeNode, right: &LightTreeNode) -> f32 {
    let p = a / (a + b);
    if a > 0.0 && b > 0.0 {
        (1.0 - DEFENSIVE_SHARE) * p + DEFENSIVE_SHARE * (left.weight / (left.weight + right.weight))
    } else {
        p
    }
}

/// A leaf's probability in a flat draw: (1 − D) of its importance's share of `sum_i` plus D
/// of its weight's of `sum_w` (the weight's alone when `sum_i` is not positive).
fn flat_mass(importance: f32, weight: f32, sum_i: f32, sum_w: f32) -> f32 {
    if sum_i > 0.0 {
        (1.0 - DEFENSIVE_SHARE) * (importance / sum_i) + DEFENSIVE_SHARE * (weight / sum_w)
    } else {
        weight / sum_w
    }
}

/// The first mean free path of a segment of length `len`, 1/σt (all of it when shorter).
fn free_path(sigma_t: f32, len: f32) -> f32 {
    if sigma_t * len > 1.0 { 1.0 / sigma_t } else { len }
}

/// Mean free paths of a VBL its tree bounds cover (see [`LightTree::over_vbls`]).
const CLIP_FREE_PATHS: f32 = 8.0;

/// A light as the tree is built over it: its box (a segment runs along a diagonal, given by
/// the index's bits [`DIAGONAL_SHIFT`]), selection weight, σt and index.
#[derive(Clone, Copy, Debug)]
pub struct TreeLight {
    pub lo: Vec3,
    pub hi: Vec3,
    pub weight: f32,
    pub sigma_t: f32,
    /// The phase function's g of a segment light's medium (0 for points).
    pub g: f32,
    /// The lobe a VSL on a glossy surface sends its light in ([`Emission::NONE`] otherwise).
    pub emission: Emission,
    /// A VSL's normal on the side it sends light to (zero for segment lights).
    pub normal: Vec3,
    pub index: u32,
}

fn positive_or_zero(x: f32) -> f32 {
    if x > 0.0 && x.is_finite() { x } else { 0.0 }
}

impl LightTree {
    /// The tree over a pass's VSLs (VPLs inflated by the pass's radius).
    pub fn over_vsls(scene: &Scene, vpls: &[SurfaceVertex]) -> LightTree {
        Self::build(vpls.iter().enumerate().map(|(i, v)| {
            let p = Vec3::from(v.pos);
            TreeLight {
                lo: p,
                hi: p,
                weight: vsl_weight(scene, v),
                sigma_t: 0.0,
                g: 0.0,
                emission: Emission::of_vsl(scene, v),
                normal: Vec3::from(v.normal).try_normalize().unwrap_or(Vec3::ZERO),
                index: i as u32,
            }
        }))
    }

    /// The tree over a pass's VBLs (VRLs inflated by the pass's radius `r`).
    pub fn over_vbls(scene: &Scene, vrls: &[LightSegment], r: f32) -> LightTree {
        let stretches: Vec<VblStretch> = vrls.iter().map(|v| VblStretch::of(scene, v, r)).collect();
        let mut tree = Self::build(vrls.iter().zip(&stretches).enumerate().map(|(i, (v, stretch))| {
            // The bounds cover the stretch where the light scatters ([`VblStretch`]): a long
            // segment's box would otherwise hold most of the scene and make every node
            // around it look close to every receiver.
            let VblStretch {
                start,
                end,
                sigma_t,
                weight,
                ..
            } = *stretch;
            let (o, d) = (Vec3::from(v.origin), Vec3::from(v.dir));
            let (a, b) = (o + d * start, o + d * end);
            let diagonal = (a.x > b.x) as u32 | ((a.y > b.y) as u32) << 1 | ((a.z > b.z) as u32) << 2;
            TreeLight {
                lo: a.min(b),
                hi: a.max(b),
                weight,
                sigma_t,
                g: scene.media[v.medium as usize].g,
                emission: Emission::NONE,
                normal: Vec3::ZERO,
                index: i as u32 | diagonal << DIAGONAL_SHIFT,
            }
        }));
        if stretches.iter().any(|s| s.profile.is_some()) {
            tree.profiles = stretches.iter().map(|s| s.profile).collect();
        }
        tree
    }

    /// Builds a tree over `lights`; lights whose weight is not positive or whose box is not
    /// finite are left out (they contribute nothing).
    pub fn build(lights: impl Iterator<Item = TreeLight>) -> LightTree {
        let mut items: Vec<TreeLight> = lights
            .inspect(|l| {
                assert!(
                    l.index & !(LIGHT_MASK | 7 << DIAGONAL_SHIFT) == 0,
                    "more than 2^28 lights"
                )
            })
            .filter(|l| l.weight > 0.0 && l.weight.is_finite() && l.lo.is_finite() && l.hi.is_finite())
            .collect();
        let mut tree = LightTree {
            nodes: Vec::with_capacity(2 * items.len()),
            profiles: Vec::new(),
        };
        if !items.is_empty() {
            tree.nodes.push(LightTreeNode::default());
            tree.fill(0, &mut items);
        }
        tree
    }

    /// Writes node `at` over `items`: a leaf for one light, else the two halves of a median
    /// split of the centres along the widest axis of their bounds.
    fn fill(&mut self, at: usize, items: &mut [TreeLight]) {
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
        let emission = Emission::bound(items.iter().map(|it| (it.emission, it.weight)));
        // The normals' cone, when every light has a normal.
        let normals = items
            .iter()
            .map(|it| (it.normal != Vec3::ZERO).then_some((it.normal, 1.0f32)))
            .reduce(|a, b| Some(cone_union(a?, b?)))
            .flatten();
        let (normal, normal_cos) = normals.map_or(([0.0; 3], 0.0), |(a, c)| (a.into(), c));
        if items.len() == 1 {
            self.nodes[at] = LightTreeNode {
                lo: lo.into(),
                weight,
                hi: hi.into(),
                child: LEAF | items[0].index,
                sigma_t: items[0].sigma_t,
                g: items[0].g,
                normal,
                normal_cos,
                ..LightTreeNode::with_emission(&emission)
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
            // Positive in a tree of segment lights: no horizon culling there (their bounds are
            // clipped, see `importance`).
            sigma_t: items.iter().map(|l| l.sigma_t).fold(0.0, f32::max),
            g: 0.0,
            normal,
            normal_cos,
            ..LightTreeNode::with_emission(&emission)
        };
        let (a, b) = items.split_at_mut(mid);
        self.fill(left, a);
        self.fill(left + 1, b);
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Draws one light: the root's choice by the uniform number `u` in [0, 1), every deeper
    /// choice by a fresh number from `s`. Returns the light's index and probability, or `None`
    /// when the descent ends at a node none of whose lights can reach the receiver.
    ///
    /// Fresh numbers rather than `u` rescaled from level to level: a rescaled number carries
    /// the rounding of every probability above it, amplified by 1/p at each level, so the
    /// GPU's descent (whose `atan`, fused multiply-adds and divisions round differently)
    /// would part from the CPU's in a visible share of records; with fresh numbers a choice
    /// differs only when its number falls within rounding of the branch probability.
    pub fn sample(&self, rx: &Receiver, r: f32, mut u: f32, s: &mut Sampler) -> Option<(u32, f32)> {
        let mut at = 0usize;
        let mut pmf = 1.0f32;
        loop {
            let node = self.nodes.get(at)?;
            if node.is_leaf() {
                return Some((node.light(), pmf));
            }
            let c = node.child as usize;
            let a = importance(&self.nodes[c], rx, r);
            let b = importance(&self.nodes[c + 1], rx, r);
            if !(a + b > 0.0) {
                return None;
            }
            let p_left = left_probability(a, b, &self.nodes[c], &self.nodes[c + 1]);
            if u < p_left {
                pmf *= p_left;
                at = c;
            } else {
                pmf *= 1.0 - p_left;
                at = c + 1;
            }
            u = s.next_1d();
        }
    }

    /// `k` lights for one record: slot k's root choice by the stratified number (k + ξ)/k,
    /// its deeper choices from the stream `stream(slot)`.
    pub fn sample_k<'a>(
        &'a self,
        rx: &Receiver,
        r: f32,
        k: u32,
        xi: f32,
        stream: impl Fn(u32) -> Sampler + 'a,
    ) -> impl Iterator<Item = Pick> + 'a {
        let rx = *rx;
        (0..k).filter_map(move |slot| {
            let u = ((slot as f32 + xi) / k as f32).min(ONE_BELOW);
            self.sample(&rx, r, u, &mut stream(slot))
                .map(|(light, pmf)| Pick { light, pmf, slot })
        })
    }

    /// The light-selection estimate of the sum over the tree's lights of `f(slot, light)`:
    /// `k` lights drawn for the receiver as `draw` says ([`LightTree::sample_k`], the descent,
    /// whose deeper choices come from `stream(slot)`, or [`LightTree::sample_flat_k`] by the
    /// given masses), each contribution over its probability, averaged. Unbiased for the
    /// all-pairs sum when `f` is zero for every light the draw cannot pick (see the module
    /// documentation).
    #[allow(clippy::too_many_arguments)]
    pub fn estimate(
        &self,
        rx: &Receiver,
        r: f32,
        k: u32,
        xi: f32,
        draw: Draw,
        stream: impl Fn(u32) -> Sampler,
        mut f: impl FnMut(u32, usize) -> Rgb,
    ) -> Rgb {
        if self.nodes.is_empty() {
            return Rgb::ZERO;
        }
        let mut term = |p: Pick| f(p.slot, p.light as usize) / p.pmf;
        let sum: Rgb = match draw {
            Draw::Descent => self.sample_k(rx, r, k, xi, stream).map(&mut term).sum(),
            Draw::Flat(masses) => Self::sample_flat_k(masses, k, xi).into_iter().map(&mut term).sum(),
            Draw::Own => self.sample_flat_own(rx, r, k, xi).into_iter().map(&mut term).sum(),
        };
        sum / k as f32
    }

    /// [`flat_importance`] of leaf `n` for `rx`, with where along its VBL the light scatters
    /// when the tree knows it ([`Profile`]).
    pub fn flat_importance(&self, n: &LightTreeNode, rx: &Receiver, r: f32) -> f32 {
        flat_importance(n, rx, r, self.profiles.get(n.light() as usize).and_then(Option::as_ref))
    }

    /// Each leaf's share of a flat draw for `rx`, in node order: (light, probability). A flat
    /// draw passes the tree's interior by and weighs every leaf at once: (1 − D) of its
    /// importance's share plus D of its weight's, D = [`DEFENSIVE_SHARE`] (all of the
    /// weight's when no leaf has any importance). Empty when no leaf has weight.
    ///
    /// Why: a VBL is long, and the boxes of a tree over VBLs in a room span the room from its
    /// first levels on, so a camera segment's descent cannot tell its children apart and
    /// halves a light's probability at every level however bright it is; and the descent's
    /// leaves take the phase functions at the lines' closest points, which misses a VBL that
    /// runs against the camera ray beside it by thousands. In the glossy fog box a draw of
    /// `Lmm` had a relative variance of 59 descending, 37 drawing lights uniformly, 2.0 flat
    /// by [`flat_importance`], 1.1 with the ideal probabilities (`examples/lmm_variance.rs`).
    /// The cost is a [`flat_importance`] per light (0.4 µs; 220 VBLs a pass: about 90 µs)
    /// for each group of [`FLAT_GROUP`] records that shares the masses, against some 4 µs a
    /// drawn pair (see docs/rendering.md for what it gains).
    ///
    /// The GPU draws by these same masses (`GatherInputs::media_masses`), so they are weighed
    /// only here.
    pub fn flat_masses(&self, rx: &Receiver, r: f32) -> Vec<(u32, f32)> {
        let leaves = || self.nodes.iter().filter(|n| n.is_leaf());
        let importances: Vec<f32> = leaves().map(|n| self.flat_importance(n, rx, r)).collect();
        let (mut sum_i, mut sum_w) = (0.0f32, 0.0f32);
        for (n, i) in leaves().zip(&importances) {
            sum_i += i;
            sum_w += n.weight;
        }
        if !(sum_w > 0.0) {
            return Vec::new();
        }
        leaves()
            .zip(importances)
            .map(|(n, i)| (n.light(), flat_mass(i, n.weight, sum_i, sum_w)))
            .collect()
    }

    /// `k` lights for one record drawn flat by its own masses: what
    /// [`LightTree::sample_flat_k`] draws from [`LightTree::flat_masses`]`(rx, r)`, weighed as
    /// it goes, without allocating them (a VSL draw does this for every record).
    pub fn sample_flat_own(&self, rx: &Receiver, r: f32, k: u32, xi: f32) -> Vec<Pick> {
        thread_local! {
            static IMPORTANCES: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        IMPORTANCES.with_borrow_mut(|importances| {
            importances.clear();
            let (mut sum_i, mut sum_w) = (0.0f32, 0.0f32);
            for n in self.nodes.iter().filter(|n| n.is_leaf()) {
                let i = self.flat_importance(n, rx, r);
                importances.push(i);
                sum_i += i;
                sum_w += n.weight;
            }
            let mut picks = Vec::with_capacity(k as usize);
            if !(sum_w > 0.0) {
                return picks;
            }
            // As `sample_flat_k`: slot + ξ < running·K.
            let (mut slot, mut running, mut last) = (0u32, 0.0f32, None);
            for (n, &i) in self.nodes.iter().filter(|n| n.is_leaf()).zip(importances.iter()) {
                let pmf = flat_mass(i, n.weight, sum_i, sum_w);
                running += pmf;
                while slot < k && slot as f32 + xi < running * k as f32 {
                    picks.push(Pick {
                        light: n.light(),
                        pmf,
                        slot,
                    });
                    slot += 1;
                }
                if pmf > 0.0 {
                    last = Some((n.light(), pmf));
                }
            }
            if let Some((light, pmf)) = last {
                while slot < k {
                    picks.push(Pick { light, pmf, slot });
                    slot += 1;
                }
            }
            picks
        })
    }

    /// The masses every group of records 0..`n` draws by ([`FLAT_GROUP`]): for group g,
    /// [`LightTree::flat_masses`] at the receiver of its representative record
    /// ([`flat_group_representative`]). Record i's are at `i / FLAT_GROUP`.
    /// The groups are weighed in parallel.
    pub fn group_masses(&self, n: usize, r: f32, rx: impl Fn(usize) -> Receiver + Sync) -> Vec<Vec<(u32, f32)>> {
        use rayon::prelude::*;
        (0..n.div_ceil(FLAT_GROUP))
            .into_par_iter()
            .map(|g| {
                let first = g * FLAT_GROUP;
                let len = FLAT_GROUP.min(n - first);
                self.flat_masses(&rx(first + flat_group_representative(len)), r)
            })
            .collect()
    }

    /// `k` lights for one record drawn flat by `masses` ([`LightTree::flat_masses`]): slot k
    /// takes the leaf where the running sum of the masses, in node order, first exceeds the
    /// stratified number (k + ξ)/K (a number beyond the whole sum, by rounding, takes the last
    /// leaf with a mass).
    pub fn sample_flat_k(masses: &[(u32, f32)], k: u32, xi: f32) -> Vec<Pick> {
        let mut picks = Vec::with_capacity(k as usize);
        let mut slot = 0u32;
        let mut running = 0.0f32;
        // (slot + ξ)/K < running, compared as slot + ξ < running·K: f32 addition and
        // multiplication are correctly rounded on every GPU (division is not), so the WGSL
        // twin makes the same picks from the same masses, bit for bit.
        let passed = |slot: u32, running: f32| slot as f32 + xi < running * k as f32;
        for &(light, pmf) in masses {
            running += pmf;
            while slot < k && passed(slot, running) {
                picks.push(Pick { light, pmf, slot });
                slot += 1;
            }
        }
        if let Some(&(light, pmf)) = masses.iter().rev().find(|m| m.1 > 0.0) {
            while slot < k {
                picks.push(Pick { light, pmf, slot });
                slot += 1;
            }
        }
        picks
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
            if node.is_leaf() {
                out[node.light() as usize] += p;
                continue;
            }
            let c = node.child as usize;
            let a = importance(&self.nodes[c], rx, r);
            let b = importance(&self.nodes[c + 1], rx, r);
            if !(a + b > 0.0) {
                continue;
            }
            let p_left = left_probability(a, b, &self.nodes[c], &self.nodes[c + 1]);
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
            if n.is_leaf() {
                let light = n.light() as usize;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A record's own flat draw picks what the shared one picks from the same receiver's
    /// masses, with the same probabilities: the two differ only in where the masses are
    /// kept. Catches a running sum or a defensive share that differs, and a fallback to the
    /// last leaf that is not the last with a mass.
    #[test]
    fn a_records_own_flat_draw_is_the_shared_one() {
        let mut s = Sampler::new(9, 0, 0);
        let lights: Vec<TreeLight> = (0..57)
            .map(|i| {
                let p = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 4.0 - 2.0;
                TreeLight {
                    lo: p,
                    hi: p,
                    weight: if i % 7 == 0 { 0.0 } else { 0.1 + s.next_1d() },
                    sigma_t: 0.0,
                    g: 0.0,
                    emission: Emission::NONE,
                    normal: Vec3::new(s.next_1d() - 0.5, 1.0, s.next_1d() - 0.5).normalize(),
                    index: i,
                }
            })
            .collect();
        let tree = LightTree::build(lights.into_iter());
        for case in 0..200 {
            let rx = Receiver::Point {
                p: Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 5.0 - 2.5,
                n: Vec3::new(s.next_1d() - 0.5, s.next_1d() - 0.5, s.next_1d() - 0.5).normalize(),
                gloss: Gloss::LAMBERT,
            };
            let (k, xi) = (1 + case % 5, s.next_1d());
            let shared = LightTree::sample_flat_k(&tree.flat_masses(&rx, 0.2), k, xi);
            assert_eq!(tree.sample_flat_own(&rx, 0.2, k, xi), shared, "case {case}");
        }
    }

    /// Boxes wholly below a shading point's horizon get nothing; just above, something.
    #[test]
    fn horizon_culling_is_conservative() {
        let node = |y: f32| LightTreeNode {
            lo: [-1.0, y - 0.1, -1.0],
            weight: 1.0,
            hi: [1.0, y + 0.1, 1.0],
            child: LEAF,
            ..Default::default()
        };
        let rx = Receiver::Point {
            p: Vec3::ZERO,
            n: Vec3::Y,
            gloss: Gloss::LAMBERT,
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
            g: 0.7,
        };
        for y in [-3.0, 0.0, 0.5, 40.0] {
            let v = importance(&node(y), &seg, r);
            assert!(v > 0.0 && v.is_finite(), "y {y}: {v}");
        }
    }
}
