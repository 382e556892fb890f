//! The run as other programs follow it: a stream of JSON events, one a
//! line (`--progress-json`), and a stop file whose appearance stops the
//! solve (`--stop-file`), the way a front end such as the Blender add-on
//! drives a progressive solve (Wallace, Elmquist & Haines 1989 made the
//! shooting loop progressive so it could be watched and stopped; this is
//! that, for a program instead of a person).
//!
//! Events (every object has `event`; numbers are plain JSON numbers):
//!
//! * `{"event": "stage", "stage": "refining"}`: receiver refinement's
//!   coarse pass has started;
//! * `{"event": "stage", "stage": "solving", "scene", "surfaces",
//!   "elements", "vertices"}`: the solve has started on its final mesh;
//! * `{"event": "progress", "shots", "unshot_fraction", "stop_at",
//!   "completion", "elapsed_s", "remaining_s", "rays_per_second"}`: after a
//!   shot, at most ten a second (and the last shot's always);
//! * `{"event": "stage", "stage": "writing", "message"}`: the solve has
//!   ended and the outputs are being made (again for an output that takes
//!   a while, such as a lightmap bake);
//! * `{"event": "stage", "stage": "final pass", "what"}`: the final pass
//!   has started on `what` (`picture`, `lightmap` or `sensors`);
//! * `{"event": "final_pass", "what", "done", "total", "completion",
//!   "elapsed_s", "remaining_s"}`: its points shaded so far (`total` 0 and
//!   `completion` null where not known beforehand), at most ten a second
//!   (and the last always);
//! * `{"event": "done", "stop_reason", "shots", "unshot_fraction",
//!   "solve_s", "written", "warnings"}`: the last line of a run that
//!   succeeded;
//! * `{"event": "error", "message"}`: the last line of a run that failed
//!   (also said on standard error), or that was ended before the final pass
//!   was done (the message names the outputs written and those not).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow};
use serde_json::{Value, json};

use radiosity::app::{Outcome, Progress};

/// Progress events are written at most this often.
pub const EVENT_INTERVAL: Duration = Duration::from_millis(100);

/// How often `--stop-file` is looked for.
pub const STOP_FILE_POLL: Duration = Duration::from_millis(100);

/// A stream of JSON events, one a line, flushed after each.
pub struct Events {
    out: Box<dyn Write + Send>,
    last_progress: Option<Instant>,
    /// The newest progress not yet written (throttled).
    pending: Option<Value>,
    /// Set once a write failed: the stream is then silent (a reader that
    /// went away must not stop the solve).
    broken: bool,
}

impl Events {
    /// Events to `path`, or to standard output for `-`.
    ///
    /// # Errors
    ///
    /// When the file cannot be created.
    pub fn open(path: &Path) -> Result<Events> {
        let out: Box<dyn Write + Send> = if path == Path::new("-") {
            Box::new(std::io::stdout())
        } else {
            Box::new(BufWriter::new(File::create(path).with_context(|| {
                format!("--progress-json: cannot create {}", path.display())
            })?))
        };
        Ok(Events {
            out,
            last_progress: None,
            pending: None,
            broken: false,
        })
    }

    fn write(&mut self, value: &Value) {
        if self.broken {
            return;
        }
        let ok = serde_json::to_writer(&mut self.out, value).is_ok()
            && self.out.write_all(b"\n").is_ok()
            && self.out.flush().is_ok();
        self.broken = !ok;
    }

    /// Writes a throttled progress event that is still waiting.
    fn flush_pending(&mut self) {
        if let Some(value) = self.pending.take() {
            self.write(&value);
        }
    }

    /// A `stage` event, with `fields` beside `stage`.
    pub fn stage(&mut self, stage: &str, fields: Value) {
        self.flush_pending();
        let mut value = json!({"event": "stage", "stage": stage});
        if let (Some(map), Value::Object(extra)) = (value.as_object_mut(), fields) {
            map.extend(extra);
        }
        self.write(&value);
    }

    /// A `progress` event, written now or with the next event when the
    /// last was written less than [`EVENT_INTERVAL`] ago.
    pub fn progress(&mut self, p: &Progress, stop_at: f64) {
        let value = json!({
            "event": "progress",
            "shots": p.shots,
            "unshot_fraction": finite(p.unshot_fraction),
            "stop_at": stop_at,
            "completion": finite(p.completion),
            "elapsed_s": p.elapsed.as_secs_f64(),
            "remaining_s": p.remaining.map(|r| r.as_secs_f64()),
            "rays_per_second": finite(p.rays_per_second),
        });
        self.throttled(value);
    }

    /// A `final_pass` event, throttled as [`Events::progress`] is.
    pub fn final_pass(
        &mut self,
        what: &str,
        done: u64,
        total: u64,
        elapsed: Duration,
        remaining: Option<Duration>,
    ) {
        let value = json!({
            "event": "final_pass",
            "what": what,
            "done": done,
            "total": total,
            "completion": (total > 0).then(|| (done as f64 / total as f64).min(1.0)),
            "elapsed_s": elapsed.as_secs_f64(),
            "remaining_s": remaining.map(|r| r.as_secs_f64()),
        });
        self.throttled(value);
    }

    /// Writes `value` now, or with the next event when the last throttled
    /// one was written less than [`EVENT_INTERVAL`] ago.
    fn throttled(&mut self, value: Value) {
        let due = self
            .last_progress
            .is_none_or(|t| t.elapsed() >= EVENT_INTERVAL);
        if due {
            self.pending = None;
            self.last_progress = Some(Instant::now());
            self.write(&value);
        } else {
            self.pending = Some(value);
        }
    }

    /// The `done` event of a run that succeeded.
    pub fn done(&mut self, o: &Outcome) {
        self.flush_pending();
        let value = json!({
            "event": "done",
            "stop_reason": o.stop.name(),
            "shots": o.stats.shots,
            "unshot_fraction": finite(o.unshot_fraction),
            "solve_s": o.solve_time.as_secs_f64(),
            "written": o.written.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "warnings": o.warnings,
        });
        self.write(&value);
    }

    /// The `error` event of a run that failed.
    pub fn error(&mut self, error: &anyhow::Error) {
        self.flush_pending();
        self.write(&json!({"event": "error", "message": format!("{error:#}")}));
    }
}

/// JSON has no infinities or NaN: those become `null`.
fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// Raises `flag` once `path` exists, looking every [`STOP_FILE_POLL`] from
/// a thread of its own (which ends with the process or the flag).
///
/// # Errors
///
/// When `path` exists already (a stale stop file would stop the run at
/// once) or its folder does not exist (it could never appear).
pub fn watch_stop_file(path: PathBuf, flag: Arc<AtomicBool>) -> Result<()> {
    if path.exists() {
        return Err(anyhow!(
            "--stop-file {} exists already: remove it, or name a file that does not exist",
            path.display()
        ));
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        return Err(anyhow!(
            "--stop-file {}: its folder {} does not exist",
            path.display(),
            parent.display()
        ));
    }
    std::thread::Builder::new()
        .name("stop-file".into())
        .spawn(move || {
            while !flag.load(Ordering::SeqCst) {
                if path.exists() {
                    eprintln!(
                        "{} appeared: stopping and writing the outputs from the state reached",
                        path.display()
                    );
                    flag.store(true, Ordering::SeqCst);
                    break;
                }
                std::thread::sleep(STOP_FILE_POLL);
            }
        })
        .context("cannot start the --stop-file watcher")?;
    Ok(())
}
