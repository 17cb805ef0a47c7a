//! How `--method auto` combines its two estimators ([`crate::auto`] decides which runs when):
//! both estimators' running sums per component ([`AutoSums`]), each one's error model
//! (`ComponentError`: its variance, and the part of the two estimates' difference, of the
//! image means and pixel by pixel, their noise does not explain), and the combination of the
//! two with one weight per component, inversely proportional to the errors. The reasons for
//! each choice are in [`crate::auto`]'s documentation.
use crate::{Film, Image, components::SceneFeatures, film::mean_and_variance};
use beamlight_scene::Rgb;
use beamlight_trace::{TraceScene, components::Component};

use crate::source::N;
/// `vbl` passes before its estimate of a component gets any weight: the variance of two or
/// three heavy-tailed passes says too little.
pub const MIN_VBL_PASSES: u64 = 4;

/// Path-traced samples of a component before they are mixed with `vbl`'s estimate of it
/// (alone, with no `vbl` estimate, they count from the first). Where light reaches a
/// component only through glass the path tracer's samples are heavy-tailed, and the variance
/// of a few dozen says as little as that of two or three `vbl` passes: in `lamp_in_glass`
/// (96², 4 s) `Lmm` got `pt` weight 0.04 from 21 samples, and that 4 % carried a firefly
/// that left the component at relMSE 4.8 against another run's (one run in four at that
/// budget). 64 is what a pass budget's schedule path traces in the four rounds after which
/// `vbl` gets its weight ([`crate::auto::PT_SPP_PER_ROUND`] a round). A time budget gives a
/// path-tracing scene's components hundreds in the first second.
pub const MIN_PT_SAMPLES: u64 = 64;

/// Where each component's estimate came from: what `--stats`, `--stats-json` and the EXR
/// header report.
#[derive(Clone, Debug, Default)]
pub struct AutoReport {
    /// Path-traced samples per pixel that estimated each component (the path tracer runs
    /// restricted to the components it serves best, [`beamlight_trace::pt::PathTracerSettings::components`]), and
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
    /// report; during the render [`crate::Progress::auto_sums`] lends them).
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
                                " unused (vbl alone: the caustics, or light the path tracer cannot see behind glass)"
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
/// caustics, always; and every component but `direct` when the path tracer cannot see the
/// lights: with delta lights (punctual glTF lights) and delta surfaces (mirrors, glass), since
/// light leaving a delta light through a delta surface reaches them all and the path tracer
/// cannot follow it; or when most of the lights' power leaves them through glass or a mirror
/// ([`power_through_delta`]), since then next-event estimation reaches little of the light
/// and the rest comes from rare, heavy-tailed hits of an emitter behind the glass.
pub fn vbl_only(ts: &TraceScene) -> [bool; N] {
    let features = SceneFeatures::of(&ts.scene);
    let blind =
        features.specular_surfaces && (!ts.scene.lights.is_empty() || power_through_delta(ts) > LIGHT_BEHIND_GLASS);
    std::array::from_fn(|k| match Component::ALL[k] {
        Component::CausticSurface | Component::CausticVolume => true,
        Component::Direct => false,
        _ => blind,
    })
}

/// The share of the lights' power above which they count as behind glass for [`vbl_only`]:
/// most of it. `lamp_in_glass` and CARS (bulbs inside glass globes) have all of it there; a
/// small light over a glass ball (`caustic_sphere`) sends the ball a few percent, and its
/// other components are the path tracer's to share.
pub const LIGHT_BEHIND_GLASS: f32 = 0.5;

/// Rays from the lights for [`power_through_delta`]: its standard error is at most 0.8 %.
const POWER_RAYS: u32 = 4096;

/// The share of the lights' emitted power whose first surface is a mirror or glass (the
/// light sampler's emission samples, weighted by power; media and invisible medium
/// boundaries are passed through). Light that escapes the scene counts as not behind glass.
/// Deterministic: a fixed sample sequence.
pub fn power_through_delta(ts: &TraceScene) -> f32 {
    let scene = &ts.scene;
    let (mut total, mut behind) = (0.0f64, 0.0f64);
    for i in 0..POWER_RAYS {
        let mut s = beamlight_scene::rng::Sampler::new(0x5eed_91a5, 0, i);
        let Some(e) = ts.lights.sample_emission(scene, &mut s) else {
            continue;
        };
        let power = beamlight_scene::luminance_mean(e.power) as f64;
        if !(power.is_finite() && power > 0.0) {
            continue;
        }
        total += power;
        let mut o = match e.surface {
            Some((tri, _)) => ts.spawn_from_triangle(tri, e.p, e.dir),
            None => e.p,
        };
        // The first surface that has a BSDF (a medium's invisible boundary has none).
        for _ in 0..64 {
            let Some((_, hit)) = ts.intersect(o, e.dir, f32::INFINITY) else {
                break;
            };
            match &ts.material(&hit).bsdf {
                Some(b) => {
                    if b.is_delta() {
                        behind += power;
                    }
                    break;
                }
                None => o = hit.spawn(e.dir),
            }
        }
    }
    if total > 0.0 { (behind / total) as f32 } else { 0.0 }
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
    /// range's round r runs `vbl` pass r and `pt` samples from r · [`crate::auto::PT_SPP_PER_ROUND`]).
    pub pt_next: u64,
    pub vbl_next: u64,
}

impl AutoSums {
    /// Nothing accumulated yet, for a render whose first round is `first_round`.
    pub fn new(ts: &TraceScene, w: u32, h: u32, pt_next: u64, vbl_next: u64) -> Self {
        let needed_list = SceneFeatures::of(&ts.scene).needed();
        Self {
            pt: (0..N).map(|_| Film::new(w, h)).collect(),
            vbl: (0..N).map(|_| Film::new(w, h)).collect(),
            pt_means: Default::default(),
            vbl_means: Default::default(),
            needed: std::array::from_fn(|k| needed_list.contains(&Component::ALL[k])),
            vbl_only: vbl_only(ts),
            pt_next,
            vbl_next,
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
    pub(crate) fn add(&mut self, other: &PassMeans) {
        self.n += other.n;
        self.sum += other.sum;
        self.sum_sq += other.sum_sq;
    }

    pub(crate) fn push(&mut self, pass: &[Rgb]) {
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
/// squared difference of the two estimates that their noise does not explain (of the image
/// means, and pixel by pixel), likewise weighted, credited by the image means' sign (see
/// [`ComponentError::of`]).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct ComponentError {
    pub(crate) pt: f64,
    pub(crate) vbl: f64,
    /// `vbl`'s bias: the light its blur loses (darker than `pt`) or moves between pixels.
    pub(crate) bias2: f64,
    /// `vbl` brighter than `pt`: light the path tracer has not found yet.
    pub(crate) pt_tail2: f64,
}

impl ComponentError {
    /// `pt` from `n_pt` samples and `vbl` from `pass_means`-tracked passes, over an image whose
    /// entries have relative-error weights `relative`; `blurred`: `vbl`'s estimate of the
    /// component gathers within a radius (every component but `direct`).
    pub(crate) fn of(
        pt: &Film,
        vbl: &Film,
        vbl_means: &PassMeans,
        pt_means: &PassMeans,
        relative: &[Rgb],
        blurred: bool,
    ) -> Self {
        let mut e = ComponentError::default();
        let (mut diff, mut level, mut level_weighted) = (0f64, 0f64, 0f64);
        // Σ r ((m_vbl − m_pt)² − var_pt − var_vbl): the two estimates are independent, so each
        // entry's expected squared difference is its squared bias plus the two variances of
        // the mean, and the sum estimates the weighted squared bias pixel by pixel.
        let mut local = 0f64;
        for (i, r) in relative.iter().enumerate() {
            for c in 0..3 {
                let r = r[c] as f64;
                let (m, v) = pt.entry(i, c);
                let (mv, vv) = vbl.entry(i, c);
                e.pt += v * r;
                e.vbl += vv * r;
                diff += mv - m;
                local += ((mv - m) * (mv - m) - v - vv) * r;
                // The level the difference is measured against: the brighter estimate, so
                // that a path tracer that has found none of a component's light (all its
                // samples zero, its variance zero: it would look exact) is judged against the
                // light `vbl` shows instead of against nothing.
                let top = m.max(mv);
                level += top;
                level_weighted += top * top * r;
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
        // The difference pixel by pixel sees what the image means cannot: `vbl`'s blur moves
        // light from bright pixels to dim ones and keeps the image mean (on the Cornell box at
        // 96², 16 s, `vbl`'s squared bias was a quarter of its variance, its image mean
        // within 0.1 % of the reference's; at 193 passes this sum gave a fifth). It is `vbl`'s,
        // unless the image means already say the path tracer is missing light: then its unseen
        // tail is in the pixels' differences too. Only once the path tracer's estimate is
        // weighed ([`MIN_PT_SAMPLES`]): the per-pixel variance of a few heavy-tailed samples is
        // mostly zero, and the sum then reads `vbl`'s whole light as bias (the smoke box's
        // `Lss` at 6 samples: 363 against a variance of 345, 7.8 at 64 samples), and the
        // schedule paid for path-traced samples that got 5 % of the weight. Only where `vbl`
        // blurs: its `direct` is the path tracer's first vertex (a light sample and a BSDF
        // sample, `beamlight_trace::direct`), with no radius to blur with. `caustic_sphere`'s
        // `direct` read 250–300 against variances of 30–40 (not pinned down; the path
        // tracer's rare hits of the light through the glass ball would give it), and the
        // schedule gave the path tracer 1953 samples of it.
        if blurred && vbl.samples >= 2 && pt.samples >= MIN_PT_SAMPLES {
            let local = local.max(0.0);
            if e.pt_tail2 > 0.0 {
                e.pt_tail2 = e.pt_tail2.max(local);
            } else {
                e.bias2 = e.bias2.max(local);
            }
        }
        e
    }

    /// `vbl`'s weight: inverse errors; 0 when `vbl` has no estimate yet, 1 when `pt` has none.
    pub(crate) fn vbl_weight(&self, has_vbl: bool, has_pt: bool) -> f64 {
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

    /// The same error after `more` path-traced samples on top of `n_pt`: its variance of the
    /// mean (and its missing tail, modelled as variance) scaled as the count.
    pub(crate) fn with_more_pt(&self, n_pt: f64, more: f64) -> Self {
        let scale = n_pt / (n_pt + more);
        Self {
            pt: self.pt * scale,
            pt_tail2: self.pt_tail2 * scale,
            ..*self
        }
    }

    /// The combined error with `n_pt` samples of `pt` and `n_vbl` passes of `vbl` (from the
    /// per-sample variances now), and its derivatives by each count.
    /// `pt`'s missing tail is modelled as variance: it shrinks as the samples that find the
    /// light accumulate. `vbl`'s bias shrinks too, as its radius does: by `bias_decay`, the
    /// power of `n_vbl` it falls as (see [`bias_decay`]); 0 holds it fixed.
    pub(crate) fn model(&self, n_pt: f64, n_vbl: f64, has_vbl: bool, bias_decay: f64) -> (f64, f64, f64) {
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
        // d e_vbl / d n_vbl: the variance's −s/n², and the bias's −decay·B²/n.
        let d_e_vbl = -s_vbl / (n_vbl * n_vbl) - bias_decay * self.bias2 / n_vbl;
        let d_vbl = mse * mse * q * q * d_e_vbl;
        (mse, d_pt, d_vbl)
    }
}

/// The power of its passes by which `vbl`'s squared bias falls: 1 − α. The bias is the light
/// its blur loses where a sphere or beam meets a surface (`ComponentError::bias2`), first
/// order in the pass's radius r; the estimate's is the mean over its passes, and with eq. 11's
/// r² ∝ i^(α−1) at pass i that mean falls as n^((α−1)/2), its square as n^(α−1).
pub(crate) fn bias_decay(alpha: f64) -> f64 {
    (1.0 - alpha).clamp(0.0, 1.0)
}

/// Whether each estimator's estimate of a component (from `pt_samples` path-traced samples
/// and `vbl_passes` passes) is weighed: `vbl`'s after [`MIN_VBL_PASSES`] (from its first
/// when it alone serves the component); the path tracer's after [`MIN_PT_SAMPLES`] when
/// `vbl`'s is, and from its second alone (it is then what there is).
pub(crate) fn weighed(pt_samples: u64, vbl_passes: u64, vbl_only: bool) -> (bool, bool) {
    let has_vbl = vbl_passes >= MIN_VBL_PASSES || (vbl_only && vbl_passes > 0);
    let has_pt = !vbl_only && (pt_samples >= MIN_PT_SAMPLES || (!has_vbl && pt_samples >= 2));
    (has_vbl, has_pt)
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

/// The combined estimate, as films whose means are the combination and whose variances are
/// its estimated variance (so that every consumer of a film reads it as usual), and the
/// per-component errors the schedule works from.
pub(crate) struct Combined {
    pub(crate) film: Film,
    pub(crate) components: Vec<Film>,
    pub(crate) errors: [ComponentError; N],
}

impl Combined {
    pub(crate) fn new(w: u32, h: u32) -> Self {
        Self {
            film: Film::new(w, h),
            components: (0..N).map(|_| Film::new(w, h)).collect(),
            errors: Default::default(),
        }
    }

    /// The error model and `vbl`'s weight of every component, from the estimates now.
    pub(crate) fn weigh(&mut self, est: &AutoSums, report: &mut AutoReport) {
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
            let blurred = Component::ALL[k] != Component::Direct;
            self.errors[k] = ComponentError::of(pt, vbl, &est.vbl_means[k], &est.pt_means[k], &relative, blurred);
            let (has_vbl, has_pt) = weighed(pt.samples, vbl.samples, vbl_only[k]);
            report.vbl_weight[k] = self.errors[k].vbl_weight(has_vbl, has_pt);
        }
    }

    /// The combined films with the weights of the last [`Combined::weigh`], as if from
    /// `samples` passes.
    pub(crate) fn combine(&mut self, est: &AutoSums, report: &AutoReport, samples: u64) {
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
            true,
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

    /// Each estimator is weighed only after enough of its own: the path tracer's few dozen
    /// heavy-tailed samples no more than `vbl`'s first passes (catches the old rule, `pt`
    /// mixed in from its second sample, and a path tracer left out where it is all there is).
    #[test]
    fn each_estimate_waits_for_enough_of_its_own() {
        // Both early: the path tracer alone.
        assert_eq!(weighed(10, 3, false), (false, true));
        // `vbl` ready, the path tracer not yet: `vbl` alone.
        assert_eq!(weighed(21, 7, false), (true, false));
        assert_eq!(weighed(MIN_PT_SAMPLES, 7, false), (true, true));
        // A component only `vbl` serves: from its first pass, and never the path tracer.
        assert_eq!(weighed(500, 1, true), (true, false));
        // Before any `vbl` pass the path tracer is weighed from its second sample.
        assert_eq!(weighed(1, 0, false), (false, false));
        assert_eq!(weighed(2, 0, false), (false, true));
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
        // The same difference within both estimates' noise (a pass-to-pass spread of 2.0 in
        // every pixel and of the whole image, as when a pass's few lights reach every pixel)
        // is not bias.
        let (pt_noisy, vbl_noisy) = (film(w, h, 64, 1.0, 2.0), film(w, h, 64, 0.8, 2.0));
        let e = errors(&pt_noisy, &vbl_noisy, &means(64, 1.0, 2.0), &means(64, 0.8, 2.0));
        assert_eq!(e.bias2, 0.0);
        // Unbiased and far more precise: it takes nearly all of the weight.
        let vbl = film(w, h, 64, 1.0, 0.01);
        let e = errors(&pt, &vbl, &means(64, 1.0, 0.4 / 16.0), &means(64, 1.0, 0.01));
        assert!(e.vbl_weight(true, true) > 0.99);
    }

    /// `vbl`'s blur moves light between pixels and keeps the image mean: pixel by pixel it
    /// is biased although the image means agree. The pixels' squared differences beyond both
    /// variances are its squared bias, and it loses weight by them (catches a model that
    /// sees only the image means: no bias, and `vbl`'s weight 0.8 from the variances alone).
    #[test]
    fn a_blur_that_keeps_the_mean_is_still_bias() {
        let (w, h) = (16, 16);
        let pt = film(w, h, 64, 1.0, 0.4);
        // Pixels alternately 10 % too bright and too dark, as a checkerboard.
        let mut vbl = Film::new(w, h);
        for pass in 0..64 {
            let noise = if pass % 2 == 0 { 0.2 } else { -0.2 };
            let pixels: Vec<Rgb> = (0..w * h)
                .map(|i| Rgb::splat(if (i % w + i / w) % 2 == 0 { 1.1 } else { 0.9 } + noise))
                .collect();
            vbl.add_pass(&pixels);
        }
        let e = errors(&pt, &vbl, &means(64, 1.0, 0.4 / 16.0), &means(64, 1.0, 0.2 / 16.0));
        let entries = (3 * w * h) as f64;
        let (vp, vv) = (pt.entry(0, 0).1, vbl.entry(0, 0).1);
        let expected = entries * (0.1f64.powi(2) - vp - vv);
        assert!(
            (e.bias2 - expected).abs() < 1e-4 * expected,
            "{} vs {expected}",
            e.bias2
        );
        assert_eq!(e.pt_tail2, 0.0);
        let weight = e.vbl_weight(true, true);
        assert!(weight < 0.3, "a blur of ±10 % kept vbl's weight at {weight}");
        // The combination keeps pt's image mean and lowers the checkerboard's amplitude.
        let (image, _) = combine(&pt, &vbl, weight);
        assert!((image.pixels[0][0] - 1.0 - 0.1 * weight as f32).abs() < 1e-5);
        // Before the path tracer's estimate is weighed its per-pixel variances are not
        // trusted, and the pixels' differences are not read as bias.
        let few = film(w, h, MIN_PT_SAMPLES - 2, 1.0, 0.4);
        let e = errors(
            &few,
            &vbl,
            &means(MIN_PT_SAMPLES - 2, 1.0, 0.4 / 16.0),
            &means(64, 1.0, 0.2 / 16.0),
        );
        assert_eq!(e.bias2, 0.0);
        // Nor where `vbl` does not blur (`direct`).
        let relative = vec![Rgb::ONE; (w * h) as usize];
        let means_pt = means(64, 1.0, 0.4 / 16.0);
        let e = ComponentError::of(&pt, &vbl, &means(64, 1.0, 0.2 / 16.0), &means_pt, &relative, false);
        assert_eq!(e.bias2, 0.0);
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

    /// A path tracer that has found none of a component's light (every sample zero, so zero
    /// variance, as behind glass early on) is not exact: against a `vbl` that shows the light
    /// it carries the whole missing light as its error, and `vbl` takes the weight and the
    /// schedule's attention. (Measured against `pt`'s level alone it had neither: its tail
    /// term needs a level, the model then saw a zero error and no gain in any step, and the
    /// component was left with `vbl`'s first passes at weight 0 in `lamp_in_glass`.)
    #[test]
    fn a_path_tracer_that_found_nothing_is_not_exact() {
        let (w, h) = (16, 16);
        let pt = film(w, h, 6, 0.0, 0.0);
        let vbl = film(w, h, 4, 1.0, 0.5);
        let e = errors(&pt, &vbl, &means(6, 0.0, 0.0), &means(4, 1.0, 0.5 / 16.0));
        assert_eq!(e.pt, 0.0);
        assert!(e.pt_tail2 > 0.0, "{e:?}");
        assert!(e.vbl_weight(true, true) > 0.9, "{e:?}");
        let (mse, d_pt, d_vbl) = e.model(6.0, 4.0, true, 0.3);
        assert!(mse > 0.0 && d_pt < 0.0 && d_vbl < 0.0, "{mse} {d_pt} {d_vbl}");
        // Both at zero: nothing to tell apart, no error.
        let e = errors(&pt, &film(w, h, 4, 0.0, 0.0), &means(6, 0.0, 0.0), &means(4, 0.0, 0.0));
        assert_eq!((e.pt_tail2, e.bias2), (0.0, 0.0));
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
        let (mse, d_pt, _) = e.model(100.0, 10.0, false, 0.3);
        assert!((mse - 0.5).abs() < 1e-12);
        assert!((d_pt + 0.5 / 100.0).abs() < 1e-12, "{d_pt}");
        let h = 1e-3;
        // With the bias held (decay 0) and falling as n^−0.3 (`bias_decay(0.7)`).
        for decay in [0.0, bias_decay(0.7)] {
            let (mse, d_pt, d_vbl) = e.model(100.0, 10.0, true, decay);
            assert!((mse - 1.0 / (1.0 / 0.5 + 1.0 / 0.26)).abs() < 1e-12);
            // Moving n while the per-sample variance stays put: the model's variance scales
            // as n_then / n, the squared bias as (n_then / n)^decay.
            let scaled = |n_pt: f64, n_vbl: f64| {
                ComponentError {
                    pt: 0.5 * 100.0 / n_pt,
                    vbl: 0.25 * 10.0 / n_vbl,
                    bias2: 0.01 * (10.0 / n_vbl).powf(decay),
                    pt_tail2: 0.0,
                }
                .model(n_pt, n_vbl, true, decay)
                .0
            };
            let fd_pt2 = (scaled(100.0 + h, 10.0) - scaled(100.0 - h, 10.0)) / (2.0 * h);
            let fd_vbl = (scaled(100.0, 10.0 + h) - scaled(100.0, 10.0 - h)) / (2.0 * h);
            assert!((d_pt - fd_pt2).abs() < 1e-6 * fd_pt2.abs(), "{d_pt} vs {fd_pt2}");
            assert!(
                (d_vbl - fd_vbl).abs() < 1e-6 * fd_vbl.abs(),
                "{decay}: {d_vbl} vs {fd_vbl}"
            );
        }
    }
}
