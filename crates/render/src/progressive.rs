//! The progressive loop: passes, each a pure function of `(scene, settings, seed, pass
//! index)`, from the method's sources ([`crate::source`]), in the order and combination its
//! schedule decides ([`crate::schedule`], [`crate::auto`]), until the budget runs out. The loop
//! owns the budget, the progress reports and the overlap: while a pass's GPU gathers run, the
//! next pass is traced and estimated on the CPU.
use crate::{
    Film,
    accum::Accumulators,
    auto::{Auto, AutoReport, AutoSums},
    many_lights::{Discards, PassTimes},
    method::Method,
    options::{Budget, RenderOptions},
    schedule::{EveryPass, Remaining, Schedule, Step},
    source::{InFlight, N, PassOutput, PassSource, SourceInputs},
};
use beamlight_trace::TraceScene;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

pub struct RenderResult {
    pub film: Film,
    /// One film per component in `Component::ALL` order, when `RenderOptions::components`.
    pub components: Vec<Film>,
    pub passes: u64,
    pub elapsed: Duration,
    /// Where each many-light pass's time went (empty for `pt`).
    pub pass_times: Vec<PassTimes>,
    /// `--method auto`: where each component's estimate came from.
    pub auto: Option<AutoReport>,
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
    pub auto: Option<&'a AutoReport>,
    pub auto_sums: Option<&'a AutoSums>,
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
    on_pass: impl FnMut(&Progress) -> bool,
) -> Result<RenderResult, String> {
    let (sources, schedule) = setup(ts, opts, resume)?;
    let mut run = Run {
        schedule,
        on_pass,
        started: Instant::now(),
        total: match opts.budget {
            Budget::Passes(n) => Some(n),
            Budget::Time(_) => None,
        },
        passes: 0,
        steps_left: VecDeque::new(),
        pass_times: Vec::new(),
        discarded: resume.map_or(Discards::default(), |acc| acc.discarded),
        free: Vec::new(),
    };
    let pixels = (opts.width * opts.height) as usize;
    // Started steps not yet finished: between units, at most the newest, while its GPU work
    // runs.
    let mut in_flight: VecDeque<Started> = VecDeque::new();
    let mut planned = 0u64;
    'render: loop {
        let remaining = match opts.budget {
            Budget::Passes(n) => (planned < n).then_some(Remaining::Passes),
            Budget::Time(limit) => Some(Remaining::Time {
                left: limit.as_secs_f64() - opts.start.elapsed().as_secs_f64(),
                limit: limit.as_secs_f64(),
            }),
        };
        let pending = in_flight.back().map(|s| s.step);
        let Some(steps) = remaining.and_then(|r| run.schedule.plan(r, pending.as_ref())) else {
            // Nothing to start now: finish what is in flight and ask again, or end.
            if in_flight.is_empty() {
                break;
            }
            while let Some(s) = in_flight.pop_front() {
                if !run.finish(s)? {
                    break 'render;
                }
            }
            continue;
        };
        planned += 1;
        if steps.is_empty() {
            // Nothing to run in this unit (a schedule with nothing left to estimate): it is
            // done as planned.
            if !run.unit_done() {
                break;
            }
            continue;
        }
        run.steps_left.push_back(steps.len());
        for step in steps {
            let clock = Instant::now();
            let out = run.free.pop().unwrap_or_else(|| PassOutput::new(pixels));
            let flight = sources[step.source].start(step.pass, step.components, step.pixels, out)?;
            in_flight.push_back(Started {
                step,
                flight,
                held: clock.elapsed(),
            });
            // Keep only the newest step in flight, and only while the GPU works on it.
            while in_flight.len() > 1 || in_flight.front().is_some_and(|s| !s.flight.pending()) {
                let s = in_flight.pop_front().expect("not empty");
                if !run.finish(s)? {
                    // A pass still in flight is dropped unfinished.
                    break 'render;
                }
            }
        }
    }
    let outcome = run.schedule.outcome();
    Ok(RenderResult {
        film: outcome.film,
        components: if opts.components {
            outcome.components
        } else {
            Vec::new()
        },
        passes: run.passes,
        elapsed: run.started.elapsed(),
        pass_times: run.pass_times,
        auto: outcome.auto,
        discarded: run.discarded,
    })
}

/// A render's pass sources, indexed by [`Step::source`].
type Sources<'a> = Vec<Box<dyn PassSource + 'a>>;

/// A started step.
struct Started<'a> {
    step: Step,
    flight: Box<dyn InFlight + 'a>,
    /// How long its start took.
    held: Duration,
}

/// The loop's state apart from what is in flight.
struct Run<'a, F> {
    schedule: Box<dyn Schedule + 'a>,
    on_pass: F,
    started: Instant,
    total: Option<u64>,
    /// Units (passes) done.
    passes: u64,
    /// Steps not yet finished of each planned unit, oldest first.
    steps_left: VecDeque<usize>,
    pass_times: Vec<PassTimes>,
    discarded: Discards,
    /// Output buffers of finished steps, for the next ones.
    free: Vec<PassOutput>,
}

impl<F: FnMut(&Progress) -> bool> Run<'_, F> {
    /// Finishes a step and hands it to the schedule; after a unit's last step, reports
    /// progress. False when the caller asked to stop.
    fn finish(&mut self, s: Started) -> Result<bool, String> {
        let clock = Instant::now();
        let mut finished = s.flight.finish()?;
        let seconds = (s.held + clock.elapsed()).as_secs_f64();
        if let Some(times) = &mut finished.times {
            // The seconds the pass held the loop. Over a render these add up to its time: while
            // this pass's GPU work runs, the loop's time goes to other steps (the next pass's
            // CPU share, `auto`'s path tracing) and counts for them.
            times.wall = Duration::from_secs_f64(seconds);
            self.discarded.add(&times.discarded);
            self.pass_times.push(*times);
        }
        self.schedule.absorb(&s.step, &finished, seconds);
        self.free.push(finished.out);
        let left = self.steps_left.front_mut().expect("a finished step belongs to a unit");
        *left -= 1;
        if *left > 0 {
            return Ok(true);
        }
        self.steps_left.pop_front();
        Ok(self.unit_done())
    }

    /// A unit's last step was absorbed: reports progress. False when the caller asked to stop.
    fn unit_done(&mut self) -> bool {
        self.passes += 1;
        self.schedule.unit_done();
        let snapshot = self.schedule.snapshot();
        (self.on_pass)(&Progress {
            passes: self.passes,
            total: self.total,
            film: snapshot.film,
            components: snapshot.components,
            elapsed: self.started.elapsed(),
            discarded: self.discarded,
            auto: snapshot.auto,
            auto_sums: snapshot.auto_sums,
        })
    }
}

/// The sources and the schedule of a render with these options, continuing `resume`'s
/// accumulated passes when given: every method but `auto` is one source whose passes are all
/// averaged, `auto` the path tracer and `vbl` under its own schedule.
pub(crate) fn setup<'a>(
    ts: &'a TraceScene,
    opts: &'a RenderOptions,
    resume: Option<&Accumulators>,
) -> Result<(Sources<'a>, Box<dyn Schedule + 'a>), String> {
    let (width, height) = (opts.width, opts.height);
    let sources = opts.method.sources(SourceInputs {
        ts,
        width,
        height,
        seed: opts.seed,
        path_tracer: opts.path_tracer,
        many_lights: &opts.many_lights,
        split: opts.components,
        gpu: opts.gpu.as_deref(),
    });
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
        let fixed = matches!(opts.budget, Budget::Passes(_));
        let schedule = Auto::new(
            ts,
            (width, height),
            opts.first_pass,
            sums,
            fixed,
            opts.many_lights.alpha,
        )?;
        return Ok((sources, Box::new(schedule)));
    }
    let n_components = if opts.components { N } else { 0 };
    let films = match resume {
        Some(acc) => {
            if (acc.film.width, acc.film.height) != (width, height) || acc.components.len() != n_components {
                return Err("the checkpoint holds a different image size or set of layers".into());
            }
            if acc.end_pass() != opts.first_pass {
                return Err(format!(
                    "the checkpoint ends at pass {}, the render would start at pass {}",
                    acc.end_pass(),
                    opts.first_pass
                ));
            }
            Some((&acc.film, &acc.components[..]))
        }
        None => None,
    };
    let schedule = EveryPass::new(width, height, opts.components, opts.first_pass, films);
    Ok((sources, Box::new(schedule)))
}
