//! The [`Observer`] that feeds the live view from the solve thread
//! (beyond the paper): snapshots of the solution at most every
//! [`SNAPSHOT_INTERVAL`] of solve time, pauses and holds at shot counts,
//! the stop and the final pass's progress, and the final picture
//! ([`Shared::draw_frame`]) once the solve is done.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use radiosity::app::Observer;
use radiosity::final_gather::FinalGather;
use radiosity::mesh::Mesh;
use radiosity::scene::Scene;
use radiosity::solver::{Flow, Solver, StopReason};

use super::state::{FinalPassStatus, Phase, SNAPSHOT_INTERVAL, Shared, initial_ambient};

/// When the solve thread takes a snapshot while the solve runs: after the
/// first shot, then once [`SNAPSHOT_INTERVAL`] of solve time (pauses
/// excluded) has passed since the last snapshot, whatever took it. Two
/// snapshots taken while solving are therefore at least the interval of
/// solve time apart, which the status's `elapsed_seconds` shows.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Throttle {
    /// Solve time of the last snapshot.
    last: Option<Duration>,
}

impl Throttle {
    /// Whether a snapshot is due at solve time `active`.
    pub(super) fn due(&self, active: Duration) -> bool {
        self.last
            .is_none_or(|last| active.saturating_sub(last) >= SNAPSHOT_INTERVAL)
    }

    /// A snapshot was taken at solve time `active`.
    pub(super) fn taken(&mut self, active: Duration) {
        self.last = Some(active);
    }
}

/// The [`Observer`] that feeds the live view from the solve thread.
pub struct LiveObserver {
    shared: Arc<Shared>,
    solve_start: Instant,
    paused_total: Duration,
    throttle: Throttle,
    /// Active solve time and rays at the last snapshot, for rays/s.
    last_rays: (Duration, u64),
    rays_per_second: f64,
}

impl LiveObserver {
    /// An observer publishing into `shared`.
    pub fn new(shared: Arc<Shared>) -> LiveObserver {
        LiveObserver {
            shared,
            solve_start: Instant::now(),
            paused_total: Duration::ZERO,
            throttle: Throttle::default(),
            last_rays: (Duration::ZERO, 0),
            rays_per_second: 0.0,
        }
    }

    fn active_time(&self) -> Duration {
        self.solve_start.elapsed().saturating_sub(self.paused_total)
    }

    fn publish(&mut self, solver: &Solver<'_>, phase: Phase, stop: Option<StopReason>) {
        let stats = solver.stats();
        let active = self.active_time();
        let window = active.saturating_sub(self.last_rays.0);
        // Too short a window (a pause right after a snapshot) keeps the
        // previous rate rather than showing noise.
        if window >= Duration::from_millis(50) {
            self.rays_per_second =
                stats.rays_cast.saturating_sub(self.last_rays.1) as f64 / window.as_secs_f64();
            self.last_rays = (active, stats.rays_cast);
        }
        let rays_per_second = self.rays_per_second;
        let unshot_fraction = solver.unshot_fraction();
        let device = solver.device_report();
        self.shared
            .publish(solver.radiosity().to_vec(), solver.ambient(), |status| {
                status.phase = phase;
                if phase == Phase::Paused {
                    status.pause_requested = false;
                }
                status.shots = stats.shots;
                status.subsources = stats.subsources;
                status.rays = stats.rays_cast;
                status.rays_per_second = rays_per_second;
                status.unshot_fraction = unshot_fraction;
                status.elapsed_seconds = active.as_secs_f64();
                status.device = device.name.unwrap_or_else(|| "cpu".to_string());
                status.device_shots = device.device_shots;
                if let Some(stop) = stop {
                    status.stop_reason = Some(stop.describe());
                }
            });
        self.throttle.taken(active);
    }
}

impl Observer for LiveObserver {
    fn started(&mut self, scene: &Scene, mesh: &Mesh) {
        self.shared.set_scene(scene, mesh);
        // Before the first shot only the emitters shine, and the ambient
        // term stands for all the rest: shown while the first shot (long
        // on a large scene) runs.
        let radiosity = mesh
            .vertices
            .iter()
            .map(|v| scene.surfaces[v.surface as usize].emission)
            .collect();
        // A hold at shot 0, or a pause pressed while loading, holds the
        // solve before its first shot.
        self.shared.hold_at(0);
        let held = self.shared.pause_flag.load(Ordering::SeqCst);
        self.shared
            .publish(radiosity, initial_ambient(scene, mesh), |status| {
                status.phase = if held { Phase::Paused } else { Phase::Solving };
                if held {
                    status.pause_requested = false;
                }
            });
        // A stop while held is seen by the solve before its first shot.
        if held && !self.shared.wait_while_paused() {
            self.shared.set_phase(Phase::Solving);
        }
        self.solve_start = Instant::now();
    }

    fn interrupt(&self) -> Option<Arc<AtomicBool>> {
        Some(Arc::clone(&self.shared.stop_flag))
    }

    fn abort(&self) -> Option<Arc<AtomicBool>> {
        Some(Arc::clone(&self.shared.abort_flag))
    }

    fn shot(&mut self, solver: &Solver<'_>) -> Flow {
        if self.shared.stop_flag.load(Ordering::SeqCst) {
            return Flow::Stop;
        }
        self.shared.hold_at(solver.stats().shots);
        if self.shared.pause_flag.load(Ordering::SeqCst) {
            self.publish(solver, Phase::Paused, None);
            let paused_at = Instant::now();
            let stop = self.shared.wait_while_paused();
            self.paused_total += paused_at.elapsed();
            if stop {
                return Flow::Stop;
            }
            self.shared.set_phase(Phase::Solving);
            return Flow::Continue;
        }
        if self.throttle.due(self.active_time()) {
            self.publish(solver, Phase::Solving, None);
        }
        Flow::Continue
    }

    fn final_pass(&mut self, what: &str, done: u64, total: u64, _elapsed: Duration) {
        self.shared.set_final_pass(FinalPassStatus {
            what: what.to_string(),
            done,
            total,
        });
    }

    fn finished(&mut self, solver: &Solver<'_>, stop: StopReason) {
        self.publish(solver, Phase::Writing, Some(stop));
        if self.shared.final_gather() != FinalGather::Off {
            let shared = Arc::clone(&self.shared);
            shared.draw_frame(solver, self);
        }
    }
}
