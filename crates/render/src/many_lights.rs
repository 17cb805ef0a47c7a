//! One pass of the many-light methods on the CPU: camera gather data and a fresh set of light
//! paths, then every gather point against every virtual light, each transport component kept
//! apart (`Component::ALL` order). The indirect components come from virtual ray/point lights
//! (`vrl`, `vrl-clamped`) or, inflated by the pass's radius, virtual beam/spherical lights
//! (`vbl`). Light sets live for one pass only: memory does not grow as passes go on.
//!
//! Caustics come from the same light paths: progressive photon mapping over the caustic
//! photons and progressive photon beams over the beams that leave specular bounces, with the
//! pass's radius from the schedule of eq. 11 ([`crate::radius`]).
use crate::{
    radius::paths_squared_radius,
    record_gathers::{CausticLookup, PassGathers, Selection, credited, direct_stream, injected},
};
use beamlight_gpu::{
    GpuBackend, GpuError,
    gather::{GatherInputs, KERNELS, PendingGathers},
};
use beamlight_scene::{Rgb, rng::Sampler};
use beamlight_trace::{
    TraceScene,
    camera_paths::{CameraPathSettings, GatherSet, MediaSegment, PixelShare, ShadingPoint, trace_camera_pixels},
    caustics::{BeamMap, PhotonMap},
    components::Component,
    direct,
    light_paths::{Keep, LightTracerSettings, trace_light_paths},
    light_tree::{Drawing, FLAT_GROUP, LightTree, flat_draw_receiver},
    streams,
    vbl::{self, VblSettings},
};
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// What may enter an accumulator (defined beside the CPU's gathers, which use it most).
pub use crate::record_gathers::admit;

/// How the light paths' records are gathered for the indirect components.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VirtualLights {
    /// Virtual ray lights and virtual point lights (`vrl`, `vrl-clamped`).
    #[default]
    Rays,
    /// Virtual beam lights and virtual spherical lights with the pass's radius (`vbl`).
    Beams,
}

/// The seed of the many-light methods' random stream (`vbl`, `vrl`, `vrl-clamped`, and
/// `auto`'s `vbl`) in a render with `seed`; the path tracer's is `seed` itself. Salted, so
/// that inside `auto` the two estimators' streams are independent (their errors must not
/// correlate), and the same alone and inside `auto`, so that `auto`'s passes are the very
/// passes `pt` and `vbl` render with the same seed: where `auto` gives a component to one
/// estimator, its image is that estimator's after fewer passes (common random numbers:
/// comparisons at equal seed measure `auto`'s overhead, not two renders' independent noise).
pub fn stream_seed(seed: u32) -> u32 {
    beamlight_scene::rng::pcg_hash(seed ^ 0x6a09_e667)
}

/// Settings of the many-light methods.
#[derive(Clone, Copy, Debug)]
pub struct ManyLightSettings {
    pub lights: VirtualLights,
    /// The VBL/VSL estimators' settings (used with [`VirtualLights::Beams`]).
    pub vbl: VblSettings,
    /// Light paths traced per pass (each leaves several VPLs and VRLs).
    pub light_paths_per_pass: u32,
    /// Minimum distance in the inverse-square falloff of VRLs/VPLs (`vrl-clamped`); 0 for
    /// unclamped `vrl`.
    pub clamp: f32,
    /// Initial radius R0 of the virtual beam and spherical lights (`vbl`), in scene units; 0
    /// picks [`crate::radius::default_radius`].
    pub radius: f32,
    /// Initial radius R0 of the caustics' photon mapping and photon beams; 0 picks
    /// [`crate::radius::default_photon_radius`].
    pub photon_radius: f32,
    /// The radius reduction's α of eq. 11, in (0, 1): smaller shrinks faster.
    pub alpha: f32,
    /// Lights each gather record draws per component from the pass's light tree (`vbl`
    /// only, [`beamlight_trace::light_tree`]); `None` gathers every light of the pass (the
    /// all-pairs estimator, `--light-samples all`, the oracle of the sampled one).
    pub light_samples: Option<u32>,
    /// Lights each camera media segment draws from the VBL tree for `Lmm`, when it should be
    /// other than `light_samples` (`--media-light-samples`). The tree's bound for a beam seen
    /// from a segment (a double line integral, its phase functions taken at the closest
    /// points) matches the pairs' contributions least well, so in a homogeneous glossy fog
    /// `Lmm`'s selection noise dominates the pass and more draws pay: in the glossy fog box,
    /// 8 or 16 draws (with 4 elsewhere) gave the image 1.3× lower error at equal time than 4
    /// (10 s, four seeds each), but in the smoke box, whose heterogeneous medium makes each
    /// pair dearer, 1.2× and 1.6× higher. So the default stays `light_samples`.
    pub media_light_samples: Option<u32>,
    /// How camera media segments draw their VBLs for `Lmm` (`--media-light-draw`): flat by
    /// each one's pair integral ([`LightTree::flat_masses`]) unless a pass has very many, or
    /// always one way.
    pub media_drawing: MediaDraw,
    /// How gather records draw their VSLs for `Lss` and `Lms` on the CPU (`--vsl-draw`):
    /// flat, each record weighing every VSL of the pass by its own leaf importance, unless a
    /// pass has very many, or always one way. The GPU's kernels descend the tree.
    pub vsl_drawing: VslDraw,
    /// Camera samples per pixel per pass for direct light (`--direct-samples`): the gather's
    /// own and more, each with its own pixel jitter and one next-event estimate (light and
    /// BSDF/phase sampling, MIS) at each of its records. Direct light costs little next to
    /// the gathers, so it gets more samples and no longer sets the pass's noise.
    pub direct_samples: u32,
    /// Light paths traced per pass for the surface caustics alone (`--caustic-paths`), apart
    /// from the gathers' light paths: a caustic photon costs its path and a lookup, not a
    /// gather over every record, so they come in thousands. Their radius follows eq. 11 with
    /// this count. `None`: [`default_caustic_paths`] for the image size; `Some(0)` when the
    /// scene has no mirror or glass (no caustics to trace).
    pub caustic_paths: Option<u32>,
    /// Light paths traced per pass for the volume caustics (`--beam-paths`): each camera
    /// media segment looks up every photon beam whose tube it crosses, so beams cost more than
    /// photons and get fewer paths. Their radius follows eq. 11 with this count.
    pub beam_paths: u32,
    /// The components a pass computes, by [`Component::ALL`] index (every one by default);
    /// the others stay zero and cost nothing. `--method auto` leaves out those the path
    /// tracer serves better ([`crate::auto`]).
    pub components: [bool; N],
    /// Fault injection for the discard counters' tests (`--inject-nan`, hidden): the first
    /// record of each gather that runs in a pass (direct light, each virtual-light kernel on
    /// the CPU or the GPU, each caustic lookup) has its estimate replaced by NaN, which
    /// [`admit`] must count, and the first path of each light set its power
    /// ([`Discards::light_paths`]). Never on in a real render; part of the fingerprint, so a
    /// checkpoint from a poisoned render cannot continue a clean one.
    pub inject_nan: bool,
}

/// How camera media segments draw their VBLs for `Lmm` (`--media-light-draw`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MediaDraw {
    /// Flat while a pass has at most [`FLAT_MAX_VBLS`] VBLs and [`FLAT_MAX_MASSES`] masses, by
    /// the descent beyond.
    #[default]
    Auto,
    /// Always down the tree ([`Drawing::Descent`]).
    Descent,
    /// Always flat ([`Drawing::Flat`]), up to [`FLAT_EXPLICIT_MAX_MASSES`].
    Flat,
}

impl MediaDraw {
    /// How a pass with `vbls` VBLs and `segments` camera media segments draws them; an error
    /// when a flat draw asked for would hold more than [`FLAT_EXPLICIT_MAX_MASSES`] masses.
    pub fn drawing(self, vbls: usize, segments: usize) -> Result<Drawing, String> {
        let groups = segments.div_ceil(FLAT_GROUP);
        let masses = groups.saturating_mul(vbls);
        Ok(match self {
            MediaDraw::Auto if vbls <= FLAT_MAX_VBLS && masses <= FLAT_MAX_MASSES => Drawing::Flat,
            MediaDraw::Auto | MediaDraw::Descent => Drawing::Descent,
            MediaDraw::Flat if masses <= FLAT_EXPLICIT_MAX_MASSES => Drawing::Flat,
            MediaDraw::Flat => {
                return Err(format!(
                    "--media-light-draw flat: this pass would weigh {masses} masses ({groups} groups of \
                     {FLAT_GROUP} camera media segments × {vbls} VBLs, {:.1} GB), more than the \
                     {FLAT_EXPLICIT_MAX_MASSES} allowed; use --media-light-draw auto (flat while a \
                     pass has at most {FLAT_MAX_MASSES}), fewer --light-paths or a smaller image",
                    masses as f64 * 8.0 / 1e9
                ));
            }
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            MediaDraw::Auto => "auto",
            MediaDraw::Descent => "descent",
            MediaDraw::Flat => "flat",
        }
    }
}

/// How gather records draw their VSLs for `Lss` (shading points) and `Lms` (camera media
/// segments) on the CPU (`--vsl-draw`).
///
/// The descent's interior nodes are where its variance comes from: a node's box of VSLs on
/// several walls, seen from a shading point beside some of them, is weighed as if all its
/// lights were as far as its half-diagonal and as well turned as the best of them, so a VSL
/// next to the receiver that carries most of its light is drawn with a probability of a few
/// percent. `examples/lss_variance.rs` (one pass, 64 light paths, 300 shading points, every
/// VSL against each, 96²): a draw's relative variance descending / flat by each leaf's own
/// importance / ideal: Cornell box 3.96 / 0.51 / 0.06, `cars_small` 7.6 / 0.56 / 0.05, glossy
/// fog box 11.8 / 0.75. Flat over the 64 nodes six levels down, then descending, still gave
/// 2.1 / 2.3 / 3.6, and masses shared by 16 neighbouring records (as `Lmm`'s are) 17 / 6.7 /
/// 99: a shading point's light comes from the VSLs beside it, which its neighbours on another
/// wall do not share. So each record weighs every VSL itself: [`FLAT_MAX_VSLS`] bounds that.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VslDraw {
    /// Flat on the CPU while a pass has at most [`FLAT_MAX_VSLS`] VSLs, by the descent beyond
    /// (and on the GPU).
    #[default]
    Auto,
    /// Always down the tree ([`Drawing::Descent`]).
    Descent,
    /// Always flat on the CPU ([`Drawing::Flat`]); refused when the GPU gathers the VSLs.
    Flat,
}

impl VslDraw {
    /// How a pass with `vsls` VSLs draws them on the CPU.
    pub fn drawing(self, vsls: usize) -> Drawing {
        match self {
            VslDraw::Auto if vsls <= FLAT_MAX_VSLS => Drawing::Flat,
            VslDraw::Auto | VslDraw::Descent => Drawing::Descent,
            VslDraw::Flat => Drawing::Flat,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            VslDraw::Auto => "auto",
            VslDraw::Descent => "descent",
            VslDraw::Flat => "flat",
        }
    }
}

/// The most VSLs a pass draws flat by default: a flat draw weighs every VSL for each record,
/// so its cost grows with the pass's VSLs where the descent's grows with their logarithm.
pub const FLAT_MAX_VSLS: usize = 1024;

/// The most VBLs a pass draws `Lmm`'s beams from flat by default. A flat draw weighs every
/// VBL once per group of [`beamlight_trace::light_tree::FLAT_GROUP`] camera segments and
/// walks them all for each segment, so its cost grows with the pass's VBLs where the
/// descent's grows with their logarithm. Yet it stays ahead well past the default 64 light
/// paths a pass: the glossy fog box (about 3.4 VBLs a light path), `vbl --only Lmm`, 96²,
/// 16 s, the CPU, relMSE between two seeds' renders, flat against descending: 64 paths 9.3e-4
/// against 2.1e-2; 256 paths 1.8e-3 (70 passes) against 2.4e-2 (150); 1024 paths (about 3 500
/// VBLs) 5.4e-3 (20 passes) against 5.1e-2 (131). Beyond some 4 000 its cost per pass would
/// keep growing while the descent's would not, so the default stops there.
pub const FLAT_MAX_VBLS: usize = 4096;

/// The most masses (groups of [`FLAT_GROUP`] camera media segments × VBLs) a pass draws flat
/// by default: with the GPU they are held for the whole pass (8 bytes each on the CPU, 4 on
/// the GPU), 2²⁵ of them some 400 MB. At 1280×720 (about 58 000 groups of one segment a
/// pixel) that allows some 580 VBLs, over twice the default 64 light paths' (about 220 in the
/// glossy fog box).
pub const FLAT_MAX_MASSES: usize = 1 << 25;

/// The most masses a pass may weigh when the flat draw is asked for (`--media-light-draw
/// flat`): 2²⁸, 2 GB on the CPU. Beyond it a pass is refused with an error naming the flag,
/// rather than growing memory with the light paths and the image until the machine swaps.
pub const FLAT_EXPLICIT_MAX_MASSES: usize = 1 << 28;

/// Lights a gather record draws per component by default (`--light-samples`; more draws with
/// cheaper pairs did not pay everywhere, see [`beamlight_trace::vbl::DEFAULT_DIRECTIONS`]).
pub const DEFAULT_LIGHT_SAMPLES: u32 = 4;
/// Camera samples per pixel per pass for direct light by default (`--direct-samples`).
pub const DEFAULT_DIRECT_SAMPLES: u32 = 4;
/// Caustic light paths per pixel and pass by default (`--caustic-paths`). A pass's gathers
/// cost in proportion to its pixels, a photon path does not, so a fixed count would give the
/// caustics a share of the pass that shrinks as the image grows (CARS at 1280×720 had 0.04
/// paths a pixel and blotchy caustics; cars_small at 96² had 3.6). Measured, one run each:
/// cars_small at 96² and 16 s, image relMSE 8.1e-3 at 0.9 paths a pixel, 7.1e-3 at 1.8,
/// 6.9e-3 at 3.6 and 7.1, 8.7e-3 at 14 (a flat optimum); CARS at 320×180 and 60 s, 4 paths a
/// pixel instead of 0.57 (32 768): `caustic_surface`'s variance 3.1× lower, the others' 1.1–1.3×
/// higher (fewer passes), the image's 5 % lower. Where the variance falls as the count to the
/// −0.43 (as there), the image's error is lowest with the caustics taking about 0.4 of the
/// rest of the pass; 4 a pixel gives them about 0.3.
pub const CAUSTIC_PATHS_PER_PIXEL: u32 = 4;
/// The fewest caustic paths a pass traces by default: small images keep a photon map dense
/// enough for a radius that is not most of the scene.
pub const MIN_CAUSTIC_PATHS: u32 = 32768;
/// The most caustic paths a pass traces by default, to bound a pass's memory (a photon and
/// its index take about 100 bytes, and a path leaves one to a few): beyond 1024² pixels the
/// count stops growing with the image.
pub const MAX_DEFAULT_CAUSTIC_PATHS: u32 = 1 << 22;

/// Light paths per pass for the surface caustics of a `w` × `h` image by default.
pub fn default_caustic_paths(w: u32, h: u32) -> u32 {
    let per_pixel = w as u64 * h as u64 * CAUSTIC_PATHS_PER_PIXEL as u64;
    per_pixel.clamp(MIN_CAUSTIC_PATHS as u64, MAX_DEFAULT_CAUSTIC_PATHS as u64) as u32
}

/// The most light paths a pass may trace for the gathers (`--light-paths`): each leaves its
/// VRLs and VPLs (48 and 64 bytes, one of each per bounce), with light trees over them, so
/// an estimated gigabyte or so at the limit. A count typed with a few zeros too many is
/// refused, not traced until memory runs out.
pub const MAX_LIGHT_PATHS: u32 = 1 << 20;
/// The most caustic paths a pass may trace (`--caustic-paths`): one to a few photons a path
/// at about 100 bytes with their index, an estimated 2–5 GB at the limit.
pub const MAX_CAUSTIC_PATHS: u32 = 1 << 24;
/// The most beam paths a pass may trace (`--beam-paths`): a few 48-byte beams a path, but every
/// camera media segment crossing a beam's tube looks it up, so time runs out long before
/// memory (an estimated 0.5 GB at the limit).
pub const MAX_BEAM_PATHS: u32 = 1 << 22;

/// Light paths per pass for the volume caustics by default (`--beam-paths`).
pub const DEFAULT_BEAM_PATHS: u32 = 2048;

impl Default for ManyLightSettings {
    fn default() -> Self {
        Self {
            lights: VirtualLights::Rays,
            vbl: VblSettings::default(),
            light_paths_per_pass: 64,
            clamp: 0.0,
            radius: 0.0,
            photon_radius: 0.0,
            alpha: 0.7,
            light_samples: Some(DEFAULT_LIGHT_SAMPLES),
            media_light_samples: None,
            media_drawing: MediaDraw::Auto,
            vsl_drawing: VslDraw::Auto,
            direct_samples: DEFAULT_DIRECT_SAMPLES,
            caustic_paths: None,
            beam_paths: DEFAULT_BEAM_PATHS,
            components: [true; N],
            inject_nan: false,
        }
    }
}

/// The default clamp distance of `vrl-clamped`: 5 % of the diagonal of the scene's bounds (the
/// VRL paper leaves the choice to the user; a fixed share of the scene keeps it scale-free).
pub fn default_clamp(scene: &beamlight_scene::Scene) -> f32 {
    let (lo, hi) = scene.bounds();
    let diagonal = (hi - lo).length();
    if diagonal.is_finite() { 0.05 * diagonal } else { 0.0 }
}

/// The squared radius of pass `pass` (0-based) for initial radius `r0` and these settings'
/// light paths per pass (M) and α, from eq. 11 in log space.
pub fn pass_squared_radius(r0: f32, settings: &ManyLightSettings, pass: u32) -> f32 {
    paths_squared_radius(r0, settings.alpha, settings.light_paths_per_pass, pass)
}

const N: usize = Component::ALL.len();

/// Where a pass's time went: CPU tracing and estimating, and GPU kernel time (from timestamp
/// queries; zero on the CPU backend); and what its estimators had to discard.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassTimes {
    /// Camera paths, light paths and the photon/beam maps.
    pub trace: Duration,
    /// The part of `trace` that does not depend on the pixels a pass covers: the light paths,
    /// the photon and beam maps, the VPLs' walls. What a pass over fewer pixels still costs.
    pub light_side: Duration,
    /// The estimators that ran on the CPU (everything on the CPU backend; direct light and
    /// caustics with the GPU), overlapping the GPU's work.
    pub cpu_estimates: Duration,
    /// Waiting for the GPU's results after the CPU's own share was done.
    pub gpu_wait: Duration,
    /// GPU kernel time, per gather kernel ([`beamlight_gpu::gather::GatherKernel`] order).
    pub kernels: [f64; KERNELS],
    /// Wall time the pass held the render loop: its start (tracing, CPU estimates) and its
    /// finish (waiting for the GPU), set by the loop; over a render these add up to its time.
    pub wall: Duration,
    /// CPU time (summed over threads, seconds) spent in each component's estimator on the CPU,
    /// in [`Component::ALL`] order. A component whose records or virtual lights are empty
    /// (no media segments, no VRLs in a scene without media) is not timed: it stays at 0.
    pub component_cpu: [f64; N],
    /// What the pass had to leave out ([`Discards`]). Zero in a sane scene: anything else is a
    /// bug or a numerical breakdown that would otherwise only show as missing light.
    pub discarded: Discards,
    /// Gather records of the pass: the camera's shading points and media segments, and the
    /// walks' through sharp media (`beamlight_trace::camera_paths`) points and segments.
    pub records: Records,
}

/// How many gather records a pass had, by kind (see [`PassTimes::records`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct Records {
    pub shading_points: u64,
    pub media_segments: u64,
    pub walk_points: u64,
    pub walk_segments: u64,
}

/// What a render had to leave out, counted so that nothing is lost unseen: estimates that came
/// out NaN, infinite or negative ([`admit`]; on the CPU and the GPU alike) per component, in
/// [`Component::ALL`] order, and light paths ended because their power turned NaN or infinite
/// ([`beamlight_trace::light_paths::LightSet::nonfinite_paths`], over the pass's light sets).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Discards {
    pub estimates: [u64; N],
    pub light_paths: u64,
}

impl Discards {
    pub fn add(&mut self, other: &Discards) {
        for (a, b) in self.estimates.iter_mut().zip(other.estimates) {
            *a += b;
        }
        self.light_paths += other.light_paths;
    }

    /// Whether anything was left out.
    pub fn any(&self) -> bool {
        *self != Discards::default()
    }
}

/// Every component's count in order, then the light paths': "direct 0, Lsm 3, …,
/// caustic_volume 0; light paths 0" (`--stats`, the EXR header, warnings).
impl std::fmt::Display for Discards {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (k, (c, n)) in Component::ALL.iter().zip(self.estimates).enumerate() {
            write!(f, "{}{} {n}", if k > 0 { ", " } else { "" }, c.name())?;
        }
        write!(f, "; light paths {}", self.light_paths)
    }
}

/// The GPU's gather kernels, by which [`PassTimes::kernels`] is indexed.
pub use beamlight_gpu::gather::GatherKernel;

/// The component each of [`gpu_kernels`]'s kernels computes, in its order.
pub const KERNEL_COMPONENTS: [Component; 4] = [Component::Lss, Component::Lsm, Component::Lms, Component::Lmm];

/// The GPU kernels of these settings' method, in (Lss, Lsm, Lms, Lmm) order.
pub fn gpu_kernels(lights: VirtualLights) -> [GatherKernel; 4] {
    match lights {
        VirtualLights::Rays => GatherKernel::RAYS,
        VirtualLights::Beams => GatherKernel::BEAMS,
    }
}

/// Whether the GPU has every gather kernel of this method.
pub fn gpu_has_kernels(lights: VirtualLights) -> bool {
    gpu_kernels(lights).iter().all(|k| k.available())
}

/// A pass whose CPU share is done and whose GPU gathers may still be running: the
/// orchestrator starts the next pass's tracing before it waits for this one
/// ([`crate::progressive`] keeps one pass in flight).
pub struct PassInFlight {
    pub pass: u32,
    /// The CPU's estimates (every component on the CPU backend).
    out: [Vec<Rgb>; N],
    pending: Option<PendingGathers>,
    kernels: [GatherKernel; 4],
    /// The pixel of each shading point and each media segment, for the GPU's results.
    point_pixels: Vec<u32>,
    segment_pixels: Vec<u32>,
    /// The component each walk record's gathers are credited to, by record index (`None`:
    /// a camera record, each estimate in its own component; see [`credited`]).
    point_credits: Vec<Option<Component>>,
    segment_credits: Vec<Option<Component>>,
    /// [`ManyLightSettings::components`].
    computed: [bool; N],
    times: PassTimes,
}

impl PassInFlight {
    /// Whether gathers of the pass run on the GPU (and [`PassInFlight::finish`] waits for them).
    pub fn on_gpu(&self) -> bool {
        self.pending.is_some()
    }

    /// Waits for the pass's GPU gathers (if any) and writes the whole pass into `out`, one
    /// buffer per component in [`Component::ALL`] order.
    pub fn finish(mut self, gpu: Option<&GpuBackend>, out: &mut [Vec<Rgb>]) -> Result<PassTimes, GpuError> {
        if let Some(pending) = self.pending {
            let gpu = gpu.expect("a pass with GPU work needs its GPU to finish");
            let clock = Instant::now();
            let g = pending.finish(&gpu.gpu)?;
            self.times.gpu_wait = clock.elapsed();
            self.times.kernels = g.kernel_seconds;
            for (kernel, component) in self.kernels.into_iter().zip(KERNEL_COMPONENTS) {
                let (pixels, credits) = if kernel.on_surfaces() {
                    (&self.point_pixels, &self.point_credits)
                } else {
                    (&self.segment_pixels, &self.segment_credits)
                };
                for ((&pixel, &credit), v) in pixels.iter().zip(credits).zip(&g.results[kernel as usize]) {
                    let k = credited(component, credit) as usize;
                    if self.computed[k] {
                        self.out[k][pixel as usize] += *v;
                    }
                }
                self.times.discarded.estimates[component as usize] += g.discarded[kernel as usize];
            }
        }
        assert_eq!(out.len(), N, "one output buffer per component");
        for (dst, src) in out.iter_mut().zip(&mut self.out) {
            std::mem::swap(dst, src);
        }
        Ok(self.times)
    }
}

/// Traces pass `pass` over the pixels of `pixels`, submits its gathers to `gpu` (when it has
/// the method's kernels) and computes the rest on the CPU while the GPU works;
/// [`PassInFlight::finish`] completes it. Pixels the pass does not cover stay zero.
pub fn start_pass(
    ts: &TraceScene,
    settings: &ManyLightSettings,
    w: u32,
    h: u32,
    pixels: PixelShare,
    seed: u32,
    pass: u32,
    gpu: Option<&GpuBackend>,
) -> Result<PassInFlight, GpuError> {
    let mut out: [Vec<Rgb>; N] = std::array::from_fn(|_| vec![Rgb::ZERO; (w * h) as usize]);
    let mut times = PassTimes::default();
    let clock = Instant::now();
    let gather = trace_camera_pixels(ts, &CameraPathSettings::default(), w, h, pixels, seed, pass);
    let camera_done = clock.elapsed();
    // The camera's records, then the walks' through sharp media, whose gathers are credited
    // to `Lmm` (segments) or the component each walk point names.
    let points: Vec<ShadingPoint> = gather
        .shading_points
        .iter()
        .copied()
        .chain(gather.walk_points.iter().map(|w| w.0))
        .collect();
    let point_credits: Vec<Option<Component>> = std::iter::repeat_n(None, gather.shading_points.len())
        .chain(gather.walk_points.iter().map(|w| Some(w.1)))
        .collect();
    let segments: Vec<MediaSegment> = [&gather.media_segments[..], &gather.walk_segments[..]].concat();
    times.records = Records {
        shading_points: gather.shading_points.len() as u64,
        media_segments: gather.media_segments.len() as u64,
        walk_points: gather.walk_points.len() as u64,
        walk_segments: gather.walk_segments.len() as u64,
    };
    let segment_credits: Vec<Option<Component>> = std::iter::repeat_n(None, gather.media_segments.len())
        .chain(std::iter::repeat_n(Some(Component::Lmm), gather.walk_segments.len()))
        .collect();
    let light_tracer = LightTracerSettings {
        inject_nan: settings.inject_nan,
        ..Default::default()
    };
    let lights = trace_light_paths(ts, &light_tracer, settings.light_paths_per_pass, seed, pass);
    let r2 = pass_squared_radius(settings.radius, settings, pass);
    // The caustics' own light paths, one set for the photons and one for the beams (their
    // VPLs and VRLs are not used), each with its own count M in the estimates and eq. 11.
    let caustic_set = |paths: u32, salt: u32, keep: Keep| {
        if paths > 0 {
            let seed_c = beamlight_scene::rng::pcg_hash(seed ^ salt);
            let tracer = LightTracerSettings { keep, ..light_tracer };
            trace_light_paths(ts, &tracer, paths, seed_c, pass)
        } else {
            Default::default()
        }
    };
    let on = |c: Component| settings.components[c as usize];
    let caustic_paths = settings.caustic_paths.unwrap_or_else(|| default_caustic_paths(w, h));
    // A caustic component the pass does not compute traces no light paths.
    let paths_for = |c: Component, paths: u32| if on(c) { paths } else { 0 };
    let (photon_lights, beam_lights) = (
        caustic_set(
            paths_for(Component::CausticSurface, caustic_paths),
            0x1656_67b1,
            Keep::CAUSTIC_PHOTONS,
        ),
        caustic_set(
            paths_for(Component::CausticVolume, settings.beam_paths),
            0x3c6e_f372,
            Keep::PHOTON_BEAMS,
        ),
    );
    let (m_photons, m_beams) = (photon_lights.paths.max(1) as f32, beam_lights.paths.max(1) as f32);
    let photon_r2 = paths_squared_radius(settings.photon_radius, settings.alpha, caustic_paths, pass);
    let beam_r2 = paths_squared_radius(settings.photon_radius, settings.alpha, settings.beam_paths, pass);
    times.discarded.light_paths =
        (lights.nonfinite_paths + photon_lights.nonfinite_paths + beam_lights.nonfinite_paths) as u64;
    let photons = PhotonMap::build(&photon_lights.caustic_photons, photon_r2);
    let beams = BeamMap::build(&beam_lights.photon_beams, beam_r2);
    let beams_on = settings.lights == VirtualLights::Beams;
    // The walls next to each VPL, found once for all the records that gather from it.
    let vpl_walls = if beams_on {
        vbl::vpl_walls_all(ts, &lights.vpls, r2)
    } else {
        Vec::new()
    };
    times.trace = clock.elapsed();
    times.light_side = times.trace - camera_done;
    // With light selection, each record draws `k` lights per component from the pass's trees.
    let r = r2.max(0.0).sqrt();
    let media_drawing = settings
        .media_drawing
        .drawing(lights.vrls.len(), segments.len())
        .map_err(GpuError::Inputs)?;
    let selection = match (beams_on, settings.light_samples) {
        (true, Some(k)) => Some(Selection {
            k: k.max(1),
            k_media: settings.media_light_samples.unwrap_or(k).max(1),
            media_drawing,
            vsl_drawing: settings.vsl_drawing.drawing(lights.vpls.len()),
            r,
            pair_seed: streams::pair_seed(seed),
            pass,
            vsls: LightTree::over_vsls(&ts.scene, &lights.vpls),
            vbls: LightTree::over_vbls(&ts.scene, &lights.vrls, r),
        }),
        _ => None,
    };
    let kernels = gpu_kernels(settings.lights);
    let gpu = gpu.filter(|_| gpu_has_kernels(settings.lights));
    // The GPU kernels a pass runs: those of the components it computes, or of one a walk
    // record credits.
    let run_kernels: [bool; KERNELS] = std::array::from_fn(|k| {
        let kernel = GatherKernel::ALL[k];
        let Some(i) = kernels.iter().position(|&x| x == kernel) else {
            return false;
        };
        let credits = if kernel.on_surfaces() {
            &point_credits
        } else {
            &segment_credits
        };
        gpu.is_some() && (on(KERNEL_COMPONENTS[i]) || credits.iter().any(|c| c.is_some_and(on)))
    });
    // The GPU's VSL kernels descend the tree: a flat draw asked for cannot run there.
    let vsl_on_gpu = run_kernels[GatherKernel::VslSurface as usize] || run_kernels[GatherKernel::VslMedia as usize];
    if vsl_on_gpu && settings.vsl_drawing == VslDraw::Flat && selection.is_some() {
        return Err(GpuError::Inputs(
            "--vsl-draw flat runs on the CPU only (the GPU's VSL kernels descend the light tree): \
             use --vsl-draw auto or descent with a GPU, or --backend cpu"
                .into(),
        ));
    }
    // A flat `Lmm` draw on the GPU draws by masses weighed here (see `GatherInputs`); the
    // CPU's gathers weigh theirs group by group.
    let clock = Instant::now();
    let media_masses = match &selection {
        Some(sel) if run_kernels[GatherKernel::VblMedia as usize] && media_drawing == Drawing::Flat => sel
            .vbls
            .group_masses(segments.len(), sel.r, |i| flat_draw_receiver(&ts.scene, &segments[i])),
        _ => Vec::new(),
    };
    if !media_masses.is_empty() {
        times.component_cpu[Component::Lmm as usize] +=
            clock.elapsed().as_secs_f64() * rayon::current_num_threads() as f64;
    }
    // What the virtual-light gathers read, on the GPU or on the CPU.
    let inputs = GatherInputs {
        shading_points: &points,
        media_segments: &segments,
        vpls: &lights.vpls,
        vpl_walls: &vpl_walls,
        vrls: &lights.vrls,
        paths: lights.paths,
        pair_seed: streams::pair_seed(seed),
        pass,
        clamp: settings.clamp,
        radius2: r2,
        vbl: settings.vbl,
        light_samples: selection.as_ref().map_or(0, |s| s.k),
        media_light_samples: selection.as_ref().map_or(0, |s| s.k_media),
        media_drawing,
        media_masses: &media_masses,
        inject_nan: settings.inject_nan,
        vsl_tree: selection.as_ref().map_or(&[], |s| &s.vsls.nodes),
        vbl_tree: selection.as_ref().map_or(&[], |s| &s.vbls.nodes),
    };
    let pending = match gpu {
        Some(g) => Some(g.gathers.submit(&g.gpu, &g.scene, &ts.scene, &inputs, run_kernels)?),
        None => None,
    };
    let clock = Instant::now();
    // Direct light: the gather's camera sample and `direct_samples − 1` more of its own.
    let direct_samples = settings.direct_samples.max(1);
    let direct = &mut out[Component::Direct as usize];
    let mut discarded = 0;
    for k in 0..if on(Component::Direct) { direct_samples } else { 0 } {
        if k == 0 {
            discarded += direct_light(ts, &gather, seed, pass, settings.inject_nan, direct);
            continue;
        }
        let seed_k = direct_seed(seed, k);
        let direct_only = CameraPathSettings {
            walks: false,
            ..Default::default()
        };
        let extra = trace_camera_pixels(ts, &direct_only, w, h, pixels, seed_k, pass);
        discarded += direct_light(ts, &extra, seed_k, pass, false, direct);
    }
    times.discarded.estimates[Component::Direct as usize] = discarded;
    let scale = 1.0 / direct_samples as f32;
    direct.iter_mut().for_each(|v| *v *= scale);
    times.component_cpu[Component::Direct as usize] =
        clock.elapsed().as_secs_f64() * rayon::current_num_threads() as f64;
    // Caustics keep one stream per record; each (record, virtual light) pair has its own
    // ([`streams`]), which the GPU kernels draw from too.
    let stream = |kind: u32, i: usize| Sampler::new(seed ^ 0x7f4a_7c15, pass, (i as u32).wrapping_mul(2) + kind);
    let computed = settings.components;
    // Each gather record against every virtual light (or those it draws): the sum over a
    // light set divided by its path count M is the per-pass estimate.
    let gathers = PassGathers {
        ts,
        inputs: &inputs,
        seed,
        computed,
        virtual_lights: pending.is_none(),
        selection: selection.as_ref(),
        beams: beams_on,
    };
    let photon_lookup = |_: usize, sp: &ShadingPoint| photons.radiance(ts, sp) / m_photons;
    let beam_lookup = |i: usize, seg: &MediaSegment| beams.radiance(ts, seg, &mut stream(1, i)) / m_beams;
    let at_points = gathers.estimate(
        inputs.shading_points,
        &point_credits,
        (!photons.is_empty()).then_some(&photon_lookup as CausticLookup<ShadingPoint>),
    );
    let along_segments = gathers.estimate(
        inputs.media_segments,
        &segment_credits,
        (!beams.is_empty()).then_some(&beam_lookup as CausticLookup<MediaSegment>),
    );
    for e in at_points.into_iter().chain(along_segments) {
        for (k, v) in e.value.into_iter().enumerate() {
            out[k][e.pixel as usize] += v;
            times.component_cpu[k] += e.seconds[k];
            times.discarded.estimates[k] += e.discarded[k];
        }
    }
    times.cpu_estimates = clock.elapsed();
    Ok(PassInFlight {
        pass,
        out,
        pending,
        kernels,
        point_pixels: points.iter().map(|sp| sp.pixel).collect(),
        segment_pixels: segments.iter().map(|seg| seg.pixel).collect(),
        point_credits,
        segment_credits,
        computed,
        times,
    })
}

/// The seed of direct light's `k`-th extra camera sample (k ≥ 1) of a render with `seed`.
fn direct_seed(seed: u32, k: u32) -> u32 {
    beamlight_scene::rng::pcg_hash(seed ^ 0x2545_f491).wrapping_add(k)
}

/// Adds one camera sample's direct light to `out`, per pixel: emission seen directly (also
/// through specular chains) and next-event estimation at each of its records, whose streams
/// are keyed by `seed`. Returns how many estimates it discarded ([`admit`]); `inject_nan`
/// poisons the first record's ([`ManyLightSettings::inject_nan`]).
fn direct_light(ts: &TraceScene, gather: &GatherSet, seed: u32, pass: u32, inject_nan: bool, out: &mut [Rgb]) -> u64 {
    let stream = |kind: u32, i: usize| direct_stream(seed, pass, kind, i);
    for (o, e) in out.iter_mut().zip(&gather.emitted) {
        *o += *e;
    }
    let at_points: Vec<(u32, Rgb)> = gather
        .shading_points
        .par_iter()
        .enumerate()
        .map(|(i, sp)| (sp.pixel, direct::direct_at_surface(ts, sp, &mut stream(0, i))))
        .collect();
    let along_segments: Vec<(u32, Rgb)> = gather
        .media_segments
        .par_iter()
        .enumerate()
        .map(|(i, seg)| (seg.pixel, direct::direct_in_medium(ts, seg, &mut stream(1, i))))
        .collect();
    let mut discarded = 0;
    for (i, (pixel, v)) in at_points.into_iter().chain(along_segments).enumerate() {
        out[pixel as usize] += admit(injected(v, inject_nan && i == 0), &mut discarded);
    }
    discarded
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `auto` draws flat within both caps and descends beyond either; the explicit settings
    /// ignore them, but a flat draw asked for beyond [`FLAT_EXPLICIT_MAX_MASSES`] is an error
    /// naming the flag (made to fail by letting `Flat` through: the last check).
    #[test]
    fn auto_media_draw_keeps_to_its_caps() {
        let (vbls, segments) = (220, 96 * 96);
        assert_eq!(MediaDraw::Auto.drawing(vbls, segments), Ok(Drawing::Flat));
        assert_eq!(MediaDraw::Auto.drawing(FLAT_MAX_VBLS, 16), Ok(Drawing::Flat));
        assert_eq!(MediaDraw::Auto.drawing(FLAT_MAX_VBLS + 1, 16), Ok(Drawing::Descent));
        // 1280×720 with one segment a pixel: 57 600 groups.
        let hd = 1280 * 720;
        assert_eq!(MediaDraw::Auto.drawing(580, hd), Ok(Drawing::Flat));
        assert_eq!(MediaDraw::Auto.drawing(600, hd), Ok(Drawing::Descent));
        assert_eq!(MediaDraw::Flat.drawing(FLAT_MAX_VBLS + 1, hd), Ok(Drawing::Flat));
        assert_eq!(MediaDraw::Descent.drawing(vbls, segments), Ok(Drawing::Descent));
        assert_eq!(MediaDraw::Descent.drawing(1 << 20, 4 * hd), Ok(Drawing::Descent));
        // 57 600 groups × 4 661 VBLs: 2²⁸ and a few.
        let refused = MediaDraw::Flat.drawing(4661, hd).unwrap_err();
        assert!(
            refused.contains("--media-light-draw flat") && refused.contains("268473600"),
            "{refused}"
        );
    }
}
