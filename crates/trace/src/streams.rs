//! The random streams of the many-light gathers: one per (gather record, virtual light) pair,
//! so a pair's samples depend on nothing but its keys — not on which other pairs were
//! evaluated, nor in what order. The GPU kernels (`shaders/lib/gather.wgsl`) evaluate pairs in
//! parallel and draw exactly the same numbers.
use beamlight_scene::rng::{Sampler, pcg_hash};

/// Which estimator a stream feeds (the low bits of the stream index).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum GatherKind {
    VplToSurface = 0,
    VrlToSurface = 1,
    VplToMedia = 2,
    VrlToMedia = 3,
}

/// The base seed of a render's pair streams (kept apart from the camera, light-path and
/// direct-lighting streams, which hash the render seed differently).
pub fn pair_seed(seed: u32) -> u32 {
    pcg_hash(seed ^ 0x5bd1_e995)
}

/// The stream of gather record `record` (a shading point or media segment index) and virtual
/// light `light` of kind `kind`, in pass `pass`.
pub fn pair_sampler(pair_seed: u32, pass: u32, kind: GatherKind, record: u32, light: u32) -> Sampler {
    Sampler::new(
        pair_seed.wrapping_add(light),
        pass,
        record.wrapping_mul(4).wrapping_add(kind as u32),
    )
}

/// With light selection: the stream of the `slot`-th light gather record `record` drew. Keyed
/// by the slot, not the light, so two strata that draw the same light sample it
/// independently.
pub fn drawn_pair_sampler(pair_seed: u32, pass: u32, kind: GatherKind, record: u32, slot: u32) -> Sampler {
    Sampler::new(
        pcg_hash(pair_seed ^ 0x68e3_1da4).wrapping_add(slot),
        pass,
        record.wrapping_mul(4).wrapping_add(kind as u32),
    )
}

/// With light selection: the number ξ in [0, 1) that stratifies record `record`'s draws,
/// (slot + ξ)/K for slot = 0 … K − 1.
pub fn selection_number(pair_seed: u32, pass: u32, kind: GatherKind, record: u32) -> f32 {
    Sampler::new(
        pcg_hash(pair_seed ^ 0xb529_7a4d),
        pass,
        record.wrapping_mul(4).wrapping_add(kind as u32),
    )
    .next_1d()
}

/// With light selection: the stream of the tree descent of the `slot`-th light gather record
/// `record` draws (its choices below the root).
pub fn selection_sampler(pair_seed: u32, pass: u32, kind: GatherKind, record: u32, slot: u32) -> Sampler {
    Sampler::new(
        pcg_hash(pair_seed ^ 0x27d4_eb2f).wrapping_add(slot),
        pass,
        record.wrapping_mul(4).wrapping_add(kind as u32),
    )
}
