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
    /// Units completed (the periods recorded).
    completed: u64,
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
            completed: 0,
            last_completion: Instant::now(),
        }
    }
}

/// The time between pass completions to plan with: the mean of the last few.
fn period(recent: &VecDeque<Duration>) -> f64 {
    recent.iter().map(Duration::as_secs_f64).sum::<f64>() / recent.len().max(1) as f64
}

/// How many recent pass periods [`period`] averages.
const PERIODS: usize = 4;

/// `recent` after a pass completed `period` after the one before: the first period (which
/// carries the render's warm-up: threads starting, memory first touched) is replaced by the
/// second, and only the last [`PERIODS`] are kept.
fn record_period(recent: &mut VecDeque<Duration>, completed: u64, period: Duration) {
    if completed == 2 || recent.len() == PERIODS {
        recent.pop_front();
    }
    recent.push_back(period);
}

/// Whether a new pass should start with `left` seconds of the budget to go, when passes
/// finish `period` seconds apart and it would be the `queued`-th to finish from now (the one
/// still on the GPU comes first): yes when it is expected to end nearer the budget's end than
/// the render would without it, i.e. when it would overrun by less than stopping after the
/// ones before it underruns. The render then ends within half a period of the budget,
/// either side, instead of up to a whole period early.
pub(crate) fn worth_starting(period: f64, queued: u32, left: f64) -> bool {
    let end_with = period * queued as f64;
    let end_without = period * (queued - 1) as f64;
    end_with - left < left - end_without
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
            } else if !worth_starting(period(&self.recent_periods), 1 + pending.is_some() as u32, left) {
                return None;
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
        self.completed += 1;
        record_period(&mut self.recent_periods, self.completed, self.last_completion.elapsed());
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The time budget's planning: a pass starts when it ends nearer the budget than stopping
    /// does. Catches a rule that stops a whole period early (the old one: `left` 0.9 periods
    /// refused) or that starts a pass with no time for it (`left` 0.4 periods accepted).
    #[test]
    fn a_pass_starts_when_it_ends_nearer_the_budget() {
        // One pass at a time (nothing on the GPU): the pass ends at `period`.
        assert!(worth_starting(1.0, 1, 0.9));
        assert!(worth_starting(1.0, 1, 0.6));
        assert!(!worth_starting(1.0, 1, 0.4));
        assert!(!worth_starting(1.0, 1, 0.0));
        assert!(!worth_starting(1.0, 1, -0.2));
        // With a pass still on the GPU, a new one ends after it, two periods from now.
        assert!(worth_starting(1.0, 2, 1.6));
        assert!(!worth_starting(1.0, 2, 1.4));
        // A budget of passes `period` long, planned one at a time from the start, ends
        // within half a period of the budget, whatever the budget and the period.
        for period in [0.01, 0.3, 2.5] {
            for i in 1..200 {
                let budget = period * i as f64 / 16.0;
                let mut end = 0.0;
                while worth_starting(period, 1, budget - end) {
                    end += period;
                }
                assert!(
                    (end - budget).abs() <= period / 2.0 + 1e-12,
                    "{period} {budget}: ends at {end}"
                );
            }
        }
    }

    /// The planning period leaves the warm-up out once a later pass shows the steady cost,
    /// and follows the recent passes after that. Catches the warm-up pass (here 3x the
    /// others) planning a short budget to stop early, and a window that never forgets.
    #[test]
    fn the_period_leaves_the_warm_up_out() {
        let mut recent = VecDeque::new();
        let mut means = Vec::new();
        for (i, ms) in [300, 100, 120, 140, 160, 180].into_iter().enumerate() {
            record_period(&mut recent, i as u64 + 1, Duration::from_millis(ms));
            means.push(period(&recent));
        }
        let expect = [0.3, 0.1, 0.11, 0.12, 0.13, 0.15];
        for (m, e) in means.iter().zip(expect) {
            assert!((m - e).abs() < 1e-9, "{means:?}");
        }
    }
}
