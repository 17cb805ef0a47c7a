//! use lib/gather.wgsl
//! use lib/light_tree.wgsl
//! use lib/scene.wgsl
// The record hooks of the gather kernels into camera media segments (Lms, Lmm), for the
// shared entry point (lib/gather_entry.wgsl): a record is its segment. Whether its medium
// gathers at all (`gathers_in_medium`) each estimator checks itself, as on the CPU.

struct GatherRecord {
    seg: MediaSegment,
}

fn gather_record(i: u32) -> GatherRecord {
    return GatherRecord(media_segments[i]);
}

fn gathers_here(r: GatherRecord) -> bool {
    return true;
}

// What light selection bounds a tree node's light against (unused by kernels without a tree).
fn record_receiver(r: GatherRecord) -> Receiver {
    return segment_receiver(r.seg.origin, r.seg.dir, r.seg.length, media[r.seg.medium].g);
}
