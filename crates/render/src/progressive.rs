//! The progressive loop: independent passes, each a pure function of
//! `(scene, settings, seed, pass index)`, averaged into a [`Film`] until the budget runs out.
use crate::{
    Film,
    accum::Accumulators,
    many_lights::{self, Discards, ManyLightSettings, PassInFlight, PassTimes, VirtualLights},
};
use beamlight_gpu::GpuBackend;
use beamlight_scene::{Rgb, rng::Sampler};
use beamlight_trace::{
    TraceScene,
    components::Component,
    pt::{self, PathTracerSettings},
};
use rayon::prelude::*;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Estimator family (`--method`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Unbiased volumetric path tracer (ground truth).
    Pt,
    /// Unclamped virtual ray lights + virtual point lights.
    Vrl,
    /// Clamped VRLs + VPLs.
    VrlClamped,
    /// Progressive virtual beam lights + virtual spherical lights.
    Vbl,
    /// Each component from `pt` and `vbl`, combined by their measured errors, with the time
    /// going where it lowers the error most ([`crate::auto`]).
    Auto,
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::Pt => "pt",
            Method::Vrl => "vrl",
            Method::VrlClamped => "vrl-clamped",
            Method::Vbl => "vbl",
            Method::Auto => "auto",
        }
    }
}

/// When to stop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// Exactly this many passes (for `pt` one pass is one sample per pixel).
    Passes(u64),
    /// Stop before the wall-clock time since `RenderOptions::start` would exceed this; at
    /// least one pass is always rendered.
    Time(Duration),
}

#[derive(Clone, Debug)]
pub struct RenderOptions {
    pub method: Method,
    pub width: u32,
    pub height: u32,
    pub budget: Budget,
    pub seed: u32,
    /// First pass index (ranges of passes can be rendered separately and averaged).
    pub first_pass: u64,
    pub path_tracer: PathTracerSettings,
    /// The moment the time budget counts from (process start, so start-up is included).
    pub start: Instant,
    /// Also accumulate each transport component separately (`RenderResult::components`).
    pub components: bool,
    pub many_lights: ManyLightSettings,
    /// The GPU that runs the gathers it has kernels for; `None` renders on the CPU alone.
    pub gpu: Option<Arc<GpuBackend>>,
}

pub struct RenderResult {
    pub film: Film,
    /// One film per component in `Component::ALL` order, when `RenderOptions::components`.
    pub components: Vec<Film>,
    pub passes: u64,
    pub elapsed: Duration,
    /// Where each many-light pass's time went (empty for `pt`).
    pub pass_times: Vec<PassTimes>,
    /// `--method auto`: where each component's estimate came from.
    pub auto: Option<crate::auto::AutoReport>,
    /// Estimates discarded per component over the whole render ([`PassTimes::discarded`]):
    /// its passes and those of the checkpoint it continued.
    pub discarded: Discards,
}

/// The state of a render after a pass, handed to the caller (progress display, intermediate
/// images).
pub struct Progress<'a> {
    pub passes: u64,
    /// Total passes when the budget is a pass count.
    pub total: Option<u64>,
    pub film: &'a Film,
    /// Per-component films (empty unless `RenderOptions::components`).
    pub components: &'a [Film],
    pub elapsed: Duration,
    /// Estimates discarded so far, per component ([`PassTimes::discarded`]), a continued
    /// checkpoint's included.
    pub discarded: Discards,
    /// `--method auto`: where each component's estimate came from so far, and the running
    /// sums behind it (for checkpoints).
    pub auto: Option<&'a crate::auto::AutoReport>,
    pub auto_sums: Option<&'a crate::auto::AutoSums>,
}

/// Renders until the budget is spent, calling `on_pass` after each pass; when it returns
/// false the render stops there (the result holds the passes done).
pub fn render(
    ts: &TraceScene,
    opts: &RenderOptions,
    on_pass: impl FnMut(&Progress) -> bool,
) -> Result<RenderResult, String> {
    render_from(ts, opts, None, on_pass)
}

/// [`render`] continuing from accumulated passes (a checkpoint): the new passes are added to
/// `resume`'s films, and `opts.first_pass` must be the pass after its last one. The budget
/// counts the new passes only.
pub fn render_from(
    ts: &TraceScene,
    opts: &RenderOptions,
    resume: Option<&Accumulators>,
    mut on_pass: impl FnMut(&Progress) -> bool,
) -> Result<RenderResult, String> {
    // `vrl` is unclamped by definition; `vrl-clamped` uses the given distance or the default.
    let specular = crate::components::SceneFeatures::of(&ts.scene).specular_surfaces;
    let many_light_settings = ManyLightSettings {
        lights: match opts.method {
            Method::Vbl | Method::Auto => VirtualLights::Beams,
            _ => VirtualLights::Rays,
        },
        clamp: match opts.method {
            Method::VrlClamped if opts.many_lights.clamp > 0.0 => opts.many_lights.clamp,
            Method::VrlClamped => many_lights::default_clamp(&ts.scene),
            _ => 0.0,
        },
        radius: if opts.many_lights.radius > 0.0 {
            opts.many_lights.radius
        } else {
            many_lights::default_radius(&ts.scene)
        },
        // Without mirrors or glass there are no caustics: no light paths for them.
        caustic_paths: if specular {
            opts.many_lights.caustic_paths
        } else {
            Some(0)
        },
        beam_paths: if specular { opts.many_lights.beam_paths } else { 0 },
        photon_radius: if opts.many_lights.photon_radius > 0.0 {
            opts.many_lights.photon_radius
        } else {
            many_lights::default_photon_radius(&ts.scene)
        },
        ..opts.many_lights
    };
    if opts.method == Method::Auto {
        let sums = match resume {
            Some(acc) => Some((
                acc.auto
                    .as_ref()
                    .ok_or("the checkpoint holds no `auto` render's estimators")?,
                acc.passes(),
            )),
            None => None,
        };
        let discarded = resume.map_or(Discards::default(), |acc| acc.discarded);
        return crate::auto::render(ts, opts, &many_light_settings, sums, discarded, on_pass);
    }
    let (w, h) = (opts.width, opts.height);
    let mut film = Film::new(w, h);
    let mut buffer = vec![Rgb::ZERO; (w * h) as usize];
    let n_components = if opts.components { Component::ALL.len() } else { 0 };
    let mut components: Vec<Film> = (0..n_components).map(|_| Film::new(w, h)).collect();
    if let Some(acc) = resume {
        if (acc.film.width, acc.film.height) != (w, h) || acc.components.len() != n_components {
            return Err("the checkpoint holds a different image size or set of layers".into());
        }
        if acc.end_pass() != opts.first_pass {
            return Err(format!(
                "the checkpoint ends at pass {}, the render would start at pass {}",
                acc.end_pass(),
                opts.first_pass
            ));
        }
        film = acc.film.clone();
        components = acc.components.clone();
    }
    let mut component_buffers = vec![vec![Rgb::ZERO; (w * h) as usize]; n_components];
    let mut many_light_buffers: [Vec<Rgb>; Component::ALL.len()] = match opts.method {
        Method::Pt => Default::default(),
        _ => std::array::from_fn(|_| vec![Rgb::ZERO; (w * h) as usize]),
    };
    let started = Instant::now();
    let total = match opts.budget {
        Budget::Passes(n) => Some(n),
        Budget::Time(_) => None,
    };
    let mut passes = 0u64;
    let mut pass_times = Vec::new();
    let mut discarded_so_far = resume.map_or(Discards::default(), |acc| acc.discarded);
    // Passes started; with the many-light methods one pass is in flight (its GPU gathers
    // running) while the next one is traced and estimated on the CPU.
    let mut started_passes = 0u64;
    let mut in_flight: Option<PassInFlight> = None;
    let gpu = opts.gpu.as_deref();
    let mut last_finish = Instant::now();
    // Wall time between the last few pass completions (for the time budget).
    let mut recent_periods: std::collections::VecDeque<Duration> = Default::default();
    let mut last_completion = started;
    loop {
        let start_another = match opts.budget {
            Budget::Passes(n) => started_passes < n,
            // Until a pass has finished there is no estimate of a pass's time: the first pass
            // always runs, and no second one starts while it is in flight.
            Budget::Time(_) if passes == 0 => started_passes == 0,
            Budget::Time(limit) => {
                // Start a pass only if it is expected to finish within the budget: passes
                // finish one period apart, and a new one finishes after the one in flight.
                // The period is the longest of the last few (the mean so far would carry the
                // first pass's warm-up and stop a short budget early).
                let period = recent_periods.iter().copied().max().unwrap_or_default();
                let queued = 1 + in_flight.is_some() as u32;
                opts.start.elapsed() + period * queued <= limit
            }
        };
        let pass = (opts.first_pass + started_passes) as u32;
        if opts.method == Method::Pt {
            if !start_another {
                break;
            }
            started_passes += 1;
            path_trace_pass(
                ts,
                &opts.path_tracer,
                w,
                h,
                opts.seed,
                pass,
                &mut buffer,
                &mut component_buffers,
            );
        } else {
            let next = if start_another {
                started_passes += 1;
                Some(
                    many_lights::start_pass(ts, &many_light_settings, w, h, opts.seed, pass, gpu)
                        .map_err(|e| format!("pass {pass} on the GPU: {e}"))?,
                )
            } else {
                None
            };
            let Some(done) = std::mem::replace(&mut in_flight, next) else {
                if in_flight.is_some() {
                    continue; // nothing was in flight: nothing to finish yet
                }
                break;
            };
            let done_pass = done.pass;
            let mut times = done
                .finish(gpu, &mut many_light_buffers)
                .map_err(|e| format!("pass {done_pass} on the GPU: {e}"))?;
            times.wall = last_finish.elapsed();
            last_finish = Instant::now();
            discarded_so_far.add(&times.discarded);
            pass_times.push(times);
            for (i, px) in buffer.iter_mut().enumerate() {
                *px = many_light_buffers.iter().map(|b| b[i]).sum();
            }
            if opts.components {
                for (dst, src) in component_buffers.iter_mut().zip(&many_light_buffers) {
                    dst.copy_from_slice(src);
                }
            }
        }
        film.add_pass(&buffer);
        components
            .par_iter_mut()
            .zip(component_buffers.par_iter())
            .for_each(|(f, b)| f.add_pass(b));
        passes += 1;
        if recent_periods.len() == 4 {
            recent_periods.pop_front();
        }
        recent_periods.push_back(last_completion.elapsed());
        last_completion = Instant::now();
        let go_on = on_pass(&Progress {
            passes,
            total,
            film: &film,
            components: &components,
            elapsed: started.elapsed(),
            discarded: discarded_so_far,
            auto: None,
            auto_sums: None,
        });
        if !go_on {
            // A pass still in flight is dropped unfinished.
            break;
        }
    }
    Ok(RenderResult {
        film,
        components,
        passes,
        elapsed: started.elapsed(),
        pass_times,
        auto: None,
        discarded: discarded_so_far,
    })
}

/// One sample per pixel, rows in parallel; with component buffers (one per `Component::ALL`
/// entry, or none) also each pixel's sample split by component.
pub fn path_trace_pass(
    ts: &TraceScene,
    settings: &PathTracerSettings,
    w: u32,
    h: u32,
    seed: u32,
    pass: u32,
    out: &mut [Rgb],
    components: &mut [Vec<Rgb>],
) {
    let split = !components.is_empty();
    let rows = out.par_chunks_mut(w as usize).enumerate();
    if split {
        // Each row of the image with the same row of every component buffer, so that the
        // rows' threads write their components in place.
        let mut component_rows: Vec<Vec<&mut [Rgb]>> = (0..h).map(|_| Vec::new()).collect();
        for buffer in components.iter_mut() {
            for (row, chunk) in component_rows.iter_mut().zip(buffer.chunks_mut(w as usize)) {
                row.push(chunk);
            }
        }
        rows.zip(component_rows.into_par_iter())
            .for_each(|((y, row), mut comps)| {
                for c in comps.iter_mut() {
                    c.fill(Rgb::ZERO);
                }
                for (x, px) in row.iter_mut().enumerate() {
                    let mut s = Sampler::new(seed, pass, y as u32 * w + x as u32);
                    let mut sum = Rgb::ZERO;
                    pt::sample_pixel_split(ts, settings, x as u32, y as u32, w, h, &mut s, &mut |k, l| {
                        comps[k as usize][x] += l;
                        sum += l;
                    });
                    *px = sum;
                }
            });
    } else {
        rows.for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let mut s = Sampler::new(seed, pass, y as u32 * w + x as u32);
                *px = pt::sample_pixel(ts, settings, x as u32, y as u32, w, h, &mut s);
            }
        });
    }
}
