//! What one pass of the many-light methods holds in memory, estimated before a render starts.
//! A path count typed with a few zeros too many (`--caustic-paths 4000000000`) would otherwise
//! be traced until the machine swaps or the kernel kills the process; the fixed limits on the
//! counts ([`crate::many_lights::MAX_LIGHT_PATHS`] and the others) bound it only on a machine
//! large enough for them. Records per path depend on the scene (bounces, glass, media), so a
//! few paths of each set are traced first and the pass is extrapolated from them.
use crate::many_lights::{ManyLightSettings, default_caustic_paths};
use beamlight_trace::{
    TraceScene,
    components::Component,
    light_paths::{Keep, LightSegment, LightSet, LightTracerSettings, SurfaceVertex, trace_light_paths},
    light_tree::LightTreeNode,
    vbl::Walls,
};
use std::mem::size_of;

/// Paths traced of each set to measure its records per path.
pub const PILOT_PATHS: u32 = 1024;

/// One set of a pass's light paths, as the estimate sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathMemory {
    /// The option that sets its count.
    pub flag: &'static str,
    pub paths: u32,
    /// Estimated bytes a path of the set costs a pass (see [`estimate`]).
    pub bytes_per_path: f64,
}

impl PathMemory {
    pub fn bytes(&self) -> f64 {
        self.paths as f64 * self.bytes_per_path
    }
}

/// A box-tree index ([`beamlight_trace::spatial::BoxTree`]) per item: its index (4 bytes) and
/// box (24), the boxes handed to the build (24), and nodes of 32 bytes for every two items
/// (leaves of four, as many interior nodes).
const BOX_TREE_BYTES: usize = 4 + 24 + 24 + 16;

/// Bytes a record of each kind costs a pass: the record, its index (a light tree has about
/// two nodes a light; a VPL also its walls, [`Walls`]) and, for the caustic sets, the box tree.
fn record_bytes(set: &LightSet, gathers: bool) -> f64 {
    let tree = 2 * size_of::<LightTreeNode>();
    let (vrl, vpl) = if gathers {
        (
            size_of::<LightSegment>() + tree,
            size_of::<SurfaceVertex>() + tree + size_of::<Walls>(),
        )
    } else {
        (size_of::<LightSegment>(), size_of::<SurfaceVertex>())
    };
    let photon = size_of::<SurfaceVertex>() + BOX_TREE_BYTES;
    let beam = size_of::<LightSegment>() + BOX_TREE_BYTES;
    (set.vrls.len() * vrl + set.vpls.len() * vpl + set.caustic_photons.len() * photon + set.photon_beams.len() * beam)
        as f64
}

/// The pass's light-path sets of a `w` × `h` render with `settings`, each with its estimated
/// bytes per path: [`PILOT_PATHS`] of its paths traced as the pass would (same keeps, the
/// pass-0 streams of `seed`), their records' bytes with their indices ([`record_bytes`]),
/// doubled for what a pass holds twice for a while (the traced chunks and the joined set,
/// vectors grown by doubling). Sets the pass does not trace (a component turned off, a
/// count of 0) are left out. Measured against a whole pass's heap in `tests/memory.rs`.
pub fn estimate(ts: &TraceScene, settings: &ManyLightSettings, w: u32, h: u32, seed: u32) -> Vec<PathMemory> {
    let on = |c: Component| settings.components[c as usize];
    let caustic_paths = settings.caustic_paths.unwrap_or_else(|| default_caustic_paths(w, h));
    let sets = [
        ("--light-paths", settings.light_paths_per_pass, Keep::ALL, true),
        (
            "--caustic-paths",
            if on(Component::CausticSurface) {
                caustic_paths
            } else {
                0
            },
            Keep::CAUSTIC_PHOTONS,
            false,
        ),
        (
            "--beam-paths",
            if on(Component::CausticVolume) {
                settings.beam_paths
            } else {
                0
            },
            Keep::PHOTON_BEAMS,
            false,
        ),
    ];
    sets.into_iter()
        .filter(|&(_, paths, _, _)| paths > 0)
        .map(|(flag, paths, keep, gathers)| {
            let tracer = LightTracerSettings {
                keep,
                ..Default::default()
            };
            let pilot = trace_light_paths(ts, &tracer, PILOT_PATHS, seed, 0);
            PathMemory {
                flag,
                paths,
                bytes_per_path: 2.0 * record_bytes(&pilot, gathers) / PILOT_PATHS as f64,
            }
        })
        .collect()
}

/// The memory a render may use: `MemAvailable` of /proc/meminfo (Linux), in bytes; `None`
/// where it cannot be read.
pub fn available() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// `Err` naming the set that takes most of a pass that would not fit in `limit` bytes:
/// its option and count, the estimate, and the limit with `limit_source` (where it comes from).
pub fn check(sets: &[PathMemory], limit: f64, limit_source: &str) -> Result<(), String> {
    let total: f64 = sets.iter().map(PathMemory::bytes).sum();
    let Some(largest) = sets.iter().max_by(|a, b| a.bytes().total_cmp(&b.bytes())) else {
        return Ok(());
    };
    if total <= limit {
        return Ok(());
    }
    let gib = |b: f64| b / (1u64 << 30) as f64;
    Err(format!(
        "{} {}: a pass would hold an estimated {:.2} GiB of light paths ({:.0} bytes a path, measured over {PILOT_PATHS} paths traced first; {:.2} GiB with the pass's other light paths), more than the limit of {:.2} GiB ({limit_source}); lower {} or raise --memory-limit",
        largest.flag,
        largest.paths,
        gib(largest.bytes()),
        largest.bytes_per_path,
        gib(total),
        gib(limit),
        largest.flag,
    ))
}
