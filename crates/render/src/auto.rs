//! `--method auto`: each transport component from whichever estimator lowers its error fastest.
//!
//! The path tracer (`pt`) and progressive virtual beam lights (`vbl`) split every path into
//! the same components ([`Component`]), and each component is its own integral, so the two
//! estimates of a component can be combined. `auto` keeps both estimators' running sums apart,
//! per component, and
//! * **combines** them per component with one weight each, inversely proportional to each
//!   estimator's estimated error in the image's relative error (`compare`'s relMSE): the
//!   variance of its pixels' means (from the films' sums of squares) and, for `vbl`, a
//!   squared-bias term, the part of the squared difference between the two image means that
//!   their variances do not explain (the blur of `vbl`'s radius loses some light, issue 19).
//!   One weight per component, not per pixel or tile: the weights are estimated from the same
//!   samples they weigh, and `vbl`'s first passes are heavy-tailed (a few bright virtual
//!   lights), so a tile whose passes missed them looks both darker and less noisy and would be
//!   trusted more — measured, 8×8-pixel tiles after 2–5 passes left `Lsm` and `Lss` 5 % dark
//!   in the glossy fog box. Pooled over the image, that correlation is negligible; and `vbl`
//!   gets no weight before [`MIN_VBL_PASSES`] passes;
//! * **schedules** the time: after measuring both (the first steps run each), every step goes
//!   to a `pt` slice or to a `vbl` pass over the components whose own share of a pass lowers
//!   the combined error faster per second than the same time given to `pt` would. The
//!   reduction comes from the error model above with the measured costs: seconds per `pt`
//!   sample and, per `vbl` component, its estimator's seconds per pass plus a share of the
//!   pass's tracing.
//!
//! **Consistency.** Both estimators converge to the true component (the path tracer is
//! unbiased; `vbl`'s radius shrinks by eq. 11), and the combination is a convex one of the two
//! with weights in [0, 1], so it converges too, whatever the weights. A bias `vbl` still has is
//! seen as a growing squared difference against the shrinking variances, and its weight falls.
//!
//! **Caustics come from the photon estimators** (`vbl`'s progressive photon maps and beams)
//! alone. The path tracer reaches a caustic only when a sampled direction happens to hit an
//! emitter through the mirror or glass (next-event estimation cannot cross a delta surface),
//! so its estimate is heavy-tailed: behind glass a small light is found by few samples of
//! large value, and the sample variance cannot show the light not found yet. Weighted by that
//! variance, it was trusted too early: in a fog box whose 0.1-wide light shines through a glass
//! ball, `auto` ended at 1.6× `vbl`'s error after 60 s (issue 32). The photon estimators exist
//! for these paths (light traced from the light's side), and the path tracer restricted away
//! from them spends nothing on them.
//!
//! **Components the path tracer cannot reach** come from `vbl` alone: with a point, spot or
//! directional light and mirrors or glass in the scene, paths that leave the delta light
//! through a delta surface are beyond the path tracer (it can neither hit the light nor connect
//! to it through the surface), and they feed the caustics and every indirect component (the
//! caustic on a floor lights the walls). Its estimate of those components then lacks light
//! with no variance to show it, so it must not be mixed in. Only `direct` (next-event
//! estimation straight to the light) stays with both.
//!
//! With a time budget the schedule follows measured costs, so it differs from run to run; with
//! a pass budget (`--passes N`) it is fixed, N rounds of one `vbl` pass over every component and
//! [`PT_SPP_PER_ROUND`] path-traced samples per pixel, so the same seed gives the same image.
//! Checkpoints and pass ranges keep both estimators' sums ([`AutoSums`]), which add up; a
//! merge combines them again.
use crate::{
    Film, Image,
    components::SceneFeatures,
    film::mean_and_variance,
    many_lights::{self, Discards, ManyLightSettings, PassTimes},
    progressive::{Budget, Progress, RenderOptions, RenderResult, path_trace_pass},
};
use beamlight_scene::Rgb;
use beamlight_trace::{TraceScene, components::Component, pt::PathTracerSettings};
use rayon::prelude::*;
use std::time::{Duration, Instant};

const N: usize = Component::ALL.len();
/// `vbl` passes before its estimate of a component gets any weight: the variance of two or
/// three heavy-tailed passes says too little.
pub const MIN_VBL_PASSES: u64 = 4;
/// How often the combined films are refreshed for progress with a time budget.
const REFRESH: Duration = Duration::from_millis(500);
/// The largest share of a time budget spent measuring `vbl` before the schedule weighs it.
const EXPLORE_SHARE: f64 = 0.1;
/// Path-traced samples per pixel per round with a pass budget.
pub const PT_SPP_PER_ROUND: u32 = 16;
/// The seed of `auto`'s `vbl` passes in a render with `seed`: derived with a salt, so that
/// the two estimators' random streams are independent (their errors must not correlate).
pub fn vbl_seed(seed: u32) -> u32 {
    beamlight_scene::rng::pcg_hash(seed ^ 0x6a09_e667)
}

/// Where each component's estimate came from: what `--stats`, `--stats-json` and the EXR
/// header report.
#[derive(Clone, Debug, Default)]
pub struct AutoReport {
    /// Path-traced samples per pixel that estimated each component (the path tracer runs
    /// restricted to the components it serves best, [`PathTracerSettings::components`]), and
    /// the path tracer's seconds in all.
    pub pt_spp: [u64; N],
    pub pt_seconds: f64,
    /// `vbl` passes that computed each component, in [`Component::ALL`] order.
    pub vbl_passes: [u64; N],
    /// Seconds of `vbl` passes in all, and per component its estimator's share (the rest of
    /// a pass, tracing, is shared).
    pub vbl_seconds: f64,
    pub vbl_component_seconds: [f64; N],
    /// `vbl`'s weight per component, one for the whole image (0: all `pt`).
    pub vbl_weight: [f64; N],
    /// Components the scene can produce.
    pub needed: [bool; N],
    /// Components only `vbl` can estimate (see the module documentation).
    pub vbl_only: [bool; N],
    /// The render's running sums, for its accumulators (set in the finished render's
    /// report; during the render [`Progress::auto_sums`] lends them).
    pub sums: Option<AutoSums>,
}

impl AutoReport {
    /// The path tracer's seconds, then one line per component the scene can produce, e.g.
    /// `Lsm: pt 512 spp, vbl 20 passes (1.2 s), vbl weight 0.38`.
    pub fn lines(&self) -> Vec<String> {
        let pt = format!("pt: {:.2} s in all", self.pt_seconds);
        std::iter::once(pt)
            .chain(
                Component::ALL
                    .iter()
                    .enumerate()
                    .filter(|(k, _)| self.needed[*k])
                    .map(|(k, c)| {
                        format!(
                            "{}: pt {} spp{}, vbl {} passes ({:.2} s), vbl weight {:.2}",
                            c.name(),
                            self.pt_spp[k],
                            if self.vbl_only[k] {
                                " unused (vbl alone: the caustics, or light from a delta light through glass)"
                            } else {
                                ""
                            },
                            self.vbl_passes[k],
                            self.vbl_component_seconds[k],
                            self.vbl_weight[k]
                        )
                    }),
            )
            .collect()
    }
}

/// Components `auto` takes from `vbl` alone in this scene (see the module documentation): the
/// caustics, always; and with delta lights (punctual glTF lights) and delta surfaces (mirrors,
/// glass), every component but `direct`, since light leaving the light through a delta surface
/// reaches them all and the path tracer cannot follow it.
pub fn vbl_only(ts: &TraceScene) -> [bool; N] {
    let features = SceneFeatures::of(&ts.scene);
    let blind = features.specular_surfaces && !ts.scene.lights.is_empty();
    std::array::from_fn(|k| match Component::ALL[k] {
        Component::CausticSurface | Component::CausticVolume => true,
        Component::Direct => false,
        _ => blind,
    })
}

/// The two estimators' running sums, per component, and their passes' image means: what a
/// checkpoint or a pass range's accumulators hold of an `auto` render (`crate::accum`), and
/// all the combination needs.
#[derive(Clone, Debug)]
pub struct AutoSums {
    pub pt: Vec<Film>,
    pub vbl: Vec<Film>,
    pub pt_means: [PassMeans; N],
    pub vbl_means: [PassMeans; N],
    /// Components the scene can produce, and those only `vbl` can estimate ([`vbl_only`]).
    pub needed: [bool; N],
    pub vbl_only: [bool; N],
    /// The next `pt` sample's and `vbl` pass's index in their global sequences (a pass
    /// range's round r runs `vbl` pass r and `pt` samples from r · [`PT_SPP_PER_ROUND`]).
    pub pt_next: u64,
    pub vbl_next: u64,
}

impl AutoSums {
    /// Nothing accumulated yet, for a render whose first round is `first_round`.
    pub fn new(ts: &TraceScene, w: u32, h: u32, first_round: u64) -> Self {
        let needed_list = SceneFeatures::of(&ts.scene).needed();
        Self {
            pt: (0..N).map(|_| Film::new(w, h)).collect(),
            vbl: (0..N).map(|_| Film::new(w, h)).collect(),
            pt_means: Default::default(),
            vbl_means: Default::default(),
            needed: std::array::from_fn(|k| needed_list.contains(&Component::ALL[k])),
            vbl_only: vbl_only(ts),
            pt_next: first_round * PT_SPP_PER_ROUND as u64,
            vbl_next: first_round,
        }
    }

    /// The components the path tracer estimates: those the scene has, but not those only
    /// `vbl` can reach.
    pub fn pt_serves(&self) -> [bool; N] {
        std::array::from_fn(|k| self.needed[k] && !self.vbl_only[k])
    }

    /// Adds another render's sums (other passes of the same render, as [`Film::add_film`]).
    pub fn add(&mut self, other: &AutoSums) {
        for (a, b) in self
            .pt
            .iter_mut()
            .zip(&other.pt)
            .chain(self.vbl.iter_mut().zip(&other.vbl))
        {
            a.add_film(b);
        }
        for (a, b) in self.pt_means.iter_mut().zip(&other.pt_means) {
            a.add(b);
        }
        for (a, b) in self.vbl_means.iter_mut().zip(&other.vbl_means) {
            a.add(b);
        }
        self.pt_next = self.pt_next.max(other.pt_next);
        self.vbl_next = self.vbl_next.max(other.vbl_next);
    }

    /// The combined image (beauty, then each component in [`Component::ALL`] order) as films
    /// whose means are the combination and whose variances its variance, as if from `passes`
    /// passes; and `vbl`'s weight per component.
    pub fn combined(&self, passes: u64) -> (Film, Vec<Film>, [f64; N]) {
        let (w, h) = (self.pt[0].width, self.pt[0].height);
        let mut c = Combined::new(w, h);
        let mut report = AutoReport::default();
        c.weigh(self, &mut report);
        c.combine(self, &report, passes);
        (c.film, c.components, report.vbl_weight)
    }
}

/// A step of the schedule.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Step {
    /// This many path-traced samples per pixel of these components.
    Pt(u32, [bool; N]),
    /// One `vbl` pass over these components.
    Vbl([bool; N]),
}

/// Measured costs, running means.
#[derive(Default)]
struct Costs {
    /// Per set of components the path tracer was restricted to: its seconds and samples.
    pt: Vec<([bool; N], f64, u64)>,
    /// Per `vbl` pass: the shared part (wall time not in any component's estimator), and per
    /// component its estimator's seconds (CPU seconds over the threads plus GPU kernel seconds)
    /// summed over the passes that computed it.
    vbl_shared: f64,
    vbl_passes: u64,
    vbl_component: [f64; N],
    vbl_component_passes: [u64; N],
}

impl Costs {
    /// Seconds per path-traced sample of the components in `mask`, once measured.
    fn pt_per_spp(&self, mask: &[bool; N]) -> Option<f64> {
        self.pt
            .iter()
            .find(|(m, _, _)| m == mask)
            .map(|(_, seconds, spp)| seconds / (*spp).max(1) as f64)
    }

    fn add_pt(&mut self, mask: &[bool; N], seconds: f64, spp: u64) {
        match self.pt.iter_mut().find(|(m, _, _)| m == mask) {
            Some((_, s, n)) => {
                *s += seconds;
                *n += spp;
            }
            None => self.pt.push((*mask, seconds, spp)),
        }
    }

    fn shared(&self) -> f64 {
        self.vbl_shared / self.vbl_passes.max(1) as f64
    }

    fn component(&self, k: usize) -> f64 {
        self.vbl_component[k] / self.vbl_component_passes[k].max(1) as f64
    }

    fn add_vbl(&mut self, times: &PassTimes, wall: f64, computed: &[bool; N]) {
        let threads = rayon::current_num_threads() as f64;
        let mut busy = [0f64; N];
        for (k, b) in busy.iter_mut().enumerate() {
            *b = times.component_cpu[k] / threads;
        }
        let kernels = many_lights::gpu_kernels(many_lights::VirtualLights::Beams);
        for (kernel, c) in kernels.iter().zip(many_lights::KERNEL_COMPONENTS) {
            busy[c as usize] += times.kernels[*kernel as usize];
        }
        // The estimators overlap (CPU and GPU) and run on several threads: scale their shares
        // to the pass's wall time when they add up to more.
        let sum: f64 = busy.iter().sum();
        let scale = if sum > wall { wall / sum } else { 1.0 };
        self.vbl_shared += (wall - sum * scale).max(0.0);
        self.vbl_passes += 1;
        for k in 0..N {
            if computed[k] {
                self.vbl_component[k] += busy[k] * scale;
                self.vbl_component_passes[k] += 1;
            }
        }
    }
}

/// Mean over pixels and channels of one pass, per pass: how much a pass's whole image moves,
/// which the pixels' own variances understate when their errors correlate (a pass's virtual
/// lights reach many pixels at once).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PassMeans {
    pub n: f64,
    pub sum: f64,
    pub sum_sq: f64,
}

impl PassMeans {
    /// Adds another set of passes' means.
    fn add(&mut self, other: &PassMeans) {
        self.n += other.n;
        self.sum += other.sum;
        self.sum_sq += other.sum_sq;
    }

    fn push(&mut self, pass: &[Rgb]) {
        let m = pass.iter().map(|v| (v[0] + v[1] + v[2]) as f64).sum::<f64>() / (3 * pass.len().max(1)) as f64;
        self.n += 1.0;
        self.sum += m;
        self.sum_sq += m * m;
    }

    /// Variance of the mean over the passes so far (0 with fewer than two).
    fn variance_of_mean(&self) -> f64 {
        mean_and_variance(self.n, self.sum, self.sum_sq).1
    }
}

/// One component's error model: each estimator's variance, summed over pixels and channels
/// with each entry's relative-error weight (1/(value² + 0.01), as `compare`'s relMSE), and the
/// squared difference of the two image means that their noise does not explain, likewise
/// weighted, credited by its sign (see [`ComponentError::of`]).
#[derive(Clone, Copy, Debug, Default)]
struct ComponentError {
    pt: f64,
    vbl: f64,
    /// `vbl` darker than `pt`: its blur's loss of light.
    bias2: f64,
    /// `vbl` brighter than `pt`: light the path tracer has not found yet.
    pt_tail2: f64,
}

impl ComponentError {
    /// `pt` from `n_pt` samples and `vbl` from `pass_means`-tracked passes, over an image whose
    /// entries have relative-error weights `relative`.
    fn of(pt: &Film, vbl: &Film, vbl_means: &PassMeans, pt_means: &PassMeans, relative: &[Rgb]) -> Self {
        let mut e = ComponentError::default();
        let (mut diff, mut level, mut level_weighted) = (0f64, 0f64, 0f64);
        for (i, r) in relative.iter().enumerate() {
            for c in 0..3 {
                let r = r[c] as f64;
                let (m, v) = pt.entry(i, c);
                let (mv, vv) = vbl.entry(i, c);
                e.pt += v * r;
                e.vbl += vv * r;
                diff += mv - m;
                level += m;
                level_weighted += m * m * r;
            }
        }
        // Relative difference of the image means, β = Δ/level, minus what the noise of the two
        // image means explains (from their pass-to-pass spread, which includes the pixels'
        // correlation); as a squared error it weighs like the component itself. Its sign says
        // whose error it is. `vbl` darker: its blur loses light where it meets surfaces
        // (issue 19), and it does not gain any, so it is `vbl`'s bias. `vbl` brighter: the path
        // tracer, unbiased but heavy-tailed where light reaches the component only through
        // glass or a mirror (found only by hitting an emitter through it), has not yet drawn the
        // rare bright paths, and its sample variance cannot show them; so it is `pt`'s error.
        let entries = (3 * relative.len()).max(1) as f64;
        if level > 0.0 && vbl.samples >= 2 {
            let beta = diff / level;
            let noise =
                (vbl_means.variance_of_mean() + pt_means.variance_of_mean()) * entries * entries / (level * level);
            let excess = (beta * beta - noise).max(0.0) * level_weighted;
            if diff < 0.0 {
                e.bias2 = excess;
            } else {
                e.pt_tail2 = excess;
            }
        }
        e
    }

    /// `vbl`'s weight: inverse errors; 0 when `vbl` has no estimate yet, 1 when `pt` has none.
    fn vbl_weight(&self, has_vbl: bool, has_pt: bool) -> f64 {
        match (has_vbl, has_pt) {
            (false, _) => 0.0,
            (true, false) => 1.0,
            (true, true) => {
                // A zero or overflowed total (a black component, sums beyond f64) says
                // nothing: pt's estimate, unless only pt's error is infinite.
                let vbl = self.vbl + self.bias2;
                let pt = self.pt + self.pt_tail2;
                let w = pt / (pt + vbl);
                if w.is_finite() {
                    w.clamp(0.0, 1.0)
                } else if pt.is_infinite() && vbl.is_finite() {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }

    /// The combined error with `n_pt` samples of `pt` and `n_vbl` passes of `vbl` (from the
    /// per-sample variances now), and its derivatives by each count.
    /// `pt`'s missing tail is modelled as variance: it shrinks as the samples that find the
    /// light accumulate.
    fn model(&self, n_pt: f64, n_vbl: f64, has_vbl: bool) -> (f64, f64, f64) {
        let s_pt = (self.pt + self.pt_tail2) * n_pt;
        let p = if s_pt > 0.0 { n_pt / s_pt } else { f64::INFINITY };
        if !has_vbl {
            return if s_pt > 0.0 {
                (1.0 / p, -1.0 / (p * p * s_pt), 0.0)
            } else {
                (0.0, 0.0, 0.0)
            };
        }
        let s_vbl = self.vbl * n_vbl;
        let e_vbl = s_vbl / n_vbl + self.bias2;
        let q = if e_vbl > 0.0 { 1.0 / e_vbl } else { f64::INFINITY };
        if !(p + q).is_finite() {
            return (0.0, 0.0, 0.0);
        }
        let mse = 1.0 / (p + q);
        let d_pt = if s_pt > 0.0 { -mse * mse / s_pt } else { 0.0 };
        let d_vbl = -mse * mse * q * q * s_vbl / (n_vbl * n_vbl);
        (mse, d_pt, d_vbl)
    }
}

/// The combined estimate of one component with `vbl`'s weight `a`: its image and the variance
/// of each pixel's estimate.
fn combine(pt: &Film, vbl: &Film, a: f64) -> (Image, Image) {
    let (mp, vp) = (pt.image(), pt.variance_of_mean());
    let (mv, vv) = (vbl.image(), vbl.variance_of_mean());
    let a = a as f32;
    let mut image = Image::new(pt.width, pt.height);
    let mut variance = Image::new(pt.width, pt.height);
    for i in 0..image.pixels.len() {
        image.pixels[i] = mp.pixels[i] * (1.0 - a) + mv.pixels[i] * a;
        variance.pixels[i] = vp.pixels[i] * (1.0 - a) * (1.0 - a) + vv.pixels[i] * a * a;
    }
    (image, variance)
}

/// Renders with `--method auto` (see the module documentation). `vbl` holds the resolved
/// settings of the `vbl` passes; `resume`, the sums and step count of a checkpoint to
/// continue, and `discarded` its estimates discarded so far.
pub fn render(
    ts: &TraceScene,
    opts: &RenderOptions,
    vbl: &ManyLightSettings,
    resume: Option<(&AutoSums, u64)>,
    mut discarded: Discards,
    mut on_pass: impl FnMut(&Progress) -> bool,
) -> Result<RenderResult, String> {
    let (w, h) = (opts.width, opts.height);
    let pixels = (w * h) as usize;
    let mut est = match resume {
        Some((sums, _)) => {
            if (sums.pt[0].width, sums.pt[0].height) != (w, h) {
                return Err("the checkpoint holds a different image size".into());
            }
            sums.clone()
        }
        None => AutoSums::new(ts, w, h, opts.first_pass),
    };
    let (needed, vbl_only) = (est.needed, est.vbl_only);
    let mut costs = Costs::default();
    let mut report = AutoReport {
        needed,
        vbl_only,
        pt_spp: std::array::from_fn(|k| est.pt[k].samples),
        vbl_passes: std::array::from_fn(|k| est.vbl[k].samples),
        ..Default::default()
    };
    let vbl_seed = vbl_seed(opts.seed);
    let gpu = opts.gpu.as_deref();
    let started = Instant::now();
    let total = match opts.budget {
        Budget::Passes(n) => Some(n),
        Budget::Time(_) => None,
    };
    let mut beauty = vec![Rgb::ZERO; pixels];
    let mut pt_components = vec![vec![Rgb::ZERO; pixels]; N];
    let mut vbl_out: [Vec<Rgb>; N] = std::array::from_fn(|_| vec![Rgb::ZERO; pixels]);
    let mut pass_times = Vec::new();
    let mut steps = 0u64;
    // Steps of the checkpoint continued: the combined films count every step.
    let passes_before = resume.map_or(0, |(_, passes)| passes);
    let mut combined = Combined::new(w, h);
    let mut last_combined = Instant::now();
    loop {
        let plan: Vec<Step> = match opts.budget {
            Budget::Passes(n) if steps >= n => break,
            Budget::Passes(_) => round_steps(&est, est.vbl_next),
            Budget::Time(limit) => {
                let left = limit.saturating_sub(opts.start.elapsed()).as_secs_f64();
                match next_step(&est, &costs, &combined, limit, left) {
                    Some(step) if steps == 0 || step_seconds(step, &costs) <= left => vec![step],
                    // What is left fits only a shorter `pt` slice, if anything; with no
                    // measured cost (nothing to render: a scene without light), one sample.
                    _ => {
                        let all = est.pt_serves();
                        let k = match costs.pt_per_spp(&all) {
                            None => u32::from(steps == 0),
                            Some(c) => (left / c.max(1e-9)).floor().min(u32::MAX as f64) as u32,
                        };
                        if k == 0 {
                            break;
                        }
                        vec![Step::Pt(k, all)]
                    }
                }
            }
        };
        for step in plan {
            let clock = Instant::now();
            match step {
                Step::Pt(k, mask) => {
                    let settings = PathTracerSettings {
                        components: mask,
                        ..opts.path_tracer
                    };
                    for _ in 0..k {
                        let pass = est.pt_next as u32;
                        est.pt_next += 1;
                        path_trace_pass(ts, &settings, w, h, opts.seed, pass, &mut beauty, &mut pt_components);
                        // Seven films per sample cost about a tenth of a 96² sample on one
                        // thread: the ones this sample estimated, in parallel.
                        est.pt
                            .par_iter_mut()
                            .zip(est.pt_means.par_iter_mut())
                            .zip(pt_components.par_iter())
                            .enumerate()
                            .filter(|(k, _)| mask[*k])
                            .for_each(|(_, ((film, means), b))| {
                                film.add_pass(b);
                                means.push(b);
                            });
                        for (n, _) in report.pt_spp.iter_mut().zip(mask).filter(|(_, m)| *m) {
                            *n += 1;
                        }
                    }
                    let s = clock.elapsed().as_secs_f64();
                    // The render's first slice pays for warming up (threads starting, memory
                    // first touched): it measured twice the cost of later ones. Not a cost.
                    if report.pt_seconds > 0.0 {
                        costs.add_pt(&mask, s, k as u64);
                    }
                    report.pt_seconds += s;
                }
                Step::Vbl(mask) => {
                    let settings = ManyLightSettings {
                        components: mask,
                        ..*vbl
                    };
                    let pass = est.vbl_next as u32;
                    est.vbl_next += 1;
                    let mut times = many_lights::start_pass(ts, &settings, w, h, vbl_seed, pass, gpu)
                        .and_then(|p| p.finish(gpu, &mut vbl_out))
                        .map_err(|e| format!("vbl pass {pass} on the GPU: {e}"))?;
                    let wall = clock.elapsed();
                    times.wall = wall;
                    for k in 0..N {
                        if mask[k] {
                            est.vbl[k].add_pass(&vbl_out[k]);
                            est.vbl_means[k].push(&vbl_out[k]);
                            report.vbl_passes[k] += 1;
                        }
                    }
                    discarded.add(&times.discarded);
                    costs.add_vbl(&times, wall.as_secs_f64(), &mask);
                    report.vbl_seconds += wall.as_secs_f64();
                    pass_times.push(times);
                }
            }
        }
        steps += 1;
        report.vbl_component_seconds = costs.vbl_component;
        combined.weigh(&est, &mut report);
        // The combined films cost a few image passes: after each round of a pass budget, but
        // at most twice a second with a time budget (progress lines and `--write-every` do not
        // need more). The result is always up to date.
        if total.is_some() || last_combined.elapsed() >= REFRESH {
            combined.combine(&est, &report, passes_before + steps);
            last_combined = Instant::now();
        }
        let go_on = on_pass(&Progress {
            passes: steps,
            total,
            film: &combined.film,
            components: &combined.components,
            elapsed: started.elapsed(),
            discarded,
            auto: Some(&report),
            auto_sums: Some(&est),
        });
        if !go_on {
            break;
        }
    }
    combined.combine(&est, &report, passes_before + steps);
    // Samples the films dropped as non-finite: a bug if ever non-zero, reported with the image.
    combined.film.rejected = est.pt.iter().chain(&est.vbl).map(|f| f.rejected).sum();
    report.sums = Some(est);
    Ok(RenderResult {
        film: combined.film,
        components: if opts.components {
            combined.components
        } else {
            Vec::new()
        },
        passes: steps,
        elapsed: started.elapsed(),
        pass_times,
        auto: Some(report),
        discarded,
    })
}

/// The combined estimate, as films whose means are the combination and whose variances are
/// its estimated variance (so that every consumer of a film reads it as usual), and the
/// per-component errors the schedule works from.
struct Combined {
    film: Film,
    components: Vec<Film>,
    errors: [ComponentError; N],
}

impl Combined {
    fn new(w: u32, h: u32) -> Self {
        Self {
            film: Film::new(w, h),
            components: (0..N).map(|_| Film::new(w, h)).collect(),
            errors: Default::default(),
        }
    }

    /// The error model and `vbl`'s weight of every component, from the estimates now.
    fn weigh(&mut self, est: &AutoSums, report: &mut AutoReport) {
        let (needed, vbl_only) = (&est.needed, &est.vbl_only);
        // Each pixel's relative-error weight 1/(b² + 0.01), with b the beauty from the smaller
        // of the two estimates of each component where both have one. Not from the path
        // tracer's alone: where it is heavy-tailed (light through glass), a pixel that drew a
        // rare bright path would divide its own variance by its own square and hide the very
        // noise that makes it a firefly (measured: `pt`'s weight in a glass-ball fog box
        // stayed at half where its error was 20× `vbl`'s). The smaller value damps the outliers
        // of either estimator alike (`vbl`'s early passes have bright virtual lights), and a
        // common scale of the weights does not change how the two compare.
        let pixels = self.film.width as usize * self.film.height as usize;
        let relative: Vec<Rgb> = (0..pixels)
            .map(|i| {
                let b = |c: usize| {
                    (0..N)
                        .map(|k| {
                            let pt = (est.pt[k].samples > 0 && !vbl_only[k]).then(|| est.pt[k].entry(i, c).0);
                            let vbl = (est.vbl[k].samples > 0).then(|| est.vbl[k].entry(i, c).0);
                            match (pt, vbl) {
                                (Some(p), Some(v)) => p.min(v),
                                (p, v) => p.or(v).unwrap_or(0.0),
                            }
                        })
                        .sum::<f64>() as f32
                };
                let b = Rgb::new(b(0), b(1), b(2));
                Rgb::ONE / (b * b + Rgb::splat(0.01))
            })
            .collect();
        for k in 0..N {
            let (pt, vbl) = (&est.pt[k], &est.vbl[k]);
            if !needed[k] {
                self.errors[k] = ComponentError::default();
                continue;
            }
            self.errors[k] = ComponentError::of(pt, vbl, &est.vbl_means[k], &est.pt_means[k], &relative);
            let has_vbl = vbl.samples >= MIN_VBL_PASSES || (vbl_only[k] && vbl.samples > 0);
            let has_pt = pt.samples >= 2 && !vbl_only[k];
            report.vbl_weight[k] = self.errors[k].vbl_weight(has_vbl, has_pt);
        }
    }

    /// The combined films with the weights of the last [`Combined::weigh`], as if from
    /// `samples` passes.
    fn combine(&mut self, est: &AutoSums, report: &AutoReport, samples: u64) {
        let (w, h) = (self.film.width, self.film.height);
        let needed = &est.needed;
        let mut total = Image::new(w, h);
        let mut total_var = Image::new(w, h);
        for k in 0..N {
            if !needed[k] {
                self.components[k] = Film::new(w, h);
                continue;
            }
            let (image, variance) = combine(&est.pt[k], &est.vbl[k], report.vbl_weight[k]);
            for i in 0..image.pixels.len() {
                total.pixels[i] += image.pixels[i];
                total_var.pixels[i] += variance.pixels[i];
            }
            self.components[k] = Film::from_estimate(&image, &variance, samples);
        }
        self.film = Film::from_estimate(&total, &total_var, samples);
    }
}

/// Round `r` of a pass budget's fixed schedule: one `vbl` pass over every component, then
/// [`PT_SPP_PER_ROUND`] path-traced samples, half of them over all the components `pt`
/// serves and half over one of them alone, each in turn (so that the restricted path tracer
/// takes part in a reproducible render, too).
fn round_steps(est: &AutoSums, r: u64) -> Vec<Step> {
    let serves = est.pt_serves();
    let served: Vec<usize> = (0..N).filter(|&k| serves[k]).collect();
    let mut steps = vec![Step::Vbl(est.needed)];
    if served.len() > 1 {
        let alone = served[(r % served.len() as u64) as usize];
        steps.push(Step::Pt(PT_SPP_PER_ROUND / 2, serves));
        steps.push(Step::Pt(PT_SPP_PER_ROUND / 2, std::array::from_fn(|k| k == alone)));
    } else {
        steps.push(Step::Pt(PT_SPP_PER_ROUND, serves));
    }
    steps
}

/// Predicted seconds of a step.
fn step_seconds(step: Step, costs: &Costs) -> f64 {
    match step {
        Step::Pt(k, mask) => k as f64 * costs.pt_per_spp(&mask).unwrap_or(0.0),
        Step::Vbl(mask) => costs.shared() + (0..N).filter(|&k| mask[k]).map(|k| costs.component(k)).sum::<f64>(),
    }
}

/// The next step with a time budget: first measure both estimators (two `pt` samples of
/// every component it serves, two of each kind of restricted slice, then
/// [`MIN_VBL_PASSES`] `vbl` passes over every component, so that each has a variance and a
/// cost), then whichever lowers the modelled error fastest per second: a `pt` slice over all
/// its components, over the medium-first or the surface-first ones, or over one alone
/// (restricted, its samples are cheaper and, in homogeneous media, less noisy:
/// `pt::PathTracerSettings::components`), or a `vbl` pass over the components worth their
/// own seconds.
fn next_step(est: &AutoSums, costs: &Costs, combined: &Combined, limit: Duration, left: f64) -> Option<Step> {
    let (needed, vbl_only) = (&est.needed, &est.vbl_only);
    let serves = est.pt_serves();
    let slice = (limit.as_secs_f64() / 32.0).clamp(0.05, 1.0).min(left.max(0.0));
    let any_pt = serves.iter().any(|&s| s);
    let any_vbl = needed.iter().any(|&n| n);
    if any_pt && (0..N).any(|k| serves[k] && est.pt[k].samples < 2) {
        return Some(Step::Pt(2, serves));
    }
    // The path tracer's slices: over all its components, over those whose first vertex is in
    // a medium or on a surface (each shares its camera rays), or over one alone.
    let mut slices = vec![serves];
    if serves.iter().filter(|&&s| s).count() > 1 {
        use Component::*;
        for group in [[Lmm, Lms, CausticVolume], [Lsm, Lss, CausticSurface]] {
            let m: [bool; N] = std::array::from_fn(|k| serves[k] && group.contains(&Component::ALL[k]));
            if m.iter().filter(|&&x| x).count() > 1 {
                slices.push(m);
            }
        }
        slices.extend((0..N).filter(|&k| serves[k]).map(|k| std::array::from_fn(|j| j == k)));
    }
    // Each slice's cost, measured once up front.
    if let Some(unmeasured) = slices.iter().find(|m| costs.pt_per_spp(m).is_none()) {
        return Some(Step::Pt(2, *unmeasured));
    }
    // Measuring `vbl` takes at most a tenth of the budget (after its first pass, which shows
    // what a pass costs), unless a component has no other estimator.
    let explore = costs.vbl_passes == 0
        || (0..N).any(|k| needed[k] && vbl_only[k])
        || step_seconds(Step::Vbl(*needed), costs) * MIN_VBL_PASSES as f64 <= EXPLORE_SHARE * limit.as_secs_f64();
    let vbl_runs = est.vbl.iter().map(|f| f.samples).max().unwrap_or(0);
    if any_vbl && vbl_runs < MIN_VBL_PASSES && costs.vbl_passes < MIN_VBL_PASSES && explore {
        return Some(Step::Vbl(*needed));
    }
    // Error reduction per path-traced sample and per `vbl` pass of each component. A sample
    // of a component alone counts as one of a slice over several: it is as noisy or less
    // (its paths carry no other component's light, and in homogeneous media it collides
    // for sure), so the choice below errs towards the slice over all.
    let mut pt_gain = [0f64; N];
    let mut vbl_gain = [0f64; N];
    for k in 0..N {
        if !needed[k] {
            continue;
        }
        let n_vbl = est.vbl[k].samples as f64;
        let e = &combined.errors[k];
        if vbl_only[k] {
            // Only `vbl` serves it: a pass lowers its variance of the mean, s/n, by s/n².
            vbl_gain[k] += e.vbl / n_vbl.max(1.0);
            continue;
        }
        let n_pt = est.pt[k].samples as f64;
        let (_, d_pt, d_vbl) = e.model(n_pt, n_vbl, est.vbl[k].samples >= MIN_VBL_PASSES);
        pt_gain[k] = -d_pt;
        vbl_gain[k] -= d_vbl;
    }
    // The path tracer's best slice, by error reduction per second.
    let per_spp = |m: &[bool; N]| costs.pt_per_spp(m).unwrap_or(0.0).max(1e-9);
    let (pt_best, pt_rate) = slices
        .iter()
        .map(|m| {
            (
                *m,
                (0..N).filter(|&k| m[k]).map(|k| pt_gain[k]).sum::<f64>() / per_spp(m),
            )
        })
        .fold((serves, 0.0), |best, c| if c.1 > best.1 { c } else { best });
    // `vbl` components worth their own seconds against the path tracer's rate.
    let mut mask = [false; N];
    for k in 0..N {
        mask[k] = needed[k] && vbl_gain[k] > pt_rate * costs.component(k).max(1e-6);
    }
    if mask.iter().any(|&m| m) {
        let seconds = step_seconds(Step::Vbl(mask), costs).max(1e-6);
        let gain: f64 = (0..N).filter(|&k| mask[k]).map(|k| vbl_gain[k]).sum();
        if gain / seconds > pt_rate || !any_pt {
            return Some(Step::Vbl(mask));
        }
    }
    if !any_pt {
        return None;
    }
    let spp = ((slice / per_spp(&pt_best)).round() as u32).max(1);
    Some(Step::Pt(spp, pt_best))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A film of `n` passes whose pixel values are `mean ± spread` alternately (so its
    /// per-pixel variance of the mean is spread²·n/(n−1)/n).
    fn film(w: u32, h: u32, n: u64, mean: f32, spread: f32) -> Film {
        let mut f = Film::new(w, h);
        for i in 0..n {
            let v = if i % 2 == 0 { mean + spread } else { mean - spread };
            f.add_pass(&vec![Rgb::splat(v); (w * h) as usize]);
        }
        f
    }

    /// The error model of two films with their pass means tracked.
    fn errors(pt: &Film, vbl: &Film, pt_means: &PassMeans, vbl_means: &PassMeans) -> ComponentError {
        ComponentError::of(
            pt,
            vbl,
            vbl_means,
            pt_means,
            &vec![Rgb::ONE; (pt.width * pt.height) as usize],
        )
    }

    fn means(n: u64, mean: f64, spread: f64) -> PassMeans {
        let mut m = PassMeans::default();
        for i in 0..n {
            let v = if i % 2 == 0 { mean + spread } else { mean - spread };
            m.push(&[Rgb::splat(v as f32)]);
        }
        m
    }

    /// Inverse-variance weights: the less noisy estimator dominates in proportion, and the
    /// combination's variance is the weighted one.
    #[test]
    fn combination_weighs_by_inverse_variance() {
        let (w, h) = (16, 16);
        // Same mean, vbl's variance a quarter of pt's: vbl's weight 4/5.
        let pt = film(w, h, 64, 1.0, 0.4);
        let vbl = film(w, h, 64, 1.0, 0.2);
        let e = errors(&pt, &vbl, &means(64, 1.0, 0.4), &means(64, 1.0, 0.2));
        assert_eq!(e.bias2, 0.0);
        let weight = e.vbl_weight(true, true);
        assert!((weight - 0.8).abs() < 1e-6, "vbl weight {weight}");
        let (image, variance) = combine(&pt, &vbl, weight);
        assert!((image.pixels[17][0] - 1.0).abs() < 1e-6);
        let vp = pt.variance_of_mean().pixels[0][0];
        let expected = vp * 0.2 * 0.2 + vp / 4.0 * 0.8 * 0.8;
        assert!((variance.pixels[0][0] - expected).abs() < 1e-6 * expected);
        // Without a vbl estimate (or before enough passes), pt alone; without pt, vbl alone.
        assert_eq!(e.vbl_weight(false, true), 0.0);
        assert_eq!(e.vbl_weight(true, false), 1.0);
        // A combined film reads back as the estimate it was made from.
        let f = Film::from_estimate(&image, &variance, 64);
        assert!((f.image().pixels[3][1] - image.pixels[3][1]).abs() < 1e-6);
        let v = f.variance_of_mean().pixels[3][1];
        assert!((v - variance.pixels[3][1]).abs() < 1e-4 * variance.pixels[3][1], "{v}");
    }

    /// A biased vbl (its image mean off by far more than both estimates' noise) loses its
    /// weight: the bias term, not the variance, decides; an unbiased one keeps it.
    #[test]
    fn a_biased_estimate_loses_its_weight() {
        let (w, h) = (16, 16);
        let pt = film(w, h, 64, 1.0, 0.4);
        let vbl = film(w, h, 64, 0.8, 0.01);
        let e = errors(&pt, &vbl, &means(64, 1.0, 0.4 / 16.0), &means(64, 0.8, 0.01));
        // Its variance alone would give it 99.9 % of the weight; pt's variance of the mean
        // (0.0025 per entry) against the squared bias (0.04) leaves it 6 %.
        let weight = e.vbl_weight(true, true);
        assert!(weight < 0.1, "a 20 % bias kept vbl's weight at {weight}");
        let (image, _) = combine(&pt, &vbl, weight);
        assert!((image.pixels[0][0] - 1.0).abs() < 0.02, "{}", image.pixels[0][0]);
        // The same difference within the image means' noise (a pass-to-pass spread of the
        // whole image of 2.0, as when a pass's few lights reach every pixel) is not bias.
        let e = errors(&pt, &vbl, &means(64, 1.0, 2.0), &means(64, 0.8, 2.0));
        assert_eq!(e.bias2, 0.0);
        // Unbiased and far more precise: it takes nearly all of the weight.
        let vbl = film(w, h, 64, 1.0, 0.01);
        let e = errors(&pt, &vbl, &means(64, 1.0, 0.4 / 16.0), &means(64, 1.0, 0.01));
        assert!(e.vbl_weight(true, true) > 0.99);
    }

    /// A `vbl` brighter than `pt` by far more than their noise is the path tracer missing
    /// light (heavy tails behind glass), not `vbl`'s bias: `pt`'s error grows and `vbl` keeps
    /// (here gains) its weight; the same difference the other way is `vbl`'s bias.
    #[test]
    fn a_brighter_vbl_is_light_the_path_tracer_missed() {
        let (w, h) = (16, 16);
        // pt looks precise (spread 0.05) but is 20 % dark; vbl is noisier (0.2).
        let pt = film(w, h, 64, 0.8, 0.05);
        let vbl = film(w, h, 64, 1.0, 0.2);
        let e = errors(&pt, &vbl, &means(64, 0.8, 0.05 / 16.0), &means(64, 1.0, 0.2 / 16.0));
        assert_eq!(e.bias2, 0.0);
        assert!(e.pt_tail2 > 0.0, "{e:?}");
        // By variances alone vbl would get 1/17 of the weight; the missing light gives it most.
        let weight = e.vbl_weight(true, true);
        assert!(weight > 0.9, "vbl weight {weight}");
        // Mirrored: vbl 20 % darker than a noisier pt is vbl's bias.
        let e = errors(&vbl, &pt, &means(64, 1.0, 0.2 / 16.0), &means(64, 0.8, 0.05 / 16.0));
        assert_eq!(e.pt_tail2, 0.0);
        assert!(e.bias2 > 0.0 && e.vbl_weight(true, true) < 0.1, "{e:?}");
    }

    /// The error model: with `vbl` absent it is pt's variance of the mean, falling as 1/n;
    /// with both, the harmonic combination, and each count's derivative matches a difference.
    #[test]
    fn error_model_and_its_derivatives() {
        let e = ComponentError {
            pt: 0.5,
            vbl: 0.25,
            bias2: 0.01,
            pt_tail2: 0.0,
        };
        let (mse, d_pt, _) = e.model(100.0, 10.0, false);
        assert!((mse - 0.5).abs() < 1e-12);
        assert!((d_pt + 0.5 / 100.0).abs() < 1e-12, "{d_pt}");
        let (mse, d_pt, d_vbl) = e.model(100.0, 10.0, true);
        assert!((mse - 1.0 / (1.0 / 0.5 + 1.0 / 0.26)).abs() < 1e-12);
        let h = 1e-3;
        // Moving n while the per-sample variance stays put: the model's variance scales as
        // n_then / n.
        let scaled = |n_pt: f64, n_vbl: f64| {
            ComponentError {
                pt: 0.5 * 100.0 / n_pt,
                vbl: 0.25 * 10.0 / n_vbl,
                bias2: 0.01,
                pt_tail2: 0.0,
            }
            .model(n_pt, n_vbl, true)
            .0
        };
        let fd_pt2 = (scaled(100.0 + h, 10.0) - scaled(100.0 - h, 10.0)) / (2.0 * h);
        let fd_vbl = (scaled(100.0, 10.0 + h) - scaled(100.0, 10.0 - h)) / (2.0 * h);
        assert!((d_pt - fd_pt2).abs() < 1e-6 * fd_pt2.abs(), "{d_pt} vs {fd_pt2}");
        assert!((d_vbl - fd_vbl).abs() < 1e-6 * fd_vbl.abs(), "{d_vbl} vs {fd_vbl}");
    }
}
