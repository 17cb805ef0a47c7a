//! use lib/gather.wgsl
//! use lib/light_tree.wgsl
//! use lib/vbl.wgsl
// The record hooks of the gather kernels into shading points (Lss, Lsm), for the shared entry
// point (lib/gather_entry.wgsl): a record is its point and BSDF, and the receiver's lobe, made
// once per record for the VSL and VBL estimators.

struct GatherRecord {
    sp: ShadingPoint,
    f_sp: Bsdf,
    // The receiver's lobe, when it has one.
    rx: Lobe,
}

fn gather_record(i: u32) -> GatherRecord {
    let sp = shading_points[i];
    let f_sp = point_bsdfs[i];
    var rx: Lobe;
    if f_sp.kind != BSDF_NONE {
        rx = surface_lobe(f_sp, sp.normal, sp.wo, 1.0);
    }
    return GatherRecord(sp, f_sp, rx);
}

// `Surface::receiver` is None for a delta or missing BSDF: no virtual light reflects there
// (every estimator's BSDF factor is zero), so nothing is gathered.
fn gathers_here(r: GatherRecord) -> bool {
    return r.f_sp.kind != BSDF_NONE;
}

// What light selection bounds a tree node's light against (unused by kernels without a tree).
fn record_receiver(r: GatherRecord) -> Receiver {
    return point_receiver(r.sp.pos, r.sp.normal, r.sp.wo, r.f_sp);
}
