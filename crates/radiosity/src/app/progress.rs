//! Watching a solve: the [`Observer`] a front end gives [`super::run`]
//! (progress displays, Ctrl-C, the live view), and the progress it can
//! show, with the time left estimated from the recent past.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::solver::{Flow, Solver, StopReason};

/// Progress after a shot, for a progress display.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Patches shot so far.
    pub shots: u64,
    /// Subsources shot so far.
    pub subsources: u64,
    /// Unshot power over emitted power.
    pub unshot_fraction: f64,
    /// Estimated completion in [0, 1], from whichever stopping rule is
    /// nearest.
    pub completion: f64,
    /// Time since the solve started.
    pub elapsed: Duration,
    /// Shadow rays per second over the recent past.
    pub rays_per_second: f64,
    /// Estimated time until a stopping rule holds, once there is enough
    /// history to say.
    pub remaining: Option<Duration>,
}

/// Follows a solve to estimate its speed and the time left: rays per
/// second, and the time until the first stopping rule holds, extrapolated
/// from the recent past (the last third of the run, at least ten seconds).
/// Convergence is followed on a log scale: the unshot fraction falls
/// roughly geometrically with the shots, but ever more slowly as the
/// brightest shooters are done, so only the recent rate predicts the rest.
#[derive(Clone, Debug)]
pub struct ProgressMeter {
    start: Instant,
    /// `(elapsed, ln unshot fraction, rays, shots)` after recent shots.
    history: std::collections::VecDeque<(Duration, f64, u64, u64)>,
}

impl Default for ProgressMeter {
    fn default() -> Self {
        ProgressMeter::new()
    }
}

impl ProgressMeter {
    /// Starts timing now.
    #[must_use]
    pub fn new() -> ProgressMeter {
        ProgressMeter {
            start: Instant::now(),
            history: std::collections::VecDeque::new(),
        }
    }

    /// Records the solver's state after a shot and estimates progress.
    pub fn update(&mut self, solver: &Solver<'_>) -> Progress {
        let mut progress = progress_of(solver);
        let elapsed = self.start.elapsed();
        let stats = solver.stats();
        let ln_fraction = progress.unshot_fraction.max(1e-300).ln();
        self.history
            .push_back((elapsed, ln_fraction, stats.rays_cast, stats.shots));
        let window = (elapsed / 3).max(Duration::from_secs(10));
        while self.history.len() > 2 && elapsed - self.history[1].0 >= window {
            self.history.pop_front();
        }
        progress.elapsed = elapsed;
        let (t0, f0, rays0, shots0) = self.history[0];
        let span = (elapsed - t0).as_secs_f64();
        if span > 0.0 {
            progress.rays_per_second = (stats.rays_cast - rays0) as f64 / span;
        }
        let settings = solver.settings();
        let mut remaining: Option<f64> = None;
        let mut nearest = |t: f64| {
            if t.is_finite() && t >= 0.0 {
                remaining = Some(remaining.map_or(t, |r: f64| r.min(t)));
            }
        };
        if span >= 1.0 && self.history.len() >= 3 {
            let rate = (f0 - ln_fraction) / span;
            if settings.converge > 0.0 && rate > 0.0 {
                nearest(((ln_fraction - settings.converge.ln()) / rate).max(0.0));
            }
            let shot_rate = (stats.shots - shots0) as f64 / span;
            if let Some(max) = settings.max_shots
                && shot_rate > 0.0
            {
                nearest(max.saturating_sub(stats.shots) as f64 / shot_rate);
            }
        }
        if let Some(limit) = settings.time_limit {
            nearest(limit.saturating_sub(elapsed).as_secs_f64());
        }
        progress.remaining = remaining.map(Duration::from_secs_f64);
        progress
    }
}

/// Watches a run: told when the mesh is ready and after every shot, and
/// able to stop the solve (the outputs are then written from the state
/// reached). Progress displays, Ctrl-C handling and the live view are
/// observers. The final pass's progress is told from a thread of its own
/// while the pool works, hence `Send`.
pub trait Observer: Send {
    /// The scene is loaded; receiver refinement's coarse pass is about to
    /// start (not called without refinement).
    fn refining(&mut self) {}

    /// The scene is loaded and meshed; the solve is about to start.
    fn started(&mut self, _scene: &Scene, _mesh: &Mesh) {}

    /// A shot has completed. Return [`Flow::Stop`] to end the solve.
    fn shot(&mut self, _solver: &Solver<'_>) -> Flow {
        Flow::Continue
    }

    /// A flag that, once raised, stops the solve at once, abandoning the
    /// shot under way (see [`Solver::interrupt_on`]): for Ctrl-C and stop
    /// buttons, which should not wait for a long shot to end.
    fn interrupt(&self) -> Option<Arc<AtomicBool>> {
        None
    }

    /// The solve has ended, for `stop`, and the outputs are about to be
    /// written from `solver`'s state: the last state a live view shows
    /// (the last [`Observer::shot`] cannot know it is the last).
    fn finished(&mut self, _solver: &Solver<'_>, _stop: StopReason) {}

    /// An output that takes a while (a lightmap bake) is being written:
    /// `what` says which.
    fn writing(&mut self, _what: &str) {}

    /// The final pass ([`crate::final_gather`]) is shading `what` (`"picture"`,
    /// `"lightmap"`, `"sensors"`): `done` of `total` points so far
    /// (`total` 0 where it is not known beforehand), `elapsed` since it
    /// began. Told about every [`FINAL_PASS_INTERVAL`], and once when done.
    fn final_pass(&mut self, _what: &str, _done: u64, _total: u64, _elapsed: Duration) {}

    /// A flag that, once raised, ends the run as soon as it can (a second
    /// Ctrl-C, SIGTERM): the solve stops as for [`Observer::interrupt`],
    /// the final pass leaves its remaining points at once, and only the
    /// outputs that are complete are written, the others named in
    /// [`super::Outcome::unwritten`].
    fn abort(&self) -> Option<Arc<AtomicBool>> {
        None
    }
}

/// How often the final pass's progress is told to an [`Observer`].
pub const FINAL_PASS_INTERVAL: Duration = Duration::from_millis(250);

/// An observer that watches nothing.
impl Observer for () {}

/// A closure called with each shot's [`Progress`] is an observer.
impl<F: FnMut(Progress) + Send> Observer for F {
    fn shot(&mut self, solver: &Solver<'_>) -> Flow {
        self(progress_of(solver));
        Flow::Continue
    }
}

/// Progress of a solver, with completion estimated from the nearest
/// stopping rule (convergence on a log scale).
#[must_use]
pub fn progress_of(solver: &Solver<'_>) -> Progress {
    let stats = solver.stats();
    let settings = solver.settings();
    let fraction = solver.unshot_fraction();
    let mut completion: f64 = 0.0;
    if settings.converge > 0.0 {
        completion =
            completion.max((fraction.max(1e-300).ln() / settings.converge.ln()).clamp(0.0, 1.0));
    }
    if let Some(m) = settings.max_shots {
        completion = completion.max(stats.shots as f64 / m.max(1) as f64);
    }
    if let Some(m) = settings.max_subsources {
        completion = completion.max(stats.subsources as f64 / m.max(1) as f64);
    }
    Progress {
        shots: stats.shots,
        subsources: stats.subsources,
        unshot_fraction: fraction,
        completion: completion.min(1.0),
        elapsed: Duration::ZERO,
        rays_per_second: 0.0,
        remaining: None,
    }
}
