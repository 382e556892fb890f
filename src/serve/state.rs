//! What the solve thread and the web server share: the scene sent to every
//! client, the latest snapshot of the solution, the status line, and the
//! page's controls (pause, stop) and the shot counts at which the solve
//! holds by itself (`--pause-at`). The solve thread writes a snapshot at
//! most every [`SNAPSHOT_INTERVAL`] of solving, and whenever it pauses; it
//! never waits for the network and blocks only while paused.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, OnceLock};
use std::time::Duration;

use axum::body::Bytes;
use glam::DVec3;
use serde::Serialize;
use tokio::sync::watch;

use super::wire::{self, Rgbe};
use radiosity::app::{self, Counts, Observer, Outcome};
use radiosity::final_gather::{FinalGather, FinalPass};
use radiosity::mesh::Mesh;
use radiosity::render::Exposure;
use radiosity::scene::{Camera, Scene};
use radiosity::solver::Solver;
use radiosity::view;

/// Shortest solve time (pauses excluded) between two snapshots of the
/// solution taken while it runs: clients are sent at most this many
/// updates, and copying the radiosities costs the solve thread a copy of
/// one vector this often. A pause always takes one.
pub const SNAPSHOT_INTERVAL: Duration = Duration::from_millis(250);

/// Smallest side of the final picture, pixels.
pub const MIN_FRAME: u32 = 16;

/// Largest side of the final picture, pixels.
pub const MAX_FRAME: u32 = 4096;

/// Where the run is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// Loading and meshing the scene.
    Loading,
    /// Shooting.
    Solving,
    /// Held by the page's pause button.
    Paused,
    /// The solve has ended; the outputs are being written.
    Writing,
    /// Outputs written; the final state is served until Ctrl-C.
    Finished,
}

/// The status line every client shows, and `GET /api/status`.
#[derive(Clone, Debug, Serialize)]
pub struct Status {
    /// Where the run is.
    pub phase: Phase,
    /// Sequence number of the snapshot these counters belong to.
    pub seq: u64,
    /// Patches shot.
    pub shots: u64,
    /// Subsources shot.
    pub subsources: u64,
    /// Shadow rays cast.
    pub rays: u64,
    /// Rays a second over the time since the previous snapshot.
    pub rays_per_second: f64,
    /// Unshot power over emitted power.
    pub unshot_fraction: f64,
    /// Time spent solving, pauses excluded.
    pub elapsed_seconds: f64,
    /// The page asked for a pause that the solve has not reached yet.
    pub pause_requested: bool,
    /// The page (or Ctrl-C) asked to stop.
    pub stop_requested: bool,
    /// Why the solve ended, once it has.
    pub stop_reason: Option<&'static str>,
    /// Files written, once they are.
    pub written: Vec<String>,
    /// The device the transfers run on (`cpu`, or the GPU adapter's name
    /// and backend), once the solve has shot.
    pub device: String,
    /// Shots whose transfers ran on it.
    pub device_shots: u64,
    /// The size of the final picture, once the server has drawn it
    /// (`GET /api/frame.png`): the solution with the final pass
    /// ([`radiosity::final_gather`]), from the scene's view, when the solve
    /// has ended (converged, stopped or out of time); `None` before, or
    /// when the final pass is off.
    pub frame: Option<[u32; 2]>,
    /// While the outputs are made: what the final pass is shading
    /// (`picture`, `lightmap`, `sensors`) and its points shaded of the
    /// total (0 where not known beforehand).
    pub final_pass: Option<FinalPassStatus>,
}

/// The final pass's progress, as the page shows it.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FinalPassStatus {
    /// What it is shading.
    pub what: String,
    /// Points shaded.
    pub done: u64,
    /// Points to shade (0: not known beforehand).
    pub total: u64,
}

/// The solution at one moment.
#[derive(Debug)]
pub struct Snapshot {
    /// Increases with every snapshot.
    pub seq: u64,
    /// Radiosity `B` per vertex (W/m^2, emission included, ambient
    /// excluded).
    pub radiosity: Vec<DVec3>,
    /// The ambient term of Cohen et al. (1988), added for display as
    /// `rho ambient`.
    pub ambient: DVec3,
    rgbe: OnceLock<Vec<Rgbe>>,
}

impl Snapshot {
    /// The radiosities in RGBE, encoded once (by the server, off the solve
    /// thread) for all clients.
    pub fn rgbe(&self) -> &[Rgbe] {
        self.rgbe
            .get_or_init(|| self.radiosity.iter().map(|b| wire::rgbe(*b)).collect())
    }
}

/// One vertex as the picker reports it.
#[derive(Clone, Copy, Debug)]
pub struct VertexInfo {
    /// Position, metres.
    pub position: DVec3,
    /// Unit normal.
    pub normal: DVec3,
    /// The input face it lies on (as in the vertex CSV).
    pub face: u32,
    /// Reflectance of its surface.
    pub rho: DVec3,
    /// Exitance of its surface, W/m^2.
    pub emission: DVec3,
}

/// The meshed scene, sent to every client when it connects.
#[derive(Debug)]
pub struct SceneInfo {
    /// The first message: name, counts, camera, display settings (JSON).
    pub json: String,
    /// The second message: [`wire::mesh_message`].
    pub mesh: Bytes,
    /// Per-vertex data for the picker.
    pub vertices: Vec<VertexInfo>,
}

/// The display settings the page starts with.
#[derive(Clone, Copy, Debug)]
pub struct Display {
    /// The view; `None` takes the scene's camera or one framing it.
    pub camera: Option<Camera>,
    /// Show the ambient term.
    pub ambient: bool,
    /// Stops on top of automatic exposure.
    pub exposure: f64,
    /// What the final picture shows (the job's `--final-gather`): with
    /// `off`, the page's own picture of the mesh is the last word.
    pub final_gather: FinalGather,
}

struct Inner {
    snapshot: Option<Arc<Snapshot>>,
    status: Status,
    paused: bool,
    /// Shot counts at which the solve pauses by itself, ascending; each is
    /// removed once reached.
    holds: Vec<u64>,
    /// The final picture (PNG), once drawn.
    frame: Option<Bytes>,
}

/// State shared by the solve thread, the server's tasks and the Ctrl-C
/// handler.
pub struct Shared {
    display: Display,
    scene: OnceLock<SceneInfo>,
    inner: Mutex<Inner>,
    /// Wakes a paused solve.
    resume: Condvar,
    /// Read on every shot without taking the lock.
    pub(super) pause_flag: AtomicBool,
    pub(super) stop_flag: Arc<AtomicBool>,
    /// Set by a stop while the outputs are made: the final pass ends.
    pub(super) abort_flag: Arc<AtomicBool>,
    shutdown_flag: AtomicBool,
    /// Bumped on every change clients should see.
    changed: watch::Sender<u64>,
    /// Set when the server is to close.
    closing: watch::Sender<bool>,
    /// The size the page draws at, for the final picture.
    view_size: Mutex<[u32; 2]>,
}

impl Shared {
    /// Fresh state: loading, nothing to show yet. The solve pauses by
    /// itself once it has made each of `pause_at` shots (0: before the
    /// first), as if the page's pause had been pressed then.
    pub fn new(display: Display, pause_at: &[u64]) -> Shared {
        let mut holds = pause_at.to_vec();
        holds.sort_unstable();
        holds.dedup();
        Shared {
            display,
            scene: OnceLock::new(),
            inner: Mutex::new(Inner {
                snapshot: None,
                status: Status {
                    phase: Phase::Loading,
                    seq: 0,
                    shots: 0,
                    subsources: 0,
                    rays: 0,
                    rays_per_second: 0.0,
                    unshot_fraction: 1.0,
                    elapsed_seconds: 0.0,
                    pause_requested: false,
                    stop_requested: false,
                    stop_reason: None,
                    written: Vec::new(),
                    device: "cpu".to_string(),
                    device_shots: 0,
                    frame: None,
                    final_pass: None,
                },
                paused: false,
                holds,
                frame: None,
            }),
            resume: Condvar::new(),
            pause_flag: AtomicBool::new(false),
            stop_flag: Arc::new(AtomicBool::new(false)),
            abort_flag: Arc::new(AtomicBool::new(false)),
            shutdown_flag: AtomicBool::new(false),
            changed: watch::Sender::new(0),
            closing: watch::Sender::new(false),
            view_size: Mutex::new(app::DEFAULT_PICTURE),
        }
    }

    /// What the final picture shows ([`Display::final_gather`]).
    pub fn final_gather(&self) -> FinalGather {
        self.display.final_gather
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        // A panic elsewhere while holding the lock leaves consistent data
        // (every write is a plain assignment), so carry on.
        self.inner
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn notify(&self) {
        self.changed.send_modify(|v| *v = v.wrapping_add(1));
    }

    /// The meshed scene, once loaded.
    pub fn scene(&self) -> Option<&SceneInfo> {
        self.scene.get()
    }

    /// The status line and the latest snapshot.
    pub fn current(&self) -> (Status, Option<Arc<Snapshot>>) {
        let inner = self.lock();
        (inner.status.clone(), inner.snapshot.clone())
    }

    /// Subscribes to changes of the status or the snapshot.
    pub fn subscribe(&self) -> watch::Receiver<u64> {
        self.changed.subscribe()
    }

    /// Subscribes to the server's closing.
    pub fn closing(&self) -> watch::Receiver<bool> {
        self.closing.subscribe()
    }

    /// Holds the solve after its current shot. A pause that comes after a
    /// resume the solve thread has not taken up yet (its phase still says
    /// paused) keeps it paused.
    pub fn pause(&self) {
        let mut inner = self.lock();
        let running = matches!(
            inner.status.phase,
            Phase::Loading | Phase::Solving | Phase::Paused
        );
        if running && !inner.paused {
            inner.paused = true;
            inner.status.pause_requested = inner.status.phase != Phase::Paused;
            self.pause_flag.store(true, Ordering::SeqCst);
        }
        drop(inner);
        self.notify();
    }

    /// Lets a paused solve go on.
    pub fn resume(&self) {
        let mut inner = self.lock();
        inner.paused = false;
        inner.status.pause_requested = false;
        self.pause_flag.store(false, Ordering::SeqCst);
        drop(inner);
        self.resume.notify_all();
        self.notify();
    }

    /// Ends the solve after its current shot; the outputs are then written
    /// from the state reached. While they are made (the final pass), ends
    /// that too: the outputs complete are written, the others named.
    pub fn stop(&self) {
        let mut inner = self.lock();
        if !matches!(inner.status.phase, Phase::Writing | Phase::Finished) {
            inner.status.stop_requested = true;
        }
        if inner.status.phase == Phase::Writing {
            self.abort_flag.store(true, Ordering::SeqCst);
        }
        self.stop_flag.store(true, Ordering::SeqCst);
        drop(inner);
        self.resume.notify_all();
        self.notify();
    }

    /// Ctrl-C: stop the solve (if it still runs), then close once the
    /// outputs are written.
    pub fn request_shutdown(&self) {
        self.shutdown_flag.store(true, Ordering::SeqCst);
        self.stop();
    }

    /// Whether Ctrl-C (or [`Shared::request_shutdown`]) was received.
    pub fn shutdown_requested(&self) -> bool {
        self.shutdown_flag.load(Ordering::SeqCst)
    }

    /// Tells the server's tasks to close their connections.
    pub fn close(&self) {
        self.closing.send_replace(true);
    }

    /// The run is over: `outcome`'s files are written.
    pub fn finished(&self, outcome: &Outcome) {
        let mut inner = self.lock();
        inner.status.phase = Phase::Finished;
        inner.status.final_pass = None;
        inner.status.stop_reason = Some(outcome.stop.describe());
        inner.status.written = outcome
            .written
            .iter()
            .map(|p| p.display().to_string())
            .collect();
        inner.status.pause_requested = false;
        drop(inner);
        self.notify();
    }

    /// The size the page draws at (device pixels), for the final picture:
    /// clamped to [`MIN_FRAME`, `MAX_FRAME`] per side.
    pub fn set_view_size(&self, width: u32, height: u32) {
        let clamp = |v: u32| v.clamp(MIN_FRAME, MAX_FRAME);
        *self
            .view_size
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = [clamp(width), clamp(height)];
    }

    /// The final picture (PNG), once drawn.
    pub fn frame(&self) -> Option<Bytes> {
        self.lock().frame.clone()
    }

    /// Draws the final picture of `solver`'s solution from the scene's
    /// view at the page's size, with the final pass, as `radiosity render`
    /// draws its picture ([`app::picture`]: 3 x 3 supersampling, automatic
    /// exposure plus the display's stops), telling `observer` its progress,
    /// and publishes it; a stop pressed mid-way leaves it unpublished.
    pub(super) fn draw_frame(&self, solver: &Solver<'_>, observer: &mut dyn Observer) {
        let scene = solver.scene();
        let [width, height] = *self
            .view_size
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let mut pass = FinalPass::new(solver, self.display.final_gather);
        if let Some(flag) = observer.abort() {
            pass.stop_on(flag);
        }
        let image = app::picture(
            solver,
            Some(&pass),
            &app::PictureView {
                width,
                height,
                camera: self.camera_of(scene),
                supersampling: 3,
                ambient: self.display.ambient,
            },
            observer,
        );
        if pass.cut_short() {
            return;
        }
        let scale = image.exposure_scale(Exposure::Auto {
            ev: self.display.exposure,
        });
        let mut png = Vec::new();
        if radiosity::export::write_png(&mut png, width, height, &image.to_srgb8(scale)).is_err() {
            return;
        }
        let mut inner = self.lock();
        inner.frame = Some(Bytes::from(png));
        inner.status.frame = Some([width, height]);
        drop(inner);
        self.notify();
    }

    /// The view the page starts from: the display's camera, or the
    /// scene's, or one framing it.
    fn camera_of(&self, scene: &Scene) -> Camera {
        self.display
            .camera
            .unwrap_or_else(|| view::camera_or_framing(scene))
    }

    pub(super) fn set_scene(&self, scene: &Scene, mesh: &Mesh) {
        let camera = self.camera_of(scene);
        let counts = Counts::of(scene, mesh);
        let (lo, hi) = scene.bounds();
        let mesh_message = wire::mesh_message(scene, mesh);
        let json = serde_json::json!({
            "type": "scene",
            "name": scene.name,
            "surfaces": counts.surfaces,
            "patches": counts.patches,
            "elements": counts.elements,
            "vertices": counts.vertices,
            "triangles": wire::triangles(mesh).len(),
            "bounds": [lo.to_array(), hi.to_array()],
            "camera": {
                "eye": camera.eye.to_array(),
                "target": camera.target.to_array(),
                "up": camera.up.to_array(),
                "fov": camera.fov_degrees,
            },
            "ambient": self.display.ambient,
            "exposure": self.display.exposure,
        })
        .to_string();
        let vertices = mesh
            .vertices
            .iter()
            .map(|v| {
                let surface = &scene.surfaces[v.surface as usize];
                VertexInfo {
                    position: v.position,
                    normal: v.normal,
                    face: surface.face,
                    rho: surface.rho,
                    emission: surface.emission,
                }
            })
            .collect();
        // Only one solve runs per server: a second call keeps the first.
        let _ = self.scene.set(SceneInfo {
            json,
            mesh: Bytes::from(mesh_message),
            vertices,
        });
    }

    pub(super) fn publish(
        &self,
        radiosity: Vec<DVec3>,
        ambient: DVec3,
        update: impl FnOnce(&mut Status),
    ) {
        let mut inner = self.lock();
        let seq = inner.snapshot.as_ref().map_or(1, |s| s.seq + 1);
        inner.snapshot = Some(Arc::new(Snapshot {
            seq,
            radiosity,
            ambient,
            rgbe: OnceLock::new(),
        }));
        inner.status.seq = seq;
        update(&mut inner.status);
        drop(inner);
        self.notify();
    }

    /// The final pass's progress, told to the page.
    pub(super) fn set_final_pass(&self, progress: FinalPassStatus) {
        let mut inner = self.lock();
        if inner.status.final_pass.as_ref() == Some(&progress) {
            return;
        }
        inner.status.final_pass = Some(progress);
        drop(inner);
        self.notify();
    }

    pub(super) fn set_phase(&self, phase: Phase) {
        let mut inner = self.lock();
        inner.status.phase = phase;
        match phase {
            Phase::Paused => inner.status.pause_requested = false,
            // A pause that came while the solve was waking up is pending.
            Phase::Solving => inner.status.pause_requested = inner.paused,
            _ => {}
        }
        drop(inner);
        self.notify();
    }

    /// Pauses the solve if it has reached a hold of `--pause-at` with
    /// `shots` shots (every hold at or below `shots` is then used up).
    pub(super) fn hold_at(&self, shots: u64) {
        let mut inner = self.lock();
        let reached = inner.holds.partition_point(|&h| h <= shots);
        if reached > 0 {
            inner.holds.drain(..reached);
            inner.paused = true;
            self.pause_flag.store(true, Ordering::SeqCst);
        }
    }

    /// Blocks the solve thread while paused; true if it should stop.
    pub(super) fn wait_while_paused(&self) -> bool {
        let mut inner = self.lock();
        while inner.paused && !self.stop_flag.load(Ordering::SeqCst) {
            inner = self
                .resume
                .wait(inner)
                .unwrap_or_else(std::sync::PoisonError::into_inner);
        }
        self.stop_flag.load(Ordering::SeqCst)
    }
}

/// The ambient term before any shot, when every patch's unshot radiosity
/// is its emission: [`Solver::ambient`] at the start (Cohen et al. 1988;
/// design.md section 2), without building a solver.
#[must_use]
pub fn initial_ambient(scene: &Scene, mesh: &Mesh) -> DVec3 {
    let mut area = 0.0;
    let mut unshot = DVec3::ZERO;
    let mut rho = DVec3::ZERO;
    for patch in &mesh.patches {
        let surface = &scene.surfaces[patch.surface as usize];
        area += patch.area;
        unshot += surface.emission * patch.area;
        rho += surface.rho * patch.area;
    }
    if area <= 0.0 {
        return DVec3::ZERO;
    }
    (unshot / area) / (DVec3::ONE - rho / area)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serve::observer::{LiveObserver, Throttle};
    use radiosity::mesh::MeshSettings;
    use radiosity::solver::Settings;

    /// The page's defaults: the scene's view, the ambient term shown, no
    /// stops, the default final pass.
    fn plain_display() -> Display {
        Display {
            camera: None,
            ambient: true,
            exposure: 0.0,
            final_gather: FinalGather::Direct,
        }
    }

    /// Snapshots while solving: the first shot's, then one once the
    /// interval of solve time has passed since the last, whatever took it.
    #[test]
    fn snapshots_are_an_interval_of_solve_time_apart() {
        let ms = Duration::from_millis;
        let mut throttle = Throttle::default();
        assert!(throttle.due(Duration::ZERO), "the first shot's");
        throttle.taken(ms(40));
        assert!(!throttle.due(ms(40)));
        assert!(!throttle.due(ms(40) + SNAPSHOT_INTERVAL - Duration::from_nanos(1)));
        assert!(throttle.due(ms(40) + SNAPSHOT_INTERVAL));
        // A pause's snapshot (taken whenever the pause comes) starts the
        // interval again.
        throttle.taken(ms(100));
        assert!(!throttle.due(ms(300)));
        assert!(throttle.due(ms(350)));
        // Solve time never runs backwards, but a clock read before the last
        // snapshot is not due.
        assert!(!throttle.due(ms(10)));
    }

    /// Holds of `--pause-at` pause the solve once, at the first shot count
    /// at or past them, in any order given.
    #[test]
    fn holds_pause_once_at_their_shot_counts() {
        let shared = Shared::new(plain_display(), &[5, 0, 9, 5]);
        let paused = |shared: &Shared| shared.pause_flag.load(Ordering::SeqCst);
        shared.hold_at(0);
        assert!(paused(&shared));
        shared.resume();
        for shots in 1..5 {
            shared.hold_at(shots);
            assert!(!paused(&shared), "{shots}");
        }
        shared.hold_at(5);
        assert!(paused(&shared));
        shared.resume();
        // A count past a hold not asked at it still pauses.
        shared.hold_at(12);
        assert!(paused(&shared));
        shared.resume();
        shared.hold_at(13);
        assert!(!paused(&shared), "every hold used up");
        assert!(shared.lock().holds.is_empty());
    }

    /// The final pass's progress reaches the page's status (and its JSON),
    /// the newest each time.
    #[test]
    fn the_final_pass_progress_is_in_the_status() {
        let shared = Arc::new(Shared::new(plain_display(), &[]));
        assert_eq!(shared.current().0.final_pass, None);
        let mut observer = LiveObserver::new(Arc::clone(&shared));
        observer.final_pass("picture", 10, 40, Duration::ZERO);
        observer.final_pass("picture", 25, 40, Duration::from_secs(1));
        let status = shared.current().0;
        assert_eq!(
            status.final_pass,
            Some(FinalPassStatus {
                what: "picture".into(),
                done: 25,
                total: 40,
            })
        );
        let json = serde_json::to_value(&status).unwrap();
        assert_eq!(json["final_pass"]["done"], 25);
        assert_eq!(json["final_pass"]["what"], "picture");
    }

    /// A stop while the solve runs ends the solve, not the final pass
    /// that follows (the picture of what was reached is still drawn); a stop
    /// while the outputs are made ends the final pass.
    #[test]
    fn a_stop_in_the_final_pass_ends_it() {
        let shared = Arc::new(Shared::new(plain_display(), &[]));
        let observer = LiveObserver::new(Arc::clone(&shared));
        let abort = observer.abort().unwrap();
        let interrupt = observer.interrupt().unwrap();
        shared.set_phase(Phase::Solving);
        shared.stop();
        assert!(interrupt.load(Ordering::SeqCst));
        assert!(!abort.load(Ordering::SeqCst));
        shared.set_phase(Phase::Writing);
        shared.stop();
        assert!(abort.load(Ordering::SeqCst));
    }

    /// A pause right after a resume, before the solve thread has woken,
    /// keeps the solve paused; pressing pause while paused changes nothing.
    #[test]
    fn a_pause_right_after_resume_is_not_lost() {
        let shared = Shared::new(plain_display(), &[]);
        shared.set_phase(Phase::Solving);
        shared.pause();
        assert!(shared.current().0.pause_requested);
        // The solve thread takes the pause.
        shared.set_phase(Phase::Paused);
        assert!(!shared.current().0.pause_requested);
        shared.pause();
        assert!(!shared.current().0.pause_requested, "already paused");
        shared.resume();
        assert!(!shared.pause_flag.load(Ordering::SeqCst));
        // Pause again before the solve thread has run: its phase still
        // says paused, and the solve must stay held.
        shared.pause();
        assert!(shared.pause_flag.load(Ordering::SeqCst));
        assert!(shared.lock().paused);
        assert!(!shared.current().0.pause_requested);
        // The solve thread wakes (the resume it saw) with that pause
        // pending: the status says so until the shot ends.
        shared.set_phase(Phase::Solving);
        assert!(shared.current().0.pause_requested);
        assert!(shared.pause_flag.load(Ordering::SeqCst));
        // Once writing, pause does nothing.
        shared.resume();
        shared.set_phase(Phase::Writing);
        shared.pause();
        assert!(!shared.pause_flag.load(Ordering::SeqCst));
    }

    /// The ambient term shown before the first shot is the solver's own at
    /// the start.
    #[test]
    fn initial_ambient_is_the_solvers() {
        for name in ["cornell", "room"] {
            let scene = radiosity::scene::load(name).unwrap();
            let sized = MeshSettings::default().sized_for(&scene);
            let settings = MeshSettings {
                element_size: 4.0 * sized.element_size,
                ..sized
            };
            let mesh = Mesh::build(&scene, &settings).unwrap();
            let solver = Solver::new(&scene, &mesh, Settings::wong_tsang93());
            let expected = solver.ambient();
            let got = initial_ambient(&scene, &mesh);
            assert!(expected.max_element() > 0.0);
            assert!(
                (got - expected).length() <= 1e-12 * expected.length(),
                "{name}: {got} vs {expected}"
            );
        }
    }
}
