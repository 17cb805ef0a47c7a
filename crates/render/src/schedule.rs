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
pub struct EveryPass {
    film: Film,
    /// One film per component, or none when the render does not keep them.
    components: Vec<Film>,
    next_pass: u64,
    started: u64,
    finished: u64,
    /// Wall time between the last few pass completions (for the time budget).
    recent_periods: VecDeque<Duration>,
    last_completion: Instant,
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
            recent_periods: VecDeque::new(),
            last_completion: Instant::now(),
        }
    }
}

impl Schedule for EveryPass {
    fn plan(&mut self, remaining: Remaining, pending: Option<&Step>) -> Option<Vec<Step>> {
        if let Remaining::Time { left, .. } = remaining {
            if self.finished == 0 {
                // Until a pass has finished there is no estimate of a pass's time: the first
                // pass always runs, and no second one starts while it is in flight.
                if self.started > 0 {
                    return None;
                }
            } else {
                // Start a pass only if it is expected to finish within the budget: passes
                // finish one period apart, and a new one finishes after the one in flight.
                // The period is the longest of the last few (the mean so far would carry the
                // first pass's warm-up and stop a short budget early).
                let period = self.recent_periods.iter().copied().max().unwrap_or_default();
                let queued = 1 + pending.is_some() as u32;
                if (period * queued).as_secs_f64() > left {
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
        }])
    }

    fn absorb(&mut self, _step: &Step, finished: &Finished, _seconds: f64) {
        self.film.add_pass(&finished.out.beauty);
        self.components
            .par_iter_mut()
            .zip(finished.out.components.par_iter())
            .for_each(|(f, b)| f.add_pass(b));
        self.finished += 1;
    }

    fn unit_done(&mut self) {
        if self.recent_periods.len() == 4 {
            self.recent_periods.pop_front();
        }
        self.recent_periods.push_back(self.last_completion.elapsed());
        self.last_completion = Instant::now();
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
