//! Schedules: which source's pass the loop runs next, and how the passes' estimates add up to
//! the image.
//!
//! The loop ([`crate::progressive`]) asks its schedule for the next unit of work, a *pass* as
//! the budget, progress and checkpoints count it (one pass of a single estimator; a round or a
//! slice of `auto`'s), made of one or more [`Step`]s, each one pass of one source. It runs the
//! steps, hands each finished one back ([`Schedule::absorb`]), and after a unit's last step
//! shows the schedule's films ([`Schedule::snapshot`]).
use crate::{
    Film,
    combine::{AutoReport, AutoSums},
    source::{Components, Finished, N},
};
use beamlight_scene::Rgb;
use beamlight_trace::camera_paths::PixelShare;
use rayon::prelude::*;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// One pass of one source over some components.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// Index of the source in the list the schedule was made with.
    pub source: usize,
    /// The pass index in that source's global sequence (what its random numbers derive from).
    pub pass: u32,
    pub components: Components,
    /// The pixels it covers: all, but in a time budget's shortened last pass.
    pub pixels: PixelShare,
}

/// What the budget leaves when the loop asks for the next unit.
#[derive(Clone, Copy, Debug)]
pub enum Remaining {
    /// A pass budget with passes to go: the next unit is due whatever it costs.
    Passes,
    /// A time budget: seconds left of `limit` (which counts from the process's start).
    Time { left: f64, limit: f64 },
}

/// What a schedule shows after a unit: the image so far (and, for `auto`, where each
/// component's estimate came from and the sums behind it, for checkpoints).
pub struct Snapshot<'a> {
    pub film: &'a Film,
    pub components: &'a [Film],
    pub auto: Option<&'a AutoReport>,
    pub auto_sums: Option<&'a AutoSums>,
}

/// The image a schedule ends with.
pub struct Outcome {
    pub film: Film,
    pub components: Vec<Film>,
    pub auto: Option<AutoReport>,
}

pub trait Schedule {
    /// The steps of the next unit, or `None` when nothing fits now. `pending` is a step whose
    /// GPU work is still running (it will take some of the time left); when nothing is
    /// pending, `None` ends the render.
    fn plan(&mut self, remaining: Remaining, pending: Option<&Step>) -> Option<Vec<Step>>;
    /// A finished step: its estimate, and the seconds it held the loop (its start and its
    /// finish, not the GPU time other steps overlapped).
    fn absorb(&mut self, step: &Step, finished: &Finished, seconds: f64);
    /// The last step of a unit was absorbed.
    fn unit_done(&mut self);
    fn snapshot(&self) -> Snapshot<'_>;
    fn outcome(self: Box<Self>) -> Outcome;
}

/// Every pass of one source, averaged: `pt`, `vrl`, `vrl-clamped` and `vbl`.
///
/// With a time budget the last pass is shortened to the time left: it covers a share of the
/// pixels ([`PixelShare`]), sized by the measured cost of a pass ([`Pace`]), and each pixel's
/// estimate is the mean of its own samples. So the render ends at the budget whatever a pass
/// costs (a 1280×720 `vbl` pass takes half a minute), instead of up to half a pass away.
pub struct EveryPass {
    film: Film,
    /// One film per component, or none when the render does not keep them.
    components: Vec<Film>,
    next_pass: u64,
    started: u64,
    finished: u64,
    pace: Pace,
    /// The share of the pixels of the last pass absorbed, when it was shortened (its period is
    /// not a whole pass's).
    shortened: Option<PixelShare>,
}

impl EveryPass {
    /// A schedule whose first pass is `first_pass`, continuing `resume`'s films (a checkpoint)
    /// when given. `components`: keep a film per component.
    pub fn new(w: u32, h: u32, components: bool, first_pass: u64, resume: Option<(&Film, &[Film])>) -> Self {
        let (film, components) = match resume {
            Some((film, layers)) => (film.clone(), layers.to_vec()),
            None => (
                Film::new(w, h),
                (0..if components { N } else { 0 }).map(|_| Film::new(w, h)).collect(),
            ),
        };
        Self {
            film,
            components,
            next_pass: first_pass,
            started: 0,
            finished: 0,
            pace: Pace::new(),
            shortened: None,
        }
    }
}

/// How fast passes go, measured: the time between pass completions and the part of a pass
/// that does not shrink with its pixels (the light side: light paths, maps and trees).
#[derive(Debug)]
pub(crate) struct Pace {
    /// Wall time between the last few pass completions.
    recent: VecDeque<Duration>,
    /// Units completed (the periods recorded).
    completed: u64,
    last_completion: Instant,
    /// Running sums over the passes that report their times (the many-light ones) of their
    /// light-side seconds and of what each would take alone (its CPU share and its GPU
    /// kernels one after the other), and how many passes they sum.
    light_side: f64,
    alone: f64,
    timed: u64,
    /// Seconds per share of the pixels beyond the fixed part, as the last shortened pass took
    /// them (`None` before one): a pass alone does not overlap another's GPU work as the
    /// periods do, so a second shortened pass (when the first left time) plans by this.
    per_share: Option<f64>,
}

/// How many recent pass periods [`Pace::period`] averages.
const PERIODS: usize = 4;

impl Pace {
    pub(crate) fn new() -> Self {
        Self {
            recent: VecDeque::new(),
            completed: 0,
            last_completion: Instant::now(),
            light_side: 0.0,
            alone: 0.0,
            timed: 0,
            per_share: None,
        }
    }

    /// The time between pass completions to plan with: the mean of the last few.
    fn period(&self) -> f64 {
        self.recent.iter().map(Duration::as_secs_f64).sum::<f64>() / self.recent.len().max(1) as f64
    }

    /// A pass's seconds that do not depend on its pixels, at most its period.
    fn fixed(&self) -> f64 {
        (self.light_side / self.timed.max(1) as f64).min(self.period())
    }

    /// A whole pass completed `period` after the one before: the first period (which carries
    /// the render's warm-up: threads starting, memory first touched) is replaced by the
    /// second, and only the last [`PERIODS`] are kept.
    fn record(&mut self, period: Duration) {
        self.completed += 1;
        if self.completed == 2 || self.recent.len() == PERIODS {
            self.recent.pop_front();
        }
        self.recent.push_back(period);
    }

    /// A shortened pass over `pixels` completed `period` after the pass before.
    fn record_shortened(&mut self, period: Duration, pixels: PixelShare) {
        let share = pixels.share();
        if share > 0.0 {
            self.per_share = Some((period.as_secs_f64() - self.fixed()).max(0.0) / share);
        }
    }

    /// What to start with `left` seconds of the budget to go, while `pending` (a pass whose
    /// GPU work still runs) completes about a period after the last completion: a whole pass
    /// while one fits with room to spare, then passes over the share of the pixels that fits,
    /// then nothing. Only whole passes start behind a pending pass: the end of a pass whose
    /// GPU work overlaps another's is too uncertain to plan the last one by (on lavapipe the
    /// periods of `vrl` varied from 3.0 to 5.7 s).
    fn next(&self, left: f64, pending: Option<PixelShare>) -> Option<PixelShare> {
        let (period, fixed) = (self.period(), self.fixed());
        let ahead = match pending {
            Some(p) if p.is_all() => (period - self.last_completion.elapsed().as_secs_f64()).max(0.0),
            Some(_) => return None,
            None => 0.0,
        };
        // Before a shortened pass has shown it: a pass alone, whose GPU work overlaps nothing,
        // at its slowest (on lavapipe the "GPU" shares the cores with the CPU's share).
        let alone = self.alone / self.timed.max(1) as f64;
        let per_share = self.per_share.unwrap_or(period.max(alone) - fixed);
        match plan_share(period, fixed, per_share, left - ahead) {
            Some(p) if pending.is_some() && !p.is_all() => None,
            plan => plan,
        }
    }
}

/// A whole pass starts when this many periods are left, so that one slower than the mean (by
/// up to a quarter) still ends in time, before the shortened one.
const ROOM: f64 = 1.25;

/// The pixels of a pass that fits in `avail` seconds when a whole one takes `period`, `fixed`
/// of them whatever its pixels and `per_share` more per share of them: all when it fits with
/// [`ROOM`] to spare, a share when part of it does (the time left after the fixed part, over
/// the part that scales, at most the share that leaves the same room), `None` when not even
/// the fixed part does.
pub(crate) fn plan_share(period: f64, fixed: f64, per_share: f64, avail: f64) -> Option<PixelShare> {
    if avail >= ROOM * period {
        return Some(PixelShare::ALL);
    }
    let share = ((avail - fixed) / per_share.max(1e-9)).min(1.0 / ROOM);
    (share > 0.0).then(|| PixelShare::of(share))
}

impl Schedule for EveryPass {
    fn plan(&mut self, remaining: Remaining, pending: Option<&Step>) -> Option<Vec<Step>> {
        let mut pixels = PixelShare::ALL;
        if let Remaining::Time { left, .. } = remaining {
            if self.finished == 0 {
                // Until a pass has finished there is no estimate of a pass's time: the first
                // pass always runs, and no second one starts while it is in flight.
                if self.started > 0 {
                    return None;
                }
            } else {
                pixels = self.pace.next(left, pending.map(|s| s.pixels))?;
                // A pass of no pixel would only cost its fixed part.
                if !pixels.is_all() && pixels.share() * (self.film.width * self.film.height) as f64 <= 1.0 {
                    return None;
                }
            }
        }
        let pass = self.next_pass as u32;
        self.next_pass += 1;
        self.started += 1;
        Some(vec![Step {
            source: 0,
            pass,
            components: [true; N],
            pixels,
        }])
    }

    fn absorb(&mut self, step: &Step, finished: &Finished, _seconds: f64) {
        // A whole pass, or a shortened one over the pixels it covered.
        let add = |film: &mut Film, pass: &[Rgb]| match step.pixels.is_all() {
            true => film.add_pass(pass),
            false => film.add_partial_pass(pass, |i| step.pixels.contains(step.pass, i as u32)),
        };
        add(&mut self.film, &finished.out.beauty);
        self.components
            .par_iter_mut()
            .zip(finished.out.components.par_iter())
            .for_each(|(f, b)| add(f, b));
        if let Some(times) = &finished.times {
            let kernels: f64 = times.kernels.iter().sum();
            self.pace.light_side += times.light_side.as_secs_f64();
            self.pace.alone += (times.trace + times.cpu_estimates).as_secs_f64() + kernels;
            self.pace.timed += 1;
        }
        self.shortened = (!step.pixels.is_all()).then_some(step.pixels);
        self.finished += 1;
    }

    fn unit_done(&mut self) {
        let period = self.pace.last_completion.elapsed();
        match self.shortened {
            None => self.pace.record(period),
            Some(pixels) => self.pace.record_shortened(period, pixels),
        }
        self.pace.last_completion = Instant::now();
    }

    fn snapshot(&self) -> Snapshot<'_> {
        Snapshot {
            film: &self.film,
            components: &self.components,
            auto: None,
            auto_sums: None,
        }
    }

    fn outcome(self: Box<Self>) -> Outcome {
        Outcome {
            film: self.film,
            components: self.components,
            auto: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A time budget planned pass by pass as [`plan_share`] does, with passes that take what
    /// the model says: whole passes while they fit with room to spare, then at most two
    /// shortened to the time left. The render then ends at the budget (up to rounding the
    /// share to 2⁻³²), never after it, for any period, fixed part and budget; the old rule (a
    /// whole pass when it ends nearer the budget) missed by up to half a period either way.
    /// Catches a share that forgets the fixed part (ends late by up to `fixed`), a whole pass
    /// started without room for it, and a render that stops with time for part of a pass.
    #[test]
    fn a_time_budget_ends_with_a_pass_shortened_to_the_time_left() {
        for period in [0.004, 0.3, 2.5, 38.0] {
            for fixed_share in [0.0, 0.1, 0.5] {
                let fixed = period * fixed_share;
                for i in 1..200 {
                    let budget = period * i as f64 / 16.0;
                    let (mut end, mut shortened) = (0.0, 0);
                    while let Some(pixels) = plan_share(period, fixed, period - fixed, budget - end) {
                        // What rounding leaves: a pass of no pixel, which `EveryPass` refuses.
                        if pixels.share() * 1e6 <= 1.0 {
                            break;
                        }
                        end += match pixels.is_all() {
                            true => {
                                assert!(budget - end >= ROOM * period, "{period} {fixed} {budget}: no room");
                                period
                            }
                            false => {
                                shortened += 1;
                                fixed + pixels.share() * (period - fixed)
                            }
                        };
                        assert!(shortened <= 2, "{period} {fixed} {budget}: a third shortened pass");
                    }
                    let slack = budget - end;
                    assert!(slack >= -1e-9 * period, "{period} {fixed} {budget}: ends at {end}");
                    // Only the fixed part of a pass that does not fit may be left unused.
                    assert!(
                        slack <= fixed + 1e-9 * period,
                        "{period} {fixed} {budget}: ends at {end}"
                    );
                }
            }
        }
        // Nothing starts without time for more than its fixed part.
        assert_eq!(plan_share(1.0, 0.2, 0.8, 0.1), None);
        assert_eq!(plan_share(1.0, 0.0, 1.0, 0.0), None);
        assert_eq!(plan_share(1.0, 0.0, 1.0, -0.5), None);
        assert_eq!(plan_share(1.0, 0.2, 0.8, 1.25), Some(PixelShare::ALL));
        assert_eq!(plan_share(1.0, 0.2, 0.8, 0.6), Some(PixelShare::of(0.5)));
        // A pass alone measured slower per share than the periods say: planned by that.
        assert_eq!(plan_share(1.0, 0.2, 1.6, 0.6), Some(PixelShare::of(0.25)));
        // A whole pass would fit, but without room: the share that leaves it.
        assert_eq!(plan_share(1.0, 0.0, 1.0, 1.1), Some(PixelShare::of(0.8)));
    }

    /// The planning period leaves the warm-up out once a later pass shows the steady cost,
    /// and follows the recent passes after that. Catches the warm-up pass (here 3x the
    /// others) planning a short budget to stop early, and a window that never forgets.
    #[test]
    fn the_period_leaves_the_warm_up_out() {
        let mut pace = Pace::new();
        let mut means = Vec::new();
        for ms in [300, 100, 120, 140, 160, 180] {
            pace.record(Duration::from_millis(ms));
            means.push(pace.period());
        }
        let expect = [0.3, 0.1, 0.11, 0.12, 0.13, 0.15];
        for (m, e) in means.iter().zip(expect) {
            assert!((m - e).abs() < 1e-9, "{means:?}");
        }
    }
}
