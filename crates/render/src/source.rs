//! Pass sources: the estimators as the progressive loop sees them.
//!
//! A source renders pass `p` of some components as a pure function of its scene, settings,
//! seed and `p`, in two halves: [`PassSource::start`] does the CPU's share and may leave work
//! running on the GPU, [`InFlight::finish`] waits for that work and hands the pass's estimate
//! over. The loop ([`crate::progressive`]) starts the next pass before it finishes one whose
//! GPU work is still running, so the CPU and the GPU are busy at once.
use crate::many_lights::{self, ManyLightSettings, PassInFlight, PassTimes};
use beamlight_gpu::GpuBackend;
use beamlight_scene::{Rgb, rng::Sampler};
use beamlight_trace::{
    TraceScene,
    camera_paths::PixelShare,
    components::Component,
    pt::{self, PathTracerSettings},
};
use rayon::prelude::*;

pub const N: usize = Component::ALL.len();

/// A set of components, by [`Component::ALL`] index.
pub type Components = [bool; N];

/// One pass's estimate per pixel: the beauty and, when the source keeps them apart, each
/// component in [`Component::ALL`] order (empty otherwise). The loop owns these buffers and
/// lends them to a source for a pass; the source sizes `components` to what it writes.
pub struct PassOutput {
    pub beauty: Vec<Rgb>,
    pub components: Vec<Vec<Rgb>>,
}

impl PassOutput {
    pub fn new(pixels: usize) -> Self {
        Self {
            beauty: vec![Rgb::ZERO; pixels],
            components: Vec::new(),
        }
    }

    /// Sizes the buffers for an image of `pixels` (the loop lends a source buffers another
    /// source may have used: `auto`'s probe renders a smaller image) and makes room for the
    /// components (`split`) or drops them.
    fn fit(&mut self, pixels: usize, split: bool) {
        self.beauty.resize(pixels, Rgb::ZERO);
        self.components
            .resize_with(if split { N } else { 0 }, || vec![Rgb::ZERO; pixels]);
        for c in &mut self.components {
            c.resize(pixels, Rgb::ZERO);
        }
    }
}

/// What a finished pass hands back: its estimate and, for the many-light estimators, where
/// its time went and what it discarded.
pub struct Finished {
    pub out: PassOutput,
    pub times: Option<PassTimes>,
}

/// The components in both sets: a step's and those its source's settings allow (`--only`).
fn both(a: Components, b: Components) -> Components {
    std::array::from_fn(|k| a[k] && b[k])
}

/// An estimator that renders passes.
pub trait PassSource: Sync {
    /// Starts pass `pass` of the components in `components` that its settings compute (the
    /// others stay zero and cost nothing) over the pixels of `pixels` (the others stay zero),
    /// into `out`.
    fn start<'a>(
        &'a self,
        pass: u32,
        components: Components,
        pixels: PixelShare,
        out: PassOutput,
    ) -> Result<Box<dyn InFlight + 'a>, String>;
}

/// A started pass.
pub trait InFlight {
    /// Whether part of the pass still runs elsewhere (the GPU), so that the loop should start
    /// another before waiting for it.
    fn pending(&self) -> bool;
    fn finish(self: Box<Self>) -> Result<Finished, String>;
}

/// What a render's pass sources are made from ([`crate::method::Method::sources`]).
#[derive(Clone, Copy)]
pub struct SourceInputs<'a> {
    pub ts: &'a TraceScene,
    pub width: u32,
    pub height: u32,
    /// The render's seed (a source may derive its own from it).
    pub seed: u32,
    pub path_tracer: PathTracerSettings,
    /// As given: each method fills in what is left to it and to the scene.
    pub many_lights: &'a ManyLightSettings,
    /// Keep the components apart (`--components`; always for the many-light methods).
    pub split: bool,
    pub gpu: Option<&'a GpuBackend>,
}

/// The unbiased volumetric path tracer: one sample per pixel per pass.
pub struct PathTracer<'a> {
    pub ts: &'a TraceScene,
    pub settings: PathTracerSettings,
    pub width: u32,
    pub height: u32,
    pub seed: u32,
    /// Keep the components apart. Without, each pixel's beauty is its paths' sum in the
    /// order they were traced.
    pub split: bool,
}

impl PassSource for PathTracer<'_> {
    fn start<'a>(
        &'a self,
        pass: u32,
        components: Components,
        pixels: PixelShare,
        mut out: PassOutput,
    ) -> Result<Box<dyn InFlight + 'a>, String> {
        out.fit((self.width * self.height) as usize, self.split);
        let settings = PathTracerSettings {
            components: both(components, self.settings.components),
            ..self.settings
        };
        path_trace_pass(
            self.ts,
            &settings,
            self.width,
            self.height,
            pixels,
            self.seed,
            pass,
            &mut out.beauty,
            &mut out.components,
        );
        Ok(Box::new(Done(out)))
    }
}

/// A pass that was complete when it started (what a CPU-only source returns).
pub struct Done(pub PassOutput);

impl InFlight for Done {
    fn pending(&self) -> bool {
        false
    }

    fn finish(self: Box<Self>) -> Result<Finished, String> {
        Ok(Finished {
            out: self.0,
            times: None,
        })
    }
}

/// The many-light estimators (`vrl`, `vrl-clamped`, `vbl`): light paths, their virtual
/// lights gathered at camera records, direct light and caustics, with the gathers the GPU
/// has kernels for on the GPU when there is one ([`many_lights::start_pass`]).
pub struct ManyLights<'a> {
    pub ts: &'a TraceScene,
    pub settings: ManyLightSettings,
    pub width: u32,
    pub height: u32,
    pub seed: u32,
    pub gpu: Option<&'a GpuBackend>,
}

impl PassSource for ManyLights<'_> {
    fn start<'a>(
        &'a self,
        pass: u32,
        components: Components,
        pixels: PixelShare,
        mut out: PassOutput,
    ) -> Result<Box<dyn InFlight + 'a>, String> {
        out.fit((self.width * self.height) as usize, true);
        let settings = ManyLightSettings {
            components: both(components, self.settings.components),
            ..self.settings
        };
        let flight = many_lights::start_pass(
            self.ts,
            &settings,
            self.width,
            self.height,
            pixels,
            self.seed,
            pass,
            self.gpu,
        )
        .map_err(|e| format!("pass {pass} on the GPU: {e}"))?;
        Ok(Box::new(ManyLightPass {
            flight,
            out,
            gpu: self.gpu,
        }))
    }
}

struct ManyLightPass<'a> {
    flight: PassInFlight,
    out: PassOutput,
    gpu: Option<&'a GpuBackend>,
}

impl InFlight for ManyLightPass<'_> {
    fn pending(&self) -> bool {
        self.flight.on_gpu()
    }

    fn finish(self: Box<Self>) -> Result<Finished, String> {
        let ManyLightPass { flight, mut out, gpu } = *self;
        let pass = flight.pass;
        let times = flight
            .finish(gpu, &mut out.components)
            .map_err(|e| format!("pass {pass} on the GPU: {e}"))?;
        for (i, px) in out.beauty.iter_mut().enumerate() {
            *px = out.components.iter().map(|b| b[i]).sum();
        }
        Ok(Finished {
            out,
            times: Some(times),
        })
    }
}

/// One sample per pixel of `pixels` (the others get zero), rows in parallel; with component
/// buffers (one per `Component::ALL` entry, or none) also each pixel's sample split by
/// component.
#[allow(clippy::too_many_arguments)]
pub fn path_trace_pass(
    ts: &TraceScene,
    settings: &PathTracerSettings,
    w: u32,
    h: u32,
    pixels: PixelShare,
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
                    let pixel = y as u32 * w + x as u32;
                    if !pixels.contains(pass, pixel) {
                        *px = Rgb::ZERO;
                        continue;
                    }
                    let mut s = Sampler::new(seed, pass, pixel);
                    let split = pt::sample_pixel_components(ts, settings, x as u32, y as u32, w, h, &mut s);
                    for (c, l) in comps.iter_mut().zip(split) {
                        c[x] = l;
                    }
                    *px = split.iter().copied().sum();
                }
            });
    } else {
        rows.for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let pixel = y as u32 * w + x as u32;
                *px = match pixels.contains(pass, pixel) {
                    true => pt::sample_pixel(
                        ts,
                        settings,
                        x as u32,
                        y as u32,
                        w,
                        h,
                        &mut Sampler::new(seed, pass, pixel),
                    ),
                    false => Rgb::ZERO,
                };
            }
        });
    }
}
