// Counter-based random numbers: the twin of `beamlight_scene::rng`. Every number is PCG-hash
// (Jarzynski & Olano 2020) of the key words (seed, pass, stream index, dimension), so a kernel
// draws exactly the samples its CPU twin draws for the same keys.

fn pcg_hash(x: u32) -> u32 {
    let state = x * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

fn hash4(seed: u32, pass_index: u32, index: u32, dim: u32) -> u32 {
    var h = pcg_hash(seed);
    h = pcg_hash(h ^ pass_index);
    h = pcg_hash(h ^ index);
    return pcg_hash(h ^ dim);
}

// 24 random bits as a float in [0, 1), exactly representable.
fn u32_to_unit_f32(bits: u32) -> f32 {
    return f32(bits >> 8u) * (1.0 / 16777216.0);
}

// One stream of samples; each draw advances the dimension.
struct Sampler {
    seed: u32,
    pass_index: u32,
    index: u32,
    dim: u32,
}

fn sampler_new(seed: u32, pass_index: u32, index: u32) -> Sampler {
    return Sampler(seed, pass_index, index, 0u);
}

fn next_1d(s: ptr<function, Sampler>) -> f32 {
    let bits = hash4((*s).seed, (*s).pass_index, (*s).index, (*s).dim);
    (*s).dim = (*s).dim + 1u;
    return u32_to_unit_f32(bits);
}
