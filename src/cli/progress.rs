//! What a render shows while it runs and when it ends: a progress bar on a
//! terminal, a progress line every ten seconds in a log, Ctrl-C turned into
//! a stop, and the summary of the run.

use std::io::IsTerminal;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

use super::events::Events;

use radiosity::app::{self, Outcome};
use radiosity::mesh::Mesh;
use radiosity::scene::Scene;
use radiosity::solver::{Flow, Solver, StopReason};

/// How often a progress line is printed when standard error is not a
/// terminal (a log).
const PROGRESS_LINE_INTERVAL: Duration = Duration::from_secs(10);

/// Shows a solve's progress: a bar on a terminal, a line every
/// [`PROGRESS_LINE_INTERVAL`] in a log, nothing with `--quiet`; stops the
/// solve after a Ctrl-C.
pub struct ProgressDisplay {
    bar: Option<ProgressBar>,
    lines: bool,
    meter: app::ProgressMeter,
    last_line: Instant,
    /// What is being solved, until it has been said.
    header: Option<String>,
    interrupted: Arc<AtomicBool>,
    /// Raised to end the run at once ([`app::Observer::abort`]).
    abort: Arc<AtomicBool>,
    /// `--progress-json`'s stream.
    events: Option<Events>,
    /// What the final pass is shading, once it has been said.
    final_pass: Option<String>,
}

impl ProgressDisplay {
    pub fn new(
        quiet: bool,
        interrupted: Arc<AtomicBool>,
        abort: Arc<AtomicBool>,
    ) -> ProgressDisplay {
        let terminal = std::io::stderr().is_terminal();
        let bar = (!quiet && terminal).then(|| {
            let bar = ProgressBar::new(1000);
            bar.set_style(
                ProgressStyle::with_template("{spinner} [{elapsed_precise}] {wide_bar} {msg}")
                    .expect("static template"),
            );
            bar
        });
        ProgressDisplay {
            bar,
            lines: !quiet && !terminal,
            meter: app::ProgressMeter::new(),
            last_line: Instant::now(),
            header: None,
            interrupted,
            abort,
            events: None,
            final_pass: None,
        }
    }

    /// Also writes the run's events to `events` (`--progress-json`).
    #[must_use]
    pub fn with_events(mut self, events: Option<Events>) -> ProgressDisplay {
        self.events = events;
        self
    }

    /// The event stream, given back for the run's last event.
    pub fn take_events(&mut self) -> Option<Events> {
        self.events.take()
    }

    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

/// `1:02:03` or `2:03`.
fn clock(d: Duration) -> String {
    let s = d.as_secs();
    if s >= 3600 {
        format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
    } else {
        format!("{}:{:02}", s / 60, s % 60)
    }
}

impl app::Observer for ProgressDisplay {
    fn refining(&mut self) {
        if let Some(events) = &mut self.events {
            events.stage("refining", serde_json::json!({}));
        }
        if let Some(bar) = &self.bar {
            bar.set_message("refining the mesh: a coarse solve");
        }
    }

    fn started(&mut self, scene: &Scene, mesh: &Mesh) {
        if let Some(events) = &mut self.events {
            events.stage(
                "solving",
                serde_json::json!({
                    "scene": scene.name,
                    "surfaces": scene.surfaces.len(),
                    "elements": mesh.elements.len(),
                    "vertices": mesh.vertices.len(),
                }),
            );
        }
        self.meter = app::ProgressMeter::new();
        self.last_line = Instant::now();
        // Said with the first progress line, so a short run's log holds
        // only its summary.
        self.header = Some(format!(
            "solving {}: {} surfaces, {} elements, {} vertices",
            scene.name,
            scene.surfaces.len(),
            mesh.elements.len(),
            mesh.vertices.len()
        ));
    }

    fn shot(&mut self, solver: &Solver<'_>) -> Flow {
        let p = self.meter.update(solver);
        if let Some(events) = &mut self.events {
            events.progress(&p, solver.settings().converge);
        }
        let left = p.remaining.map_or_else(
            || "estimating time left".to_string(),
            |r| format!("about {} left", clock(r)),
        );
        let message = format!(
            "{} shots, unshot {:.2}% (stop at {:.2}%), {:.2}M rays/s, {}",
            p.shots,
            100.0 * p.unshot_fraction,
            100.0 * solver.settings().converge,
            p.rays_per_second / 1e6,
            left
        );
        if let Some(bar) = &self.bar {
            bar.set_position((p.completion * 1000.0) as u64);
            bar.set_message(message);
        } else if self.lines && self.last_line.elapsed() >= PROGRESS_LINE_INTERVAL {
            self.last_line = Instant::now();
            if let Some(header) = self.header.take() {
                eprintln!("{header}");
            }
            eprintln!("progress: {}, {} elapsed", message, clock(p.elapsed));
        }
        if self.interrupted.load(Ordering::SeqCst) {
            Flow::Stop
        } else {
            Flow::Continue
        }
    }

    fn interrupt(&self) -> Option<Arc<AtomicBool>> {
        Some(Arc::clone(&self.interrupted))
    }

    fn abort(&self) -> Option<Arc<AtomicBool>> {
        Some(Arc::clone(&self.abort))
    }

    fn final_pass(&mut self, what: &str, done: u64, total: u64, elapsed: Duration) {
        let fraction = if total > 0 {
            (done as f64 / total as f64).clamp(0.0, 1.0)
        } else {
            0.0
        };
        // The time left, from the rate so far once a second has passed.
        let remaining = (total > 0 && done > 0 && elapsed >= Duration::from_secs(1))
            .then(|| elapsed.mul_f64((1.0 - fraction) / fraction.max(1e-9)));
        let first = self.final_pass.as_deref() != Some(what);
        if first {
            self.final_pass = Some(what.to_string());
            self.last_line = Instant::now();
            if let Some(events) = &mut self.events {
                events.stage("final pass", serde_json::json!({ "what": what }));
            }
        }
        if let Some(events) = &mut self.events {
            events.final_pass(what, done, total, elapsed, remaining);
        }
        let message = if total > 0 {
            format!(
                "final pass: {what}, {:.0}% ({done} of {total} points), {}",
                100.0 * fraction,
                remaining.map_or_else(
                    || "estimating time left".to_string(),
                    |r| format!("about {} left", clock(r))
                )
            )
        } else {
            format!("final pass: {what}, {done} points")
        };
        if let Some(bar) = &self.bar {
            bar.set_position((fraction * 1000.0) as u64);
            bar.set_message(message);
        } else if self.lines && self.last_line.elapsed() >= PROGRESS_LINE_INTERVAL {
            self.last_line = Instant::now();
            eprintln!("{message}, {} elapsed", clock(elapsed));
        }
    }

    fn writing(&mut self, what: &str) {
        if let Some(events) = &mut self.events {
            events.stage("writing", serde_json::json!({ "message": what }));
        }
        if let Some(bar) = &self.bar {
            bar.set_message(what.to_string());
        } else if self.lines && self.header.is_none() {
            // Only in a log that shows progress already: a short run's log
            // holds only its summary.
            eprintln!("{what}");
        }
    }
}

/// The run's summary on standard output.
pub fn print_summary(o: &Outcome) {
    let c = o.counts;
    println!(
        "{}: {} surfaces ({} surface ids), {} shooters, {} elements, {} vertices",
        o.scene, c.surfaces, c.surface_ids, c.patches, c.elements, c.vertices
    );
    if c.refined_elements > 0 {
        println!(
            "refined: {} of {} elements split after a coarse pass of {} shots{}",
            c.refined_elements,
            c.base_elements,
            c.coarse_shots,
            if c.replayed_receivers > 0 {
                format!(
                    "; the solve went on from it, its shots replayed to {} new receivers",
                    c.replayed_receivers
                )
            } else {
                String::new()
            }
        );
    }
    match c.coarse_stop_reason {
        Some(StopReason::TimeLimit) => println!(
            "the coarse pass ran out of its quarter of --time-limit after {} shots: the mesh \
             depends on how fast this machine was",
            c.coarse_shots
        ),
        Some(StopReason::Stopped) => println!(
            "the coarse pass was stopped after {} shots: the base mesh was kept",
            c.coarse_shots
        ),
        _ => {}
    }
    if !o.lights.is_empty() {
        let lumens: f64 = o.lights.iter().map(|l| l.lumens).sum();
        println!(
            "lights: {} ({}), {:.0} lm sent",
            o.lights.len(),
            o.lights
                .iter()
                .map(|l| l.kind)
                .collect::<Vec<_>>()
                .join(", "),
            lumens
        );
        if o.lights.iter().any(|l| l.kind == "sky") {
            println!(
                "the sky: sampled through {} opening(s) (found in the geometry, marked with \
                 #@portal, or glass), the rest over its patches",
                o.stats.sky_portals
            );
        }
    }
    println!(
        "solved: {} shots, {} subsources, {} rays, unshot {:.2}% ({}) in {:.2} s on {} thread(s)",
        o.stats.shots,
        o.stats.subsources,
        o.stats.rays_cast,
        100.0 * o.unshot_fraction,
        o.stop.describe(),
        o.solve_time.as_secs_f64(),
        o.threads
    );
    if let Some(name) = &o.device.name {
        println!(
            "device: {name}: {} of {} shots{}; upload {:.2} s, kernels {:.2} s, readback \
             {:.2} s",
            o.device.device_shots,
            o.stats.shots,
            if c.coarse_shots > 0 {
                format!(
                    "; coarse pass {} of {} shots",
                    c.coarse_device_shots, c.coarse_shots
                )
            } else {
                String::new()
            },
            o.device.upload_time.as_secs_f64(),
            o.device.kernel_time.as_secs_f64(),
            o.device.readback_time.as_secs_f64()
        );
        if let Some(stages) = o.device.stages {
            let parts: Vec<String> = stages
                .named()
                .iter()
                .map(|(name, time)| format!("{name} {:.2} s", time.as_secs_f64()))
                .collect();
            println!("device time by stage: {}", parts.join(", "));
        }
    }
    if let Some(peak) = o.peak_memory_bytes {
        println!(
            "memory: peak {} resident (estimated {})",
            radiosity::memory::bytes(peak),
            radiosity::memory::bytes(o.memory_estimate.total())
        );
    }
    if let Some(l) = &o.lightmap {
        println!(
            "lightmap: {} x {} texels at {:.1} per metre ({}), {} texels shown{}; layout {:.2} s, \
             texels {:.2} s",
            l.width,
            l.height,
            l.density,
            if l.generated {
                format!("{} charts generated", l.charts)
            } else {
                "the input's TEXCOORD_1".into()
            },
            l.texels,
            if l.missing > 0 {
                format!(
                    ", {} found no element and took their neighbours' value",
                    l.missing
                )
            } else {
                String::new()
            },
            l.layout_seconds,
            l.texel_seconds
        );
    }
    for path in &o.written {
        println!("wrote {}", path.display());
    }
}
