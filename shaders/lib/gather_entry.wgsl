//! use lib/gather.wgsl
//! use lib/light_tree.wgsl
//! hooks GATHER_KIND GatherRecord gather_record gathers_here light_tree_of record_receiver light_contribution
// The entry point of every gather kernel: one invocation per gather record sums its estimate
// over the pass's virtual lights, all of them, each with its pair's stream, or with light
// selection (`params.light_samples` > 0) that many drawn from the pass's light tree (for
// camera media segments against VBLs, from all its leaves at once), each over its probability (the CPU's twin: `record_gathers::gather_lights`), and writes it with its
// discard count. The kernel supplies what differs between kernels (the `hooks` above), the
// record's part from lib/surface_record.wgsl or lib/media_record.wgsl:
//   const GATHER_KIND: u32                    the gather kind, which names its random streams
//   struct GatherRecord                       what the kernel reads of a record, once
//   fn gather_record(i: u32) -> GatherRecord
//   fn gathers_here(r: GatherRecord) -> bool  false: nothing to gather at this record
//   fn light_tree_of(r: GatherRecord) -> vec2<u32>  its tree's first node and node count
//   fn record_receiver(r: GatherRecord) -> Receiver  what the tree's bounds are taken for
//   fn light_contribution(r: GatherRecord, light: u32, s: ptr<function, Sampler>) -> vec3<f32>

// A drawn light's term: its pair from the stream of record `i`'s slot `slot`, admitted, over
// its probability.
fn drawn_term(r: GatherRecord, i: u32, slot: u32, pick: Pick, discarded: ptr<function, u32>) -> vec3<f32> {
    var s = drawn_pair_sampler(GATHER_KIND, i, slot);
    return admit(light_contribution(r, pick.light, &s), discarded) / pick.pmf;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = record_index(gid);
    if i >= params.records {
        return;
    }
    let r = gather_record(i);
    var sum = vec3<f32>(0.0);
    var discarded = 0u;
    if gathers_here(r) {
        let tree = light_tree_of(r);
        if params.light_samples == 0u {
            let end = min(params.first_light + params.light_chunk, params.lights);
            for (var j = params.first_light; j < end; j++) {
                var s = pair_sampler(GATHER_KIND, i, j);
                sum += admit(light_contribution(r, j, &s), &discarded);
            }
        } else if tree.y > 0u {
            let xi = selection_number(GATHER_KIND, i);
            if GATHER_KIND == KIND_VRL_TO_MEDIA && params.media_drawing == 1u {
                // `Lmm` drawn flat (`LightTree::sample_flat_k`): by the masses of the record's
                // group, in node order. Slot k's light is the first leaf at which the running
                // sum passes its stratified number, compared as slot + ξ < running·K (addition
                // and multiplication are correctly rounded, so the picks are the CPU's). The
                // numbers grow with k, so one walk serves every slot; the pairs are estimated
                // outside it, so that a SIMD group's invocations estimate theirs together.
                let base = flat_group(i) * flat_stride(tree.y);
                let k_f = f32(params.light_samples);
                var n = 0u;
                var leaf = 0u;
                var running = 0.0;
                var current = Pick(0u, 0.0, false);
                var last = Pick(0u, 0.0, false);
                for (var slot = 0u; slot < params.light_samples; slot++) {
                    let number = f32(slot) + xi;
                    while !(number < running * k_f) && n < tree.y {
                        let node = light_tree[tree.x + n];
                        n++;
                        if (node.child & LIGHT_LEAF) == 0u {
                            continue;
                        }
                        current = Pick(node.child & LIGHT_MASK, flat_masses[base + leaf], true);
                        leaf++;
                        running += current.pmf;
                        if current.pmf > 0.0 {
                            last = current;
                        }
                    }
                    // A number beyond the whole sum, by rounding: the last leaf with a mass.
                    var pick = current;
                    if !(number < running * k_f) {
                        pick = last;
                    }
                    if pick.found {
                        sum += drawn_term(r, i, slot, pick, &discarded);
                    }
                }
            } else {
                let receiver = record_receiver(r);
                for (var k = 0u; k < params.light_samples; k++) {
                    let pick = tree_sample_slot(tree.x, receiver, GATHER_KIND, i, k, xi);
                    if pick.found {
                        sum += drawn_term(r, i, k, pick, &discarded);
                    }
                }
            }
            sum = sum / f32(params.light_samples);
        }
    }
    let total = admit(injected(sum * params.scale, i), &discarded);
    // lavapipe (llvmpipe) caps the loop iterations of a whole invocation, all its loops
    // together (65 535 in Mesa 22), and past the cap leaves every loop after its first turn,
    // silently: BVH traversals then miss, cone integrals stop early. A loop whose count the
    // compiler cannot know (two turns, from a uniform) tells whether the cap was reached; −1
    // in w reports it (`PendingGathers::finish`).
    let turns_wanted = min(params.records + 1u, 2u);
    var turns = 0u;
    for (var k = 0u; k < turns_wanted; k++) {
        turns++;
    }
    var out = vec4<f32>(total, f32(discarded));
    if params.first_light > 0u {
        let before = gathered[i];
        out = vec4<f32>(before.xyz + total, select(before.w + f32(discarded), -1.0, before.w < 0.0));
    }
    gathered[i] = select(out, vec4<f32>(out.xyz, -1.0), turns < turns_wanted);
}

